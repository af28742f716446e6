"""NDVI -> LAI (Rouse et al. 1974), the retrieval added through the index registry alone
(s2cl/retrieve/indices.py): kernel against its float64 twin, one verdict on both paths, the built-in
scene end to end, and the scene errors of its band roles."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from s2cl.app.analysis import analysis_design, pixel_results
from s2cl.app.library_simulation import simulate
from s2cl.app.plan import plan_sweep
from s2cl.errors import InputError
from s2cl.reference import stages as ref
from s2cl.reference.sweep import evaluate
from s2cl.retrieve.index_kernel import IndexKernel, normalised_difference
from s2cl.scene.scene import Scene
from s2cl.status import Status
from s2cl.sweep.engine import evaluate_chunk
from s2cl.sweep.kernel import SweepKernel

OFFSETS = (0.0, 0.0)
SCENE = {
    "scene": {"name": "ndvi-test"},
    "surface": {"library": "builtin:lib2", "quantity": "reflectance", "copies": 6},
    "sensor": {"bands": ["B4", "B8"]},
    "effects": {"atmosphere": True, "correct": True, "seed": 3},
    "sweep": {"bands": ["B4", "B8"], "ranges": {"B4": {"centre": 665, "width": 30}, "B8": {"centre": 842,
                                                                                          "width": 115}}},
    "analysis": {"kind": "ndvi", "parameter": "lai", "nir": "B8", "red": "B4"},
    "compute": {"precision": "float64"},
}


@pytest.mark.parametrize("n", [1, 13, 10007])
def test_ndvi_matches_its_float64_twin(rt, real_t, lanes, n) -> None:
    rng = np.random.default_rng(n)
    refl = np.vstack([rng.uniform(0.01, 0.15, n), rng.uniform(0.2, 0.6, n)])  # red, NIR
    out = IndexKernel(rt, "ndvi", real_t=real_t, lanes=lanes)(refl, 1, 0)
    expect, status = ref.normalised_difference(refl[1], refl[0], OFFSETS)
    np.testing.assert_array_equal(out.status, status)
    np.testing.assert_allclose(out.index, expect, rtol=0, atol=1e-6 if real_t == "float32" else 1e-14)


def test_ndvi_values_and_hard_cases(rt, real_t) -> None:
    """Dense canopy NIR 0.45 / red 0.05 -> 0.8; a zero or negative reflectance (noise on a dark red band),
    NaN, inf and |rho| > 10 are INVALID with index 0; a flat spectrum gives 0."""
    nir = np.array([0.45, 0.45, 0.45, np.nan, 0.45, 20.0, 0.3, np.inf])
    red = np.array([0.05, 0.0, -0.001, 0.05, 0.45, 0.05, 0.3, 0.05])
    out = normalised_difference(np.vstack([nir, red]), "ndvi", 0, 1, real_t=real_t)
    assert out.index[0] == pytest.approx(0.8, abs=1e-6)
    np.testing.assert_array_equal(out.status, [0, 3, 3, 3, 0, 3, 0, 3])
    assert np.all(np.isfinite(out.index)) and np.all(out.index[out.status == Status.INVALID] == 0.0)
    assert out.index[4] == 0.0 and out.index[6] == 0.0
    expect, status = ref.normalised_difference(nir, red, OFFSETS)
    np.testing.assert_array_equal(out.status, status)
    np.testing.assert_allclose(out.index, expect, atol=1e-6)


def test_simulate_and_sweep_give_each_pixel_one_ndvi_verdict(rt) -> None:
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    scene = Scene.from_dict(copy.deepcopy(SCENE))
    direct = pixel_results(rt, scene, simulate(scene))
    job = plan_sweep(scene)
    swept = SweepKernel(job.tables, job.analysis, rt, precision="float64")(0, 1)
    np.testing.assert_array_equal(swept.status[0], direct.status)
    np.testing.assert_allclose(swept.index[0], direct.index, rtol=0, atol=1e-12)
    assert np.all(direct.status == Status.OK) and 0.3 < np.median(direct.index) < 0.95


def test_builtin_scene_sweeps_ndvi_against_lai(rt) -> None:
    """scenes/ndvi-lai.toml: kernel and numpy twin agree on every configuration; NDVI explains LAI."""
    scene = Scene.load("ndvi-lai")
    job = plan_sweep(scene)
    assert job.n_configs == 20 and job.analysis.kind == "ndvi" and job.analysis.regression
    got = SweepKernel(job.tables, job.analysis, rt, precision="float32")(0, job.n_configs)
    want = evaluate(job.tables, job.analysis, 0, job.n_configs)
    assert np.mean(got.status == want.status) > 0.999
    # float32: a DN may round the other way near .5; one DN of a dark red band moves NDVI by up to ~3e-3
    diff = np.abs(got.index - want.index)
    assert np.mean(diff < 1e-5) > 0.999 and np.max(diff) < 1e-2
    rows = evaluate_chunk(job, 0, job.n_configs)
    assert np.all(np.isfinite(rows["rms"])) and np.all(rows["r2"] > 0.7)
    assert not rows["underdetermined"].any()


@pytest.mark.parametrize(
    ("change", "key", "message"),
    [({"swir": "B11"}, "analysis.swir", "not a band role of ndvi (its roles: nir, red)"),
     ({"red": "B5"}, "analysis.red", "band 'B5' is not among the bands B4, B8"),
     ({"parameter": None}, "analysis.parameter", "e.g. 'lai'")],
)
def test_role_errors_name_the_key(change: dict, key: str, message: str) -> None:
    data = copy.deepcopy(SCENE)
    data["analysis"].update(change)
    data["analysis"] = {k: v for k, v in data["analysis"].items() if v is not None}
    with pytest.raises(InputError) as err:
        analysis_design(Scene.from_dict(data))
    assert key in str(err.value) and message in str(err.value), str(err.value)


def test_one_band_in_both_roles_is_underdetermined() -> None:
    data = copy.deepcopy(SCENE)
    data["analysis"].update(nir="B4", red="B4")
    with pytest.raises(InputError, match="underdetermined: the NDVI's nir band B4 and red band B4 are the same"):
        analysis_design(Scene.from_dict(data))
