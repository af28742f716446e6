"""The benchmark harness end to end on one tiny knob, so that ``python -m bench`` cannot rot.

Runs ``python -m bench --quick --only atmosphere`` in-process (a few seconds): the knob validates
the reference chain against the float64 oracles, times both settings, and the command writes the
JSON, Markdown and Pareto plot. No timing is asserted, only that the numbers exist and make sense.
Also: the registry's families are consistent with the functions they run, every shipped suite
result still renders, and the one sweep-kernel check passes the kernel and stops a wrong one.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.bench


@pytest.fixture
def bench_main(bench_path: None) -> Callable[[list[str]], int]:
    from bench.__main__ import main

    return main


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


def test_registry_declares_every_family_once(bench_main: Callable[[list[str]], int]) -> None:
    import inspect

    from bench.registry import FAMILIES, GROUPS

    assert len({f.name for f in FAMILIES}) == len(FAMILIES)
    assert {f.group.key for f in FAMILIES} == {g.key for g in GROUPS}
    for f in FAMILIES:
        assert f.columns and f.full.keys() == f.quick.keys(), f.name
        params = list(inspect.signature(f.run).parameters)
        assert params[0] == "ctx" and set(f.full) <= set(params[1:]), f.name  # run(ctx, **sizes)


def test_report_renders_every_shipped_suite_result(bench_main: Callable[[list[str]], int]) -> None:
    """Older results (from before the registry) still render, every family with its table."""
    from bench.registry import FAMILIES
    from bench.report import markdown

    shipped = [json.loads(p.read_text()) for p in sorted((ROOT / "bench" / "results").glob("*.json"))]
    suites = [r for r in shipped if r.get("benchmark") == "s2cl suite"]
    assert suites
    for results in suites:
        md = markdown(results, {}, docs=True)
        assert "does not declare" not in md and "Why the defaults" in md
        for f in FAMILIES:
            if f.key in results.get(f.group.key, {}):
                assert f.title in md or results[f.group.key][f.key].get("title", "") in md, f.name


def test_sweep_validation_fails_on_a_wrong_kernel(bench_main: Callable[[list[str]], int]) -> None:
    """The one sweep check passes the real kernel and stops one whose statuses disagree."""
    from dataclasses import replace

    from bench.chain import Context
    from bench.common import BenchValidationError
    from bench.scaling import _sweep_scene
    from bench.sweep_check import SAME_STATUS_MIN, validate_sweep
    from s2cl.app.plan import plan_sweep
    from s2cl.reference.sweep import evaluate

    job = plan_sweep(_sweep_scene(Context.make(True), 2))
    ok = validate_sweep(job)
    assert ok["same_status_class_fraction"] >= SAME_STATUS_MIN and "criterion" in ok

    def wrong(start: int, stop: int) -> Any:  # a raw chunk whose fits all come back degenerate or invalid
        raw = evaluate(job.tables, job.analysis, start, stop)
        return replace(raw, status=((raw.status + 2) % 6).astype(raw.status.dtype))

    with pytest.raises(BenchValidationError, match="disagrees"):
        validate_sweep(job, wrong)


@pytest.mark.skipif(not any(__import__("shutil").which(c) for c in ("cc", "gcc")), reason="needs a C compiler")
def test_native_resampling_reference_agrees_with_the_oracle(bench_path: None) -> None:
    """``python -m bench.resample_native``'s compiled C loop (the kernel's access pattern, for the profile) is checked
    against the float64 oracle before it is timed, on a pixel count with a partial last block of rows."""
    from bench.resample_native import measure

    result = measure(1003, 1)
    assert set(result["median_rate_per_s"]) == {*result["kernel_over_this_median_paired"],
                                                "s2cl OpenCL kernel (data on the device)"}
    assert all(r > 0 for r in result["median_rate_per_s"].values())
    assert max(result["validation_max_rel_vs_float64"].values()) < 2e-6


def test_resample_rounds_summary_states_the_goal_against_the_bound_and_the_read(bench_path: None) -> None:
    """``bench_resample``'s summary (the figures docs/performance.md quotes for the 2× goal): the bound is the best
    read bandwidth of all rounds, and each round's kernel and 2× baseline are set against the faster of that
    round's two no-arithmetic reads."""
    from bench.bench_resample import BANDS_READ, UNION_READ, rounds_summary
    from bench.common import comparison_rows

    def round_(api: float, kernel: float, numpy: float, union: float, bands: float, read_gbps: float) -> dict:
        rates = {"api": api, "kernel": kernel, "numpy": numpy, "support-read bound": 1.0, UNION_READ: union,
                 BANDS_READ: bands}
        return {"rows": comparison_rows(rates, "numpy"), "read_bandwidth_GBps": read_gbps,
                "support_bytes_per_spectrum": 5000.0}

    result = rounds_summary([round_(9.0, 9.5, 5.0, 10.0, 11.0, 50.0), round_(6.0, 6.4, 2.5, 8.0, 7.5, 40.0),
                             round_(8.0, 8.2, 4.0, 9.0, 8.5, 45.0)])
    assert result["rows"][0]["per_s"] == 8.0  # the round with the median ratio over numpy (2.0 of 1.8, 2.4, 2.0)
    bound = 50e9 / 5000.0  # spectra/s at the best bandwidth of the three rounds
    assert result["goal_2x_share_of_bound"] == pytest.approx([10 / bound, 5 / bound, 8 / bound])
    assert result["share_of_read"]["s2cl kernel alone"] == pytest.approx([9.5 / 11, 6.4 / 8, 8.2 / 9])
    assert result["share_of_read"]["2× the per-band slices"] == pytest.approx([10 / 11, 5 / 8, 8 / 9])
