"""The benchmark harness end to end on one tiny knob, so that ``python -m bench`` cannot rot.

Runs ``python -m bench --quick --only atmosphere`` in-process (a few seconds): the knob validates
the reference chain against the float64 oracles, times both settings, and the command writes the
JSON, Markdown and Pareto plot. No timing is asserted, only that the numbers exist and make sense.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.bench


@pytest.fixture
def bench_main() -> Iterator[Callable[[list[str]], int]]:
    if not (ROOT / "bench" / "__main__.py").is_file():
        pytest.skip("bench/ is not in this checkout (installed package only)")
    sys.path.insert(0, str(ROOT))
    try:
        from bench.__main__ import main

        yield main
    finally:
        sys.path.remove(str(ROOT))


def test_quick_atmosphere_knob_end_to_end(bench_main: Callable[[list[str]], int], tmp_path: Path) -> None:
    assert bench_main(["--quick", "--only", "atmosphere", "--out", str(tmp_path), "--no-docs"]) == 0
    (result,) = tmp_path.glob("*-quick-atmosphere.json")
    data = json.loads(result.read_text())
    fam = data["knobs"]["atmosphere"]
    rows = {r["setting"].split(" (")[0]: r for r in fam["rows"]}
    assert set(rows) == {"atmosphere on", "atmosphere off"}
    for r in rows.values():
        assert r["seconds"] > 0 and math.isfinite(r["speedup"])
        assert 0 < r["rms_cab"] < 50  # ug/cm2: a chlorophyll retrieval, not garbage
    assert rows["atmosphere on"]["default"]
    # the reference chain was validated against the float64 numpy oracles before anything was timed
    assert data["validation"]["chain: reference_band_radiance_max_rel_vs_numpy"] < 1e-10
    assert data["validation"]["chain: reference_lp_vs_scipy_nm"] < 1e-2
    assert len(data["load_average"]["before"]) == 3 and len(data["load_average"]["after"]) == 3
    assert rows["atmosphere off"]["err_radiance_ner_max"] > 1  # the atmosphere is far above the noise
    md = result.with_suffix(".md").read_text()
    assert "What accuracy costs" in md and "atmosphere off" in md and "load average" in md
    assert result.with_name(result.stem + "-pareto.png").stat().st_size > 1000


def test_only_rejects_unknown_part(bench_main: Callable[[list[str]], int]) -> None:
    with pytest.raises(SystemExit, match="unknown part"):
        bench_main(["--only", "no-such-knob"])


def test_validation_failure_exits_1(bench_main: Callable[[list[str]], int], tmp_path: Path,
                                    monkeypatch: pytest.MonkeyPatch) -> None:
    import bench.chain
    from bench.common import BenchValidationError

    def wrong(ctx: bench.chain.Context) -> None:
        raise BenchValidationError("float64 chain band radiance disagrees with the numpy oracle (simulated)")

    monkeypatch.setattr(bench.chain, "validate_reference", wrong)
    with pytest.raises(SystemExit) as exit_info:
        bench_main(["--quick", "--only", "atmosphere", "--out", str(tmp_path), "--no-docs"])
    assert exit_info.value.code == 1
    assert not list(tmp_path.iterdir())  # nothing timed, nothing written
