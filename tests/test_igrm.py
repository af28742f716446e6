"""IGRM fitting kernel against its oracles (scipy least_squares, the numpy twin, the plain variant)."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.reference.igrm import fit_numpy_lm, fit_scipy, model
from s2cl.reference.igrm_cases import BANDS_4, BANDS_6, band_centres, synthetic
from s2cl.reference.igrm_varpro import fit_numpy_varpro
from s2cl.retrieve.igrm import BoundFlag, FitStatus, IgrmFitter, IgrmSettings, fit_igrm

WL4, WL6 = band_centres(BANDS_4), band_centres(BANDS_6)
#: float64 reference settings: tight tolerance, generous iteration limit
TIGHT = IgrmSettings(tol=1e-10, max_iter=255, residual_floor=1e-12)


# {{{ settings and input checks

def test_settings_defaults_and_validation():
    s = IgrmSettings()
    assert (s.l0_min_nm, s.l0_max_nm, s.s_min_nm, s.s_max_nm) == (650.0, 700.0, 10.0, 80.0)
    with pytest.raises(InputError, match=r"igrm\.s_max_nm"):
        IgrmSettings(s_min_nm=50.0, s_max_nm=40.0)
    with pytest.raises(InputError, match=r"igrm\.loss"):
        IgrmSettings(loss="cauchy")
    with pytest.raises(InputError, match=r"igrm\.max_iter"):
        IgrmSettings(max_iter=0)
    with pytest.raises(InputError, match=r"igrm\.tol"):
        IgrmSettings(tol=float("nan"))


def test_settings_from_mapping_names_file_and_key():
    s = IgrmSettings.from_mapping({"l0_min_nm": 640.0, "loss": "soft_l1"}, source="scene.toml")
    assert s.l0_min_nm == 640.0 and s.loss == "soft_l1"
    with pytest.raises(InputError, match=r"scene\.toml: igrm: unknown key\(s\) \['l0_mni_nm'\]"):
        IgrmSettings.from_mapping({"l0_mni_nm": 640.0}, source="scene.toml")
    with pytest.raises(InputError, match=r"scene\.toml: igrm\.depth_min"):
        IgrmSettings.from_mapping({"depth_min": -1.0}, source="scene.toml")


def test_input_errors(rt):
    with pytest.raises(InputError, match="at least 4 bands"):
        IgrmFitter(rt, 3)
    f = IgrmFitter(rt, 4)
    with pytest.raises(InputError, match=r"reflectance: must have shape \(4, n_pixels\)"):
        f.fit(np.zeros((5, 10)), WL4)
    with pytest.raises(InputError, match="strictly increasing"):
        f.fit(np.zeros((4, 10)), WL4[::-1])
    with pytest.raises(InputError, match="nm within 300-2600"):
        f.fit(np.zeros((4, 10)), WL4 / 1000.0)
    with pytest.raises(InputError, match="floating point"):
        f.fit(np.zeros((4, 10), dtype=np.uint16), WL4)

# }}}


# {{{ accuracy against oracles

@pytest.mark.parametrize("wl", [WL4, WL6], ids=["4bands", "6bands"])
def test_noise_free_recovers_truth(rt, real_t, wl):
    y, truth = synthetic(2000, wl, noise=0.0, seed=3)
    r = IgrmFitter(rt, len(wl), TIGHT if real_t == "float64" else None, real_t=real_t).fit(y, wl)
    ok = r.status == FitStatus.CONVERGED
    assert ok.mean() >= 0.995
    tol_nm = 1e-4 if real_t == "float64" else 0.05
    for key in ("l0", "s"):
        err = np.abs(getattr(r, key)[ok] - truth[key][ok])
        assert np.quantile(err, 0.99) <= tol_nm, f"{key}: 99th percentile error {np.quantile(err, 0.99):.3g} nm"
    np.testing.assert_allclose(r.lp, r.l0 + r.s, rtol=1e-6)


@pytest.mark.parametrize("wl", [WL4, WL6], ids=["4bands", "6bands"])
@pytest.mark.parametrize("loss", ["linear", "soft_l1"])
def test_float64_kernel_matches_scipy(rt, wl, loss):
    """Same data, bounds, loss and initial guess: the kernel's float64 fit and scipy's trf agree."""
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    y, _ = synthetic(150, wl, noise=0.003, seed=11)
    settings = IgrmSettings(tol=1e-10, max_iter=255, residual_floor=1e-12, loss=loss)
    ref = fit_scipy(y, wl, settings)
    r = IgrmFitter(rt, len(wl), settings, real_t="float64").fit(y, wl)
    both = (r.status == FitStatus.CONVERGED) & (ref.status == FitStatus.CONVERGED)
    assert both.mean() >= 0.97
    np.testing.assert_array_equal(r.status, ref.status)
    # l0 and s to 1e-3 nm, reflectances to 1e-5; the cost may not be worse than scipy's
    np.testing.assert_allclose(r.l0[both], ref.l0[both], atol=1e-3)
    np.testing.assert_allclose(r.s[both], ref.s[both], atol=1e-3)
    np.testing.assert_allclose(r.rmin[both], ref.rmin[both], atol=1e-5)
    assert np.all(r.rms[both] <= ref.rms[both] * (1 + 1e-6) + 1e-11)
    np.testing.assert_array_equal(r.bounds[both], ref.bounds[both])


@pytest.mark.parametrize("solver", ["varpro", "lm"])
@pytest.mark.parametrize("init", ["data", "grid"])
def test_float64_kernel_is_twin_of_numpy(rt, init, solver):
    """The numpy twin of each solver follows the same steps: identical status and iteration counts in float64."""
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    y, _ = synthetic(3000, WL6, noise=0.003, seed=5)
    settings = IgrmSettings(init=init, solver=solver)
    r = IgrmFitter(rt, 6, settings, real_t="float64").fit(y, WL6)
    twin = fit_numpy_varpro if solver == "varpro" else fit_numpy_lm
    n = twin(y, WL6, settings, dtype=np.float64)
    assert np.mean(r.status == n.status) >= 0.999
    assert np.mean(r.iterations == n.iterations) >= 0.99
    same = r.iterations == n.iterations
    np.testing.assert_allclose(r.lp[same], n.lp[same], atol=1e-6)


def test_grid_init_agrees_with_scipy_from_grid_start(rt):
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    y, _ = synthetic(100, WL4, noise=0.003, seed=8)
    settings = IgrmSettings(init="grid", tol=1e-10, max_iter=255)
    ref = fit_scipy(y, WL4, settings)
    r = IgrmFitter(rt, 4, settings, real_t="float64").fit(y, WL4)
    both = (r.status == 0) & (ref.status == 0)
    assert both.mean() >= 0.97
    np.testing.assert_allclose(r.lp[both], ref.lp[both], atol=1e-3)


def test_fast_variant_matches_plain_builtin_variant(rt):
    """Own exp + 8 lanes against builtin exp + scalar code (the obviously-correct variant)."""
    y, _ = synthetic(20000, WL6, noise=0.003, seed=2)
    fast = IgrmFitter(rt, 6, lanes=8, exp="poly").fit(y, WL6)
    plain = IgrmFitter(rt, 6, lanes=1, exp="builtin").fit(y, WL6)
    assert np.mean(fast.fitted() == plain.fitted()) >= 0.998
    # statuses differ only at the CONVERGED/STALLED threshold (lp_tol_nm = 1e-3 nm), where two float32
    # exp implementations round the Gauss-Newton step differently
    differ = fast.status != plain.status
    assert np.mean(differ) <= 0.01
    assert set(np.unique(np.concatenate([fast.status[differ], plain.status[differ]]))) <= {0, 4}
    assert np.all(np.abs(fast.lp - plain.lp)[differ] <= 0.01)
    d = np.abs(fast.lp - plain.lp)
    assert np.quantile(d, 0.99) <= 0.01 and np.mean(d <= 0.05) >= 0.998


def test_float32_close_to_float64(rt):
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    y, _ = synthetic(20000, WL4, noise=0.003, seed=4)
    r32 = IgrmFitter(rt, 4).fit(y, WL4)
    r64 = IgrmFitter(rt, 4, TIGHT, real_t="float64").fit(y, WL4)
    d = np.abs(r32.lp - r64.lp)
    assert np.median(d) <= 1e-3 and np.mean(d <= 0.05) >= 0.995


@pytest.mark.parametrize("n", [1, 7, 9, 1003])
def test_any_pixel_count_and_lane_independence(rt, n):
    """Pixel counts off the lane width give the same per-pixel results as one big batch."""
    y, _ = synthetic(2048, WL4, noise=0.003, seed=6)
    f = IgrmFitter(rt, 4)
    full = f.fit(y, WL4)
    part = f.fit(y[:, 500:500 + n], WL4)
    for name in ("lp", "rmax", "rmin", "rms", "status", "iterations", "bounds"):
        np.testing.assert_array_equal(getattr(part, name), getattr(full, name)[500:500 + n], err_msg=name)


def test_lane_width_does_not_change_results(rt):
    """One pixel per work-item or 4/8/16 in vectors: bit-identical results (no lane mixes with another),
    and each within the float32 tolerance of the converged float64 fit."""
    y, _ = synthetic(3000, WL6, noise=0.003, seed=13)
    results = {lanes: IgrmFitter(rt, 6, lanes=lanes).fit(y, WL6) for lanes in (1, 4, 8, 16)}
    for lanes in (4, 8, 16):
        for name in ("lp", "rmin", "rms", "status", "iterations", "bounds"):
            np.testing.assert_array_equal(getattr(results[lanes], name), getattr(results[1], name), err_msg=name)
    if rt.has_fp64:
        r64 = IgrmFitter(rt, 6, TIGHT, real_t="float64").fit(y, WL6)
        d = np.abs(results[16].lp - r64.lp)
        assert np.median(d) <= 1e-3 and np.mean(d <= 0.05) >= 0.995


def test_zero_pixels(rt):
    r = IgrmFitter(rt, 4).fit(np.zeros((4, 0)), WL4)
    assert r.n_pixels == 0 and r.lp.shape == (0,)


def test_chunking_is_invisible(rt):
    y, _ = synthetic(1000, WL4, noise=0.003, seed=9)
    f = IgrmFitter(rt, 4)
    a, b = f.fit(y, WL4), f.fit(y, WL4, chunk=96)
    np.testing.assert_array_equal(a.lp, b.lp)
    np.testing.assert_array_equal(a.status, b.status)


def test_wide_iteration_counter(rt):
    y, _ = synthetic(64, WL4, noise=0.003, seed=1)
    r = fit_igrm(y, WL4, IgrmSettings(max_iter=300))
    assert r.iterations.dtype == np.uint16 and np.all(r.status <= FitStatus.ITERATION_LIMIT)


def test_soft_l1_resists_one_bad_band(rt):
    """With a gross error in one of six bands, soft-L1 stays closer to the clean solution."""
    y, truth = synthetic(500, WL6, noise=0.001, seed=12)
    y[3] += 0.08  # B7 off by 8 % reflectance
    lin = IgrmFitter(rt, 6).fit(y, WL6)
    rob = IgrmFitter(rt, 6, IgrmSettings(loss="soft_l1", f_scale=0.005)).fit(y, WL6)
    err_lin = np.median(np.abs(lin.lp - truth["l0"] - truth["s"]))
    err_rob = np.median(np.abs(rob.lp - truth["l0"] - truth["s"]))
    assert err_rob < 0.5 * err_lin


def test_prosail_canopies_order_by_chlorophyll(rt):
    """Realism: PROSAIL canopies (LAI 3) on the four S2 bands: lp rises with Cab."""
    pytest.importorskip("prosail")
    from s2cl.reference.igrm_cases import box_resample, prosail_canopies

    cab = np.arange(10.0, 91.0, 10.0)
    y = box_resample(prosail_canopies(cab, np.full(cab.size, 3.0)), BANDS_4)
    r = IgrmFitter(rt, 4).fit(y, WL4)
    assert np.all(r.status == FitStatus.CONVERGED)
    assert np.all(np.diff(r.lp) > 0)
    assert np.all((r.l0 > 660) & (r.l0 < 695) & (r.s > 20) & (r.s < 60))
    assert np.all((r.bounds & int(BoundFlag.L0_LOW | BoundFlag.L0_HIGH | BoundFlag.S_LOW | BoundFlag.S_HIGH)) == 0)


def test_model_helper():
    y = model(np.array([680.0, 1e6]), [0.5], [0.1], [680.0], [30.0])
    np.testing.assert_allclose(y[:, 0], [0.1, 0.5])

# }}}


@pytest.mark.parametrize("group", [2, 8, 64])
def test_work_group_size_changes_no_bits(rt, monkeypatch, group: int) -> None:
    """Whatever work-group size a device would ask for (a size that divides the launch, or the driver's
    choice where it does not), the fits are the same bits."""
    y, _ = synthetic(1024, WL4, noise=0.003, seed=5)
    y = y.astype(np.float32)
    for n in (1024, 1000):  # 1,024: every group divides the work-items at 1-16 lanes; 1,000: none at 8 or 16
        base = IgrmFitter(rt, 4).fit(y[:, :n], WL4)
        with monkeypatch.context() as m:
            m.setattr(type(rt), "work_group", lambda self, kernel: group)
            assert rt.local_size(None, 64) == (group,)
            assert rt.local_size(None, 63) == ((1,) if "CPU" in rt.info.kind else None)
            other = IgrmFitter(rt, 4).fit(y[:, :n], WL4)
        for name in ("lp", "status", "iterations", "rmin", "rmax", "l0", "s"):
            assert np.array_equal(getattr(base, name), getattr(other, name)), name


def test_fits_read_and_write_host_memory_in_place(rt) -> None:
    """On host-memory devices the fit reads its input in place, aligned or not (the kernel loads it with
    vloadN), and writes its outputs into aligned host arrays (no copies): the same bits either way."""
    y, _ = synthetic(4096, WL4, noise=0.003, seed=9)
    y = y.astype(np.float32)
    align = rt.alignment
    raw = np.empty(y.size * 4 + 2 * align + 4, np.uint8)
    start = (-raw.ctypes.data) % align
    aligned = raw[start:start + y.nbytes].view(np.float32).reshape(y.shape)
    misaligned = raw[start + 4:start + 4 + y.nbytes].view(np.float32).reshape(y.shape)
    aligned[:] = y
    a = IgrmFitter(rt, 4).fit(aligned, WL4)
    misaligned[:] = y
    b = IgrmFitter(rt, 4).fit(misaligned, WL4)
    assert aligned.ctypes.data % align == 0 and misaligned.ctypes.data % align != 0
    for name in ("lp", "status", "iterations", "bounds"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    array, buffer = rt.output((3, 5), np.float32)
    assert array.shape == (3, 5) and (not rt.host_memory or array.ctypes.data % align == 0)
    rt.upload(buffer, np.arange(15, dtype=np.float32).reshape(3, 5))
    assert np.array_equal(rt.result(buffer, array), np.arange(15, dtype=np.float32).reshape(3, 5))
