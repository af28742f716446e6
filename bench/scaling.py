"""Throughput and scaling: forward-chain pixels/s, IGRM fits/s and sweep configuration-pixel
evaluations/s; time against pixels, configurations and bands (log–log with fitted slopes);
memory against the sweep's chunk size; the sweep on Dask with 1 and 2 workers.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.chain import BANDS, REFERENCE_FIT, Context, oracle_band_radiance
from bench.common import ROOT, check, max_rel_error, median_time
from bench.sweep_check import validate_sweep
from s2cl.app.chain_parts import scene_simulator
from s2cl.cl.runtime import get_runtime
from s2cl.retrieve.igrm import IgrmFitter
from s2cl.scene.library import scene_library
from s2cl.scene.terms import scene_atmosphere


def slope(x: list[float], t: list[float]) -> float:
    """Exponent of t ∝ x^slope (least squares in log–log)."""
    return float(np.polyfit(np.log(x), np.log(t), 1)[0])


def _series(x_label: str, xs: list[int], seconds: list[float], per: str, *, scale: int = 1, **extra: Any
            ) -> dict[str, Any]:
    """Points (x, seconds, rate = x · scale / seconds) and the log–log slope of time against x."""
    return {"x": x_label, "points": [{"x": x, "seconds": s, "rate_per_s": x * scale / s}
                                     for x, s in zip(xs, seconds, strict=True)],
            "slope": slope(xs, seconds), "rate_unit": per, **extra}


def _full_scene(ctx: Context, **overrides: Any) -> Any:
    """The default scene with all 13 bands."""
    return ctx.scene(all_bands=True, **overrides)


def forward_vs_pixels(ctx: Context, block: int) -> dict[str, Any]:
    """Forward chain (6S atmosphere + SRFs of 13 bands + noise, DN, calibration, correction) on
    distinct spectra, float32, in blocks of at most 10^5 spectra (each block resampled anew)."""
    scene = _full_scene(ctx)
    lib = scene_library(scene)
    terms = scene_atmosphere(scene)
    check(terms is not None, "the default scene has no atmosphere")
    sim = scene_simulator(get_runtime(), scene, atmosphere=terms)
    sizes = [1_000, 10_000, 100_000, 1_000_000]
    spectra = np.ascontiguousarray(np.resize(lib.spectra, (min(block, max(sizes)), lib.spectra.shape[1])),
                                   dtype=np.float32)
    err = max_rel_error(sim.band_radiance(lib.spectra.astype(np.float32)),
                        oracle_band_radiance(lib.spectra, terms, sim.plan.weights))
    check(err < 1e-4, f"float32 forward chain disagrees with the float64 oracle: max rel {err:.2e}")

    def chain(n: int) -> None:
        done = 0
        while done < n:
            m = min(spectra.shape[0], n - done)
            out = sim.sense(sim.band_radiance(spectra[:m]), seed=1, pixel_offset=done)
            check(out is not None, "the default scene does not sense")
            done += m

    seconds = [median_time(lambda n=n: chain(n), ctx.repeat if n < 1_000_000 else 2, warmup=1) for n in sizes]
    return _series("pixels", sizes, seconds, "pixels/s", bands=13, precision="float32",
                   validation_max_rel_vs_float64=err)


def fits_vs_pixels(ctx: Context) -> dict[str, Any]:
    """IGRM fits (float32, 4 bands, default settings) of noisy PROSAIL canopies, 10^3-10^6 pixels."""
    from s2cl.reference.igrm_cases import band_centres, prosail_population

    sizes = [1_000, 10_000, 100_000, 1_000_000]
    y, _ = prosail_population(max(sizes), BANDS, noise=0.003, seed=1)
    y = np.ascontiguousarray(y, dtype=np.float32)
    wl = band_centres(BANDS)
    fitter = IgrmFitter(get_runtime(), len(BANDS))
    from bench.bench_igrm import at_optimum

    ref = IgrmFitter(get_runtime(), len(BANDS), REFERENCE_FIT, real_t="float64").fit(
        y[:, :5000].astype(np.float64), wl)
    ok = float(at_optimum(fitter.fit(y[:, :5000], wl), ref).mean())
    check(ok > 0.99, f"only {ok:.2%} of float32 fits at the float64 optimum")
    seconds = [median_time(lambda n=n: fitter.fit(y[:, :n], wl), ctx.repeat, warmup=1) for n in sizes]
    return _series("pixels", sizes, seconds, "fits/s",
                   validation_frac_at_float64_optimum=ok)


def resample_vs_bands(ctx: Context, spectra: int) -> dict[str, Any]:
    """SRF resampling of random spectra into the first 1, 2, 4, 8 and 13 bands, float32; each
    band plan validated on a slice against the float64 oracle before it is timed."""
    from bench.bench_resample import random_spectra, validated_resampler

    data = random_spectra(spectra)
    counts = [1, 2, 4, 8, 13]
    validated = [validated_resampler(data, k) for k in counts]
    seconds = [median_time(lambda r=res: r(data), ctx.repeat, warmup=1) for res, _ in validated]
    return _series("bands", counts, seconds, "band values/s", scale=spectra, pixels=spectra,
                   validation_max_rel_vs_float64=max(err for _, err in validated),
                   note="bands B1… in order: supports differ (B8 115 nm, B12 180 nm FWHM), so time follows the "
                        "summed support, not the count")


def _sweep_scene(ctx: Context, copies: int) -> Any:
    return _full_scene(ctx, **{"surface.copies": copies})


def validated_job(ctx: Context, copies: int, chunk: int | None = None) -> tuple[Any, dict[str, Any]]:
    """The default scene's sweep with ``copies`` copies, its kernel checked by
    :func:`bench.sweep_check.validate_sweep` once per process (and copies)."""
    from s2cl.app.plan import plan_sweep

    job = plan_sweep(_sweep_scene(ctx, copies), chunk=chunk)
    key = f"sweep-validation-{copies}"
    if key not in ctx.cache:
        ctx.cache[key] = validate_sweep(job)
    return job, ctx.cache[key]


def sweep_vs_configs(ctx: Context, copies: int) -> dict[str, Any]:
    """The fused sweep kernel (gather → noise → DN → calibration → correction → IGRM → metrics)
    on the default scene's B4 B5 B6 B8 sweep, validated against the numpy float64 oracle first."""
    from s2cl.sweep.engine import evaluate_chunk

    job, checked = validated_job(ctx, copies)
    pixels = job.tables.n_pixels
    counts = [10, 100, 1000, job.n_configs]
    seconds = [median_time(lambda c=c: evaluate_chunk(job, 0, c), ctx.repeat if c < 1000 else 2, warmup=1)
               for c in counts]
    out = _series("configurations", counts, seconds, "configurations/s",
                  pixels_per_config=pixels, validation_max_rel_rms_vs_float64=checked["rms_rel_diff_max"],
                  validation_same_status_class_fraction=checked["same_status_class_fraction"])
    for p in out["points"]:
        p["config_pixels_per_s"] = p["rate_per_s"] * pixels
    return out


_MEMORY_PROBE = """
import json, sys, threading, time
from bench.chain import Context
from bench.scaling import _sweep_scene
from s2cl.app.plan import plan_sweep
from s2cl.sweep.engine import evaluate_chunk

def rss():
    with open("/proc/self/status") as fh:
        return next(int(line.split()[1]) for line in fh if line.startswith("VmRSS")) / 1024

chunk, copies = int(sys.argv[1]), int(sys.argv[2])
from s2cl.io.budget import Budget
# the probe measures what a chunk takes, also beyond the default 4 GB limit (up to 90 % of what is free)
job = plan_sweep(_sweep_scene(Context.make(True), copies), chunk=chunk, budget=Budget.of("1T"))
evaluate_chunk(job, 0, 2)
base, peak, running = rss(), [0.0], True
def sample():
    while running:
        peak[0] = max(peak[0], rss())
        time.sleep(0.0005)
th = threading.Thread(target=sample)
th.start()
t = time.perf_counter()
evaluate_chunk(job, 0, chunk)
sec = time.perf_counter() - t
running = False
th.join()
peak[0] = max(peak[0], rss())
print(json.dumps({"chunk": chunk, "rss_before_mib": base, "chunk_rss_mib": peak[0] - base, "seconds": sec}))
"""


def memory_vs_chunk(ctx: Context, copies: int, chunks: tuple[int, ...]) -> dict[str, Any]:
    """Resident memory one sweep chunk adds (VmRSS sampled every 0.5 ms), in a fresh process per
    chunk size (PoCL's OpenCL buffers live in host memory, so RSS sees them)."""
    job, _ = validated_job(ctx, copies)  # the kernel the probes run, checked in this process
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    points = []
    for c in chunks:
        out = subprocess.run([sys.executable, "-c", _MEMORY_PROBE, str(c), str(copies)], capture_output=True,
                             text=True, env=env, cwd=ROOT, check=True)
        points.append(json.loads(out.stdout.strip().splitlines()[-1]))
    from s2cl.app.checks import check_sweep
    from s2cl.app.sweep_budget import host_footprint
    from s2cl.cl.runtime import get_runtime
    from s2cl.sweep.host_footprint import per_unit_bytes
    from s2cl.sweep.metrics_kernel import metrics_on_device

    rt = get_runtime()
    on_device = metrics_on_device(rt)
    chunk_part = host_footprint(check_sweep(_sweep_scene(ctx, copies)), host_metrics=not on_device,
                                device_memory=rt.host_memory, device_metrics=on_device).chunk
    per_config = per_unit_bytes(chunk_part)
    for p in points:
        p["mib_per_config"] = p["chunk_rss_mib"] / p["chunk"]
        p["estimate_mib"] = p["chunk"] * per_config / 2**20
    return {"pixels_per_config": job.tables.n_pixels, "points": points,
            "note": "chunk_rss_mib: peak growth of the resident set while the chunk runs, over the process after "
                    "set-up (sampled, so a lower bound); estimate_mib: s2cl's own planning estimate "
                    f"(s2cl.app.sweep_budget.host_footprint), {per_config / job.tables.n_pixels:.1f} B per "
                    "configuration-pixel"}


def dask_workers(ctx: Context, copies: int) -> dict[str, Any]:
    """The whole sweep written to Parquet in-process and with Dask LocalCluster(1 and 2 workers)."""
    from s2cl.sweep.engine import run_sweep

    job, _ = validated_job(ctx, copies, chunk=512)
    rows: list[dict[str, Any]] = []
    results = {}
    for workers in (None, 1, 2):
        with tempfile.TemporaryDirectory() as tmp:
            t = time.perf_counter()
            path = run_sweep(job, Path(tmp) / "out", workers=workers)
            sec = time.perf_counter() - t
            import pyarrow.parquet as pq

            results[workers] = pq.read_table(path).column("rms").to_numpy()
        rows.append({"workers": workers or 0, "label": "in-process" if workers is None else f"Dask, {workers}",
                     "seconds": sec, "configs_per_s": job.n_configs / sec})
    check(all(np.array_equal(results[None], v) for v in results.values()), "Dask results differ from in-process")
    return {"configurations": job.n_configs, "pixels_per_config": job.tables.n_pixels,
            "chunk": job.chunk, "rows": rows,
            "note": "wall time including cluster start-up; one run each (2 shared cores: the second worker competes "
                    "with the first and with the other users)"}
