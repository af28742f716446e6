"""``s2cl sweep count|run|report`` and ``s2cl optimise``: band-design sweeps, checked before they start."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from s2cl.app.optimise import MAX_WORKERS, count_sweep, report_results
from s2cl.app.optimise import optimise as optimise_scene  # the command below is `optimise`
from s2cl.cli.console import progress_bar, rich_console
from s2cl.cli.options import DEVICE_HELP, MAX_MEMORY_HELP, quiet_option
from s2cl.cli.pareto_table import print_pareto
from s2cl.cli.ranking import print_sweep
from s2cl.io.budget import gb


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
    def print_counts(name: str, variants: list[dict[str, Any]], configurations: int) -> None:
        if quiet:
            click.echo(f"{configurations}")
            return
        from rich.table import Table

        table = Table(title=f"{name}: band variants")
        for title in ("band", "variants", "centres nm", "widths nm"):
            table.add_column(title, justify="right")
        for r in variants:
            table.add_row(r["band"], f"{r['variants']:,}", r["centres_nm"], r["widths_nm"])
        rich_console().print(table)
        click.echo(f"configurations: {configurations:,}")

    count = count_sweep(scene, max_memory=max_memory, on_counted=print_counts)
    if quiet:
        return
    click.echo(f"memory: about {gb(count.memory_bytes)} in chunks of {count.chunk:,} configurations")
    fate = "kept, flagged" if count.underdetermined_policy == "keep" else "left out of the ranking"
    click.echo("underdetermined (the analysis cannot fit them): "
               + (f"{count.underdetermined:,} ({fate})" if count.underdetermined is not None
                  else "not counted (too many variants)"))


def _sweep_options(f: Callable) -> Callable:
    """The options of `s2cl sweep run` and `s2cl optimise`."""
    options = [
        click.option("--output", "-o", type=click.Path(file_okay=False, path_type=Path),
                     help="output folder (default: the scene's output.directory, else s2cl-out/<scene name>)"),
        click.option("--workers", type=click.IntRange(1, MAX_WORKERS), help="run on a local Dask cluster of N workers"),
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
    """Parse, call :func:`s2cl.app.optimise.optimise` (which checks everything before it creates anything), print."""
    if workers and scheduler:
        raise click.UsageError("give --workers or --scheduler, not both")
    with progress_bar(None, "sweep", not quiet, unit="configs") as advance:
        def on_start(job: Any, todo: int, done: int) -> None:
            if not quiet:
                click.echo(f"{job.scene_name}: {job.n_configs:,} configurations × {job.tables.n_pixels:,} pixels "
                           f"({job.tables.n_spectra} spectra × {job.tables.copies} copies), chunks of {job.chunk}")
            advance.start(todo + done, done, per_item=job.tables.n_pixels)
            if done:
                click.echo(f"resuming: {done:,} configurations already done, {todo:,} to go")

        result = optimise_scene(scene, output, workers=workers, scheduler=scheduler, overwrite=overwrite,
                                chunk=chunk, device=device, max_memory=max_memory, progress=advance,
                                on_start=on_start)
    print_sweep(result.summary)
    print_pareto(result.summary)
    click.echo("wrote " + ", ".join(str(p) for p in result.written))


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
    summary, written = report_results(results, band)
    print_sweep(summary)
    print_pareto(summary)
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
