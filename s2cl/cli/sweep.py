"""``s2cl sweep count|run|report`` and ``s2cl optimise``: band-design sweeps, checked before they start."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from s2cl.cli.console import progress_bar, rich_console
from s2cl.cli.options import DEVICE_HELP, MAX_MEMORY_HELP, check_scheduler, output_dir, quiet_option, runtime
from s2cl.cli.ranking import report_sweep


@click.group()
def sweep() -> None:
    """Band-optimisation sweeps: count, run (resumable, local or Dask), report.

    A sweep scene has a [sweep] section (which bands move, and where) and an [analysis] section (an
    IGRM fit, a normalised-difference index such as GVMI, or SAM); see scenes/default.toml. `s2cl
    optimise` runs and reports in one go.
    """


@sweep.command("count")
@click.argument("scene", default="default")
@click.option("--max-memory", help=MAX_MEMORY_HELP)
@quiet_option
def sweep_count(scene: str, max_memory: str | None, quiet: bool) -> None:
    """Print the variants of each band, the number of configurations of SCENE and the memory the sweep
    would take. Checks the scene exactly as `s2cl optimise` does (counts are computed, not enumerated)."""
    from s2cl.io.budget import Budget, gb
    from s2cl.io.outdir import check_output_dir
    from s2cl.scene.caveats import report
    from s2cl.scene.scene import Scene
    from s2cl.scene.validate import check_sweep
    from s2cl.sweep.budget import sweep_resources
    from s2cl.sweep.engine import resumable_chunk

    budget = Budget.of(max_memory)
    sc = Scene.load(scene)
    checked = check_sweep(sc, budget=budget)
    out, where = output_dir(sc, None)
    check_output_dir(out, where=where)  # as optimise would (nothing is created)
    report(checked.caveats)
    assert checked.space is not None
    if quiet:
        click.echo(f"{checked.space.size}")
    else:
        _print_variants(sc, checked.space.size)
    plan = sweep_resources(checked, budget=budget, resumed=resumable_chunk(out),
                           host_metrics=not runtime(sc.run.device).has_fp64)  # as optimise would
    if not quiet:
        click.echo(f"memory: about {gb(plan.memory_bytes)} in chunks of {plan.chunk:,} configurations")
    if not quiet and checked.analysis is not None:
        _print_underdetermined(sc, checked)


def _print_variants(sc: Any, configurations: int) -> None:
    """The band variants of a sweep scene as a table, and the number of configurations."""
    from rich.table import Table

    from s2cl.sweep.plan import count_table

    table = Table(title=f"{sc.name}: band variants")
    for title in ("band", "variants", "centres nm", "widths nm"):
        table.add_column(title, justify="right")
    for r in count_table(sc):
        table.add_row(r["band"], f"{r['variants']:,}", r["centres_nm"], r["widths_nm"])
    rich_console().print(table)
    click.echo(f"configurations: {configurations:,}")


def _print_underdetermined(sc: Any, checked: Any) -> None:
    """How many configurations the analysis cannot fit, and what the ranking does with them."""
    from s2cl.sweep.plan import underdetermined_count

    bad = underdetermined_count(checked.space, checked.analysis)
    fate = "kept, flagged" if sc.spec.sweep.underdetermined == "keep" else "left out of the ranking"
    click.echo("underdetermined (the analysis cannot fit them): "
               + (f"{bad:,} ({fate})" if bad is not None else "not counted (too many variants)"))


def _sweep_options(f: Callable) -> Callable:
    """The options of `s2cl sweep run` and `s2cl optimise`."""
    options = [
        click.option("--output", "-o", type=click.Path(file_okay=False, path_type=Path),
                     help="output folder (default: the scene's output.directory, else s2cl-out/<scene name>)"),
        click.option("--workers", type=click.IntRange(1, 1024), help="run on a local Dask cluster of N workers"),
        click.option("--scheduler", help="run on a Dask cluster: scheduler address, e.g. tcp://10.0.0.5:8786"),
        click.option("--overwrite", is_flag=True, help="replace a different sweep found in the output folder"),
        click.option("--chunk", type=click.IntRange(1), help="configurations per chunk (default: auto)"),
        click.option("--device", "-d", help=DEVICE_HELP),
        click.option("--max-memory", help=MAX_MEMORY_HELP),
        click.option("--quiet", "-q", is_flag=True, help="no progress bar and no notes (the ranking still prints)"),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def _run_sweep(scene: str, output: Path | None, workers: int | None, scheduler: str | None, overwrite: bool,
               chunk: int | None, device: str | None, max_memory: str | None, quiet: bool) -> None:
    """Check everything (scene, output folder, memory, disk, device, scheduler), build the sweep's tables and
    kernel, and only then run in the claimed folder: a run that fails any of this creates nothing."""
    from s2cl.io.budget import Budget
    from s2cl.io.outdir import check_output_dir, claim
    from s2cl.scene.caveats import report
    from s2cl.scene.scene import Scene
    from s2cl.scene.validate import check_sweep
    from s2cl.sweep.budget import require_sweep_disk, sweep_resources
    from s2cl.sweep.engine import check_folder, kernel_evaluator, reach_scheduler, resumable_chunk
    from s2cl.sweep.plan import plan_sweep

    if workers and scheduler:
        raise click.UsageError("give --workers or --scheduler, not both")
    budget = Budget.of(max_memory)
    if scheduler:
        scheduler = check_scheduler(scheduler)
    sc = Scene.load(scene)
    out, where = output_dir(sc, output)
    checked = check_sweep(sc, budget=budget)
    check_output_dir(out, where=where)
    rt = runtime(device or sc.run.device)  # the device is checked (and compiles) before anything is created
    # the metrics run on this device when it has float64 and no Dask worker (another device) evaluates
    host_metrics = bool(workers or scheduler) or not rt.has_fp64
    plan = sweep_resources(checked, chunk=chunk, budget=budget, resumed=resumable_chunk(out, overwrite),
                           host_metrics=host_metrics)
    require_sweep_disk(checked, out)
    if scheduler:
        reach_scheduler(scheduler)
    t0 = time.perf_counter()
    job = plan_sweep(sc, chunk=plan.chunk, checked=checked, budget=budget, host_metrics=host_metrics,
                     device=device)
    check_folder(job, out, overwrite=overwrite)
    if not (workers or scheduler):
        kernel_evaluator(job, device)  # the sweep kernel builds here, not after the folder is made
    warnings = report(checked.caveats)
    with claim(out):
        _sweep_into(sc, job, out, dict(workers=workers, scheduler=scheduler, overwrite=overwrite, device=device),
                    quiet, warnings, t0)


def _sweep_into(sc: Any, job: Any, out: Path, run_options: dict[str, Any], quiet: bool, warnings: list[str],
                t0: float) -> None:
    """Run the planned sweep into ``out`` (resuming finished chunks), then rank, print and write the report."""
    from s2cl.sweep.engine import run_sweep
    from s2cl.sweep.plan import reference_row
    from s2cl.sweep.report import Digest, open_results, paper_match, summarise

    if not quiet:
        click.echo(f"{sc.name}: {job.n_configs:,} configurations × {job.tables.n_pixels:,} pixels "
                   f"({job.tables.n_spectra} spectra × {job.tables.copies} copies), chunks of {job.chunk}")
    with progress_bar(job.n_configs, "sweep", not quiet, unit="configs", per_item=job.tables.n_pixels) as advance:
        def on_start(todo: int, done: int) -> None:
            if done:
                click.echo(f"resuming: {done:,} configurations already done, {todo:,} to go")
                advance(0)

        results = run_sweep(job, out, progress=advance, on_start=on_start, **run_options)
    path, meta = open_results(results)
    reference = reference_row(sc, job, run_options["device"])
    digest = Digest.of_file(path, meta, reference=reference, match=paper_match(sc.name, list(job.tables.bands)))
    summary = summarise(digest, meta, reference)
    summary["seconds"] = time.perf_counter() - t0
    summary["warnings"] = warnings
    plots = report_sweep(digest, summary, out, summary["bands"])
    click.echo(f"wrote {results}" + "".join(f", {p}" for p in plots))


@sweep.command("run")
@click.argument("scene", default="default")
@_sweep_options
def sweep_run(**kwargs: Any) -> None:
    """Run (or resume) the sweep of SCENE; writes results.parquet, summary.json, heatmaps.

    Finished chunks are kept: a sweep stopped at any moment resumes when the same command runs
    again. On a cluster: start `dask scheduler` and `dask worker ADDRESS` processes (each with
    s2cl and an OpenCL driver installed), then pass --scheduler ADDRESS.
    """
    _run_sweep(**kwargs)


@sweep.command("report")
@click.argument("results", type=click.Path(exists=True, path_type=Path))
@click.option("--band", help="band of the heatmap (default: every band that moves)")
@click.option("--quiet", "-q", is_flag=True, help="no list of the files written (the ranking still prints)")
def sweep_report(results: Path, band: str | None, quiet: bool) -> None:
    """Rank the configurations of a finished sweep (a results folder or .parquet file) and plot."""
    from s2cl.io.outdir import check_output_dir, claim
    from s2cl.sweep.report import (
        Digest,
        bands_of,
        check_band,
        open_results,
        paper_match,
        read_summary,
        reference_of,
        summarise,
    )

    path, meta = open_results(results)
    columns = Digest.of_columns(path)
    folder = results if results.is_dir() else results.parent
    bands = [check_band(columns, band, results)] if band else bands_of(columns)
    check_output_dir(folder, writes=(results.name,))
    previous = folder / "summary.json"
    # the reference row (the sensor's own bands), run time and warnings come from the run, not the table
    kept = read_summary(previous) if previous.exists() else {}
    reference = reference_of(kept)
    digest = Digest.of_file(path, meta, reference=reference, match=paper_match(meta.get("scene", ""),
                                                                                 bands_of(columns)))
    summary = summarise(digest, meta, reference)
    for key in ("seconds", "warnings"):
        if key in kept:
            summary[key] = kept[key]
    with claim(folder):
        written = report_sweep(digest, summary, folder, bands)
    if not quiet:
        for p in written:
            click.echo(f"wrote {p}")


@click.command()
@click.argument("scene", default="default")
@_sweep_options
def optimise(**kwargs: Any) -> None:
    """Find the best band design of SCENE (default: the built-in default scene).

    Runs the scene's sweep (every combination of band variants through the whole sensor chain,
    resumable), ranks the configurations, compares with the sensor's own bands, and writes
    results.parquet, summary.json and heatmaps (centre × width, best marked). The paper's scenes
    (table3-*, table4-b4, table5-b11, table6-b12) also print Segl et al. (2012)'s values beside
    s2cl's; Tables 4-6 also write heatmap_<band>_vs_paper.png (docs/paper.md).
    """
    _run_sweep(**kwargs)
