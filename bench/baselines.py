"""s2cl beside what a user would otherwise run, in the same process, after a correctness check:
numpy matmul and SPy's BandResampler for SRF resampling, scipy least_squares (per pixel, on a
sample, extrapolated) and a vectorised numpy LM for IGRM, SPy's spectral_angles for SAM.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.chain import BANDS, Context
from bench.common import check, max_rel_error, median_time


def _rows(rates: dict[str, float], base: str, extra: dict[str, dict[str, Any]] | None = None
          ) -> list[dict[str, Any]]:
    return [{"method": k, "per_s": v, "ratio_s2cl_over_this": rates[next(iter(rates))] / v,
             "baseline": k == base, **(extra or {}).get(k, {})} for k, v in rates.items()]


def resample(ctx: Context) -> dict[str, Any]:
    """2101-wavelength spectra → 13 Sentinel-2 bands, float32."""
    from spectral import BandResampler

    from s2cl.cl.runtime import get_runtime
    from s2cl.forward.resample import ResamplePlan, Resampler
    from s2cl.grid import DEFAULT_GRID
    from s2cl.reference.forward import resample as ref_resample
    from s2cl.sensor.sensor import Sensor

    rt = get_runtime()
    sensor = Sensor.sentinel2()
    plan = ResamplePlan.of(sensor.bands, DEFAULT_GRID)
    n = 20_000 if ctx.quick else 100_000
    spectra = np.random.default_rng(0).random((n, DEFAULT_GRID.size), dtype=np.float32)
    res = Resampler(rt, plan, "float32")
    want = ref_resample(spectra[:500], plan.weights)
    err = max_rel_error(res(spectra[:500]), want)
    check(err < 2e-6, f"s2cl resampling disagrees with the float64 oracle: {err:.2e}")
    dense = plan.dense().astype(np.float32)
    err_np = max_rel_error((spectra[:500] @ dense.T).T, want)
    check(err_np < 2e-5, f"numpy matmul baseline disagrees with the float64 oracle: {err_np:.2e}")
    spy = BandResampler(DEFAULT_GRID.wavelengths, [b.centre_nm for b in sensor.bands], None,
                        [b.fwhm_nm for b in sensor.bands])
    sample = spectra[: 500 if ctx.quick else 2000]

    def spy_loop() -> None:
        for row in sample:
            spy(row)

    t_s2cl = median_time(lambda: res(spectra), ctx.repeat, warmup=1)
    t_np = median_time(lambda: spectra @ dense.T, ctx.repeat, warmup=1)
    t_spy = median_time(spy_loop, max(1, ctx.repeat // 2), warmup=1) * n / sample.shape[0]
    rates = {"s2cl OpenCL (host arrays in and out)": n / t_s2cl, "numpy float32 matmul (dense SRF matrix)": n / t_np,
             "SPy BandResampler, per spectrum (sampled, extrapolated)": n / t_spy}
    return {"name": "resample", "title": "SRF resampling, 2101 λ → 13 bands, float32", "unit": "spectra/s",
            "n": n, "validation_max_rel_vs_float64": err,
            "rows": _rows(rates, "numpy float32 matmul (dense SRF matrix)",
                          {"SPy BandResampler, per spectrum (sampled, extrapolated)":
                           {"note": "Gaussian SRFs, not the eq. 1 model: a different (cruder) band model"}})}


def igrm(ctx: Context) -> dict[str, Any]:
    """IGRM fits of noisy PROSAIL canopies on B4 B5 B6 B8, each method at its own accuracy."""
    from bench.bench_igrm import REFERENCE_SETTINGS, at_optimum
    from s2cl.reference.igrm import fit_numpy_lm, fit_scipy
    from s2cl.reference.igrm_cases import band_centres, prosail_population
    from s2cl.retrieve.igrm import IgrmFitter, IgrmSettings

    n = 100_000 if ctx.quick else 1_000_000
    n_scipy = 200 if ctx.quick else 1000
    wl = band_centres(BANDS)
    y64, _ = prosail_population(n, BANDS, noise=0.003, seed=1)
    y = np.ascontiguousarray(y64, dtype=np.float32)
    ref = IgrmFitter(len(BANDS), REFERENCE_SETTINGS, real_t="float64").fit(y.astype(np.float64), wl)
    sample = np.linspace(0, n - 1, n_scipy).astype(int)
    sp_ref = fit_scipy(y[:, sample].astype(np.float64), wl, REFERENCE_SETTINGS)
    both = sp_ref.fitted() & ref.fitted()[sample]
    dlp = float(np.max(np.abs(sp_ref.lp[both] - ref.lp[sample][both])))
    check(dlp < 1e-2, f"float64 IGRM reference disagrees with scipy: {dlp:.2e} nm")
    fast = IgrmFitter(len(BANDS))
    r_fast = fast.fit(y, wl)
    t_fast = median_time(lambda: fast.fit(y, wl), ctx.repeat, warmup=1)
    m = n // 10
    r_np = fit_numpy_lm(y[:, :m], wl)
    t_np = median_time(lambda: fit_numpy_lm(y[:, :m], wl), 1) * n / m
    sp = fit_scipy(y[:, sample].astype(np.float64), wl, IgrmSettings())
    t_sp = median_time(lambda: fit_scipy(y[:, sample].astype(np.float64), wl, IgrmSettings()), 1) * n / n_scipy
    sub_ref, sub_np = ref.take(sample), ref.take(slice(0, m))
    s2cl_, numpy_, scipy_ = ("s2cl OpenCL float32", "numpy vectorised LM float32 (same algorithm, 1 thread)",
                             "scipy least_squares trf per pixel (sampled, extrapolated)")
    acc = {s2cl_: float(at_optimum(r_fast, ref).mean()), numpy_: float(at_optimum(r_np, sub_np).mean()),
           scipy_: float(at_optimum(sp, sub_ref).mean())}
    rates = {s2cl_: n / t_fast, numpy_: n / t_np, scipy_: n / t_sp}
    return {"name": "igrm", "title": "IGRM fits, noisy PROSAIL canopies, 4 bands", "unit": "fits/s", "n": n,
            "validation_reference_vs_scipy_nm": dlp,
            "samples": {"numpy": m, "scipy": n_scipy},
            "rows": _rows(rates, scipy_,
                          {k: {"frac_at_float64_optimum": v} for k, v in acc.items()})}


def sam(ctx: Context) -> dict[str, Any]:
    """SAM, 13 bands, 20 references: classify (best reference + angle)."""
    import spectral

    from bench.bench_sam import numpy_sam
    from bench.bench_sam import scene as sam_scene
    from s2cl.reference import stages as ref
    from s2cl.retrieve.sam import SamClassifier

    n = 100_000 if ctx.quick else 1_000_000
    refs, _, pix = sam_scene(n, 13, 20)
    clf = SamClassifier(refs)
    k = 20_000  # the validated slice
    best, angle, _ = ref.sam_classify(pix[:, :k], refs)
    got = clf.classify(pix[:, :k])
    agree = float(np.mean(got.reference == best))
    check(agree > 0.999 and float(np.max(np.abs(got.angle - angle))) < 1e-3, "SAM disagrees with the float64 oracle")
    cube = np.ascontiguousarray(pix.T).reshape(1000, n // 1000, 13)
    refs32 = refs.astype(np.float32)

    def spy(c: np.ndarray = cube) -> Any:
        a = spectral.spectral_angles(c, refs32)
        return np.argmin(a, axis=2), np.min(a, axis=2)

    # the baselines on the same slice before timing them: the same classes and angles as the oracle
    spy_best, spy_angle = spy(np.ascontiguousarray(pix[:, :k].T).reshape(1, k, 13))
    np_best, np_angle = numpy_sam(pix[:, :k], clf.unit_refs)
    for what, b, a in (("SPy spectral_angles", spy_best.ravel(), spy_angle.ravel()), ("numpy SAM", np_best, np_angle)):
        b_agree, d_angle = float(np.mean(b == best)), float(np.max(np.abs(a - angle)))
        check(b_agree > 0.999 and d_angle < 1e-3,
              f"{what} baseline disagrees with the float64 oracle: {b_agree:.4%} same class, max |d angle| "
              f"{d_angle:.1e} rad")

    t_s2cl = median_time(lambda: clf.classify(pix), ctx.repeat, warmup=1)
    t_spy = median_time(spy, ctx.repeat, warmup=1)
    t_np = median_time(lambda: numpy_sam(pix, clf.unit_refs), ctx.repeat, warmup=1)
    rates = {"s2cl OpenCL": n / t_s2cl, "SPy spectral_angles + argmin": n / t_spy,
             "numpy float32 matmul + argmax": n / t_np}
    return {"name": "sam", "title": "SAM, 13 bands, 20 references", "unit": "pixels/s", "n": n,
            "validation_agreement": agree, "rows": _rows(rates, "SPy spectral_angles + argmin")}


BASELINES = {"resample": resample, "igrm": igrm, "sam": sam}
