"""The fused sweep kernel against the float64 numpy evaluation of the same configurations."""

from __future__ import annotations

import numpy as np
import pytest
from sweep_fixtures import Terms, gvmi_job, scene_analysis, scene_space, scene_tables

from s2cl.libraries.registry import load_library
from s2cl.reference.sweep import evaluate
from s2cl.scene.scene import Scene
from s2cl.status import Status
from s2cl.sweep.kernel import SweepKernel


def test_gvmi_sweep_matches_numpy(rt, real_t: str, lanes: int) -> None:
    job = gvmi_job(copies=7)  # 246 spectra x 7 copies: pixels not a multiple of the lanes
    ref = evaluate(job.tables, job.analysis, 0, job.n_configs)
    got = SweepKernel(job.tables, job.analysis, rt, precision=real_t, lanes=lanes)(0, job.n_configs)
    assert np.array_equal(got.status, ref.status)
    # float32: a DN may round the other way near .5 (one DN ≈ 0.02 % of B11's range), which moves the index
    # by up to 2e-3; that is rare, and every other pixel agrees to float32 rounding (measured: 0.01 % of
    # pixels off by more than 1e-5), so a calibration slope one count off (every pixel 2.4e-4 relative) fails
    # (float64: not bit-equal, as OpenCL contracts a*b+c into FMA; numpy does not)
    err = np.abs(got.index - ref.index)
    assert err.max() < (1e-12 if real_t == "float64" else 2e-3)
    assert np.mean(err > 1e-5) < 1e-3


def test_chunks_are_independent(rt) -> None:
    job = gvmi_job(copies=5)
    k = SweepKernel(job.tables, job.analysis, rt)
    whole = k(0, job.n_configs)
    part = k(7, 19)
    assert np.array_equal(part.index, whole.index[7:19])


def _sam_job(threshold: float | None):
    scene = Scene.from_dict({
        "scene": {"name": "sam-test"},
        "grid": {"start_nm": 1500, "stop_nm": 2500},
        "surface": {"library": "builtin:minerals-swir", "quantity": "reflectance", "copies": 9},
        "effects": {"atmosphere": True, "correct": True, "seed": 2},
        "sensor": {"bands": ["B11", "B12"]},
        "sweep": {"bands": ["B11", "B12"], "ranges": {
            "B11": {"centre": 1610, "width": 90},
            "B12": {"centres": [2150, 2190, 2220], "widths": [30, 60, 180]}}},
        "analysis": {"kind": "sam", **({"angle_threshold_deg": threshold} if threshold else {})},
    })
    space = scene_space(scene)
    lib = load_library("builtin:minerals-swir", scene.grid)
    classes = tuple(sorted(set(lib.groups)))
    terms = Terms(scene.grid.size)
    target = np.array([classes.index(g) for g in lib.groups], dtype=float)
    tables = scene_tables(scene, space, lib, terms, terms, target=target, class_names=classes)
    return tables, scene_analysis(scene, space.bands)


@pytest.mark.parametrize("threshold", [None, 3.0])
def test_sam_sweep_matches_numpy(rt, real_t: str, threshold: float | None) -> None:
    tables, analysis = _sam_job(threshold)
    ref = evaluate(tables, analysis, 0, tables.n_configs)
    got = SweepKernel(tables, analysis, rt, precision=real_t)(0, tables.n_configs)
    agree = np.mean((got.index == ref.index) & (got.status == ref.status))
    assert agree > (0.9999 if real_t == "float64" else 0.995)
    if threshold:
        assert np.any(ref.status == Status.UNCLASSIFIED)  # some pixels are unclassified at 3 degrees


def _igrm_job(copies: int = 6):
    scene = Scene.from_dict({
        "scene": {"name": "igrm-test"},
        "surface": {"library": "builtin:lib1", "quantity": "reflectance", "copies": copies},
        "effects": {"atmosphere": True, "correct": True, "seed": 9},
        "sweep": {"bands": ["B4", "B5", "B6", "B7"], "ranges": {
            "B4": {"centres": [665, 680], "widths": [30]}, "B5": {"centre": 705, "width": 15},
            "B6": {"centres": [740], "widths": [15, 30]}, "B7": {"centre": 783, "width": 20}}},
        "analysis": {"kind": "igrm", "parameter": "cab"},
    })
    space = scene_space(scene)
    lib = load_library("builtin:lib1", scene.grid)
    terms = Terms(scene.grid.size)
    tables = scene_tables(scene, space, lib, terms, terms, target=lib.params["cab"])
    return tables, scene_analysis(scene, space.bands)


def test_igrm_sweep_matches_numpy_lm(rt) -> None:
    tables, analysis = _igrm_job()
    ref = evaluate(tables, analysis, 0, tables.n_configs)
    got = SweepKernel(tables, analysis, rt, precision="float64")(0, tables.n_configs)
    same = got.status == ref.status
    assert same.mean() > 0.995
    ok = same & (ref.status == 0)
    assert np.percentile(np.abs(got.index - ref.index)[ok], 99) < 1e-6
    f32 = SweepKernel(tables, analysis, rt, precision="float32")(0, tables.n_configs)
    ok32 = (f32.status == 0) & (ref.status == 0)
    assert ok32.mean() > 0.95
    assert np.median(np.abs(f32.index - ref.index)[ok32]) < 0.01  # nm


def test_igrm_sweep_lanes_are_independent(rt, lanes: int) -> None:
    """The fused IGRM sweep at any lane width gives what one pixel per work-item gives, bit for bit."""
    tables, analysis = _igrm_job(copies=3)
    one = SweepKernel(tables, analysis, rt, lanes=1)(0, tables.n_configs)
    got = SweepKernel(tables, analysis, rt, lanes=lanes)(0, tables.n_configs)
    assert np.array_equal(got.index, one.index)
    assert np.array_equal(got.status, one.status) and np.array_equal(got.bounds, one.bounds)


def test_igrm_sweep_sorts_bands_and_flags_coincident_ones_by_condition(rt) -> None:
    """Configurations whose B5 lies above B6 are fitted with the bands sorted by centre (as the direct
    API needs them), exactly as the numpy twin sorts; one with B5 on B6's centre gets the largest
    condition codes (the design cannot pin four parameters)."""
    scene = Scene.from_dict({
        "scene": {"name": "sort-test"},
        "surface": {"library": "builtin:lib1", "quantity": "reflectance", "copies": 4},
        "effects": {"atmosphere": True, "correct": True, "seed": 9},
        "sweep": {"bands": ["B4", "B5", "B6", "B7"], "ranges": {
            "B4": {"centre": 665, "width": 30}, "B5": {"centres": [720, 745, 740], "widths": [15]},
            "B6": {"centre": 740, "width": 15}, "B7": {"centre": 783, "width": 20}}},
        "analysis": {"kind": "igrm", "parameter": "cab"},
    })
    space = scene_space(scene)
    lib = load_library("builtin:lib1", scene.grid)
    terms = Terms(scene.grid.size)
    tables = scene_tables(scene, space, lib, terms, terms, target=lib.params["cab"])
    analysis = scene_analysis(scene, space.bands)
    ref = evaluate(tables, analysis, 0, 3)
    got = SweepKernel(tables, analysis, rt, precision="float64")(0, 3)
    assert np.mean(got.status == ref.status) > 0.99
    ok = (got.status == 0) & (ref.status == 0)
    assert np.percentile(np.abs(got.index - ref.index)[ok], 99) < 1e-6  # config 1 (B5 745 > B6 740) included
    # where the estimate means something (below 10 decades) kernel and twin agree to a code; near singular
    # matrices (the coincident design) it is rounding noise above that
    sane = (ref.condition < 200) & (got.condition < 200) & ok
    assert np.mean(np.abs(got.condition.astype(int) - ref.condition.astype(int))[sane] <= 1) > 0.999
    median = np.median(got.condition, axis=1)
    # measured: 14, 29 and 173 codes (0.7, 1.5 and 8.7 decades)
    assert median[2] >= 140 and median[0] < 60 and median[1] < 60


def test_profile_builds_reproduce_the_sweep(rt) -> None:
    """The profile switches (bench/sweep_profile.py) measure the sweep's own work: the fit from the stored
    reflectances gives the fused kernel's results bit for bit, and so does the standalone IGRM fit of the same
    reflectances (bands sorted by centre), whose iteration counts the ``iterations`` build reports."""
    from s2cl.retrieve.igrm import IgrmFitter, IgrmSettings
    from s2cl.sweep.raw import variant_indices

    tables, analysis = _igrm_job(copies=5)
    n, m = tables.n_configs, tables.n_pixels
    full = SweepKernel(tables, analysis, rt)
    want = full(0, n)

    def build(*switches: str) -> SweepKernel:
        return SweepKernel(tables, analysis, rt, profile=frozenset(switches))

    out = build("reflectance")._launch(0, n)
    rho = rt.fetch(out["rho_out"], (n, tables.n_slots, full.pitch), full.T.dtype)
    fit_only = build("fit_only")
    got = fit_only._fetch(fit_only._launch(0, n, {"rho_in": out["rho_out"]}), 0, n)
    assert np.array_equal(got.index, want.index) and np.array_equal(got.status, want.status)
    assert np.array_equal(got.condition, want.condition) and np.array_equal(got.bounds, want.bounds)
    counting = build("iterations")
    iterations = counting._fetch(counting._launch(0, n), 0, n).condition
    idx = variant_indices(tables, 0, n)
    fitter = IgrmFitter(rt, tables.n_slots, IgrmSettings.from_mapping(dict(analysis.igrm)))
    for c in range(n):
        centres = np.array([tables.centre[k][idx[c, k]] for k in range(tables.n_slots)])
        order = np.argsort(centres, kind="stable")
        r = fitter.fit(np.ascontiguousarray(rho[c][order][:, :m]), centres[order])
        assert np.array_equal(r.lp, want.index[c]) and np.array_equal(r.status, want.status[c])
        assert np.array_equal(r.iterations, iterations[c]) and iterations[c].max() > 1
    stand_in = build("no_fit")._fetch(build("no_fit")._launch(0, n), 0, n)
    assert np.all(np.isfinite(stand_in.index)) and not stand_in.status.any()


@pytest.mark.parametrize("switches", [{"sorting"}, {"no_fit", "fit_only"}])
def test_profile_switches_are_checked(rt, switches: set[str]) -> None:
    from s2cl.errors import InputError

    tables, analysis = _igrm_job(copies=1)
    with pytest.raises(InputError, match="profile switches"):
        SweepKernel(tables, analysis, rt, profile=frozenset(switches))


def test_iterations_switch_needs_the_igrm(rt) -> None:
    from s2cl.errors import InputError

    job = gvmi_job(copies=1)
    with pytest.raises(InputError, match="iterative fit only"):
        SweepKernel(job.tables, job.analysis, rt, profile=frozenset({"iterations"}))
