"""Band-addition sweeps (s2cl.sweep.addition): a fixed base set plus one added band, each
candidate scored by its gain over the base alone on the same pixels and noise; the scene section [sweep.add]
checked once, before any work."""

from __future__ import annotations

import csv
import importlib.resources
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from s2cl.app.checks import check_simulate, check_sweep
from s2cl.app.plan import plan_sweep, reference_row
from s2cl.cl.runtime import get_runtime
from s2cl.errors import InputError
from s2cl.retrieve.design import design_problem
from s2cl.retrieve.igrm import IgrmFitter
from s2cl.scene.scene import Scene
from s2cl.sweep.engine import evaluate_chunk

MINERALS = {
    "scene": {"name": "add-test"},
    "surface": {"library": "builtin:minerals-swir", "quantity": "reflectance", "copies": 5},
    "grid": {"start_nm": 1500, "stop_nm": 2500},
    "sensor": {"bands": ["B11", "B12"]},
    "effects": {"atmosphere": True, "correct": True, "seed": 1},
    "analysis": {"kind": "sam", "classes": ["Al-OH", "Mg-OH/C-O"]},
    "sweep": {"bands": ["B11", "B12"], "ranges": {"B11": {"centre": 1610.0, "width": 90.0}},
              "add": {"name": "N2300", "like": "B12", "centres": [2300.0, 2325.0], "widths": [15.0, 30.0]}},
}


def _scene(data: dict[str, Any], **changes: Any) -> Scene:
    """``data`` with ``changes`` (dotted keys: ``"sweep.add.name"``; None removes the key)."""
    import copy

    d = copy.deepcopy(data)
    for dotted, value in changes.items():
        *path, last = dotted.split(".")
        node = d
        for p in path:
            node = node.setdefault(p, {})
        if value is None:
            node.pop(last, None)
        else:
            node[last] = value
    return Scene.from_dict(d)


def _refused(scene: Scene, key: str, text: str) -> None:
    with pytest.raises(InputError) as err:
        check_sweep(scene)
    assert err.value.key == key, str(err.value)
    assert text in str(err.value), str(err.value)
    assert "\n" not in str(err.value)


# {{{ the scene section, checked once

@pytest.mark.parametrize(("changes", "key", "text"), [
    ({"sweep.add.name": "B12"}, "sweep.add.name", "is a band of the sensor"),
    ({"sweep.add.name": "N 2300/x"}, "sweep.add.name", "is not allowed"),
    ({"sweep.add.like": "B99"}, "sweep.add.like", "no band 'B99'"),
    ({"sweep.bands": ["B11", "B12", "N2300"]}, "sweep.bands", "sweep.bands lists the fixed base bands only"),
    ({"sweep.ranges.B12": {"centres": [2190.0, 2200.0], "widths": [180.0]}}, "sweep.ranges.B12",
     "holds its base bands fixed, but B12 moves"),
    ({"sweep.preset": "table2"}, "sweep.preset", "preset = 'table2' would move them"),
    ({"sweep.add.centres": [2190.0, 2300.0], "sweep.add.widths": [180.0]}, "sweep.add",
     "candidate 2190/180 nm of N2300 is base band B12 itself"),
    ({"sweep.add.widths": [-5.0]}, "sweep.add", "widths must be > 0"),
    ({"sweep.add.centres": None}, "sweep.add", "a grid band gives centres and widths only"),
    ({"sweep.ranges.N2300": {"centre": 2300.0, "width": 20.0}}, "sweep.ranges", "goes in [sweep.add]"),
    ({"sweep.add.centres": [2480.0]}, "sweep.add", "outside the spectral grid"),
    ({"sweep.add.centres": [2190.0], "sweep.add.widths": [180.0000001]}, "sweep.add",  # one band by the design rule
     "is base band B12 itself"),
    ({"sweep.bands": ["B12"], "sweep.ranges": {}}, "sweep.add", "the base set B12 alone cannot be scored by sam"),
])
def test_bad_addition_sections_are_refused_in_one_line(changes: dict[str, Any], key: str, text: str) -> None:
    _refused(_scene(MINERALS, **changes), key, text)


def test_a_key_outside_the_schema_names_sweep_add() -> None:
    with pytest.raises(InputError) as err:
        _scene(MINERALS, **{"sweep.add.colour": "red"})
    assert err.value.key == "sweep.add.colour" and "allowed keys here" in str(err.value)


VEG = {
    "scene": {"name": "add-igrm"},
    "surface": {"library": "builtin:lib1", "quantity": "reflectance", "copies": 2},
    "effects": {"atmosphere": True, "correct": True, "seed": 1},
    "analysis": {"kind": "igrm", "parameter": "cab"},
    "sweep": {"bands": ["B5", "B6", "B7"],
              "add": {"name": "N680", "like": "B4", "centres": [670.0, 680.0], "widths": [20.0]}},
}


def test_a_base_the_direct_api_refuses_is_refused_by_the_addition_sweep() -> None:
    """IGRM on three base bands: `simulate` and IgrmFitter refuse it, so it cannot give a base score."""
    base_only = _scene(VEG, **{"analysis.bands": ["B5", "B6", "B7"], "sweep": None})
    with pytest.raises(InputError, match="at least 4 bands"):
        check_simulate(base_only)
    with pytest.raises(InputError, match="at least 4 bands"):
        IgrmFitter(get_runtime(), 3)
    _refused(_scene(VEG), "sweep.add", "the base set B5, B6, B7 alone cannot be scored by igrm")
    # with a fourth base band both accept
    four = _scene(VEG, **{"sweep.bands": ["B4", "B5", "B6", "B7"]})
    assert check_sweep(four).base.space.bands == ["B4", "B5", "B6", "B7"]


@pytest.mark.parametrize("red", ["N620", "B4"])
def test_an_index_measures_no_gain_whichever_band_it_reads(red: str) -> None:
    """A two-band index either gives the added band a role (the base set alone has no index) or leaves it
    out (every candidate would score the base exactly): refused both ways."""
    scene = _scene(VEG, **{"analysis": {"kind": "ndvi", "parameter": "cab", "nir": "B8a", "red": red},
                           "sweep.bands": ["B8a", "B4"],
                           "sweep.add": {"name": "N620", "like": "B4", "centres": [620.0], "widths": [20.0]}})
    _refused(scene, "sweep.add", "needs an analysis that uses every band")

# }}}
# {{{ the numbers: gain = base − candidate, against the ordinary sweep path


def _rows(job: Any) -> dict[str, np.ndarray]:
    return evaluate_chunk(job, 0, job.n_configs)


def _sensor_with_added_band(folder: Path) -> Path:
    """A sensor table with B11, B12 and N2300 = B12's row renamed: the added band as an ordinary sensor band."""
    ref = importlib.resources.files("s2cl") / "data" / "sentinel2_mrd_table1.csv"
    lines = [line for line in ref.read_text().splitlines() if not line.startswith("#")]
    rows = list(csv.reader(lines))
    header, body = rows[0], {r[0]: r for r in rows[1:] if r}
    path = folder / "sensor.csv"
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows([body["B11"], body["B12"], ["N2300", *body["B12"][1:]]])
    return path


def test_gain_is_the_base_score_minus_an_independent_direct_evaluation(tmp_path: Path) -> None:
    job = plan_sweep(_scene(MINERALS))
    rows = _rows(job)
    base = job.addition["base_score"]
    assert job.addition["metric"] == "omission_error_pct" and np.isfinite(base)
    np.testing.assert_array_equal(rows["gain"], base - rows["omission_error_pct"])
    assert not rows["underdetermined"].any()
    # candidate 2325/15 through the ordinary sweep path: the added band as a band of a sensor table, fixed
    sensor = _sensor_with_added_band(tmp_path)
    direct = _scene(MINERALS, **{
        "sensor": {"file": str(sensor), "bands": ["B11", "B12", "N2300"]},
        "sweep": {"bands": ["B11", "B12", "N2300"], "ranges": {
            "B11": {"centre": 1610.0, "width": 90.0}, "B12": {"centre": 2190.0, "width": 180.0},
            "N2300": {"centre": 2325.0, "width": 15.0}}}})
    one = _rows(plan_sweep(direct))
    i = int(np.flatnonzero((rows["N2300_centre_nm"] == 2325.0) & (rows["N2300_width_nm"] == 15.0))[0])
    for column in ("omission_error_pct", "overall_accuracy_pct", "unclassified_fraction", "failed_fraction"):
        assert one[column][0] == rows[column][i], column
    assert rows["gain"][i] == base - one["omission_error_pct"][0]
    # the candidates differ: the test would see a wrong candidate
    assert np.ptp(rows["omission_error_pct"]) > 0


def test_the_base_score_is_a_fixed_band_sweep_of_the_base_set() -> None:
    job = plan_sweep(_scene(MINERALS))
    fixed = _scene(MINERALS, **{"sweep": {"bands": ["B11", "B12"], "ranges": {
        "B11": {"centre": 1610.0, "width": 90.0}, "B12": {"centre": 2190.0, "width": 180.0}}}})
    plain = _rows(plan_sweep(fixed))
    for column in ("omission_error_pct", "overall_accuracy_pct", "unclassified_fraction", "failed_fraction"):
        assert job.base_row[column] == plain[column][0], column
    assert job.addition["base_score"] == plain["omission_error_pct"][0]
    # the reference row of an addition sweep is its base, the added band without a shape
    ref = reference_row(check_sweep(_scene(MINERALS)), job)
    assert ref["omission_error_pct"] == plain["omission_error_pct"][0] and ref["N2300_centre_nm"] is None


def test_an_igrm_addition_flags_exactly_what_the_design_rule_refuses() -> None:
    """Every candidate's `underdetermined` flag is the direct rule's verdict on its whole design (an added band on
    a base centre still leaves four abscissae: accepted by both)."""
    scene = _scene(VEG, **{"sweep.bands": ["B4", "B5", "B6", "B7"],
                           "sweep.add": {"name": "N720", "like": "B5", "centres": [705.0, 720.0], "widths": [10.0]}})
    job = plan_sweep(scene)
    rows = _rows(job)
    names = [*job.tables.bands]
    for k in range(job.n_configs):
        c = [rows[f"{b}_centre_nm"][k] for b in names]
        w = [rows[f"{b}_width_nm"][k] for b in names]
        assert bool(rows["underdetermined"][k]) == (design_problem("igrm", names, c, w) is not None)
    assert job.addition["metric"] == "rms"
    np.testing.assert_allclose(rows["gain"], job.addition["base_score"] - rows["rms"])

# }}}
# {{{ surface.select: the low-chlorophyll end of a library (the 620 nm scene)


def test_select_keeps_the_spectra_whose_parameter_lies_in_the_range() -> None:
    from s2cl.scene.library import scene_library

    lib = scene_library(_scene(VEG, **{"surface.select": {"cab": [0.0, 25.0]}, "sweep": None}))
    assert lib.size == 5 * 2 * 3 and set(lib.params["cab"]) == {5.0, 10.0, 15.0, 20.0, 25.0}
    with pytest.raises(InputError) as err:
        scene_library(_scene(VEG, **{"surface.select": {"chl": [0.0, 25.0]}, "sweep": None}))
    assert err.value.key == "surface.select.chl" and "it has cab, ewt, lai" in str(err.value)
    with pytest.raises(InputError, match="no spectrum of the library lies in these ranges"):
        scene_library(_scene(VEG, **{"surface.select": {"cab": [200.0, 300.0]}, "sweep": None}))
    with pytest.raises(InputError, match=r"must be \[low, high\]") as err:
        _scene(VEG, **{"surface.select": {"cab": [25.0, 0.0]}})
    assert err.value.key == "surface.select"

# }}}
