"""Design validity (s2cl.retrieve.design): one rule for simulate, sweeps, counts and the direct APIs; underdetermined
designs are flagged in results.parquet, counted in summary.json and left out of the ranking."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from s2cl.retrieve.design import count_underdetermined, design_problem, underdetermined
from s2cl.sensor.variants import table2_space


def test_igrm_needs_four_distinct_centres() -> None:
    assert design_problem("igrm", ["B4", "B5", "B6", "B7"], [665, 705, 740, 783], [30, 15, 15, 20]) is None
    problem = design_problem("igrm", ["B4", "B5", "B6", "B8"], [655, 730, 730, 790], [45, 20, 20, 40])
    assert problem and "B5 and B6 at 730 nm" in problem and "only 3 distinct centres" in problem
    # five bands with one pair on one centre still give four abscissae
    assert design_problem("igrm", list("abcde"), [665, 705, 705, 740, 783], [30] * 5) is None


def test_gvmi_and_sam_conditions() -> None:
    assert design_problem("gvmi", ["B8a", "B11"], [865, 865], [20, 20]) is not None
    assert design_problem("gvmi", ["B8a", "B11"], [865, 1610], [20, 90]) is None
    assert design_problem("sam", ["B11", "B12"], [2190, 2190], [30, 30]) is not None
    assert design_problem("sam", ["B11", "B12"], [2190, 2190], [30, 60]) is None


def test_vectorised_rule_equals_the_single_design_rule() -> None:
    rng = np.random.default_rng(1)
    centres = rng.choice([700.0, 705.0, 710.0], size=(500, 4))
    widths = rng.choice([15.0, 20.0], size=(500, 4))
    names = ["a", "b", "c", "d"]
    for kind in ("igrm", "sam", "gvmi"):
        flags = underdetermined(kind, centres, widths)
        single = [design_problem(kind, names, c, w) is not None for c, w in zip(centres, widths, strict=True)]
        assert flags.tolist() == single, kind


@pytest.mark.parametrize("bands", [["B4", "B5", "B6", "B8"], ["B4", "B5", "B6", "B7"]])
def test_counting_without_enumerating_equals_enumerating(bands: list[str]) -> None:
    space = table2_space(bands)
    shapes = space.shapes(0, space.size)
    flags = underdetermined("igrm", shapes[..., 0], shapes[..., 1])
    assert count_underdetermined("igrm", space) == int(flags.sum())
    assert count_underdetermined("igrm", space, limit=10) is None  # too many to count: said so
    if bands[-1] == "B8":
        assert int(flags.sum()) == 92  # the default scene: every one has B5 = B6


def _run(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "s2cl", *args], cwd=cwd, capture_output=True, text=True, timeout=600)


SCENE = """
[scene]
name = "coincident"
[surface]
library = "builtin:lib1"
quantity = "reflectance"
copies = 4
[effects]
atmosphere = true
correct = true
[analysis]
kind = "igrm"
parameter = "cab"
[sweep]
bands = ["B4", "B5", "B6", "B7"]
{policy}
[sweep.ranges]
B4 = {{ centre = 665, width = 30 }}
B5 = {{ centres = [720, 730], widths = [20] }}
B6 = {{ centres = [730, 740], widths = [15, 30] }}
B7 = {{ centre = 783, width = 20 }}
"""


@pytest.mark.parametrize("policy", ["", 'underdetermined = "keep"'])
def test_sweep_flags_counts_and_ranks_underdetermined_designs(tmp_path: Path, policy: str) -> None:
    (tmp_path / "s.toml").write_text(SCENE.format(policy=policy))
    count = _run("sweep", "count", "s.toml", cwd=tmp_path)
    assert count.returncode == 0, count.stderr
    assert "underdetermined (the analysis cannot fit them): 2" in count.stdout  # B5 = B6 = 730, two B6 widths
    out = _run("optimise", "s.toml", "-q", "-o", "out", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    table = pq.read_table(tmp_path / "out" / "results.parquet").to_pandas()
    flagged = table[table["underdetermined"]]
    assert len(flagged) == 2 and set(flagged["B5_centre_nm"]) == {730.0} and set(flagged["B6_centre_nm"]) == {730.0}
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["underdetermined"]["count"] == 2 and summary["underdetermined"]["coincident_centres"] == {"B5=B6": 2}
    ranked = [e["bands"]["B5"][0] == e["bands"]["B6"][0] for e in summary["top"]]
    if policy:  # kept: they are in the ranking, flagged
        assert summary["ranked"] == 8 and summary["underdetermined"]["ranking"] == "keep"
        assert any(ranked) and all(e["underdetermined"] for e in summary["top"] if e["bands"]["B5"][0] == 730.0
                                   and e["bands"]["B6"][0] == 730.0)
    else:
        assert summary["ranked"] == 6 and not any(ranked)
        assert "2 configurations are underdetermined" in out.stdout and "B5=B6" in out.stdout
    assert summary["regress"] == ["converged", "iteration_limit", "stalled"]
    for key in ("converged_fraction", "stalled_fraction", "iteration_limit_fraction", "excluded_fraction",
                "log10_condition_median"):
        assert key in summary["best"]


def test_sweep_of_one_underdetermined_design_is_refused_before_work(tmp_path: Path) -> None:
    scene = SCENE.format(policy="").replace("centres = [720, 730], widths = [20]", "centre = 730, width = 20")
    scene = scene.replace("centres = [730, 740], widths = [15, 30]", "centre = 730, width = 30")
    (tmp_path / "s.toml").write_text(scene)
    out = _run("optimise", "s.toml", "-q", "-o", "out", cwd=tmp_path)
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "underdetermined" in out.stderr and "B5 and B6 at 730 nm" in out.stderr
    assert not (tmp_path / "out").exists()
