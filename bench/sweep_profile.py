"""Where the fused sweep kernel's time goes, against the standalone IGRM fit on the same pixels.

The sweep kernel (kernels/sweep.cl.mako) evaluates one band configuration × T.lanes pixels per work-item:
gather, noise, quantise, calibrate, correct, sort the bands by centre, fit, store; the per-configuration
metrics (kernels/metrics.cl.mako) follow on the device. This profile measures, on one sweep (default
``table3-lib1-b4567``), with the kernel's profile builds (:data:`s2cl.sweep.kernel.PROFILES`, compiled out of
every sweep):

- iterations per fit (the fit's own count) over a random sample of the sweep's configurations, over the block
  ``bench.bench_sweep`` times, at the scene's own band set, and on the population ``bench.bench_igrm`` fits
  (noisy Lib1-like PROSAIL canopies on the nominal B4 B5 B6 B7); lane use: T.lanes pixels of a work-item
  iterate in lock-step until the slowest stops, so each fit pays its group's maximum ("paid" iterations) and
  the lane use is mean iterations ÷ mean paid iterations;
- rates on the timed block, in interleaved rounds: the fused kernel; without its fit (``no_fit``: the stages
  outside the fit and the stores); with the fit stopped after one iteration (``max_iter`` 1: the fixed work of
  a lane group, initial guess and verdict, and one iteration); the fit alone from the block's stored
  reflectances (``fit_only``); the standalone IGRM kernel (kernels/igrm.cl.mako) on the same reflectances, one
  launch per configuration (and the cost of as many one-group launches); the metrics kernel on the block's
  outputs, alone with its named work-groups and with the driver's (one group of all the configurations, which
  one PoCL thread runs alone), and as the sweep calls it; ``evaluate_chunk`` (kernel, metrics, rows), also with the
  driver's work-groups; the standalone kernel on ``bench.bench_igrm``'s population;
- from these, a cost model per lane group (outside the fit + fixed work + paid iterations × the cost of one),
  whose prediction of the population's time (from its paid iterations) is set beside the measured one.

The fit-only and standalone paths are checked to give the fused kernel's results on the same pixels before
anything is timed, and the kernel against the float64 numpy evaluator (:func:`bench.sweep_check.validate_sweep`).
The machine may be shared: its load averages before and after are recorded; nothing asserts a timing.

    python -m bench.sweep_profile                                 # about a minute on 2 quiet cores
    python -m bench.sweep_profile --configs 222 --sample 100      # quicker

Writes bench/results/sweep-profile-<machine>-<date>.json (``--output`` to choose).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np

from bench.bench_sweep import KERNEL_BLOCK, MAIN_SCENE
from bench.common import (
    BenchValidationError,
    check,
    interleaved_medians,
    load_average,
    load_note,
    machine_info,
    write_json,
    write_result,
)
from bench.sweep_check import validate_sweep
from s2cl.app import plan
from s2cl.app.checks import Checked, check_sweep
from s2cl.app.plan import plan_sweep
from s2cl.cl.kernel_args import bind
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.reference.igrm_cases import BANDS_4, band_centres, prosail_population
from s2cl.retrieve.family import AnalysisSettings
from s2cl.retrieve.igrm import IgrmFitter
from s2cl.scene.scene import Scene
from s2cl.sensor.variants import BandRange, SweepSpace
from s2cl.sweep.engine import SweepJob, evaluate_chunk
from s2cl.sweep.kernel import SweepKernel
from s2cl.sweep.metrics_kernel import ARGS as METRICS_ARGS
from s2cl.sweep.metrics_kernel import MetricsKernel
from s2cl.sweep.raw import variant_indices
from s2cl.sweep.tables import SweepTables

POPULATION = 1_000_000  # pixels of bench.bench_igrm's population (its default)
SAMPLE = 400
REPEAT = 7


def iteration_stats(it: np.ndarray, lanes: int, status: np.ndarray | None = None) -> dict[str, Any]:
    """Iterations per fit ``it`` (rows: configurations, columns: pixels, ``lanes`` consecutive pixels of a row per
    work-item): their distribution, the paid iterations (each group runs until its slowest lane stops: the mean
    of the groups' maxima), the lane use (mean ÷ paid) and the number of lane groups."""
    it = np.atleast_2d(np.asarray(it, dtype=np.float64))
    groups = it[:, : it.shape[1] // lanes * lanes].reshape(it.shape[0], -1, lanes)
    peak = groups.max(axis=2)
    out: dict[str, Any] = {
        "fits": int(it.size), "mean": float(it.mean()),
        "quantiles": dict(zip(("p50", "p90", "p99", "max"), np.quantile(it, [0.5, 0.9, 0.99, 1.0]).tolist(),
                              strict=True)),
        "histogram": np.bincount(it.astype(np.int64).ravel()).tolist(),
        "paid_iterations": float(peak.mean()), "lane_use": float(groups.mean() / peak.mean()),
        "lane_groups": int(peak.size),
        "per_configuration_mean": dict(zip(("min", "p50", "max"),
                                           np.quantile(it.mean(axis=1), [0, 0.5, 1.0]).tolist(), strict=True))}
    if status is not None:
        codes, counts = np.unique(status, return_counts=True)
        out["status_fractions"] = {int(c): float(n) / status.size for c, n in zip(codes, counts, strict=True)}
    return out


def pixel_orders(it: np.ndarray, lanes: int) -> dict[str, Any]:
    """Lane use of the sampled configurations' odd rows with the pixels grouped in their own order, ordered by
    their mean iterations over the even rows (other designs: what a pilot could know), and by each row's own
    iterations (known only after the fit: the bound of any order)."""
    it = np.asarray(it, dtype=np.float64)
    pilot, test = it[0::2], it[1::2]
    by_pilot = np.argsort(pilot.mean(axis=0), kind="stable")
    return {"rows": int(test.shape[0]), "natural": iteration_stats(test, lanes)["lane_use"],
            "sorted_by_other_designs": iteration_stats(test[:, by_pilot], lanes)["lane_use"],
            "sorted_by_own_iterations": iteration_stats(np.sort(test, axis=1), lanes)["lane_use"]}


def refill_cost(it: np.ndarray, lanes: int, free: int, fixed: float) -> float:
    """Cost, in lane-group iterations, of fitting pixels needing ``it`` iterations each (in order) with lanes
    refilled: a vector of ``lanes`` fits iterates; once ``free`` of its lanes have stopped, those take the next
    pixels, and each such refill costs ``fixed`` (a lane group's verdict and initial guess, which the vector
    computes for every lane), as do the first start and the last verdict together. ``free = lanes`` is today's
    lock-step groups."""
    queue = [int(v) for v in np.asarray(it)[::-1]]
    left = np.array([queue.pop() for _ in range(min(lanes, len(queue)))], dtype=np.int64)
    busy = np.ones(left.size, dtype=bool)
    cost = fixed
    while True:
        if (busy & (left > 0)).any():
            left -= 1
            cost += 1
        stopped = busy & (left <= 0)
        if not (busy & (left > 0)).any() and not queue:
            return cost
        if queue and (stopped.sum() >= free or not (busy & (left > 0)).any()):
            cost += fixed
            for lane in np.flatnonzero(stopped):
                if queue:
                    left[lane] = queue.pop()
                else:
                    busy[lane] = False


def refill_model(it: np.ndarray, lanes: int, fixed: float, rows: int = 16) -> dict[str, Any]:
    """Lanes refilled once 4, 8 or 12 of them are free (:func:`refill_cost`) against today's lock-step groups, on
    ``rows`` of the sampled configurations, with ``fixed`` the measured fixed work of a lane group in iterations:
    the time each would take relative to today's."""
    it = np.asarray(it, dtype=np.int64)[:: max(1, it.shape[0] // rows)][:rows]
    today = sum(float(r[: r.size // lanes * lanes].reshape(-1, lanes).max(axis=1).sum() + fixed * (r.size // lanes))
                for r in it)
    return {"rows": int(it.shape[0]), "fixed_iterations": fixed,
            **{f"free_{k}": sum(refill_cost(r, lanes, k, fixed) for r in it) / today for k in (4, 8, 12) if k < lanes}}


def sweep_iterations(kernel: SweepKernel, configs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Iterations and statuses of ``configs`` (the ``iterations`` build; one launch per configuration)."""
    rt, m, pitch = kernel.rt, kernel.tables.n_pixels, kernel.pitch
    its, sts = [], []
    for c in configs:
        out = kernel._launch(int(c), int(c) + 1)
        its.append(rt.fetch(out["condition"], (1, pitch), np.uint8)[0, :m])
        sts.append(rt.fetch(out["status"], (1, pitch), np.uint8)[0, :m])
    return np.array(its), np.array(sts)


def block_iterations(kernel: SweepKernel, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
    """Iterations and statuses of configurations ``lo … hi-1`` in one launch (the ``iterations`` build)."""
    out, (n, m, pitch) = kernel._launch(lo, hi), (hi - lo, kernel.tables.n_pixels, kernel.pitch)
    return (kernel.rt.fetch(out["condition"], (n, pitch), np.uint8)[:, :m],
            kernel.rt.fetch(out["status"], (n, pitch), np.uint8)[:, :m])


def reference_tables(checked: Checked, job: SweepJob) -> SweepTables:
    """The tables of the one design the sensor itself has (each band at its own centre and width)."""
    scene = checked.scene
    bands = [scene.sensor.band(b) for b in job.tables.bands]
    fixed = SweepSpace(tuple(BandRange.fixed(b.name, b.centre_nm, b.fwhm_nm) for b in bands))
    return plan.sweep_tables(checked, fixed.validate(scene.source), job.analysis)


def standalone_launches(rt: Runtime, fitter: IgrmFitter, rho: np.ndarray, centres: np.ndarray, m: int
                        ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """One standalone launch per configuration on its stored reflectances ``rho`` (configurations, slots, pitch),
    bands sorted by centre as the sweep's analysis sorts them; and as many launches of one lane group."""
    same, empty = [], []
    for c in range(rho.shape[0]):
        order = np.argsort(centres[c], kind="stable")
        y = np.ascontiguousarray(rho[c][order][:, :m])
        same.append(fitter.buffers(y, centres[c][order]))
        empty.append(fitter.buffers(np.ascontiguousarray(y[:, : fitter.types.lanes]), centres[c][order]))
    return same, empty


def run_all(rt: Runtime, fitter: IgrmFitter, launches: list[dict[str, Any]]) -> Callable[[], None]:
    def run() -> None:
        for v in launches:
            fitter.enqueue(v)
        rt.finish()

    return run


def metrics_launch(rt: Runtime, metrics: MetricsKernel, out: dict[str, Any], n: int, named: bool
                   ) -> Callable[[], None]:
    """The metrics kernel alone on the sweep kernel's outputs ``out`` (``n`` configurations), launched with the
    work-groups :meth:`MetricsKernel.__call__` names (``named``) or with the driver's choice."""
    values = {"out": rt.alloc(n * len(metrics.names) * 8), "target": metrics._target_d, "n_configs": n,
              "scratch": rt.alloc(n * metrics.n_pixels * 8),
              **{k: out[k] for k in ("index", "status", "bounds", "condition")}}
    args = bind(METRICS_ARGS, values, metrics.T)
    local = rt.local_size(metrics.kernel, n) if named else None

    def run() -> None:
        metrics.kernel(rt.queue, (n,), local, *args)
        rt.finish()

    return run


def driver_groups(fn: Callable[[], Any]) -> Callable[[], Any]:
    """``fn`` with every 1-D launch of named work-groups left to the driver instead (:meth:`Runtime.local_size`
    returning None): the sweep chunk as it ran before its metrics named their work-groups."""
    def run() -> Any:
        with mock.patch.object(Runtime, "local_size", lambda self, kernel, size: None):
            return fn()

    return run


def profile(scene_name: str, n_block: int, n_sample: int, repeat: int, seed: int = 0) -> dict[str, Any]:
    """The profile of the module's docstring for the IGRM sweep ``scene_name``: ``n_block`` configurations timed
    from a third of the way in (as ``bench.bench_sweep``), ``n_sample`` drawn with ``seed`` for the iterations,
    ``repeat`` interleaved rounds (medians, seconds)."""
    scene = Scene.load(scene_name)
    checked = check_sweep(scene)
    job = plan_sweep(scene, checked=checked)
    t, rt = job.tables, get_runtime()

    def build(*switches: str, tables: SweepTables = t, analysis: AnalysisSettings = job.analysis) -> SweepKernel:
        return SweepKernel(tables, analysis, rt, precision=job.precision, profile=frozenset(switches))

    full = build()
    lanes, m = full.T.lanes, t.n_pixels
    lo = t.n_configs // 3
    hi = min(lo + n_block, t.n_configs)
    n = hi - lo
    result: dict[str, Any] = {"scene": scene_name, "configurations": t.n_configs, "pixels": m, "lanes": lanes,
                              "precision": job.precision, "device": rt.name,
                              "block": {"first": lo, "configurations": n, "evaluations": n * m},
                              "validation": validate_sweep(job, full)}
    print("validated:", result["validation"], flush=True)

    # -- iterations and lane use ------------------------------------------------------------------------------
    counting = build("iterations")
    sample = np.sort(np.random.default_rng(seed).choice(t.n_configs, min(n_sample, t.n_configs), replace=False))
    its = {"sweep_sample": (*sweep_iterations(counting, sample), f"{sample.size} configurations drawn at random "
                            f"(seed {seed}) from the whole sweep"),
           "timed_block": (*block_iterations(counting, lo, hi), f"configurations {lo}–{hi - 1}, the block "
                           "python -m bench.bench_sweep times"),
           "reference_design": (*block_iterations(build("iterations", tables=reference_tables(checked, job)), 0, 1),
                                "the scene's own band set (" + ", ".join(
                                    f"{b} {scene.sensor.band(b).centre_nm:g}/{scene.sensor.band(b).fwhm_nm:g} nm"
                                    for b in t.bands) + ")")}
    fitter = IgrmFitter(rt, t.n_slots)
    wl = band_centres(BANDS_4)
    y64, _ = prosail_population(POPULATION, BANDS_4, noise=0.003, seed=1)
    pop = np.ascontiguousarray(y64, dtype=np.float32)
    r_pop = fitter.fit(pop, wl)
    its["standalone_population"] = (r_pop.iterations[None, :], r_pop.status[None, :],
                                    f"python -m bench.bench_igrm's population: {POPULATION:,} noisy Lib1-like PROSAIL "
                                    f"canopies on {' '.join(BANDS_4)} at their nominal centres")
    result["iterations"] = {k: {"what": what, **iteration_stats(it, lanes, st)} for k, (it, st, what) in its.items()}
    result["iterations"]["sweep_sample"]["pixel_order"] = pixel_orders(its["sweep_sample"][0], lanes)
    for k, v in result["iterations"].items():
        print(f"{k}: mean {v['mean']:.2f} iterations, {v['paid_iterations']:.2f} paid, lane use "
              f"{v['lane_use']:.3f}", flush=True)

    # -- the same pixels three ways: fused, fit only, standalone ------------------------------------------------
    dump = build("reflectance")
    out = dump._launch(lo, hi)
    rho_d = out["rho_out"]
    rho = rt.fetch(rho_d, (n, t.n_slots, full.pitch), full.T.dtype)
    fused = full._fetch(full._launch(lo, hi), lo, hi)
    fit_only = build("fit_only")
    alone = fit_only._fetch(fit_only._launch(lo, hi, {"rho_in": rho_d}), lo, hi)
    idx = variant_indices(t, lo, hi)
    centres = np.stack([t.centre[k][idx[:, k]] for k in range(t.n_slots)], axis=1)
    same, empty = standalone_launches(rt, fitter, rho, centres, m)
    stand = [fitter.fit(np.ascontiguousarray(rho[c][np.argsort(centres[c], kind="stable")][:, :m]),
                        np.sort(centres[c], kind="stable")) for c in range(0, n, max(1, n // 16))]
    rows = list(range(0, n, max(1, n // 16)))
    agree = {"fit_only_same_index_fraction": float(np.mean(alone.index == fused.index)),
             "fit_only_same_status_fraction": float(np.mean(alone.status == fused.status)),
             "standalone_same_status_fraction": float(np.mean([np.mean(s.status == fused.status[r])
                                                               for s, r in zip(stand, rows, strict=True)])),
             "standalone_lp_abs_diff_max_nm": float(max(np.nanmax(np.abs(s.lp - fused.index[r]))
                                                        for s, r in zip(stand, rows, strict=True))),
             "standalone_rows_checked": len(rows)}
    print("same pixels:", agree, flush=True)
    check(agree["fit_only_same_status_fraction"] >= 0.999 and agree["standalone_same_status_fraction"] >= 0.999,
          f"the fit-only or standalone path does not reproduce the fused kernel on the same pixels: {agree}")
    result["same_pixels"] = agree

    # -- rates, interleaved --------------------------------------------------------------------------------------
    no_fit = build("no_fit")
    one_iteration = build(analysis=replace(job.analysis, igrm=tuple(sorted({**dict(job.analysis.igrm),
                                                                            "max_iter": 1}.items()))))

    def launch(k: SweepKernel, extra: dict[str, Any] | None = None) -> Callable[[], None]:
        def run() -> None:
            k._launch(lo, hi, extra)
            rt.finish()

        return run

    metrics = MetricsKernel(rt, full.T, job.analysis, t.target, full.pitch)
    fetch_rows = lambda rows: full._fetch(out_full, lo, hi, rows)  # noqa: E731
    out_full = full._launch(lo, hi)
    rt.finish()
    pop_v = fitter.buffers(pop, wl)
    contenders: dict[str, Callable[[], Any]] = {
        "fused": launch(full), "fused_no_fit": launch(no_fit), "fused_one_iteration": launch(one_iteration),
        "fused_fit_only": launch(fit_only, {"rho_in": rho_d}),
        "standalone_same_pixels": run_all(rt, fitter, same), "standalone_empty_launches": run_all(rt, fitter, empty),
        "metrics": lambda: metrics(out_full, n, fetch_rows),
        "metrics_kernel": metrics_launch(rt, metrics, out_full, n, named=True),
        "metrics_kernel_driver_groups": metrics_launch(rt, metrics, out_full, n, named=False),
        "evaluate_chunk": lambda: evaluate_chunk(job, lo, hi),
        "evaluate_chunk_driver_groups": driver_groups(lambda: evaluate_chunk(job, lo, hi)),
        "standalone_population": run_all(rt, fitter, [pop_v])}
    seconds = dict(zip(contenders, interleaved_medians(list(contenders.values()), repeat=repeat, warmup=1),
                       strict=True))
    result["seconds"] = seconds
    e = n * m
    rate = {"fused": e / seconds["fused"], "fused_fit_only": e / seconds["fused_fit_only"],
            "standalone_same_pixels": e / seconds["standalone_same_pixels"],
            "standalone_same_pixels_less_launches": e / max(seconds["standalone_same_pixels"]
                                                            - seconds["standalone_empty_launches"], 1e-9),
            "evaluate_chunk": e / seconds["evaluate_chunk"],
            "evaluate_chunk_driver_groups": e / seconds["evaluate_chunk_driver_groups"],
            "standalone_population": POPULATION / seconds["standalone_population"]}
    result["rates_per_s"] = rate
    it_block, it_pop = result["iterations"]["timed_block"], result["iterations"]["standalone_population"]
    # per lane group: outside the fit + fixed work + paid iterations × one iteration (the one-iteration build pays
    # the fixed work and one iteration)
    groups, paid = it_block["lane_groups"], it_block["paid_iterations"]
    per_iteration = (seconds["fused"] - seconds["fused_one_iteration"]) / (groups * (paid - 1))
    fixed = (seconds["fused_one_iteration"] - seconds["fused_no_fit"]) / groups - per_iteration
    predicted_pop = it_pop["lane_groups"] * (fixed + it_pop["paid_iterations"] * per_iteration)
    result["cost_model"] = {
        "per_lane_group_iteration_ns": 1e9 * per_iteration, "fixed_per_lane_group_ns": 1e9 * fixed,
        "outside_fit_per_lane_group_ns": 1e9 * seconds["fused_no_fit"] / groups,
        "fixed_in_iterations": fixed / per_iteration,
        "standalone_population_predicted_s": predicted_pop,
        "standalone_population_measured_s": seconds["standalone_population"],
        "what": "seconds of the timed block = groups × (outside the fit + fixed + paid iterations × per iteration), "
                "fitted from the fused, no-fit and one-iteration builds; the population predicted from its own "
                "lane groups and paid iterations at the block's costs"}
    result["findings"] = {
        "fused_over_standalone_same_pixels": rate["standalone_same_pixels_less_launches"] / rate["fused"],
        "fused_over_fit_only": rate["fused_fit_only"] / rate["fused"],
        "outside_fit_share": seconds["fused_no_fit"] / seconds["fused"],
        "fixed_work_share": groups * fixed / seconds["fused"],
        "iterations_share": groups * paid * per_iteration / seconds["fused"],
        "metrics_share_of_chunk": seconds["metrics"] / seconds["evaluate_chunk"],
        "host_share_of_chunk": 1 - (seconds["fused"] + seconds["metrics"]) / seconds["evaluate_chunk"],
        "metrics_kernel_driver_over_named_groups": seconds["metrics_kernel_driver_groups"] / seconds["metrics_kernel"],
        "evaluate_chunk_driver_over_named_groups": seconds["evaluate_chunk_driver_groups"] / seconds["evaluate_chunk"],
        "population_over_fused": rate["standalone_population"] / rate["fused"],
        "iterations_ratio": it_block["mean"] / it_pop["mean"],
        "lane_use_ratio": it_pop["lane_use"] / it_block["lane_use"],
        "paid_iterations_ratio": paid / it_pop["paid_iterations"],
        "sweep_sample_lane_use": result["iterations"]["sweep_sample"]["lane_use"]}
    # lanes that never wait (every lane refilled the moment its fit stops, at no cost): the paid iterations shrink
    # to the mean, the rest stays
    use = result["iterations"]["sweep_sample"]["lane_use"]
    share = result["findings"]["iterations_share"]
    result["findings"]["perfect_lane_use_speedup_bound"] = 1 / (1 - share + share * use)
    result["refill_model"] = refill_model(its["sweep_sample"][0], lanes, result["cost_model"]["fixed_in_iterations"])
    print("refill model:", result["refill_model"], flush=True)
    print("seconds:", seconds, flush=True)
    print("findings:", result["findings"], flush=True)
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default=MAIN_SCENE, help=f"an IGRM sweep (default {MAIN_SCENE})")
    ap.add_argument("--configs", type=int, default=KERNEL_BLOCK, help="configurations in the timed block")
    ap.add_argument("--sample", type=int, default=SAMPLE, help="configurations drawn for the iteration profile")
    ap.add_argument("--repeat", type=int, default=REPEAT, help="interleaved timing rounds")
    ap.add_argument("--output", type=Path,
                    help="result file (default bench/results/sweep-profile-<machine>-<date>.json)")
    args = ap.parse_args()
    machine = machine_info(get_runtime())
    start = machine["load_average"]
    try:
        result = {"benchmark": "sweep-profile", "machine": machine, "load_average_start": start,
                  **profile(args.scene, args.configs, args.sample, args.repeat)}
    except BenchValidationError as err:
        raise SystemExit(f"not timed: {err}") from None
    result["load_average_end"] = load_average()
    result["load_note"] = load_note(start, result["load_average_end"], machine.get("cores"))
    path = write_json(args.output.resolve(), result) if args.output else write_result("sweep-profile", result)
    print("wrote", path)


if __name__ == "__main__":
    main()
