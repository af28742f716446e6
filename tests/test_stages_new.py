"""The two stages issue 33 added through the registry: per-band calibration error and inter-band crosstalk. Each lives
in four files (counted from the code, as tests/test_families.py counts the formula family's), and is seen by
``simulate``, image cubes, sweeps and searches, against its float64 twin at the kernels' tolerances and against
values worked by hand."""

from __future__ import annotations

import re
import zlib
from pathlib import Path

import numpy as np
import pytest
from sweep_fixtures import SMALL_SWEEP_TOML
from test_families import _code_words, _product_files

from s2cl.app.chain_parts import scene_simulator
from s2cl.app.image_simulation import simulate_image
from s2cl.app.library_simulation import simulate
from s2cl.atmos.correction import BandAtmosphere, correct
from s2cl.errors import InputError
from s2cl.forward.radiometry import Radiometry
from s2cl.forward.stages import STAGES, stage
from s2cl.reference import forward as ref
from s2cl.scene.scene import Scene
from s2cl.status import PixelFlag

ROOT = Path(__file__).resolve().parents[1]
#: a new per-pixel stage's files: the schema key, the stage entry, the device function, the twin
FOUR = {"s2cl/scene/schema.py", "s2cl/forward/stages.py", "kernels/common/stages.mako", "s2cl/reference/stages.py"}
SEED = 5


def _touching(name: str) -> set[str]:
    """Product files whose code (docstrings, comments and template docs apart) names stage ``name`` (any case, with
    or without its underscores: ``crosstalk_step``, ``CrosstalkSpec``, ``S2_CALIBRATION_ERROR_F1``)."""
    flat = name.replace("_", "")
    return {str(p.relative_to(ROOT)) for p in _product_files()
            if any(flat in w.lower().replace("_", "") for w in _code_words(p))}


@pytest.mark.parametrize("name", ["calibration_error", "crosstalk"])
def test_a_new_stage_touches_four_files(name: str) -> None:
    assert _touching(name) == FOUR, sorted(_touching(name) ^ FOUR)


def test_the_chain_order_is_written_once() -> None:
    """The kernels, their hosts and the chain's twins name no stage: they loop over the registry. ``quantise`` is
    in the product files of its stage entry, device function, twin and schema key only (it was in 19)."""
    generic = ["kernels/sense.cl.mako", "kernels/sweep.cl.mako", "s2cl/forward/sense.py", "s2cl/sweep/kernel.py",
               "s2cl/sweep/tables.py", "s2cl/sweep/design_tables.py", "s2cl/reference/forward.py",
               "s2cl/reference/sweep.py"]
    per_pixel = [s.name for s in STAGES if s.per_pixel]
    for path in generic:
        words = {w.lower() for w in _code_words(ROOT / path)}
        assert not words & set(per_pixel), (path, sorted(words & set(per_pixel)))
    named = {str(p.relative_to(ROOT)) for p in _product_files() if re.search("quantise", p.read_text())}
    assert named == FOUR


# -- calibration error ---------------------------------------------------------------------------------------------

def _library(effects: dict, precision: str = "float64", bands: list[str] | None = None, **extra) -> Scene:
    return Scene.from_dict({
        "scene": {"name": "lib"}, "surface": {"library": "builtin:lib1", "quantity": "reflectance", "copies": 4,
                                              "select": {"cab": [25, 40]}},
        "sensor": {"bands": bands or ["B2", "B4", "B5", "B6", "B11"]},
        "effects": {"atmosphere": True, "correct": True, "seed": SEED, **effects},
        "compute": {"precision": precision}, **extra})


def _twin(scene: Scene, sim) -> dict[str, np.ndarray]:
    """The float64 twin of the scene's per-pixel stages on the simulation's own band radiance."""
    from s2cl.scene.terms import correction_terms

    weights = [b.weights(scene.grid, scene.run.support) for b in scene.sensor.bands]
    r = Radiometry.of(scene.sensor.bands, scene.sensor.bits, correction=BandAtmosphere.of(correction_terms(scene),
                                                                                          weights),
                      settings=scene.spec.effects, seed=scene.run.seed)
    L = np.repeat(sim.band_radiance.astype(np.float64), scene.run.copies, axis=1)
    return ref.chain(L, r, scene.effects, seed=scene.run.seed)


def test_per_band_errors_given_and_drawn() -> None:
    """Given errors are the bands'; the others draw theirs once, from the seed and the band's name: the same band
    keeps its error in another band set, another seed draws another."""
    spec = {"calibration_error": {"uncertainty": 0.05, "bands": {"b5": 0.02}}}
    ctx = Radiometry.of(_library(spec).sensor.bands, 12, settings=_library(spec).spec.effects, seed=SEED)
    gain = stage("calibration_error").computed(ctx)["cal_error_gain"]
    assert gain[2] == 1.02  # B5, given (any case)
    z = [np.random.default_rng([SEED, 0x63616C65, zlib.crc32(b.encode())]).standard_normal()
         for b in ("B2", "B4", "B6", "B11")]
    np.testing.assert_allclose(gain[[0, 1, 3, 4]], 1.0 + 0.05 * np.array(z), rtol=0, atol=1e-15)
    assert len(set(gain.round(12))) == 5 and np.all(np.abs(gain - 1.0) < 0.25)
    other = _library(spec, bands=["B11", "B4"])
    again = stage("calibration_error").computed(Radiometry.of(other.sensor.bands, 12, settings=other.spec.effects,
                                                              seed=SEED))["cal_error_gain"]
    assert again.tolist() == [gain[4], gain[1]]
    reseeded = stage("calibration_error").computed(Radiometry.of(other.sensor.bands, 12,
                                                                 settings=other.spec.effects, seed=6))
    assert reseeded["cal_error_gain"][0] != gain[4]


def test_calibration_error_in_simulate_against_the_twin_and_by_hand(rt, real_t: str) -> None:
    scene = _library({"calibration_error": {"bands": {"B2": -0.03, "B5": 0.02, "B11": 0.05}}}, real_t)
    sim = simulate(scene, device=rt.info.spec)
    twin = _twin(scene, sim)
    assert sim.stage_values["calibration_error"] == pytest.approx([-0.03, 0.0, 0.02, 0.0, 0.05], abs=1e-15)
    gain = np.array([0.97, 1.0, 1.02, 1.0, 1.05])[:, None]
    bands = scene.sensor.bands
    lmin = np.array([b.lmin for b in bands])[:, None]
    step = np.array([(b.lmax - b.lmin) / 4095 for b in bands])[:, None]
    dn = sim.dn.reshape(5, -1).astype(np.float64)
    by_hand = (lmin + dn * step) * gain  # the calibrated radiance carries each band's error
    tol = 1e-12 if real_t == "float64" else 2e-6
    np.testing.assert_allclose(sim.calibrated.reshape(5, -1), by_hand, rtol=tol)
    same_dn = np.all(twin["dn"] == dn, axis=0)  # float32: a DN may round the other way at a tie
    assert same_dn.mean() >= (1.0 if real_t == "float64" else 0.99)
    np.testing.assert_allclose(sim.reflectance.reshape(5, -1)[:, same_dn], twin["reflectance"][:, same_dn],
                               rtol=tol, atol=tol)


def test_calibration_gain_is_the_shorthand_of_a_common_error(rt) -> None:
    """[correction] calibration_gain g: every band's error g - 1; the reflectance is the one the correction's terms
    used to fold it into, ρ((L - Lp/g) / (G/g)), to float64 rounding; both given: refused in one line."""
    short = _library({}, correction={"calibration_gain": 1.05})
    assert short.spec.effects.calibration_error.error == pytest.approx(0.05, abs=1e-15)
    assert short.effects.on("calibration_error")
    sim = simulate(short, device=rt.info.spec)
    from s2cl.scene.terms import correction_terms

    weights = [b.weights(short.grid, short.run.support) for b in short.sensor.bands]
    terms = BandAtmosphere.of(correction_terms(short), weights)
    bands = short.sensor.bands
    calibrated = (np.array([b.lmin for b in bands])[:, None]
                  + sim.dn.reshape(5, -1) * np.array([(b.lmax - b.lmin) / 4095 for b in bands])[:, None])
    folded = correct(calibrated, terms.path_radiance[:, None] / 1.05, terms.ground_term[:, None] / 1.05,
                     terms.spherical_albedo[:, None])
    np.testing.assert_allclose(sim.reflectance.reshape(5, -1), folded, rtol=1e-12, atol=1e-14)
    with pytest.raises(InputError, match=r"calibration_gain is the shorthand of effects\.calibration_error"):
        _library({"calibration_error": True}, correction={"calibration_gain": 1.05})


def test_hard_radiance_stays_finite_or_flagged(rt, real_t: str) -> None:
    """NaN, ±inf, zero, negative and saturating radiance through crosstalk and the calibration error: no-data stays
    NaN and flagged (and reaches the bands it leaks into), the rest finite."""
    scene = Scene.from_dict({"scene": {"name": "hard"}, "surface": {"library": "x.csv", "quantity": "radiance"},
                             "sensor": {"bands": ["B4", "B5", "B11"]},
                             "effects": {"seed": 2, "crosstalk": {"coefficient": 0.01},
                                         "calibration_error": {"error": 0.04}},
                             "compute": {"precision": real_t}})
    sim = scene_simulator(rt, scene)
    radiance = np.array([[np.nan, 0.0, -5.0, 1e4, 50.0, np.inf], [30.0, 0.0, -5.0, 1e4, 60.0, 20.0],
                         [5.0, 0.0, -5.0, 1e4, 3.0, 2.0]])
    out = sim.sense(radiance.astype(real_t), seed=2)
    nodata = (out.flags & PixelFlag.NODATA) != 0
    assert nodata[:, 0].tolist() == [True, True, False]  # B4's NaN leaks into B5 (one plane), not into B11
    assert np.all(np.isnan(out.calibrated[nodata])) and np.all(np.isfinite(out.calibrated[~nodata]))
    assert out.dn[:, 3].tolist() == [4095, 4095, 4095] and (out.flags[:, 3] & PixelFlag.HIGH).all()


# -- crosstalk -----------------------------------------------------------------------------------------------------

def test_crosstalk_by_hand_within_a_focal_plane(rt, real_t: str) -> None:
    """B4 gains 0.01 L_B5 (a pair), B5 0.002 L_B4 (the coefficient), B2 0.002 of B4 and B5; B11 and B12 (SWIR)
    only each other; with the noise, the stored radiance is (L + σz) + C (L + σz)."""
    scene = _library({"crosstalk": {"coefficient": 0.002, "pairs": {"B4": {"B5": 0.01, "B2": 0.0}}},
                      "quantise": False, "calibrate": False, "correct": False},
                     real_t, bands=["B2", "B4", "B5", "B11", "B12"])
    sim = simulate(scene, device=rt.info.spec)
    c = np.array([[0, 0.002, 0.002, 0, 0], [0.0, 0, 0.01, 0, 0], [0.002, 0.002, 0, 0, 0],
                  [0, 0, 0, 0, 0.002], [0, 0, 0, 0.002, 0]])
    assert sim.stage_values["crosstalk_from"][1] == "B5 0.01"
    L = np.repeat(sim.band_radiance.astype(np.float64), 4, axis=1)
    r = Radiometry.of(scene.sensor.bands, 12)
    noisy = ref.add_noise(L, r, SEED)
    by_hand = noisy + c @ noisy
    tol = 1e-12 if real_t == "float64" else 1e-5
    np.testing.assert_allclose(sim.noisy.reshape(5, -1), by_hand, rtol=tol)


def test_crosstalk_coefficients_from_the_sensor_table(tmp_path) -> None:
    """A sensor table's crosstalk column gives each band its coefficient (scene values win)."""
    table = (ROOT / "s2cl" / "data" / "sentinel2_mrd_table1.csv").read_text().splitlines()
    header = next(i for i, line in enumerate(table) if line.startswith("band"))
    rows = [line + (",crosstalk" if i == header else (",0.004" if line.startswith("B5,") else ","))
            for i, line in enumerate(table) if i >= header and line.strip()]
    (tmp_path / "s.csv").write_text("\n".join(table[:header] + rows) + "\n")
    for effects, b5 in (({"crosstalk": True}, 0.004), ({"crosstalk": {"coefficient": 0.001}}, 0.001)):
        scene = Scene.from_dict({"scene": {"name": "t"}, "surface": {"library": "x.csv"},
                                 "sensor": {"file": "s.csv", "bands": ["B4", "B5", "B6"]}, "effects": effects},
                                base_dir=tmp_path)
        ctx = Radiometry.of(scene.sensor.bands, 12, settings=scene.spec.effects)
        c = stage("crosstalk").computed(ctx)["crosstalk"]
        assert c[1].tolist() == [b5, 0.0, b5]
        assert c[0].tolist() == [0.0, c[0, 1], c[0, 1]] and c[0, 1] in (0.002, 0.001)


# -- sweeps, searches, image cubes ---------------------------------------------------------------------------------

NEW = 'crosstalk = {coefficient = 0.004}\ncalibration_error = {uncertainty = 0.03, bands = {B5 = 0.02}}\n'


def _sweep_toml(tmp_path: Path, name: str, extra: str = "", search: bool = False) -> Scene:
    text = SMALL_SWEEP_TOML.format(copies=6).replace("correct = true\n", "correct = true\n" + extra)
    if search:
        text = text.replace("[sweep.ranges]", 'search = "halving"\nsearch_finalists = 2\n[sweep.ranges]')
    (tmp_path / f"{name}.toml").write_text(text)
    return Scene.load(str(tmp_path / f"{name}.toml"))


def test_the_sweep_kernel_runs_both_stages_against_its_twin(rt, real_t: str, tmp_path) -> None:
    from s2cl.app.plan import plan_sweep
    from s2cl.reference.sweep import evaluate
    from s2cl.sweep.kernel import SweepKernel

    job = plan_sweep(_sweep_toml(tmp_path, "both", NEW))
    t = job.tables
    assert t.stages == ("noise", "crosstalk", "quantise", "calibrate", "calibration_error", "correct")
    assert t.values["cal_error_gain"][1] == 1.02  # every variant of B5 takes B5's error
    np.testing.assert_array_equal(t.values["crosstalk"], 0.004 * (1 - np.eye(4)))  # B4-B7: one plane
    got = SweepKernel(t, job.analysis, rt, precision=real_t)(0, t.n_configs)
    want = evaluate(t, job.analysis, 0, t.n_configs)
    # the fused IGRM kernel's stated tolerances against its twin (tests/test_sweep_kernel.py): float64, 99 % of the
    # fits within 1e-6 nm; float32 (a DN may round the other way at a tie), the median within 0.01 nm
    ok = (got.status == want.status) & (want.status == 0)
    assert ok.mean() > 0.95
    err = np.abs(got.index - want.index)[ok]
    if real_t == "float64":
        assert np.mean(got.status == want.status) > 0.995 and np.percentile(err, 99) < 1e-6
    else:
        assert np.median(err) < 0.01


def test_sweeps_and_searches_see_both_stages(tmp_path) -> None:
    """`s2cl optimise`: the sweep with the stages scores other numbers than without; its halving search finds the
    sweep's winner with the same score."""
    from s2cl.app.optimise import optimise

    plain = optimise(_sweep_toml(tmp_path, "plain"), tmp_path / "plain")
    swept = optimise(_sweep_toml(tmp_path, "swept", NEW), tmp_path / "swept")
    searched = optimise(_sweep_toml(tmp_path, "searched", NEW, search=True), tmp_path / "searched")
    assert swept.best["rms"] != plain.best["rms"]
    assert searched.summary["search"]["strategy"] == "halving"
    assert searched.best["bands"] == swept.best["bands"] and searched.best["rms"] == swept.best["rms"]


def test_an_image_cube_runs_both_stages(rt) -> None:
    """On a cube the bands of one GSD share their pixels: crosstalk among them; each variable names the band's
    calibration error and what it gains from which band."""

    base = {"scene": {"name": "cube"}, "surface": {"cube": "builtin:fields:12x12", "gsd_m": 10.0,
                                                   "quantity": "reflectance"},
            "sensor": {"bands": ["B2", "B4", "B5", "B6", "B11"]}}
    new = Scene.from_dict({**base, "effects": {"atmosphere": True, "correct": True, "seed": 1, "noise": False,
                                               "crosstalk": {"coefficient": 0.01},
                                               "calibration_error": {"bands": {"B4": 0.03}}}})
    ideal = Scene.from_dict({**base, "effects": {"atmosphere": True, "correct": True, "seed": 1, "noise": False}})
    ds, ref_ds = simulate_image(rt, new), simulate_image(rt, ideal)
    assert ds["calibrated_B4"].attrs["calibration_error"] == 0.03
    assert ds["calibrated_B4"].attrs["crosstalk_from"] == "B2 0.01"  # the 10 m bands: B2 and B4
    assert ds["calibrated_B5"].attrs["crosstalk_from"] == "B6 0.01" and ds["dn_B11"].attrs["crosstalk_from"] == "none"
    b4, b2 = ref_ds["radiance_B4"].values.astype(np.float64), ref_ds["radiance_B2"].values.astype(np.float64)
    expected = (b4 + 0.01 * b2) * 1.03
    step = (new.sensor.band("B4").lmax - new.sensor.band("B4").lmin) / 4095
    assert np.abs(ds["calibrated_B4"].values - expected).max() <= 1.03 * step / 2 + 1e-3


def test_s2cl_simulate_writes_both_stages(tmp_path) -> None:
    """`s2cl simulate` (streamed to NetCDF) runs both stages: the file equals the in-memory simulation, and names
    each band's calibration error and crosstalk along ``band``."""
    import xarray as xr

    from s2cl.app.simulate_scene import simulate_scene

    scene = _library({"crosstalk": {"coefficient": 0.003}, "calibration_error": {"bands": {"B5": 0.02}}}, "float32")
    simulate_scene(scene, tmp_path / "out")
    with xr.open_dataset(tmp_path / "out" / "simulation.nc", engine="h5netcdf") as ds:
        assert ds["calibration_error"].values.tolist() == pytest.approx([0.0, 0.0, 0.02, 0.0, 0.0], abs=1e-15)
        assert ds["crosstalk_from"].values.tolist()[4] == "none"  # B11: alone on the SWIR plane
        memory = simulate(scene).to_dataset()
        for name in ("noisy", "dn", "calibrated", "reflectance"):
            np.testing.assert_array_equal(ds[name].values, memory[name].values, err_msg=name)
