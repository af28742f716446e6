"""A retrieval written as a formula ([analysis] kind = "formula"): in a scene, in ``simulate``, in a sweep (kernel
against its float64 numpy twin), under the one design rule, with one-line errors; the shipped formula scenes run."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.reference.sweep import evaluate
from s2cl.scene.scene import Scene
from s2cl.status import Status
from s2cl.sweep.kernel import SweepKernel

S2REP = "705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5)"


def _scene(expression: str = S2REP, ranges: dict | None = None, **analysis) -> Scene:
    ranges = ranges or {"B4": {"centre": 665, "width": 30}, "B5": {"centres": [700, 705, 740], "widths": [15, 20]},
                        "B6": {"centres": [735, 740], "widths": [15, 20]}, "B7": {"centre": 783, "width": 20}}
    return Scene.from_dict({
        "scene": {"name": "formula-test"},
        "surface": {"library": "builtin:lib1", "quantity": "reflectance", "copies": 7},
        "effects": {"atmosphere": True, "correct": True, "seed": 3},
        "analysis": {"kind": "formula", "expression": expression, "parameter": "cab", **analysis},
        "sweep": {"bands": list(ranges), "ranges": ranges},
    })


def test_sweep_kernel_matches_the_float64_twin(rt, real_t: str, lanes: int) -> None:
    """Every configuration and pixel: float64 to 1e-10 relative, statuses identical. float32 S2REP lies within
    1e-3 nm of the float64 twin in every configuration whose B5 and B6 centres are 20 nm or more apart (measured:
    5e-5 nm at most); as they approach, the B6 - B5 denominator amplifies the rounding without bound (B5 at 740 nm
    against B6 at 735 nm gives values in the thousands of nm there), so those designs are compared by status only."""
    from s2cl.app.plan import plan_sweep

    job = plan_sweep(_scene())
    ref = evaluate(job.tables, job.analysis, 0, job.n_configs)
    got = SweepKernel(job.tables, job.analysis, rt, precision=real_t, lanes=lanes)(0, job.n_configs)
    ok = (ref.status == Status.OK) & (got.status == Status.OK)
    assert np.all(np.isfinite(got.index)) and np.all(got.index[got.status != Status.OK] == 0)
    if real_t == "float64":
        assert np.array_equal(got.status, ref.status)
        np.testing.assert_allclose(got.index[ok], ref.index[ok], rtol=1e-10, atol=0)
        return
    assert np.mean(got.status == ref.status) > 0.999
    from s2cl.sweep.raw import variant_indices

    t, bands = job.tables, list(job.tables.bands)
    idx = variant_indices(t, 0, job.n_configs)
    centres = np.stack([t.centre[k][idx[:, k]] for k in range(t.n_slots)], axis=1)
    apart = np.abs(centres[:, bands.index("B6")] - centres[:, bands.index("B5")]) >= 20
    assert apart.sum() >= job.n_configs // 2
    err = np.where(ok, np.abs(got.index - ref.index), 0.0)[apart]
    assert err.max() < 1e-3, err.max()


def test_coincident_subtracted_bands_are_underdetermined_everywhere(tmp_path) -> None:
    """B5 on B6 (740/15 or 740/20 in both) zeroes S2REP's denominator: the sweep flags exactly those designs, and
    ``simulate`` of such a sensor is refused before any work, with the same explained message."""
    from s2cl.app.checks import check_sweep
    from s2cl.app.plan import plan_sweep, underdetermined_count
    from s2cl.retrieve.design import design_problem

    scene = _scene()
    checked = check_sweep(scene)
    assert underdetermined_count(checked.space, checked.analysis) == 2  # 740/15 and 740/20 in B5 and B6
    problem = design_problem(checked.analysis, ["B4", "B5", "B6", "B7"], [665, 740, 740, 783], [30, 15, 15, 20])
    assert problem == ("underdetermined: the formula compares B6 with B5 (a difference or a ratio, 0 or 1 for one "
                       "band), and they are the same band (740/15 nm)")
    job = plan_sweep(scene)
    assert job.n_configs == 6 * 4
    import importlib.resources

    table = (importlib.resources.files("s2cl") / "data" / "sentinel2_mrd_table1.csv").read_text()
    sensor = tmp_path / "sensor.csv"
    sensor.write_text(table.replace("\nB5,705,15,", "\nB5,740,15,"))
    same = Scene.from_dict({"scene": {"name": "coincident"}, "sensor": {"file": str(sensor)},
                            "surface": {"library": "builtin:lib1", "quantity": "reflectance", "copies": 2},
                            "effects": {"atmosphere": True, "correct": True},
                            "analysis": {"kind": "formula", "expression": S2REP, "parameter": "cab"}})
    from s2cl.app.analysis import analysis_design

    with pytest.raises(InputError, match=r"the formula compares B6 with B5 \(a difference or a ratio"):
        analysis_design(same)


@pytest.mark.parametrize(("analysis", "key", "said"), [
    ({"expression": "705 + 35 * (B6 - B5"}, "analysis.expression", "column"),
    ({"expression": "B6 - B9"}, "analysis.expression", "unknown band 'B9'"),
    ({"expression": "__import__('os')"}, "analysis.expression", "column 1"),
    ({"expression": "sqrt(B5) - foo(B6)"}, "analysis.expression", "foo"),
])
def test_a_bad_expression_is_one_line_naming_the_key(analysis: dict, key: str, said: str) -> None:
    with pytest.raises(InputError) as err:
        from s2cl.app.checks import check_sweep

        check_sweep(_scene(**analysis) if "expression" not in analysis else _scene(analysis["expression"]))
    text = str(err.value)
    assert f"{key}: " in text and said in text and "\n" not in text


def test_an_expression_belongs_to_the_formula_kind_only() -> None:
    base = {"scene": {"name": "x"}, "surface": {"library": "builtin:lib1", "quantity": "reflectance", "copies": 2},
            "effects": {"atmosphere": True, "correct": True}}
    from s2cl.app.analysis import analysis_design

    for analysis, said in (({"kind": "formula", "parameter": "cab"}, "needs an expression"),
                           ({"kind": "igrm", "parameter": "cab", "expression": "B5 - B4"}, "only kind = 'formula'")):
        with pytest.raises(InputError, match=said):
            analysis_design(Scene.from_dict({**base, "analysis": analysis}))


@pytest.mark.parametrize("scene", ["s2rep-cab", "mtci-cab", "cire-cab", "mcari-osavi-cab"])
def test_the_shipped_formula_scenes_rank_their_designs(tmp_path, scene: str) -> None:
    out = subprocess.run([sys.executable, "-m", "s2cl", "optimise", scene, "-o", str(tmp_path / "out")],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert "reference" in out.stdout and "#1" in out.stdout and "configurations do better" in out.stdout
    assert (tmp_path / "out" / "results.parquet").is_file()


@pytest.mark.parametrize("text", ["-" * 498 + "B4", " + ".join(["B4"] * 100)])
def test_deeply_nested_expressions_are_one_line_errors_not_recursion(text: str) -> None:
    from s2cl.retrieve.families.formula import Formula

    with pytest.raises(InputError, match=r"nests \d+ operations in one another; at most 64"):
        Formula.parse(text, ["B4", "B5"])


def test_a_ratio_of_one_band_with_itself_is_underdetermined() -> None:
    """CIred-edge, B7 / B5 - 1, is 0 for every pixel when B7 and B5 are one band: flagged like a vanishing
    difference (the sweep leaves those designs out)."""
    from s2cl.app.checks import check_sweep
    from s2cl.app.plan import underdetermined_count

    checked = check_sweep(_scene("B7 / B5 - 1", {"B5": {"centres": [705, 783], "widths": [15, 20]},
                                                 "B7": {"centre": 783, "width": 20}}))
    assert checked.analysis.pairs == ((1, 0),)
    assert underdetermined_count(checked.space, checked.analysis) == 1  # B5 at 783/20 on B7
