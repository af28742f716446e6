"""Design-level knobs (``python -m bench.design_knobs``) end to end in their tiny version, and the ranking
comparison's identities. No timing is asserted, only that the numbers exist and make sense."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.bench


def _frame(rms: list[float], centres: list[float], underdetermined: list[bool] | None = None) -> Any:
    import pandas as pd

    n = len(rms)
    return pd.DataFrame({"config": range(n), "B4_centre_nm": centres, "B4_width_nm": [30.0] * n,
                         "underdetermined": underdetermined or [False] * n, "rms": rms})


def test_compare_identities(bench_path: None) -> None:
    from bench.design_rank import compare, ranked

    a = ranked(_frame([3.0, 1.0, 2.0, float("nan"), 0.5], [650, 655, 660, 665, 670], [0, 0, 0, 0, 1]))
    assert len(a) == 3 and a["B4_centre_nm"].iloc[0] == 655  # NaN and underdetermined designs are not ranked
    same = compare(a, a)
    assert same["spearman"] == 1 and same["one_minus_rho"] == 0 and same["same_winner"]
    assert same["winner_rank_in_reference"] == 1 and same["regret"] == 0 and same["max_abs_delta"] == 0
    # a coarser grid: two of the reference's designs, its winner not among them
    coarse = ranked(_frame([3.0, 2.0], [650, 660]))
    c = compare(coarse, a)
    assert c["compared"] == 2 and not c["same_winner"] and c["winner_rank_in_reference"] == 2
    assert c["regret"] == pytest.approx(1.0) and c["max_abs_delta"] == 0 and c["spearman"] == 1
    flipped = compare(ranked(_frame([1.0, 2.0, 3.0], [650, 655, 660])), a)
    assert flipped["spearman"] == pytest.approx(-0.5) and flipped["winner_rank_in_reference"] == 3


def test_splice_keeps_the_rest_of_the_page(bench_path: None) -> None:
    from bench.design_report import END, START, splice

    page = "# B\n\n## What accuracy costs\n\ntext\n\n## Throughput and scaling\n\nmore\n"
    once = splice(page, f"{START}\nv1\n{END}")
    assert once.index("v1") < once.index("## Throughput") and once.count(START) == 1
    twice = splice(once, f"{START}\nv2\n{END}")
    assert "v1" not in twice and "v2" in twice and twice.replace("v2", "v1") == once


def test_quick_design_knobs_end_to_end(bench_path: None, tmp_path: Path) -> None:
    from bench.design_knobs import main

    assert main(["--quick", "--out", str(tmp_path), "--no-docs"]) == 0
    data = json.loads((tmp_path / "design-knobs-quick.json").read_text())
    assert data["benchmark"] == "design-knobs" and data["quick"]
    assert len(data["load_average"]["before"]) == 3 and data["machine"]["cores"] >= 1
    assert data["validation"]["rms_rel_diff_max"] < 1e-3  # the kernel was checked before anything was timed
    knobs = {k["key"]: k for k in data["knobs"]}
    assert set(knobs) == {"step", "library", "copies", "precision", "igrm", "lut"}
    for k in knobs.values():
        ref, *rows = k["rows"]
        assert ref["reference"] and rows and not any(r["reference"] for r in rows)
        # the reference run twice: the same ranking, the same winner
        assert ref["spearman"] == 1 and ref["same_winner"] and ref["winner_rank_in_reference"] == 1
        assert ref["max_abs_delta"] == 0 and ref["regret"] == 0 and ref["speedup"] == 1
        assert len(ref["times"]) == data["repeat"] >= 2
        for r in k["rows"]:
            assert r["seconds_min"] <= r["seconds"] <= r["seconds_max"] and math.isfinite(r["speedup"])
            assert -1 <= r["spearman"] <= 1 and r["compared"] > 1 and r["winner_rank_in_reference"] >= 1
            assert r["regret"] >= 0 and r["max_abs_delta"] >= 0 and 0 <= r["top10_shared"] <= 10
            assert (r["winner_rank_in_reference"] == 1) == r["same_winner"] == (r["regret"] == 0)
            assert r["repeat_max_abs_delta"] == 0  # every sweep, run twice, gives the same numbers
    step = knobs["step"]["rows"]
    # common random numbers: on the designs both grids hold, the RMS does not depend on the grid
    assert step[1]["configurations"] < step[0]["configurations"]
    assert step[1]["spearman"] == 1 and step[1]["max_abs_delta"] == 0
    assert 0 < knobs["precision"]["rows"][1]["max_abs_delta"] < 0.1  # float32 vs float64: close, not equal
    assert sum(r["default"] for r in knobs["precision"]["rows"]) == 1
    md = (tmp_path / "design-knobs-quick.md").read_text()
    assert "Spearman ρ" in md and "load average" in md and "every other node, nearest" in md
    assert (tmp_path / "design-knobs-quick.png").stat().st_size > 10_000
