"""The main job: a scene's sweep, checked before it starts, run (resumably, locally or on Dask), ranked against the
sensor's own bands and reported — :func:`optimise` returns what ``s2cl optimise`` prints, as data."""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from s2cl.app.applications import check_applications
from s2cl.app.checks import Checked, check_sweep
from s2cl.app.multi_optimise import (
    PreparedApplications,
    application_heatmaps,
    prepare_applications,
    rank_applications,
    run_applications,
    unread_by_first,
)
from s2cl.app.plan import (
    count_table,
    own_design,
    plan_sweep,
    reference_pixels,
    reference_row,
    underdetermined_count,
)
from s2cl.app.sweep_budget import require_sweep_disk, sweep_resources
from s2cl.cl.runtime import get_runtime
from s2cl.errors import InputError, token
from s2cl.io.budget import Budget
from s2cl.io.outdir import check_output_dir, claim
from s2cl.scene.applications import is_multi_application
from s2cl.scene.caveats import report
from s2cl.scene.scene import Scene
from s2cl.sensor.names import safe_file_part
from s2cl.sweep.addition import addition_of, gain_plots, summarise_addition
from s2cl.sweep.cluster import reach_scheduler
from s2cl.sweep.digest import TOP
from s2cl.sweep.engine import APPLICATIONS, SweepJob, check_folder, kernel_evaluator, resumable_chunk, run_sweep
from s2cl.sweep.front_search import run_front_search
from s2cl.sweep.metrics_kernel import metrics_on_device
from s2cl.sweep.report import (
    Digest,
    bands_of,
    check_band,
    heatmap,
    heatmap_vs_paper,
    open_results,
    paper_comparison,
    paper_match,
    read_summary,
    reference_of,
    summarise,
    write_summary,
)
from s2cl.sweep.search import run_search
from s2cl.sweep.trade_off import FIGURE as PARETO_FIGURE
from s2cl.sweep.within_noise import kept_within_noise, mark_top, within_column, within_noise, within_pairs

if TYPE_CHECKING:
    import pandas as pd


@dataclass(frozen=True)
class OptimiseResult:
    """A finished sweep: ``summary`` is ``summary.json``'s content (ranking, reference row, fit accounting, the
    paper's values where the scene is one of its tables), ``folder`` the output folder, ``written`` the files
    written there (``results.parquet`` first)."""
    summary: dict[str, Any]
    folder: Path
    written: tuple[Path, ...] = field(default=())

    @property
    def reference(self) -> dict[str, Any] | None:
        """The sensor's own band set's row (a band-addition sweep: the base set's), or None."""
        return self.summary.get("reference")

    @property
    def best(self) -> dict[str, Any] | None:
        """The best configuration's row; None when no configuration could be ranked."""
        top = self.summary.get("top") or []
        return top[0] if top else None

    @property
    def ranking(self) -> pd.DataFrame:
        """The best configurations, best first: rank, each band's ``<band>_centre_nm`` and ``<band>_width_nm``,
        then the metrics (as the ranking the CLI prints; every configuration: :meth:`table`)."""
        import pandas as pd

        rows = []
        for rank, entry in enumerate(self.summary["top"], start=1):
            row: dict[str, Any] = {"rank": rank}
            for band, (centre, width) in entry["bands"].items():
                row[f"{band}_centre_nm"], row[f"{band}_width_nm"] = centre, width
            row.update({k: v for k, v in entry.items() if k != "bands"})
            rows.append(row)
        return pd.DataFrame(rows)

    def table(self) -> pd.DataFrame:
        """Every configuration, one row each (``results.parquet``), with ``within_noise`` (of #1: True or False
        for the designs tested, :mod:`s2cl.sweep.within_noise`; missing for the others)."""
        import pandas as pd

        df = pd.read_parquet(self.folder / "results.parquet")
        df["within_noise"] = within_column(self.summary, df["config"].to_numpy())
        return df


def optimise(scene: str | Path | Scene = "default", out: str | Path | None = None, *, workers: int | None = None,
             scheduler: str | None = None, overwrite: bool = False, chunk: int | None = None,
             device: str | None = None, max_memory: str | None = None,
             progress: Callable[[int], None] | None = None,
             on_start: Callable[[Any, int, int], None] | None = None) -> OptimiseResult:
    """Run the sweep of ``scene`` (a built-in name, a ``.toml`` path or a :class:`Scene`) into ``out`` (default: the
    scene's ``output.directory``, else ``s2cl-out/<name>``), rank it and write ``summary.json`` and the heatmaps.

    Everything (scene, output folder, memory, disk, device, scheduler) is checked and the sweep's tables and kernel
    are built before the folder is claimed: a run refused here creates nothing. Finished chunks are kept, so the
    same call resumes an interrupted sweep. ``progress(n)`` is called with configurations done, ``on_start(job,
    todo, done)`` once before the first chunk (``job``: the planned :class:`~s2cl.sweep.engine.SweepJob`).
    """
    scheduler = check_options(workers, scheduler, chunk)
    run = prepare(scene, out, workers=workers, scheduler=scheduler, overwrite=overwrite, chunk=chunk,
                  device=device, max_memory=max_memory)
    with claim(run.folder):
        results, record = run_designs(run, progress=progress, on_start=on_start)
        digest, summary = rank_against_reference(run, results)
        summary["seconds"] = time.perf_counter() - run.t0
        summary["warnings"] = run.warnings
        if record is not None:
            summary["search"] = record
        written = write_report(digest, summary, run.folder, summary["bands"])
    return OptimiseResult(summary, run.folder, (Path(results), *written))


def check_options(workers: int | None, scheduler: str | None, chunk: int | None) -> str | None:
    """The scheduler address (checked) after the options that do not need the scene are checked, each refusal one
    line naming its option."""
    if workers and scheduler:
        raise InputError("give workers or a scheduler, not both", key="--scheduler")
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise InputError(f"must be 1 to {MAX_WORKERS}, got {workers}", key="--workers")
    if chunk is not None and chunk < 1:
        raise InputError(f"must be at least 1 configuration, got {chunk}", key="--chunk")
    return check_scheduler(scheduler) if scheduler else scheduler


@dataclass(frozen=True)
class PreparedSweep:
    """A sweep checked and planned, nothing created yet: the scene, its output folder, the planned job, how it runs
    (``workers``/``scheduler``/``device``, ``searching``: a search instead of the whole space), the caveats' warnings
    and ``t0`` (:func:`time.perf_counter` seconds when planning began: the run time reported counts from there)."""
    scene: Scene
    folder: Path
    job: SweepJob
    searching: bool
    warnings: list[str]
    t0: float
    workers: int | None
    scheduler: str | None
    overwrite: bool
    device: str | None
    #: the scene resolved by the checks (the reference's own tables are built from its parts, nothing again)
    checked: Checked
    #: a scene with several applications (``[[application]]``): each one's sweep and the joint table
    #: (:mod:`s2cl.app.multi_optimise`); ``job`` and ``checked`` are then the first application's
    applications: PreparedApplications | None = None


def prepare(scene: str | Path | Scene, out: str | Path | None, *, workers: int | None, scheduler: str | None,
            overwrite: bool, chunk: int | None, device: str | None, max_memory: str | None) -> PreparedSweep:
    """Check everything (scene, output folder, memory, disk, device, scheduler) and plan the sweep, building its
    tables and kernel: a run refused here creates nothing."""
    budget = Budget.of(max_memory)
    sc = scene if isinstance(scene, Scene) else Scene.load(str(scene))
    folder, where = output_folder(sc, out)
    if is_multi_application(sc):
        return _prepare_applications(sc, folder, where, budget, workers=workers, scheduler=scheduler,
                                     overwrite=overwrite, chunk=chunk, device=device)
    checked = check_sweep(sc, budget=budget)
    check_output_dir(folder, where=where)
    rt = get_runtime(device or sc.run.device)  # the device is checked (and compiles) before anything is created
    host_metrics = not metrics_on_device(rt, distributed=bool(workers or scheduler))
    plan = sweep_resources(checked, chunk=chunk, budget=budget, resumed=resumable_chunk(folder, overwrite),
                           host_metrics=host_metrics, rt=rt)
    searching = sc.spec.sweep is not None and sc.spec.sweep.search != "exhaustive"
    if not searching:  # a search writes the designs it evaluates, not the space
        require_sweep_disk(checked, folder)
    if scheduler:
        reach_scheduler(scheduler)
    t0 = time.perf_counter()
    job = plan_sweep(sc, checked=checked, device=device, resources=plan)
    check_folder(job, folder, overwrite=overwrite)
    if not (workers or scheduler or searching):
        kernel_evaluator(job, device)  # the sweep kernel builds here, not after the folder is made
    return PreparedSweep(sc, folder, job, searching, report(checked.caveats), t0, workers, scheduler, overwrite,
                         device, checked)


def _prepare_applications(sc: Scene, folder: Path, where: str, budget: Budget, *, workers: int | None,
                          scheduler: str | None, overwrite: bool, chunk: int | None, device: str | None
                          ) -> PreparedSweep:
    """:func:`prepare` of a scene with several applications (:func:`s2cl.app.multi_optimise.prepare_applications`):
    the same checks, each application's sweep and the joint table planned, nothing created."""
    distributed = bool(workers or scheduler)
    check_output_dir(folder, where=where)
    if scheduler:
        reach_scheduler(scheduler)
    t0 = time.perf_counter()
    multi = prepare_applications(sc, folder, budget=budget, chunk=chunk, device=device, overwrite=overwrite,
                                 distributed=distributed)
    searching = sc.spec.sweep is not None and sc.spec.sweep.search != "exhaustive"
    return PreparedSweep(sc, folder, multi.first.job, searching, report(multi.checked.caveats), t0, workers, scheduler,
                         overwrite, device, multi.first.checked, multi)


def run_designs(run: PreparedSweep, *, progress: Callable[[int], None] | None = None,
                on_start: Callable[[Any, int, int], None] | None = None) -> tuple[Path, dict[str, Any] | None]:
    """Evaluate the sweep's designs into its (claimed) folder: the whole space, or a search's rungs; the results'
    path and the search's record (None for the whole space)."""
    if run.applications is not None and run.searching:  # the joint designs, whole Pareto layers kept per rung
        return run_front_search(run.applications, run.folder, overwrite=run.overwrite, device=run.device)
    if run.applications is not None:  # each application's sweep, then the joint table
        return run_applications(run.applications, run.folder, workers=run.workers, scheduler=run.scheduler,
                                overwrite=run.overwrite, device=run.device, progress=progress,
                                on_start=on_start), None
    if run.searching:
        return run_search(run.job, run.folder, workers=run.workers, scheduler=run.scheduler,
                          overwrite=run.overwrite, device=run.device)
    started = (lambda todo, done: on_start(run.job, todo, done)) if on_start else None
    results = run_sweep(run.job, run.folder, progress=progress, on_start=started, workers=run.workers,
                        scheduler=run.scheduler, overwrite=run.overwrite, device=run.device)
    return results, None


def rank_against_reference(run: PreparedSweep, results: Path) -> tuple[Digest, dict[str, Any]]:
    """Rank the results against the sensor's own bands (the reference row), test the best designs for being told
    apart within the noise (``within_noise_top``), and the digest and summary; a scene with several applications
    ranks for its first and adds a record per application (:func:`s2cl.app.multi_optimise.rank_applications`)."""
    if run.applications is not None:
        return rank_applications(run.applications, results, run.device)
    sc, job, checked = run.scene, run.job, run.checked
    path, meta = open_results(results)
    own = own_design(checked, job) if job.base_row is None else None  # its tables built once, for row and pixels
    reference = reference_row(checked, job, run.device, own)
    candidates = sc.spec.sweep.within_noise_top
    digest = Digest.of_file(path, meta, reference=reference, match=paper_match(sc.name, list(job.tables.bands)),
                            top_n=max(TOP, candidates))
    summary = summarise(digest, meta, reference)
    if candidates:
        tested = within_noise(job, digest.top.head(candidates), digest.metric, device=run.device,
                              reference=reference_pixels(checked, job, run.device, own), ranked=digest.ranked)
        if tested is not None:
            summary["within_noise"] = tested
        mark_top(summary)
    return digest, summary


@dataclass(frozen=True)
class SweepCount:
    """What ``s2cl sweep count`` prints: the variants per band (:func:`s2cl.app.plan.count_table` rows), the
    configurations, the memory and chunk the sweep would take, and how many configurations the analysis cannot fit
    (None: too many variants to count)."""
    scene: str
    variants: list[dict[str, Any]]
    configurations: int
    memory_bytes: float
    chunk: int
    underdetermined: int | None
    underdetermined_policy: str


def count_sweep(scene: str | Path | Scene = "default", *, max_memory: str | None = None,
                on_counted: Callable[[str, list[dict[str, Any]], int], None] | None = None) -> SweepCount:
    """Check ``scene`` exactly as :func:`optimise` does (nothing is created) and count its sweep without
    enumerating it. ``on_counted(scene name, variants, configurations)`` is called as soon as they are counted,
    before the memory is sized (which may refuse a sweep too large to run: the count is still worth showing)."""
    budget = Budget.of(max_memory)
    sc = scene if isinstance(scene, Scene) else Scene.load(str(scene))
    if is_multi_application(sc):
        return count_applications(sc, budget, on_counted)
    checked = check_sweep(sc, budget=budget)
    folder, where = output_folder(sc, None)
    check_output_dir(folder, where=where)
    report(checked.caveats)
    assert checked.space is not None
    variants = count_table(checked)
    if on_counted:
        on_counted(sc.name, variants, checked.space.size)
    rt = get_runtime(sc.run.device)
    plan = sweep_resources(checked, budget=budget, resumed=resumable_chunk(folder),
                           host_metrics=not metrics_on_device(rt), rt=rt)
    bad = underdetermined_count(checked.space, checked.analysis) if checked.analysis is not None else 0
    return SweepCount(sc.name, variants, checked.space.size, plan.memory_bytes, plan.chunk, bad,
                      sc.spec.sweep.underdetermined)


def count_applications(sc: Scene, budget: Budget,
                       on_counted: Callable[[str, list[dict[str, Any]], int], None] | None = None) -> SweepCount:
    """:func:`count_sweep` of a scene with several applications: the joint space's variants and designs; the memory
    and chunk of the largest application's sweep (they run one after the other); the designs the first application
    (the ranking's) cannot fit, counted in its own sub-space and times the designs of the bands it does not read."""
    multi = check_applications(sc, budget=budget)
    folder, where = output_folder(sc, None)
    check_output_dir(folder, where=where)
    report(multi.caveats)
    space = multi.space
    if on_counted:
        on_counted(sc.name, count_table(space), space.size)
    rt = get_runtime(sc.run.device)
    plans = [sweep_resources(p.checked, budget=budget, resumed=resumable_chunk(folder / APPLICATIONS / p.name),
                             host_metrics=not metrics_on_device(rt), rt=rt) for p in multi.parts]
    biggest = max(plans, key=lambda plan: plan.memory_bytes)
    first = multi.parts[0]
    assert first.checked.analysis is not None
    bad = underdetermined_count(first.space, first.checked.analysis)
    return SweepCount(sc.name, count_table(space), space.size, biggest.memory_bytes, biggest.chunk,
                      None if bad is None else bad * (space.size // first.space.size), sc.spec.sweep.underdetermined)


#: a Dask scheduler address: [PROTOCOL://]HOST:PORT, HOST a name, an IPv4 address or an [IPv6] address
_SCHEDULER = re.compile(r"(?:(?P<protocol>[a-z][a-z0-9+.-]*)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+)"
                        r":(?P<port>[0-9]{1,5})")
SCHEDULER_PROTOCOLS = ("tcp", "tls", "ws", "wss", "ucx")


def check_scheduler(address: str) -> str:
    """``address`` when it has the form of a Dask scheduler address (``tcp://HOST:PORT`` or ``HOST:PORT``),
    else a one-line :class:`~s2cl.errors.InputError` naming ``--scheduler``; checked before anything is
    created (whether it answers: :func:`s2cl.sweep.cluster.reach_scheduler`)."""
    m = _SCHEDULER.fullmatch(address.strip())
    if m is None or not 1 <= int(m["port"]) <= 65535 or (m["protocol"] or "tcp") not in SCHEDULER_PROTOCOLS:
        raise InputError(f"{token(address, 60)} is not a scheduler address: give [PROTOCOL://]HOST:PORT with PORT in "
                         f"1-65535 and PROTOCOL one of {', '.join(SCHEDULER_PROTOCOLS)} (e.g. tcp://10.0.0.5:8786)",
                         key="--scheduler")
    return address.strip()


MAX_WORKERS = 1024


def output_folder(sc: Scene, out: str | Path | None) -> tuple[Path, str]:
    """The output folder of a scene's run and how it was chosen (for error messages)."""
    if out is not None:
        return Path(out), "--output"
    if sc.spec.output.directory:
        return sc.output_dir, f"output.directory in {sc.source}"
    return sc.output_dir, f"scene.name in {sc.source}"


def write_report(digest: Any, summary: dict[str, Any], folder: Path, bands: list[str]) -> list[Path]:
    """The paper's values (into ``summary``), ``summary.json`` and a heatmap per moving band of ``bands`` into
    ``folder`` from the results' :class:`~s2cl.sweep.digest.Digest`; the files written."""
    plots = []
    comparison = paper_comparison(digest, summary)
    if comparison is not None:
        summary["paper"] = comparison
        if "band" in comparison:
            band = safe_file_part(comparison["band"])
            plots.append(heatmap_vs_paper(comparison, folder / f"heatmap_{band}_vs_paper.png"))
    record = addition_of(digest.meta)
    if record is not None and digest.ranked:
        summary["addition"] = summarise_addition(digest, summary, record)
        plots += gain_plots(digest, record, folder)
    if "pareto" in summary and (folder / PARETO_FIGURE).exists():  # drawn with the trade-off (s2cl.sweep.trade_off)
        plots.append(folder / PARETO_FIGURE)
    written = [write_summary(folder / "summary.json", summary)]
    moving = [b for b in bands if digest.variants(b) > 1]
    others = unread_by_first(summary, moving)  # several applications: drawn for an application that reads them
    return written + [heatmap(digest, b, folder / f"heatmap_{safe_file_part(b)}.png", hatch=within_pairs(summary, b))
                      for b in moving if b not in others] + plots + \
        application_heatmaps(digest, summary, folder, others)


def report_results(results: str | Path, band: str | None = None) -> tuple[dict[str, Any], list[Path]]:
    """Rank a finished sweep again (a results folder or ``.parquet`` file) and rewrite its report; the summary and
    the files written. The reference row, run time and warnings come from the run's ``summary.json``."""
    results = Path(results)
    path, meta = open_results(results)
    columns = Digest.of_columns(path)
    folder = results if results.is_dir() else results.parent
    bands = [check_band(columns, band, results)] if band else bands_of(columns)
    check_output_dir(folder, writes=(results.name,))
    previous = folder / "summary.json"
    kept = read_summary(previous) if previous.exists() else {}
    reference = reference_of(kept)
    digest = Digest.of_file(path, meta, reference=reference, match=paper_match(meta.get("scene", ""),
                                                                                 bands_of(columns)))
    summary = summarise(digest, meta, reference)
    for key in ("seconds", "warnings", "search", "applications", "pareto"):
        if key in kept:
            summary[key] = kept[key]
    kept_within_noise(summary, kept)
    with claim(folder):
        written = write_report(digest, summary, folder, bands)
    return summary, written
