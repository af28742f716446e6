"""Sweep throughput: configuration-pixel evaluations per second (noise → quantise → calibrate →
correct → IGRM fit, and the per-configuration metrics) of the fused OpenCL kernel against the same
sweep written as vectorised float64 numpy (s2cl.reference.sweep, the twin the tests use), in the same
process on the same tables; Dask local workers 1 vs 2 on a smaller sweep; the whole of Table 3 end
to end with peak memory.

The kernel is validated against the numpy evaluator first (:func:`bench.sweep_check.validate_sweep`,
the one check every sweep benchmark runs); the numpy evaluator is then timed on a sample of
configurations and extrapolated to the whole sweep. Timings are medians; the machine
may be shared (see ``machine`` and ``load_average_*`` in the output). Nothing here asserts a timing.
A validation failure raises :class:`bench.common.BenchValidationError` before anything is timed.

Run from the repository root:

    python -m bench.bench_sweep                          # kernel vs numpy, Dask scaling
    python -m bench.bench_sweep --lanes 8,16             # + the kernel alone at other pixels per work-item
    python -m bench.bench_sweep --chunks 444,1776 --scene table3-lib2-b4568a  # + evaluate_chunk by chunk size
    python -m bench.bench_sweep --table3-from /tmp/paper # + Table 3 from `/usr/bin/time -v` logs
    python -m bench.bench_sweep --table3-run             # + run Table 3 now (minutes)

``--table3-from DIR`` reads ``DIR/<scene>.time`` (GNU time -v output of
``s2cl optimise <scene> -o DIR/<scene>``); ``--table3-run`` runs the six sweeps itself in
subprocesses (fresh output folders) and measures wall time and peak resident memory; only then
does the result say, from the load averages before and after, whether the machine was shared.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np

from bench.common import RESULTS, ROOT, load_average, load_note, machine_info, median_and_times, write_json
from bench.sweep_check import spread, validate_sweep
from s2cl.app.plan import plan_sweep
from s2cl.cl.runtime import get_runtime
from s2cl.reference.sweep import evaluate
from s2cl.retrieve.metrics import regression_metrics
from s2cl.scene.scene import Scene
from s2cl.sweep.engine import SweepJob, evaluate_chunk, run_sweep
from s2cl.sweep.kernel import SweepKernel

OUTPUT = RESULTS / "sweep.json"
MAIN_SCENE = "table3-lib1-b4567"  # 43,056 configurations × 12,000 pixels
DASK_SCENE = "table3-lib1-b4568"  # 3,312 configurations
TABLE3 = tuple(f"table3-{lib}-b{bands}" for lib in ("lib1", "lib2") for bands in ("4567", "4568", "4568a"))
NUMPY_SAMPLE = 24
KERNEL_BLOCK = 666


def _kernel_block(job: SweepJob) -> tuple[int, int]:
    """The timed block of configurations: ``KERNEL_BLOCK`` from a third of the way into the sweep."""
    lo = job.tables.n_configs // 3
    return lo, min(lo + KERNEL_BLOCK, job.tables.n_configs)


def kernel_rate(job: SweepJob, kernel: SweepKernel) -> tuple[float, list[float]]:
    """The kernel alone on the timed block (after one untimed warm-up call): median seconds and every time."""
    lo, hi = _kernel_block(job)
    return median_and_times(lambda: kernel(lo, hi), repeat=5, warmup=1)


def time_kernel(job: SweepJob, kernel: SweepKernel) -> dict[str, Any]:
    """The kernel; the per-configuration metrics on its output in numpy on the host (``metrics_s``: the path of
    Dask workers and devices without float64); the whole ``evaluate_chunk`` as a sweep runs it in one process
    (kernel, metrics on the device where it has float64, rows)."""
    t = job.tables
    lo, hi = _kernel_block(job)
    evals = (hi - lo) * t.n_pixels
    t_kernel, times = kernel_rate(job, kernel)
    raw = kernel(lo, hi)
    t_metrics, _ = median_and_times(lambda: regression_metrics(raw.index, raw.status, raw.bounds, t.target),
                               repeat=3, warmup=0)
    t_rows, _ = median_and_times(lambda: evaluate_chunk(job, lo, hi), repeat=3, warmup=1)
    return {"configurations": hi - lo, "evaluations": evals,
            "kernel_s": t_kernel, "kernel_s_min": min(times), "kernel_evaluations_per_s": evals / t_kernel,
            "metrics_s": t_metrics, "evaluate_chunk_s": t_rows,
            "with_metrics_evaluations_per_s": evals / (t_kernel + t_metrics),
            "evaluate_chunk_evaluations_per_s": evals / t_rows,
            "precision": job.precision, "lanes": kernel.T.lanes, "device": kernel.rt.name}


def time_numpy(job: SweepJob) -> dict[str, Any]:
    t, a = job.tables, job.analysis
    sample = spread(t.n_configs, NUMPY_SAMPLE + 2)[1:-1]
    def one_pass() -> None:
        for c in sample:
            evaluate(t, a, c, c + 1)

    raw_s, times = median_and_times(one_pass, repeat=3, warmup=0)
    evals = len(sample) * t.n_pixels
    return {"sample_configurations": sample, "evaluations": evals,
            "evaluate_s": raw_s, "evaluate_s_min": min(times), "evaluations_per_s": evals / raw_s,
            "extrapolated_whole_sweep_evaluate_s": raw_s / len(sample) * t.n_configs,
            "what": "float64, one configuration at a time (the kernel's fit vectorised over pixels)"}


def time_chunks(job: SweepJob, sizes: list[int], rounds: int = 3) -> dict[int, dict[str, float]]:
    """Seconds per configuration of ``evaluate_chunk`` (kernel and metrics, as a sweep runs them) in chunks of
    each of ``sizes`` configurations from a third of the way into the sweep, in interleaved rounds (after one
    untimed call each): the median and the range over the rounds."""
    lo = job.tables.n_configs // 3
    sizes = [n for n in sizes if lo + n <= job.tables.n_configs]
    for n in sizes:
        evaluate_chunk(job, lo, lo + n)
    times: dict[int, list[float]] = {n: [] for n in sizes}
    for _ in range(rounds):
        for n in sizes:
            t0 = time.perf_counter()
            evaluate_chunk(job, lo, lo + n)
            times[n].append((time.perf_counter() - t0) / n)
    return {n: {"ms_per_configuration": 1e3 * float(np.median(v)), "min_ms": 1e3 * min(v), "max_ms": 1e3 * max(v)}
            for n, v in times.items()}


def time_dask(scene: str) -> dict[str, Any]:
    """In-process against local Dask clusters of 1 and 2 workers. Each cluster runs the sweep twice:
    cold (workers build their OpenCL context and kernel) and warm (the same workers again)."""
    from dask.distributed import LocalCluster

    job = plan_sweep(Scene.load(scene))
    out: dict[str, Any] = {"scene": scene, "configurations": job.n_configs, "pixels": job.tables.n_pixels,
                           "chunk": job.chunk, "chunks": len(job.chunks()), "validation": validate_sweep(job)}
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        run_sweep(job, Path(tmp) / "in_process")
        out["in_process_s"] = time.perf_counter() - t0
        one_thread = {"POCL_MAX_PTHREAD_COUNT": "1", "POCL_CPU_MAX_CU_NUM": "1"}
        for label, workers, env in (("workers_1", 1, {}), ("workers_2", 2, {}),
                                    ("workers_1_one_pocl_thread", 1, one_thread),
                                    ("workers_2_one_pocl_thread", 2, one_thread)):
            with mock.patch.dict(os.environ, env), \
                    LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                 dashboard_address=None) as cluster:  # the workers inherit ``env``
                for run in ("cold", "warm"):
                    t0 = time.perf_counter()
                    run_sweep(job, Path(tmp) / f"{label}_{run}", scheduler=cluster.scheduler_address)
                    out[f"dask_{label}_{run}_s"] = time.perf_counter() - t0
    out["speedup_2_vs_1_warm"] = out["dask_workers_1_warm_s"] / out["dask_workers_2_warm_s"]
    out["speedup_2_vs_1_warm_one_pocl_thread"] = (out["dask_workers_1_one_pocl_thread_warm_s"]
                                                  / out["dask_workers_2_one_pocl_thread_warm_s"])
    out["note"] = ("each worker is a process with its own OpenCL context; PoCL already spreads one process over "
                   "every core, so on a 2-core machine two workers share the same cores (the last case limits "
                   "each worker's PoCL to one thread)")
    return out


def parse_gnu_time(text: str) -> dict[str, float]:
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", text)
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    cpu = re.search(r"Percent of CPU this job got: (\d+)%", text)
    if not (wall and rss):
        raise SystemExit("not GNU time -v output")
    seconds = 0.0
    for part in wall.group(1).split(":"):
        seconds = seconds * 60 + float(part)
    return {"wall_s": seconds, "peak_rss_mb": int(rss.group(1)) / 1024, "cpu_percent": float(cpu.group(1)) if cpu
            else float("nan")}


def table3_from(folder: Path) -> dict[str, Any]:
    runs = {}
    for scene in TABLE3:
        path = folder / f"{scene}.time"
        if not path.is_file():
            raise SystemExit(f"{path} missing: run `/usr/bin/time -v -o {path} s2cl optimise {scene} -o ...` first")
        runs[scene] = parse_gnu_time(path.read_text())
    return _table3_summary(runs, f"measured by /usr/bin/time -v around `s2cl optimise SCENE` ({folder})")


def table3_run() -> dict[str, Any]:
    """The six Table 3 sweeps, each ``s2cl optimise SCENE`` in its own process under ``/usr/bin/time -v``
    (wall time, peak resident memory, CPU share of that process; without GNU time, from getrusage)."""
    import shutil

    gnu_time = shutil.which("time") if Path("/usr/bin/time").exists() else None
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in TABLE3:
            checked = validate_sweep(plan_sweep(Scene.load(scene)))  # the kernel those runs build, checked here
            command = [sys.executable, "-m", "s2cl", "optimise", scene, "-q", "-o", str(Path(tmp) / scene)]
            env = {**os.environ, "PYTHONPATH": str(ROOT)}
            if gnu_time:
                log = Path(tmp) / f"{scene}.time"
                subprocess.run(["/usr/bin/time", "-v", "-o", str(log), *command], check=True, capture_output=True,
                               env=env)
                runs[scene] = parse_gnu_time(log.read_text())
            else:
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                subprocess.run(command, check=True, capture_output=True, env=env)
                wall = time.perf_counter() - t0
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
                # ru_maxrss of children is the largest child so far: exact for the first, an upper bound later
                runs[scene] = {"wall_s": wall, "peak_rss_mb": after.ru_maxrss / 1024, "cpu_percent": 100 * cpu / wall}
            runs[scene]["validation_rms_rel_diff_max"] = checked["rms_rel_diff_max"]
            print(f"{scene}: {runs[scene]['wall_s']:.1f} s, peak {runs[scene]['peak_rss_mb']:.0f} MB", flush=True)
    how = "/usr/bin/time -v around `s2cl optimise SCENE`, one process each" if gnu_time else \
        "s2cl optimise in subprocesses (getrusage)"
    return _table3_summary(runs, how)


def _table3_summary(runs: dict[str, dict[str, float]], how: str) -> dict[str, Any]:
    configs = {s: plan_config_count(s) for s in runs}
    return {"how": how, "runs": {s: {**r, "configurations": configs[s]} for s, r in runs.items()},
            "configurations": sum(configs.values()), "wall_s": sum(r["wall_s"] for r in runs.values()),
            "peak_rss_mb": max(r["peak_rss_mb"] for r in runs.values()), "target_s": 300}


def plan_config_count(scene: str) -> int:
    from s2cl.sweep.space import sweep_space

    sc = Scene.load(scene)
    return int(sweep_space(sc.spec.sweep, sc.sensor, sc.grid, sc.run.support).size)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--table3-from", type=Path, help="folder with <scene>.time files (GNU time -v)")
    ap.add_argument("--table3-run", action="store_true", help="run the six Table 3 sweeps now")
    ap.add_argument("--skip-dask", action="store_true")
    ap.add_argument("--lanes", default="", metavar="L[,L]",
                    help="also time the kernel with these pixels per work-item (e.g. 8,16)")
    ap.add_argument("--chunks", default="", metavar="N[,N]",
                    help="also time evaluate_chunk per configuration in chunks of these sizes (e.g. 444,1776)")
    ap.add_argument("--scene", default=MAIN_SCENE, help=f"the timed sweep (default {MAIN_SCENE})")
    ap.add_argument("--output", type=Path, default=OUTPUT,
                    help=f"result file (default {OUTPUT.relative_to(ROOT)})")
    args = ap.parse_args()

    job = plan_sweep(Scene.load(args.scene))
    kernel = SweepKernel(job.tables, job.analysis, get_runtime(), precision=job.precision)
    machine = machine_info(kernel.rt)
    result: dict[str, Any] = {"benchmark": "sweep", "machine": machine,
                              "load_average_start": machine["load_average"], "scene": args.scene,
                              "configurations": job.n_configs, "pixels": job.tables.n_pixels,
                              "evaluation": "noise + quantise + calibrate + correct + IGRM fit (+ metrics)"}
    result["validation"] = validate_sweep(job, kernel)
    print("validated:", result["validation"], flush=True)
    result["opencl"] = time_kernel(job, kernel)
    print("opencl:", result["opencl"], flush=True)
    result["lanes"] = {}
    for lanes in sorted({int(v) for v in args.lanes.split(",") if v}):
        other = SweepKernel(job.tables, job.analysis, get_runtime(), precision=job.precision, lanes=lanes)
        validate_sweep(job, other)
        lo, hi = _kernel_block(job)
        result["lanes"][lanes] = (hi - lo) * job.tables.n_pixels / kernel_rate(job, other)[0]
    if result["lanes"]:
        print("kernel evaluations/s by lanes:", result["lanes"], flush=True)
    if args.chunks:
        result["chunks"] = time_chunks(job, sorted({int(v) for v in args.chunks.split(",") if v}))
        print("evaluate_chunk by chunk size:", result["chunks"], flush=True)
    result["numpy"] = time_numpy(job)
    print("numpy:", result["numpy"], flush=True)
    result["ratio_kernel"] = result["opencl"]["kernel_evaluations_per_s"] / result["numpy"]["evaluations_per_s"]
    # the numpy twin's sweep computes its metrics in numpy; the OpenCL sweep runs evaluate_chunk (metrics on the
    # device where it has float64)
    o, n = result["opencl"], result["numpy"]
    metrics_per_config = o["metrics_s"] / o["configurations"]
    numpy_sweep_s = n["extrapolated_whole_sweep_evaluate_s"] + metrics_per_config * job.n_configs
    opencl_sweep_s = o["evaluate_chunk_s"] / o["configurations"] * job.n_configs
    result["whole_sweep_extrapolated"] = {"numpy_s": numpy_sweep_s, "opencl_s": opencl_sweep_s,
                                          "ratio": numpy_sweep_s / opencl_sweep_s,
                                          "metrics_s_per_configuration": metrics_per_config}
    if not args.skip_dask:
        result["dask"] = time_dask(DASK_SCENE)
        print("dask:", result["dask"], flush=True)
    if args.table3_from:
        result["table3"] = table3_from(args.table3_from)  # measured elsewhere: this run's load says nothing
    elif args.table3_run:
        result["table3"] = table3_run()
        result["table3"]["note"] = load_note(result["load_average_start"], load_average())
    if "table3" in result:
        print("table3:", {k: v for k, v in result["table3"].items() if k != "runs"}, flush=True)
    result["load_average_end"] = load_average()
    print("wrote", write_json(args.output.resolve(), result))


if __name__ == "__main__":
    main()
