"""IGRM fits per second, side by side in one process, each at its accuracy.

Populations (float32 input, Gaussian noise sigma 0.003 reflectance), on the Sentinel-2 bands
B4-B7 (4 bands) or B4-B8a (6 bands):
  prosail    Lib1-like PROSAIL canopies (Cab 5-100 ug/cm2 step 5, LAI 3 and 4), box-averaged to the
             bands and copied to n pixels;
  synthetic  IGRM curves with rmax 0.3-0.6, rmin 0.01-0.08, l0 665-690 nm, s 25-50 nm (harder:
             narrow dips between bands make slow, ill-conditioned fits).
Reference: converged float64 fits (the kernel's float64 build with tol 1e-10, 255 iterations),
itself checked against scipy on a sample before timing.

Contenders: s2cl OpenCL float32 (fast: explicit lanes + own exp, with transfers and the kernel
alone; plain: one pixel per work-item + builtin exp; and the four-parameter LM solver), the same
algorithms vectorised in numpy (variable projection, the kernel's default, and the four-parameter
LM; float32, 64k-pixel chunks, one thread; on ``--n-numpy`` pixels, extrapolated), and
scipy.optimize.least_squares per pixel (timed on a sample, extrapolated). A fit is "at the float64
optimum" when its status class matches and its lp lies within 1e-3 nm of the optimum's.
:func:`igrm_baseline` is the measurement; the suite (``python -m bench``, part ``vs-igrm``, B4 B5 B6
B8) runs the same function. Writes bench/results/igrm.json.

    python -m bench.bench_igrm            # 10^6 pixels (a few minutes on 2 cores)
    python -m bench.bench_igrm --n 100000 # quicker
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import numpy as np

from bench.chain import REFERENCE_FIT, Context, reference_vs_scipy
from bench.common import comparison_rows, machine_info, median_time, print_comparison, write_json
from s2cl.cl.runtime import get_runtime
from s2cl.reference.igrm import fit_numpy_lm, fit_scipy
from s2cl.reference.igrm_cases import BANDS_4, BANDS_6, band_centres, prosail_population, synthetic
from s2cl.reference.igrm_varpro import fit_numpy_varpro
from s2cl.retrieve.igrm import IgrmFitter, IgrmResult, IgrmSettings

TOL_LP_NM = 1e-3
POPULATIONS = {"prosail": "noisy PROSAIL canopies", "synthetic": "noisy synthetic IGRM curves"}


def at_optimum(r: IgrmResult, ref: IgrmResult) -> np.ndarray:
    """Per-pixel: does ``r`` sit at the float64 optimum ``ref``?"""
    same_class = r.fitted() == ref.fitted()
    close = np.abs(r.lp.astype(np.float64) - ref.lp) <= TOL_LP_NM
    return same_class & np.where(ref.fitted(), close, r.status == ref.status)


def differences(r: IgrmResult, ref: IgrmResult) -> dict[str, Any]:
    """Distribution of |float32 - float64| over the pixels both fitted."""
    both = r.fitted() & ref.fitted()
    q = [0.5, 0.9, 0.99, 0.999, 1.0]
    out: dict[str, Any] = {}
    for key in ("lp", "l0", "s", "rmin", "rmax"):
        d = np.abs(getattr(r, key)[both].astype(np.float64) - getattr(ref, key)[both])
        out[key] = dict(zip(["p50", "p90", "p99", "p99.9", "max"], np.quantile(d, q).tolist(), strict=True))
    out["status_agreement"] = float(np.mean(r.status == ref.status))
    return out


def kernel_launcher(fitter: IgrmFitter, y: np.ndarray, wl: np.ndarray) -> tuple[Callable[[], None], int]:
    """The IGRM kernel alone on the first multiple of 16 pixels of ``y`` (inputs on the device,
    outputs left there), through the launch :meth:`IgrmFitter.fit` makes; and the number of pixels."""
    n = y.shape[1] // 16 * 16
    v = fitter.buffers(y[:, :n], wl)

    def launch() -> None:
        fitter.enqueue(v)
        fitter.rt.finish()

    return launch, n


def population(kind: str, n: int, bands: tuple[str, ...]) -> np.ndarray:
    """``n`` pixels (bands, n) float32 of the population ``kind`` (see the module)."""
    if kind == "prosail":
        y64, _ = prosail_population(n, bands, noise=0.003, seed=1)
    else:
        y64, _ = synthetic(n, band_centres(bands), noise=0.003, seed=1)
    return np.ascontiguousarray(y64, dtype=np.float32)


def lane_use(iterations: np.ndarray, lanes: int) -> float:
    """Share of the vector work that advances a fit: pixels run ``lanes`` at a time in lock-step until the
    slowest of them stops, so the share is mean iterations ÷ mean of each lane group's maximum (what lane
    refill could win back at most)."""
    it = np.asarray(iterations, dtype=np.float64)
    groups = it[: it.size // lanes * lanes].reshape(-1, lanes)
    return float(groups.mean() / groups.max(axis=1).mean()) if groups.size else float("nan")


def _timed(fit: Callable[[np.ndarray], IgrmResult], y: np.ndarray, ref: IgrmResult, repeat: int,
           lanes: int = 1) -> tuple[float, dict[str, Any], IgrmResult]:
    """Fits/s of ``fit`` on ``y`` (after one untimed call), its accuracy against ``ref`` and its result;
    ``lanes``: pixels per work-item in lock-step (the lane use is recorded where above 1)."""
    r = fit(y)
    accuracy = {"frac_at_float64_optimum": float(at_optimum(r, ref).mean()),
                "mean_iterations": float(r.iterations.mean()), "status_counts": r.counts()}
    if lanes > 1:
        accuracy["lane_use"] = lane_use(r.iterations, lanes)
        missed = ~at_optimum(r, ref)
        l0_min = IgrmSettings().l0_min_nm
        accuracy["missed"] = [{"status": int(r.status[i]), "lp_error_nm": float(abs(float(r.lp[i]) - ref.lp[i])),
                               "l0_on_bound": bool(r.l0[i] <= l0_min + 1e-3)} for i in np.flatnonzero(missed)[:20]]
    return y.shape[1] / median_time(lambda: fit(y), repeat), accuracy, r


def igrm_baseline(ctx: Context, n: int, n_scipy: int, n_numpy: int, bands: tuple[str, ...] | None = None,
                  kind: str = "prosail") -> dict[str, Any]:
    """IGRM fits of ``n`` pixels of population ``kind`` on ``bands`` (default: the suite's B4 B5
    B6 B8): s2cl fast (with transfers; the kernel alone), s2cl plain, s2cl with the LM solver, numpy
    variable projection and LM on ``n_numpy`` pixels and scipy on ``n_scipy``, each scored against the
    float64 optimum."""
    bands = bands or ("B4", "B5", "B6", "B8")
    wl, y = band_centres(bands), population(kind, n, bands)
    ref = IgrmFitter(get_runtime(), len(bands), REFERENCE_FIT, real_t="float64").fit(y.astype(np.float64), wl)
    sample = np.linspace(0, n - 1, n_scipy).astype(int)
    dlp = reference_vs_scipy(ref.take(sample), y[:, sample], wl)
    fast, plain = IgrmFitter(get_runtime(), len(bands)), IgrmFitter(get_runtime(), len(bands), lanes=1, exp="builtin")
    lm = IgrmFitter(get_runtime(), len(bands), IgrmSettings(solver="lm"))
    launch, n_kernel = kernel_launcher(fast, y, wl)
    s2cl_, scipy_ = "s2cl OpenCL float32 (lanes, own exp)", "scipy least_squares trf per pixel (sampled, extrapolated)"
    measured = {s2cl_: _timed(lambda v: fast.fit(v, wl), y, ref, ctx.repeat, lanes=fast.types.lanes),
                "s2cl OpenCL float32 kernel alone (data on the device)":
                    (n_kernel / median_time(launch, ctx.repeat, warmup=1), {}, None),
                "s2cl OpenCL float32 plain (1 lane, builtin exp)": _timed(lambda v: plain.fit(v, wl), y, ref, 1),
                "s2cl OpenCL float32, four-parameter LM solver": _timed(lambda v: lm.fit(v, wl), y, ref, ctx.repeat),
                "numpy vectorised variable projection float32 (the kernel's algorithm, 1 thread)":
                    _timed(lambda v: fit_numpy_varpro(v, wl), y[:, :n_numpy], ref.take(slice(0, n_numpy)), 1),
                "numpy vectorised four-parameter LM float32 (1 thread)":
                    _timed(lambda v: fit_numpy_lm(v, wl, IgrmSettings(solver="lm")), y[:, :n_numpy],
                           ref.take(slice(0, n_numpy)), 1),
                scipy_: _timed(lambda v: fit_scipy(v.astype(np.float64), wl, IgrmSettings()), y[:, sample],
                               ref.take(sample), 1)}
    rows = comparison_rows({k: v[0] for k, v in measured.items()}, scipy_, {k: v[1] for k, v in measured.items()})
    return {"title": f"IGRM fits, {POPULATIONS[kind]}, {len(bands)} bands ({' '.join(bands)})", "unit": "fits/s",
            "n": n, "bands": list(bands), "population": kind, "samples": {"numpy": n_numpy, "scipy": n_scipy},
            "validation_reference_vs_scipy_nm": dlp, "float32_vs_float64": differences(measured[s2cl_][2], ref),
            "rows": rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--n-scipy", type=int, default=1000)
    ap.add_argument("--n-numpy", type=int, help="pixels the numpy LM fits (default: all)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--populations", nargs="+", default=list(POPULATIONS), choices=list(POPULATIONS))
    args = ap.parse_args()
    ctx = Context.make(quick=False, repeat=args.repeat)
    fast = IgrmFitter(get_runtime(), 4)
    result = {"benchmark": "igrm", "machine": machine_info(fast.rt), "settings": IgrmSettings().__dict__,
              "accuracy_tolerance": {"lp_nm": TOL_LP_NM},
              "igrm_lanes_float32": fast.types.lanes, "cases": []}
    for kind in args.populations:
        for names in (BANDS_4, BANDS_6):
            case = igrm_baseline(ctx, args.n, args.n_scipy, args.n_numpy or args.n, names, kind)
            print_comparison(case)
            print("float32 - float64 |d lp| quantiles (nm):", case["float32_vs_float64"]["lp"])
            fast_row = case["rows"][0]
            print(f"lane use {fast_row['lane_use']:.1%} (mean iterations / slowest lane's); fits off the float64 "
                  f"optimum: {fast_row['missed'][:5]}")
            result["cases"].append(case)
    print("wrote", write_json("igrm.json", result))


if __name__ == "__main__":
    main()
