"""Resampling against compiled C: is the OpenCL kernel's rate the memory's limit, or the kernel's?

Generates a C loop nest with the kernel's own access pattern (each band's support in turn, 8 spectra at a
time, native-width vector loads via GCC vector extensions, the weights from the same packed plan), compiles it
with the system C compiler (``cc -O3 -march=native -fopenmp``, one thread per core), checks it against the
float64 oracle, then times it interleaved with s2cl's kernel (spectra already on the device) and the
per-band-slice numpy: each round runs every method three times back to back, in a shuffled order, and keeps the best
of its last two calls; the ratio is taken within each round.
Needs a C compiler with OpenMP (gcc); says so and stops without one. A reference for the profile, not a
baseline a user would pick. Writes bench/results/resample-native-<machine>-<date>.json.

    python -m bench.resample_native [--pixels 100000] [--rounds 30]
"""

from __future__ import annotations

import argparse
import ctypes
import os
import random
import shutil
import statistics
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bench.bench_resample import TOLERANCE, per_band_slices, random_spectra, validated_resampler
from bench.common import check, load_average, load_note, machine_info, max_rel_error, time_repeats, write_result


def native_source(bands: list[dict], n_wavelengths: int, vw: int, rows: int) -> str:
    """C source of ``resample(out, spectra, weights, n)``: the band supports of ``bands`` (as
    :meth:`ResamplePlan.packed` gives them for ``vw``-wide loads) read band after band for ``rows`` spectra at a
    time (``rows`` = 1 for the last, partial block), spectra split across OpenMP threads."""
    def block(r_count: int) -> str:
        lines = []
        for k, b in enumerate(bands):
            nvec, s0, w0 = b["length"] // vw, b["start"], b["offset"]
            lines.append("    {")
            lines += [f"      vf a{r} = {{0}};" for r in range(r_count)]
            lines.append(f"      for (int j = 0; j < {nvec}; ++j) {{ const vf w = ld(wt + {w0} + {vw} * j);")
            lines += [f"        a{r} += w * ld(s + {r * n_wavelengths} + {s0} + {vw} * j);" for r in range(r_count)]
            lines.append("      }")
            for r in range(r_count):
                tail = "".join(f" + wt[{w0 + t}] * s[{r * n_wavelengths + s0 + t}]"
                               for t in range(nvec * vw, b["length"]))
                lines.append(f"      out[{k}L * n + i + {r}] = hsum(a{r}){tail};")
            lines.append("    }")
        return "\n".join(lines)

    return f"""
typedef float vf __attribute__((vector_size({4 * vw})));
static inline vf ld(const float *p) {{ vf v; __builtin_memcpy(&v, p, sizeof v); return v; }}
static inline float hsum(vf v) {{ float t = 0.0f; for (int l = 0; l < {vw}; ++l) t += v[l]; return t; }}
void resample(float *out, const float *spectra, const float *wt, long n)
{{
  const long blocks = n / {rows};
  #pragma omp parallel for schedule(static)
  for (long q = 0; q < blocks; ++q) {{
    const long i = q * {rows};
    const float *s = spectra + i * {n_wavelengths}L;
{block(rows)}
  }}
  for (long i = blocks * {rows}; i < n; ++i) {{
    const float *s = spectra + i * {n_wavelengths}L;
{block(1)}
  }}
}}
"""


def compile_native(source: str, folder: Path) -> ctypes.CDLL:
    """``source`` built as a shared library with the system C compiler; SystemExit with the reason if none."""
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise SystemExit("resample_native: no C compiler (cc or gcc, or $CC) on PATH; nothing measured")
    src, lib = folder / "resample_native.c", folder / "resample_native.so"
    src.write_text(source)
    cmd = [cc, "-O3", "-march=native", "-fopenmp", "-fPIC", "-shared", str(src), "-o", str(lib)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"resample_native: `{' '.join(cmd)}` failed:\n{done.stderr[-2000:]}")
    native = ctypes.CDLL(str(lib))
    native.resample.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_long]
    return native


CALLS = 3  # per method and round: the first takes up what the previous method left (spinning idle threads of
#            OpenBLAS or OpenMP, cold caches); the best of the others is the method's steady state


def paired_rounds(runs: dict[str, Callable[[], Any]], rounds: int) -> dict[str, list[float]]:
    """Seconds of each run per round: per round, the methods in a shuffled order, each called :data:`CALLS` times
    back to back and its best time after the first kept (as a loop over many blocks would run it)."""
    names = list(runs)
    times: dict[str, list[float]] = {name: [] for name in names}
    for k in range(rounds):
        random.Random(k).shuffle(names)
        for name in names:
            times[name].append(min(time_repeats(runs[name], CALLS - 1, warmup=1)))
    return times


def measure(pixels: int, rounds: int) -> dict[str, Any]:
    """The s2cl kernel, the compiled C loop and the numpy slices on the same ``pixels`` spectra (validated
    first), in ``rounds`` interleaved rounds."""
    data = random_spectra(pixels)
    res, err = validated_resampler(data)
    rt, n = res.rt, pixels
    bands, weights = res.plan.packed(res.vw)
    weights32 = np.ascontiguousarray(weights, dtype=np.float32)
    threads = os.cpu_count() or 1
    os.environ.setdefault("OMP_NUM_THREADS", str(threads))
    with tempfile.TemporaryDirectory() as tmp:  # the loaded library stays mapped once its file is gone
        native = compile_native(native_source(bands, res.plan.n_wavelengths, res.vw, res.rows), Path(tmp))
    out_c = np.empty((res.plan.n_bands, n), dtype=np.float32)

    def run_c(block: np.ndarray = data, out: np.ndarray = out_c) -> np.ndarray:
        native.resample(out.ctypes.data, block.ctypes.data, weights32.ctypes.data, block.shape[0])
        return out

    from s2cl.reference.forward import resample

    sample = np.ascontiguousarray(data[:500])
    err_c = max_rel_error(run_c(sample, np.empty((res.plan.n_bands, 500), np.float32)),
                          resample(sample, res.plan.weights))
    check(err_c < TOLERANCE, f"the compiled C resampler disagrees with the float64 oracle: max rel {err_c:.2e}")
    spectra_dev, out_dev = rt.to_device(data, zero_copy=True), rt.empty(res.plan.n_bands * n * 4)

    def run_kernel() -> None:
        res.enqueue(out_dev, spectra_dev, n)
        rt.finish()

    kernel, c_loop, slices = "s2cl OpenCL kernel (data on the device)", "compiled C, same access pattern", \
        "numpy float32 per-band support slices"
    before = load_average()
    times = paired_rounds({kernel: run_kernel, c_loop: run_c, slices: per_band_slices(data, res.plan)}, rounds)
    after = load_average()
    rates = {name: n / statistics.median(t) for name, t in times.items()}
    ratio = {name: statistics.median(a / b for a, b in zip(t, times[kernel], strict=True))
             for name, t in times.items() if name != kernel}
    return {"title": "SRF resampling, 2101 λ → 13 bands, float32: OpenCL kernel against compiled C", "n": n,
            "rounds": rounds, "vector_width": res.vw, "rows": res.rows, "threads": threads,
            "compiler_flags": "-O3 -march=native -fopenmp",
            "validation_max_rel_vs_float64": {kernel: err, c_loop: err_c},
            "median_rate_per_s": rates, "kernel_over_this_median_paired": ratio,
            "load": load_note(before, after), "seconds_per_round": times}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pixels", type=int, default=100_000)
    parser.add_argument("--rounds", type=int, default=30)
    args = parser.parse_args()
    from s2cl.cl.runtime import get_runtime

    result = measure(args.pixels, args.rounds)
    for name, rate in result["median_rate_per_s"].items():
        paired = result["kernel_over_this_median_paired"].get(name)
        print(f"{name:45s} {rate / 1e6:7.2f} M spectra/s" + (f"   s2cl kernel ÷ this {paired:.3f}" if paired else ""))
    print(result["load"])
    data = {"benchmark": "resample-native", "machine": machine_info(get_runtime()), "cases": [result]}
    print("wrote", write_result("resample-native", data))


if __name__ == "__main__":
    main()
