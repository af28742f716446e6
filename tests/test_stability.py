"""The spectral-stability study (`s2cl study stability`): a drifted band's data processed as the
nominal band's. Small copies (3 noisy copies per spectrum) keep every test fast."""

from __future__ import annotations

import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from s2cl.app.plan import reference_row
from s2cl.cli.main import main
from s2cl.errors import InputError
from s2cl.resources import scene_dir
from s2cl.scene.scene import Scene
from s2cl.sensor.variants import BandList, BandRange, SweepSpace
from s2cl.studies import check_needs, stability
from s2cl.studies.common import load_study
from s2cl.studies.drift import Drifts, drift_configs, drift_space, drift_tables, load_application
from s2cl.studies.stability import both_sides, evaluate, requirement
from s2cl.sweep.engine import SweepJob
from s2cl.sweep.kernel import SweepKernel
from s2cl.sweep.tables import build_tables

COPIES = 3
DRIFTS = Drifts(shifts=(-5.0, -1.0, 0.0, 1.0, 5.0), factors=(0.9, 1.0, 1.1))


def _study(**changes) -> dict:
    data = tomllib.loads((scene_dir() / "study-stability.toml").read_text())
    data["study"].update(changes)
    return data


@pytest.fixture(scope="module")
def igrm():
    """The IGRM application (Lib1, B4 B5 B6 B7) with 3 copies per spectrum."""
    return load_application(Scene.load("study-stability"), "igrm", "table3-lib1-b4567", COPIES)


@pytest.fixture(scope="module")
def igrm_errors(igrm) -> dict:
    return evaluate(igrm, DRIFTS, noise=True)


def _per_pixel(tables, app, config: int, rt) -> np.ndarray:
    run = app.scene.run
    return SweepKernel(tables, app.analysis, rt, precision=run.precision, lanes=run.lanes)(config, config + 1).index[0]


def _fixed(app, shapes) -> SweepSpace:
    return SweepSpace(tuple(BandRange.fixed(b, c, w) for b, (c, w) in zip(app.bands, shapes, strict=True)))


def _sweep_tables(app, space):
    from s2cl.retrieve.analysis import analysis_targets
    from s2cl.scene.terms import correction_terms, scene_terms

    scene = app.scene
    lib, target, classes = analysis_targets(app.library, app.analysis, scene.spec.analysis.classes)
    return build_tables(space, lib, scene_terms(scene), correction_terms(scene), scene.sensor, scene.grid, scene.run,
                        scene.spec.effects, target=target, class_names=classes)


def test_identity_zero_drift_is_the_sweeps_nominal_design(igrm, igrm_errors, rt):
    """δ = 0 and factor 1 give the nominal error exactly, and that is the sweep engine's RMS of the sensor's own
    bands (same seed, pixels and calibration), pixel by pixel."""
    e = igrm_errors
    zero, one = DRIFTS.shifts.index(0.0), DRIFTS.factors.index(1.0)
    for b in igrm.bands:
        assert e["error"]["shift"][b][zero] == e["nominal"]
        assert e["error"]["width"][b][one] == e["nominal"]
    tables = drift_tables(igrm, DRIFTS)
    row = reference_row(igrm.checked, SweepJob(tables, igrm.analysis, chunk=1))
    assert e["nominal"] == pytest.approx(row["rms"], rel=1e-9)
    assert e["recalibrated"]["shift"][igrm.bands[0]][zero] == pytest.approx(row["rms"], rel=1e-9)
    standard = _sweep_tables(igrm, _fixed(igrm, igrm.nominal))
    np.testing.assert_array_equal(_per_pixel(tables, igrm, 0, rt), _per_pixel(standard, igrm, 0, rt))


def test_drift_is_the_instruments_radiance_through_the_nominal_processing(igrm, rt):
    """B6 moved by +1 nm: the study's configuration equals, pixel by pixel, the sweep tables of an instrument
    whose B6 sits at 741 nm with their radiance and σ put into the tables of the nominal bands."""
    k = igrm.bands.index("B6")
    moved = list(igrm.nominal)
    moved[k] = (moved[k][0] + 1.0, moved[k][1])
    instrument = _sweep_tables(igrm, _fixed(igrm, moved))
    processor = _sweep_tables(igrm, _fixed(igrm, igrm.nominal))
    composed = replace(processor, radiance=instrument.radiance,
                       values={**processor.values, "sigma": instrument.values["sigma"]})
    tables = drift_tables(igrm, DRIFTS)
    config = int(drift_configs(igrm, DRIFTS, "shift", (1.0,))[k, 0])
    np.testing.assert_array_equal(_per_pixel(tables, igrm, config, rt), _per_pixel(composed, igrm, 0, rt))
    # and it differs from the nominal: the drift is there
    assert not np.array_equal(_per_pixel(tables, igrm, config, rt), _per_pixel(tables, igrm, 0, rt))


def test_tables_hold_the_nominal_processing_for_every_variant(igrm):
    t = drift_tables(igrm, DRIFTS)
    for k, (c, w) in enumerate(igrm.nominal):
        n = len(DRIFTS.shapes((c, w)))
        assert t.counts[k] == n == len(DRIFTS.shifts) + len(DRIFTS.factors) - 1   # 0 and 1 are the nominal
        np.testing.assert_array_equal(t.centre[k], np.full(n, c))
        np.testing.assert_array_equal(t.width[k], np.full(n, w))
        for name in ("lp", "g", "s"):
            terms = t.values[name][k]
            np.testing.assert_array_equal(terms, np.full(n, terms[0]))
        # the radiance is the drifted band's: every variant but the nominal differs
        assert all(not np.array_equal(t.radiance[k][v], t.radiance[k][0]) for v in range(1, n))
    clean = drift_tables(igrm, DRIFTS, noise=False)
    assert "noise" not in clean.stages and clean.copies == 1


def test_symmetric_setup():
    """Shifts ±δ move the centre by exactly ±δ at the nominal width; factors scale the width about the nominal
    centre; a configuration drifts one band only."""
    nominal = (705.0, 15.0)
    shapes = DRIFTS.shapes(nominal)
    assert shapes[0] == nominal and len(set(shapes)) == len(shapes)
    for d in DRIFTS.shifts:
        c, w = shapes[DRIFTS.variant(nominal, "shift", d)]
        assert (c - nominal[0], w) == (d, nominal[1])
        c_minus, _ = shapes[DRIFTS.variant(nominal, "shift", -d)]
        assert c - nominal[0] == -(c_minus - nominal[0])
    for f in DRIFTS.factors:
        assert shapes[DRIFTS.variant(nominal, "width", f)] == (nominal[0], nominal[1] * f)
    space = SweepSpace((BandList("B4", tuple(DRIFTS.shapes((665.0, 30.0)))), BandList("B5", tuple(shapes))))
    idx = space.indices(0, space.size)
    assert space.index_of([0, 0]) == 0
    assert np.count_nonzero(idx[space.index_of([0, 3])]) == 1


def test_requirement_is_mirror_symmetric():
    x = np.array([-2.0, -1.0, 0.0, 1.0, 2.0])
    err = np.array([3.0, 1.5, 1.0, 1.05, 1.3])
    r = requirement(x, err, 1.0, 0.1, 0.0)
    assert r["minus"] == pytest.approx(0.2)           # 1.0 → 1.5 over 1 nm: 1.1 at 0.2 nm
    assert r["plus"] == pytest.approx(1.0 + 0.05 / 0.25)
    m = requirement(-x[::-1], err[::-1], 1.0, 0.1, 0.0)
    assert (m["minus"], m["plus"]) == pytest.approx((r["plus"], r["minus"]))
    assert both_sides(r) == pytest.approx(0.2)
    never = requirement(x, np.ones(5), 1.0, 0.1, 0.0)
    assert np.isnan(never["minus"]) and np.isnan(both_sides(never))
    assert both_sides({"minus": float("nan"), "plus": 0.7}) == 0.7   # a side not reached is unlimited
    assert np.isnan(requirement(x, err, 0.0, 0.1, 0.0)["plus"])      # no nominal error: no requirement
    widths = requirement(np.array([0.8, 1.0, 1.2]), np.array([1.0, 1.0, 1.2]), 1.0, 0.1, 1.0)
    assert np.isnan(widths["minus"]) and widths["plus"] == pytest.approx(0.1)


def test_error_grows_for_a_large_drift_of_a_red_edge_band(igrm_errors):
    """B5 and B6 sit on the red edge: ±5 nm costs more than 10 %, and B6 already ±1 nm; the noise-free run
    grows too (the drift's own effect, not the noise draws)."""
    e = igrm_errors
    nominal = e["nominal"]
    i = {d: DRIFTS.shifts.index(d) for d in DRIFTS.shifts}
    for b in ("B5", "B6"):
        assert e["error"]["shift"][b][i[-5.0]] > 1.1 * nominal
        assert e["error"]["shift"][b][i[5.0]] > 1.1 * nominal
    assert min(e["error"]["shift"]["B6"][i[-1.0]], e["error"]["shift"]["B6"][i[1.0]]) > nominal
    assert e["error"]["shift"]["B6"][i[5.0]] > e["error"]["shift"]["B6"][i[1.0]]
    assert all(0.9 < f <= 1.0 for f in e["scored_fraction"]["shift"]["B4"])


def test_noise_free_run_grows_with_the_drift(igrm):
    e = evaluate(igrm, Drifts(shifts=(0.0, 3.0), factors=()), noise=False)
    assert e["pixels"] == igrm.library.size
    assert e["error"]["shift"]["B6"][1] > 1.1 * e["nominal"] > 0


# {{{ input validation: one-line errors naming the key


def _run(base_dir: Path, data: dict) -> None:
    """What ``s2cl study FILE`` runs, on a scene given as a dict whose files are relative to ``base_dir``."""
    setup = load_study(Scene.from_dict(data, base_dir=base_dir), quick=True)
    check_needs(setup)
    stability.run(setup)


@pytest.mark.parametrize("changes, match", [
    ({"applications": {}}, r"study\.applications: the stability study needs at least one value"),
    ({"shifts_nm": []}, r"study\.shifts_nm: the stability study needs at least one value"),
    ({"applications": {"x": "no-such-scene"}}, r"study\.applications\.x: no built-in scene 'no-such-scene'"),
    ({"applications": {"x": "missing.toml"}}, r"study\.applications\.x: .*missing\.toml"),
    ({"applications": {"x": "study-ozone"}}, r"study\.applications\.x: 'study-ozone' is a study scene"),
    ({"applications": {"x": "table6-b12"}, "shifts_nm": [-100.0, 0.0]},
     r"study\.shifts_nm: band B11 of application 'x' moved to 1510/90 nm reaches 1420–1600 nm, outside its grid"),
    ({"applications": {"x": "table6-b12"}, "width_factors": [1.5]}, r"study\.width_factors: band B11"),
])
def test_bad_study_inputs_are_one_line_errors(tmp_path, changes, match):
    with pytest.raises(InputError, match=match) as err:
        _run(tmp_path, _study(**changes, quick={}))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("changes, match", [
    ({"shifts_nm": [float("nan")]}, r"study\.shifts_nm: .*shifts must be finite and within ±100 nm"),
    ({"shifts_nm": [150.0]}, r"study\.shifts_nm: .*within ±100 nm, got 150"),
    ({"width_factors": [0.0]}, r"study\.width_factors: .*width factors must be > 0"),
    ({"growth": 0.0}, r"study\.growth: "),
    ({"applications": {"": "table5-b11"}}, r"study\.applications: .*labels are 1-40 printable characters"),
])
def test_bad_study_values_are_refused_at_load(changes, match):
    with pytest.raises(InputError, match=match):
        Scene.from_dict(_study(**changes), base_dir=scene_dir())


def test_application_without_a_sweep_names_its_own_file(tmp_path):
    text = (scene_dir() / "table5-b11.toml").read_text()
    (tmp_path / "app.toml").write_text(text[:text.index("[sweep]")])
    with pytest.raises(InputError, match=r"app\.toml: sweep: the scene has no \[sweep\] section"):
        _run(tmp_path, _study(applications={"mine": "app.toml"}, quick={}))


def test_cli_error_is_one_line(tmp_path, capsys):
    text = (scene_dir() / "study-stability.toml").read_text()
    start = text.index("applications = ")
    path = tmp_path / "s.toml"
    path.write_text(text[:start] + 'applications = { x = "nope" }' + text[text.index("\n", start):])
    with pytest.raises(SystemExit) as exc:
        main(["study", str(path), "--quick", "-o", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "study.applications.x: no built-in scene 'nope'" in err


def test_application_file_relative_to_the_study_scene(tmp_path):
    (tmp_path / "leaf.toml").write_text((scene_dir() / "table5-b11.toml").read_text())
    setup = load_study(Scene.from_dict(_study(applications={"leaf": "leaf.toml"}), base_dir=tmp_path), quick=True)
    app = load_application(setup.scene, "leaf", "leaf.toml", 2)
    assert app.bands == ("B8", "B11") and app.scene.run.copies == 2
    assert app.nominal == ((842.0, 115.0), (1610.0, 90.0))
    assert drift_space(app, DRIFTS).counts == [len(DRIFTS.shifts) + len(DRIFTS.factors) - 1] * 2


def test_an_evaluation_counts_the_bytes_of_what_it_holds_per_pixel() -> None:
    """One configuration's evaluation per pixel, by hand: the sweep kernel's outputs as fetched (the index in the
    working precision, status, bounds and condition codes of a byte each), the metrics' work for one row (8 float64
    arrays of a regression, 4 of a classification), and a regression's scoring (3 masks of a byte, the used index
    taken, its float64 prediction and residual)."""
    from s2cl.retrieve.metric import CLASSIFICATION, REGRESSION
    from s2cl.studies.drift import evaluation_bytes_per_pixel

    assert evaluation_bytes_per_pixel(REGRESSION, 4) == (4 + 3) + 8 * 8 + (3 + 4 + 2 * 8)
    assert evaluation_bytes_per_pixel(REGRESSION, 8) == (8 + 3) + 8 * 8 + (3 + 8 + 2 * 8)
    assert evaluation_bytes_per_pixel(CLASSIFICATION, 4) == (4 + 3) + 4 * 8
