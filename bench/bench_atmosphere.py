"""Cost of the atmosphere effect: forward + resample throughput with the effect on vs off.

The resample kernel (``kernels/resample.cl.mako``) either reads TOA radiance spectra and applies the
SRFs (atmosphere off), or reads surface-reflectance spectra and turns each wavelength into TOA
radiance, ``L = Lp + G·ρ/(1 − S·ρ)`` (6S LUT terms of the paper's standard atmosphere), before the
SRFs (atmosphere on). 2101 wavelengths (400–2500 nm, 1 nm) into the 13 Sentinel-2 bands, float32.
Both are validated on a slice against the float64 numpy oracle (:mod:`s2cl.reference.forward`)
before timing; the float64 numpy forward + resample is timed as a baseline in the same run.
Writes bench/results/atmosphere.json (atomically). Timings are medians after one untimed warm-up
call (the first call compiles); the machine may be shared (see ``machine.load_average``).

    python -m bench.bench_atmosphere [--pixels 20000] [--repeat 3]
"""

from __future__ import annotations

import argparse

import numpy as np

from bench.chain import oracle_band_radiance
from bench.common import check, machine_info, max_rel_error, median_and_times, write_json

RESULT = "atmosphere.json"  # in bench/results/
TOLERANCE = 2e-6   # float32 kernel vs float64 oracle, max pointwise |error| / |value|


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pixels", type=int, default=20_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--check", type=int, default=500, help="pixels validated against the float64 oracle")
    args = parser.parse_args()

    from s2cl.atmos.atmosphere import AtmosphereLUT
    from s2cl.atmos.state import AtmosphereState
    from s2cl.cl.runtime import get_runtime
    from s2cl.forward.resample import ResamplePlan, Resampler
    from s2cl.grid import DEFAULT_GRID
    from s2cl.reference.forward import resample as ref_resample
    from s2cl.sensor.sensor import Sensor

    rt = get_runtime()
    sensor = Sensor.sentinel2()
    plan = ResamplePlan.of(sensor.bands, DEFAULT_GRID)
    terms = AtmosphereLUT.load().terms(AtmosphereState.paper_standard(), DEFAULT_GRID)
    n, nw = args.pixels, DEFAULT_GRID.size
    rng = np.random.default_rng(0)
    rho = (0.6 * rng.random((n, nw))).astype(np.float32)            # surface reflectance
    radiance = terms.toa_radiance(rho).astype(np.float32)           # TOA radiance, W m-2 sr-1 um-1
    off = Resampler(rt, plan, "float32")
    on = Resampler(rt, plan, "float32", atmosphere=terms)

    def oracle(x: np.ndarray) -> np.ndarray:
        return oracle_band_radiance(x, terms, plan.weights)

    # validate a slice against the float64 oracle before timing
    k = min(args.check, n)
    errors = {}
    for label, got, expected in (("atmosphere_off", off(radiance[:k]), ref_resample(radiance[:k], plan.weights)),
                                 ("atmosphere_on", on(rho[:k]), oracle(rho[:k]))):
        errors[label] = max_rel_error(got, expected)
        check(errors[label] < TOLERANCE, f"{label}: kernel differs from the float64 oracle by {errors[label]:.2e} "
                                         f"(> {TOLERANCE:g}); not timing")

    out_dev = rt.empty(plan.n_bands * n * 4)
    rho_dev = rt.to_device(rho, zero_copy=True)
    rad_dev = rt.to_device(radiance, zero_copy=True)

    def kernel(resampler: Resampler, src) -> None:
        resampler.enqueue(out_dev, src, n)
        rt.finish()

    t_off, all_off = median_and_times(lambda: kernel(off, rad_dev), args.repeat, warmup=1)
    t_on, all_on = median_and_times(lambda: kernel(on, rho_dev), args.repeat, warmup=1)
    sample = rho[: min(n, 5000)]
    t_np, _ = median_and_times(lambda: oracle(sample), args.repeat, warmup=1)
    t_np *= n / sample.shape[0]
    rate = {"kernel_atmosphere_off": n / t_off, "kernel_atmosphere_on": n / t_on,
            "numpy_float64_forward_resample": n / t_np}
    result = {
        "benchmark": "atmosphere",
        "machine": machine_info(rt),
        "pixels": n, "wavelengths": nw, "bands": plan.n_bands, "precision": "float32",
        "state": vars(AtmosphereState.paper_standard()),
        "validation_pixels": k,
        "validation_max_rel_error_vs_float64": errors,
        "seconds_median": {"kernel_atmosphere_off": t_off, "kernel_atmosphere_on": t_on,
                           "numpy_float64_forward_resample_extrapolated": t_np},
        "seconds_all": {"kernel_atmosphere_off": all_off, "kernel_atmosphere_on": all_on},
        "pixels_per_second": rate,
        "ratios": {"atmosphere_cost_on_vs_off": t_on / t_off,
                   "kernel_on_vs_numpy_float64": rate["kernel_atmosphere_on"] / rate["numpy_float64_forward_resample"]},
    }
    path = write_json(RESULT, result)
    print(f"{'method':34s} {'pixels/s':>14s}")
    for key, v in rate.items():
        print(f"{key:34s} {v:14,.0f}")
    for key, v in result["ratios"].items():
        print(f"{key:34s} {v:8.2f}")
    print(f"validation (max rel. error vs float64): {errors}")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
