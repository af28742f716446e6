"""Resampling throughput: s2cl's OpenCL kernel against numpy matmul and SPy's BandResampler.

2101-wavelength spectra (400–2500 nm, 1 nm) into the 13 Sentinel-2 bands, >= 1e5 pixels, float32.
Also measures the OpenCL copy bandwidth in the same run and the bound it implies: reading each
spectrum once (2101 × 4 B) at that bandwidth. Writes JSON to bench/results/.

    python -m bench.bench_resample [--pixels 100000] [--repeat 5]
"""

from __future__ import annotations

import argparse

import numpy as np

from bench.common import check, machine_info, max_rel_error, median_and_times, median_time, write_result


def copy_bandwidth(rt, nbytes: int, repeat: int) -> float:
    """OpenCL device copy bandwidth (bytes read + written per second) with float8 loads/stores."""
    src = ("__kernel void copy8(__global float8 *o, __global const float8 *i)"
           " { size_t g = get_global_id(0); o[g] = i[g]; }")
    kernel = rt.kernel(rt.build(src, template="bench/copy8"), "copy8")
    n8 = nbytes // 32
    a, b = rt.zeros(n8 * 32), rt.empty(n8 * 32)

    def run() -> None:
        kernel(rt.queue, (n8,), None, b, a)
        rt.finish()

    t = median_time(run, repeat, warmup=1)
    return 2 * n8 * 32 / t


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pixels", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--spy-sample", type=int, default=2000, help="pixels for the (slow) SPy per-spectrum loop")
    args = parser.parse_args()

    from spectral import BandResampler

    from s2cl.cl.runtime import get_runtime
    from s2cl.forward.resample import ResamplePlan, Resampler
    from s2cl.grid import DEFAULT_GRID
    from s2cl.reference.forward import resample as ref_resample
    from s2cl.sensor.sensor import Sensor

    rt = get_runtime()
    sensor = Sensor.sentinel2()
    plan = ResamplePlan.of(sensor.bands, DEFAULT_GRID)
    n, nw = args.pixels, DEFAULT_GRID.size
    rng = np.random.default_rng(0)
    spectra = rng.random((n, nw), dtype=np.float32)
    resampler = Resampler(rt, plan, "float32")

    # validate a slice against the float64 oracle before timing
    max_rel = max_rel_error(resampler(spectra[:500]), ref_resample(spectra[:500], plan.weights))
    check(max_rel < 2e-6, f"resampling disagrees with the float64 oracle: max rel {max_rel:.2e}; not timing")

    spectra_dev = rt.to_device(spectra, zero_copy=True)
    out_dev = rt.empty(plan.n_bands * n * 4)

    def kernel_only() -> None:
        resampler.enqueue(out_dev, spectra_dev, n)
        rt.finish()

    t_kernel, times_kernel = median_and_times(kernel_only, args.repeat, warmup=1)
    t_host = median_time(lambda: resampler(spectra), args.repeat, warmup=1)

    dense = plan.dense().astype(np.float32)
    t_numpy = median_time(lambda: spectra @ dense.T, args.repeat, warmup=1)

    spy = BandResampler(DEFAULT_GRID.wavelengths, [b.centre_nm for b in sensor.bands], None,
                        [b.fwhm_nm for b in sensor.bands])
    sample = spectra[: args.spy_sample]

    def spy_loop() -> None:
        for row in sample:
            spy(row)

    t_spy_sample = median_time(spy_loop, max(1, args.repeat // 2), warmup=1)
    t_spy = t_spy_sample * n / sample.shape[0]

    bw = copy_bandwidth(rt, spectra.nbytes, args.repeat)
    bound = bw / (nw * 4)  # spectra per second when reading each spectrum once at copy bandwidth

    rate = {"s2cl_kernel": n / t_kernel, "s2cl_with_transfers": n / t_host, "numpy_matmul_float32": n / t_numpy,
            "spy_bandresampler_loop": n / t_spy}
    result = {
        "benchmark": "resample",
        "machine": machine_info(rt),
        "pixels": n, "wavelengths": nw, "bands": plan.n_bands, "precision": "float32",
        "validation_max_rel_error_vs_float64": max_rel,
        "seconds_median": {"s2cl_kernel": t_kernel, "s2cl_with_transfers": t_host, "numpy_matmul_float32": t_numpy,
                           "spy_bandresampler_loop_extrapolated": t_spy},
        "seconds_all_kernel": times_kernel,
        "spectra_per_second": rate,
        "copy_bandwidth_GBps": bw / 1e9,
        "bandwidth_bound_spectra_per_second": bound,
        "ratios": {
            "kernel_vs_numpy": rate["s2cl_kernel"] / rate["numpy_matmul_float32"],
            "with_transfers_vs_numpy": rate["s2cl_with_transfers"] / rate["numpy_matmul_float32"],
            "kernel_vs_spy": rate["s2cl_kernel"] / rate["spy_bandresampler_loop"],
            "kernel_fraction_of_bandwidth_bound": rate["s2cl_kernel"] / bound,
        },
    }
    path = write_result("resample", result)
    print(f"{'method':32s} {'spectra/s':>14s}")
    for k, v in rate.items():
        print(f"{k:32s} {v:14,.0f}")
    print(f"{'bandwidth bound':32s} {bound:14,.0f}  (copy {bw / 1e9:.1f} GB/s)")
    for k, v in result["ratios"].items():
        print(f"{k:40s} {v:6.2f}")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
