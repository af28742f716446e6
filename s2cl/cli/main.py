"""The ``s2cl`` command line. Every command has ``--help``; errors print one line and exit 2."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click

from s2cl.cli.study import study
from s2cl.errors import S2CLError

DEVICE_HELP = ("OpenCL device: PLATFORM:DEVICE indices or part of its name (default: $PYOPENCL_CTX, "
               "else the PoCL CPU); see `s2cl devices`")


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="s2cl")
@click.option("--verbose", "-v", count=True,
              help="show s2cl's DEBUG log on stderr (device and lane choice, kernel build logs)")
def cli(verbose: int) -> None:
    """s2cl: end-to-end optical sensor simulation for spectral band selection.

    \b
    Start here:
      s2cl optimise              sweep the default scene's band designs, rank them, plot
      s2cl simulate              run the built-in default scene, write NetCDF + summary
      s2cl scenes                list built-in scenes
      s2cl libraries             list built-in spectral libraries
      s2cl sensor                show the sensor table and its noise model
      s2cl srf B1 --plot srf.png model vs measured SRF of a band (paper Fig. 2)
      s2cl study NAME            the paper's atmospheric-band studies (cirrus, water-vapour, ...)
      s2cl residuals             band-averaging residual of the atmospheric correction
      s2cl devices               list OpenCL devices

    Put -v before the command (`s2cl -v simulate`) to see the DEBUG log.
    """
    from s2cl.logs import configure

    configure(verbose)


@contextmanager
def progress_bar(total: int, label: str, enabled: bool = True, unit: str = "px",
                 per_item: int = 0) -> Iterator[Callable[[int], None]]:
    """A rich progress bar with rate and ETA; yields ``advance(n)``."""
    if not enabled:
        yield lambda n: None
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = [TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(), MofNCompleteColumn(),
               TextColumn("[cyan]{task.fields[rate]}"),
               TimeElapsedColumn(), TimeRemainingColumn()]
    with Progress(*columns, transient=False, console=_console(stderr=True)) as bar:
        task = bar.add_task(label, total=total, rate="")
        start = time.perf_counter()

        def advance(n: int) -> None:
            bar.advance(task, n)
            done = bar.tasks[0].completed
            elapsed = max(time.perf_counter() - start, 1e-9)
            rate = f"{done / elapsed:,.0f} {unit}/s"
            if per_item:
                rate += f" ({done * per_item / elapsed / 1e6:,.2f} M evaluations/s)"
            bar.update(task, rate=rate)

        yield advance


def _console(stderr: bool = False) -> Any:
    from rich.console import Console

    console = Console(stderr=stderr)
    if not console.is_terminal:
        console = Console(stderr=stderr, width=160)
    return console


SIMULATION_JSON = "simulation.json"
QUIET_HELP = "no progress bar, tables or notes: only results and the files written (warnings still show)"
MAX_MEMORY_HELP = ("memory the run may use, e.g. 8G, 512M or 16GiB (default: $S2CL_MAX_MEMORY, else 4G; never more "
                   "than 90 % of the memory available); a run that needs more is refused before it starts")


def _quiet_option(f: Callable) -> Callable:
    return click.option("--quiet", "-q", is_flag=True, help=QUIET_HELP)(f)


def _output_dir(sc: Any, output: Path | None) -> tuple[Path, str]:
    """The output folder of a scene's run and how it was chosen (for error messages)."""
    if output is not None:
        return output, "--output"
    if sc.spec.output.directory:
        return sc.output_dir, f"output.directory in {sc.source}"
    return sc.output_dir, f"scene.name in {sc.source}"


@cli.command()
@click.argument("scene", default="default")
@click.option("--output", "-o", type=click.Path(file_okay=False, path_type=Path),
              help="output folder (default: the scene's output.directory, else s2cl-out/<scene name>)")
@click.option("--device", "-d", help=DEVICE_HELP)
@click.option("--max-memory", help=MAX_MEMORY_HELP)
@_quiet_option
def simulate(scene: str, output: Path | None, device: str | None, max_memory: str | None, quiet: bool) -> None:
    """Simulate SCENE (a .toml file or a built-in scene name; default: `default`).

    Writes OUTPUT/simulation.nc (per-band images: noise-free radiance, noisy radiance, DN,
    calibrated radiance; band metadata as attributes) and OUTPUT/simulation.json (per-band summary,
    the scene's analysis, warnings), and prints the summary (radiance, SNR measured against the
    model, clipping, calibration error). Its files never replace a sweep's (results.parquet,
    summary.json). Memory stays bounded whatever surface.copies: images are written chunk by chunk.
    """
    from s2cl.forward.stream import require_netcdf_disk, simulate_memory, simulate_to_netcdf
    from s2cl.io.budget import Budget
    from s2cl.io.outdir import check_output_dir, claim
    from s2cl.io.output import write_json
    from s2cl.scene.caveats import report
    from s2cl.scene.scene import Scene
    from s2cl.scene.validate import check_simulate

    sc = Scene.load(scene)
    out, where = _output_dir(sc, output)
    checked = check_simulate(sc)
    check_output_dir(out, where=where)
    budget = Budget.of(max_memory)
    if sc.spec.surface.cube is not None:
        _require_cube_memory(sc, budget)
        _simulate_cube(sc, out, device, quiet)
        return
    simulate_memory(checked, budget)
    require_netcdf_disk(checked, out)
    _runtime(device)  # a device that does not exist is refused before the folder is made
    warnings = report(checked.caveats)
    total = checked.library.size * sc.spec.surface.copies
    t0 = time.perf_counter()
    with claim(out):
        label = f"{sc.name}: {checked.library.size} spectra × {sc.spec.surface.copies}"
        with progress_bar(total, label, not quiet) as adv:
            result = simulate_to_netcdf(checked, out / "simulation.nc", device=device, progress=adv)
        seconds = time.perf_counter() - t0
        write_json(out / SIMULATION_JSON, {"scene": sc.name, "attrs": result.attrs, "pixels": total,
                                           "seconds": seconds, "stage_seconds": result.seconds,
                                           "bands": result.rows, "analysis": result.analysis, "warnings": warnings})
    if not quiet:
        _print_summary(result.rows, result.attrs, total, seconds)
        if result.analysis:
            _print_analysis(result.analysis)
    click.echo(f"wrote {out / 'simulation.nc'} and {out / SIMULATION_JSON}")


#: bytes per pixel of a cube: per input wavelength (float64 as loaded, and a working copy), per grid
#: wavelength (on the grid, TOA radiance, resampling input) and per band (images, noise, DN, calibration)
CUBE_BYTES_PER_INPUT, CUBE_BYTES_PER_GRID, CUBE_BYTES_PER_BAND = 16, 24, 48


def _require_cube_memory(sc: Any, budget: Any) -> None:
    """Refuse a cube that would not fit in memory (it is loaded whole), from its metadata."""
    from s2cl.forward.cube import cube_size
    from s2cl.io.budget import BASELINE_BYTES

    pixels, wavelengths = cube_size(sc.resolve(sc.spec.surface.cube))
    per_pixel = (CUBE_BYTES_PER_INPUT * wavelengths + CUBE_BYTES_PER_GRID * sc.grid.size
                 + CUBE_BYTES_PER_BAND * sc.sensor.size)
    budget.require(BASELINE_BYTES + pixels * per_pixel, what=f"a cube of {pixels:,} pixels × {wavelengths} "
                   "wavelengths", key="surface.cube", source=sc.source, fits="crop the cube or coarsen grid.step_nm")


def _simulate_cube(sc: Any, out: Path, device: str | None, quiet: bool) -> None:
    from s2cl.forward.cube import simulate_cube
    from s2cl.io.outdir import claim
    from s2cl.io.output import write_netcdf

    rt = _runtime(device)
    with claim(out):
        with progress_bar(1, f"{sc.name}: cube", not quiet) as advance:
            ds = simulate_cube(rt, sc, progress=lambda n: advance(1))
        write_netcdf(out / "simulation.nc", ds)
    click.echo(f"wrote {out / 'simulation.nc'}")


def _print_summary(rows: list[dict[str, Any]], attrs: dict[str, Any], pixels: int, seconds: float) -> None:
    from rich.table import Table

    table = Table(title=f"{attrs.get('scene')}: {pixels:,} pixels in {seconds:.2f} s on {attrs.get('device')}")
    columns = [("band", "band", "{}"), ("centre_nm", "centre nm", "{:g}"), ("fwhm_nm", "FWHM nm", "{:g}"),
               ("mean_radiance", "mean L", "{:.3g}"), ("snr_measured_median", "SNR measured", "{:.1f}"),
               ("snr_model_median", "SNR model", "{:.1f}"), ("clipped_low_pct", "< Lmin %", "{:.2f}"),
               ("clipped_high_pct", "> Lmax %", "{:.2f}"), ("rms_error_vs_noise_free", "RMS cal. err", "{:.3g}")]
    present = [c for c in columns if any(c[0] in r for r in rows)]
    for _, title, _ in present:
        table.add_column(title, justify="right")
    for r in rows:
        table.add_row(*[fmt.format(r[k]) if k in r else "" for k, _, fmt in present])
    _console().print(table)
    click.echo("radiance in W m-2 sr-1 um-1; effects: " + str(attrs.get("effects")))


def _print_analysis(a: dict[str, Any]) -> None:
    bands = " ".join(a["bands"])
    if a["kind"] == "sam":
        click.echo(f"SAM on {bands}: mean omission error {a['omission_error_pct']:.1f} %, overall accuracy "
                   f"{a['overall_accuracy_pct']:.1f} %, unclassified {a['unclassified_fraction']:.1%}")
        return
    click.echo(f"{a['kind'].upper()} on {bands} -> {a['parameter']}: RMS {a['rms']:.3g}, R² {a['r2']:.3f}, "
               f"robust {a['robust_rms']:.3g}, without fits on a bound {a['rms_unbounded']:.3g}; "
               f"failed {a['failed_fraction']:.2%}, on a bound {a['bound_fraction']:.2%}")


def _runtime(device: str | None) -> Any:
    from s2cl.cl.runtime import get_runtime

    return get_runtime(device)


@cli.command()
@_quiet_option
def scenes(quiet: bool) -> None:
    """List the built-in scenes (-q: names only)."""
    from s2cl.scene.scene import builtin_scenes, read_toml

    for name, path in builtin_scenes().items():
        meta = {} if quiet else read_toml(path).get("scene", {})
        click.echo(name if quiet else f"{name:24s} {meta.get('description', '')}")


@cli.command()
@_quiet_option
def libraries(quiet: bool) -> None:
    """List the built-in spectral libraries (use as surface.library = "builtin:NAME"; -q: names only)."""
    from s2cl.libraries.registry import available_libraries

    for name, description in available_libraries().items():
        click.echo(f"builtin:{name}" if quiet else f"builtin:{name:18s} {description}")
    if not quiet:
        click.echo("or a file: .csv (wavelength_nm column + one column per spectrum) or an ENVI .sli/.hdr library")


@cli.command()
@_quiet_option
def devices(quiet: bool) -> None:
    """List the OpenCL devices (use with --device or $PYOPENCL_CTX; -q: PLATFORM:DEVICE of the default).

    Works whatever $PYOPENCL_CTX holds: a value that matches no device is reported, and the default
    without it is marked.
    """
    import os

    from s2cl.cl.devices import list_devices
    from s2cl.cl.runtime import Runtime, get_runtime
    from s2cl.errors import DeviceError, token
    from s2cl.logs import LOGGER

    infos = list_devices()
    if not infos:
        get_runtime()  # raises the error with the install hint
    try:
        default = get_runtime()
    except DeviceError:
        env = os.environ.get("PYOPENCL_CTX")
        if not env:
            raise
        LOGGER.warning("$PYOPENCL_CTX=%s matches no device: unset it, or set it to a PLATFORM:DEVICE index "
                       "listed here", token(env))
        default = Runtime(None)
    if quiet:
        click.echo(default.info.spec)
        return
    for info in infos:
        mark = "*" if info == default.info else " "
        click.echo(f"{mark} {info}")
    click.echo(f"* = default; pixels per work-item there: {default.lanes('float32')} (float32), "
               f"{default.lanes('float64')} (float64); set $S2CL_LANES to change")


@cli.command()
@click.option("--library", "-l", "libraries", multiple=True,
              help="builtin:NAME or a .csv/.sli library file (repeatable; default: builtin:flat, "
                   "builtin:lib1, builtin:lib2, builtin:minerals)")
@_quiet_option
def residuals(libraries: tuple[str, ...], quiet: bool) -> None:
    """Band-averaging residual of the atmospheric correction, without noise (paper standard atmosphere).

    Reflectance -> TOA radiance per wavelength -> SRF resampling -> band-effective correction, against
    the SRF-weighted true reflectance: the largest |error| per band in reflectance units.
    """
    from rich.table import Table

    from s2cl.atmos.residuals import DEFAULT_LIBRARIES, band_averaging_residuals

    results = band_averaging_residuals(libraries or DEFAULT_LIBRARIES)
    if quiet:  # plain lines: library, then band=residual (reflectance)
        for r in results:
            click.echo(" ".join([r.library, *(f"{b}={v:.3g}" for b, v in zip(r.bands, r.max_abs(), strict=True))]))
        return
    table = Table(title="band-averaging residual: max |corrected - true| band reflectance (x 1e-4)")
    table.add_column("library")
    for band in results[0].bands:
        table.add_column(band, justify="right")
    for r in results:
        table.add_row(r.library, *(f"{1e4 * v:.2f}" for v in r.max_abs()))
    _console().print(table)


@cli.command()
@click.option("--file", "sensor_file", type=click.Path(dir_okay=False, path_type=Path),
              help="sensor CSV (default: the built-in Sentinel-2 MRD table)")
@_quiet_option
def sensor(sensor_file: Path | None, quiet: bool) -> None:
    """Show the sensor table: bands, radiometry, and the fitted shot-noise model.

    The model is sigma^2 = a + b*L (a, b in radiance units) fitted to the table's SNR points;
    "SNR table" and "SNR model" give both at Lmin / Lref / Lmax ("–": not given).
    """
    from rich.table import Table

    from s2cl.sensor.sensor import Sensor

    s = Sensor.from_csv(sensor_file) if sensor_file else Sensor.sentinel2()
    if quiet:  # plain lines: band, centre nm, FWHM nm
        for b in s.bands:
            click.echo(f"{b.name} {b.centre_nm:g} {b.fwhm_nm:g}")
        return
    table = Table(title=f"{s.name}, {s.bits} bits (radiance in W m-2 sr-1 um-1)")
    for title in ("band", "centre nm", "FWHM nm", "GSD m", "Lmin", "Lref", "Lmax", "SNR table", "SNR model",
                  "a", "b"):
        table.add_column(title, justify="right")
    for b in s.bands:
        a, bb = b.noise_coefficients()
        given = dict(b.snr_points)
        levels = (b.lmin, b.lref, b.lmax)
        table_snr = " / ".join(f"{given[L]:g}" if L in given else "–" for L in levels)
        model_snr = " / ".join(f"{float(b.noise.snr(L)):.1f}" if L > 0 else "–" for L in levels)
        table.add_row(b.name, f"{b.centre_nm:g}", f"{b.fwhm_nm:g}", f"{b.gsd_m:g}", f"{b.lmin:g}", f"{b.lref:g}",
                      f"{b.lmax:g}", table_snr, model_snr, f"{a:.3g}", f"{bb:.3g}")
    _console().print(table)
    click.echo(f"source: {s.source}")


@cli.command()
@click.argument("band")
@click.option("--platform", type=click.Choice(["S2A", "S2B", "none"]), default="S2A", show_default=True,
              help="measured response to compare with (from Py6S; `pip install \"s2cl[sixs]\"`)")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="PNG to write (default: srf_<BAND>.png)")
@_quiet_option
def srf(band: str, platform: str, plot_path: Path | None, quiet: bool) -> None:
    """Plot the model SRF (paper eq. 1) of BAND against the measured Sentinel-2 response (Fig. 2)."""
    from s2cl.io.outdir import check_output_dir
    from s2cl.io.plots import plot_srf
    from s2cl.sensor.sensor import Sensor

    Sensor.sentinel2().band(band)  # an unknown band is refused before anything is written
    path = plot_path or Path(f"srf_{band}.png")
    check_output_dir(path.parent, where="--plot")
    path = plot_srf(band, None if platform == "none" else platform, path)
    click.echo(f"wrote {path}")


@cli.group()
def sweep() -> None:
    """Band-optimisation sweeps: count, run (resumable, local or Dask), report.

    A sweep scene has a [sweep] section (which bands move, and where) and an [analysis]
    section (igrm, gvmi or sam); see scenes/default.toml. `s2cl optimise` runs and reports in one go.
    """


@sweep.command("count")
@click.argument("scene", default="default")
@click.option("--max-memory", help=MAX_MEMORY_HELP)
@_quiet_option
def sweep_count(scene: str, max_memory: str | None, quiet: bool) -> None:
    """Print the variants of each band, the number of configurations of SCENE and the memory the sweep
    would take. Checks the scene exactly as `s2cl optimise` does (counts are computed, not enumerated)."""
    from rich.table import Table

    from s2cl.io.budget import Budget, gb
    from s2cl.io.outdir import check_output_dir
    from s2cl.scene.caveats import report
    from s2cl.scene.scene import Scene
    from s2cl.scene.validate import check_sweep
    from s2cl.sweep.budget import sweep_resources
    from s2cl.sweep.plan import count_table

    sc = Scene.load(scene)
    checked = check_sweep(sc)
    out, where = _output_dir(sc, None)
    check_output_dir(out, where=where)  # as optimise would (nothing is created)
    report(checked.caveats)
    assert checked.space is not None
    if quiet:
        click.echo(f"{checked.space.size}")
    else:
        table = Table(title=f"{sc.name}: band variants")
        for title in ("band", "variants", "centres nm", "widths nm"):
            table.add_column(title, justify="right")
        for r in count_table(sc):
            table.add_row(r["band"], f"{r['variants']:,}", r["centres_nm"], r["widths_nm"])
        _console().print(table)
        click.echo(f"configurations: {checked.space.size:,}")
    plan = sweep_resources(checked, budget=Budget.of(max_memory))
    if not quiet:
        click.echo(f"memory: about {gb(plan.memory_bytes)} in chunks of {plan.chunk:,} configurations")
    if not quiet and checked.analysis is not None:
        from s2cl.sweep.plan import underdetermined_count

        bad = underdetermined_count(checked.space, checked.analysis)
        fate = "kept, flagged" if sc.spec.sweep.underdetermined == "keep" else "left out of the ranking"
        click.echo("underdetermined (the analysis cannot fit them): "
                   + (f"{bad:,} ({fate})" if bad is not None else "not counted (too many variants)"))


def _sweep_options(f: Callable) -> Callable:
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
    """Check everything (scene, output folder, memory, disk, device), then run in the claimed folder."""
    from s2cl.io.budget import Budget
    from s2cl.io.outdir import check_output_dir, claim
    from s2cl.scene.caveats import report
    from s2cl.scene.scene import Scene
    from s2cl.scene.validate import check_sweep
    from s2cl.sweep.budget import require_sweep_disk, sweep_resources
    from s2cl.sweep.plan import plan_sweep

    if workers and scheduler:
        raise click.UsageError("give --workers or --scheduler, not both")
    sc = Scene.load(scene)
    out, where = _output_dir(sc, output)
    checked = check_sweep(sc)
    check_output_dir(out, where=where)
    budget = Budget.of(max_memory)
    plan = sweep_resources(checked, chunk=chunk, budget=budget)
    require_sweep_disk(checked, out)
    _runtime(device)  # the device is checked before anything is created
    warnings = report(checked.caveats)
    t0 = time.perf_counter()
    with claim(out):
        job = plan_sweep(sc, chunk=plan.chunk, checked=checked, budget=budget)
        _sweep_into(sc, job, out, dict(workers=workers, scheduler=scheduler, overwrite=overwrite, device=device),
                    quiet, warnings, t0)


def _sweep_into(sc: Any, job: Any, out: Path, run_options: dict[str, Any], quiet: bool, warnings: list[str],
                t0: float) -> None:
    from s2cl.sweep.engine import run_sweep
    from s2cl.sweep.plan import reference_row
    from s2cl.sweep.report import load, rankable, summarise

    if not quiet:
        click.echo(f"{sc.name}: {job.n_configs:,} configurations × {job.tables.n_pixels:,} pixels "
                   f"({job.tables.n_spectra} spectra × {job.tables.copies} copies), chunks of {job.chunk}")
    with progress_bar(job.n_configs, "sweep", not quiet, unit="configs", per_item=job.tables.n_pixels) as advance:
        def on_start(todo: int, done: int) -> None:
            if done:
                click.echo(f"resuming: {done:,} configurations already done, {todo:,} to go")
                advance(0)

        results = run_sweep(job, out, progress=advance, on_start=on_start, **run_options)
    df, meta = load(results)
    summary = summarise(df, meta, reference_row(sc, job, run_options["device"]))
    summary["seconds"] = time.perf_counter() - t0
    summary["warnings"] = warnings
    plots = _report(rankable(df, meta), summary, out, summary["bands"])
    click.echo(f"wrote {results}" + "".join(f", {p}" for p in plots))


def _report(df: Any, summary: dict[str, Any], folder: Path, bands: list[str]) -> list[Path]:
    """Paper comparison, summary.json and a heatmap per moving band of ``bands`` into ``folder``;
    print the ranking and the paper-style table; return the files written."""
    from s2cl.sweep.report import heatmap, write_summary

    plots = _paper(df, summary, folder)
    written = [write_summary(folder / "summary.json", summary)]
    moving = [b for b in bands if df[f"{b}_centre_nm"].nunique() * df[f"{b}_width_nm"].nunique() > 1]
    written += [heatmap(df, b, folder / f"heatmap_{b}.png") for b in moving] + plots
    _print_sweep(summary)
    _print_paper(summary)
    return written


def _paper(df: Any, summary: dict[str, Any], folder: Path) -> list[Path]:
    """Add the paper's values (scenes of Segl et al. 2012, Tables 3-6) to ``summary``; plot grids beside them."""
    from s2cl.sweep.report import heatmap_vs_paper, paper_comparison

    comparison = paper_comparison(df, summary)
    if comparison is None:
        return []
    summary["paper"] = comparison
    if "band" in comparison:
        return [heatmap_vs_paper(comparison, folder / f"heatmap_{comparison['band']}_vs_paper.png")]
    return []


def _print_paper(summary: dict[str, Any]) -> None:
    """The paper-style table: s2cl beside Segl et al. (2012)."""
    from rich.table import Table

    p = summary.get("paper")
    if p is None:
        return
    if p["table"] == "table3":
        bands = summary["bands"]
        table = Table(title=f"Table 3 ({p['library']}, {' '.join(bands)}): s2cl beside Segl et al. 2012")
        for title in ("", "RMS ESA", "RMS best", *(f"{b} λ/Δλ" for b in bands)):
            table.add_column(title, justify="right")
        for label, e in (("paper", p["paper"]), ("s2cl", p["s2cl"])):
            esa = "–" if e["rms_esa"] is None else f"{e['rms_esa']:.1f}"
            table.add_row(label, esa, f"{e['rms_best']:.1f}",
                          *(f"{e['best'][b][0]:g}/{e['best'][b][1]:g}" for b in bands))
        _console().print(table)
        if "paper_best_in_s2cl" in p:
            q = p["paper_best_in_s2cl"]
            click.echo(f"the paper's best bands in s2cl: rms {q[summary['metric']]:.2f}, rank {q['rank']:,} of "
                       f"{summary['configurations']:,}")
        return
    band, unit = p["band"], p["unit"]
    table = Table(title=f"Table {p['table'][5:]} ({band}, {p['metric']} {unit}): s2cl (paper)")
    table.add_column(f"{band} centre ↓ FWHM →", justify="right")
    for w in p["widths_nm"]:
        table.add_column(f"{w:g}", justify="right")
    for c, ours, theirs in zip(p["centres_nm"], p["s2cl"], p["paper"], strict=True):
        cells = ("–" if o is None else f"{o:.1f} ({t:.1f})" for o, t in zip(ours, theirs, strict=True))
        table.add_row(f"{c:g}", *cells)
    _console().print(table)
    pb, sb = p["paper_best"], p.get("s2cl_best")
    line = f"paper best {pb['bands'][0]:g}/{pb['bands'][1]:g} ({pb['value']:.1f})"
    if sb:
        line += f"; s2cl best {sb['bands'][0]:g}/{sb['bands'][1]:g} ({sb['value']:.2f})"
    if p.get("rank_correlation") is not None:
        line += f"; rank correlation of the {p['cells']} cells {p['rank_correlation']:.2f}"
    click.echo(line)


def _print_sweep(summary: dict[str, Any]) -> None:
    from rich.table import Table

    metric, bands = summary["metric"], summary["bands"]
    table = Table(title=f"{summary['scene']}: best of {summary['configurations']:,} configurations by {metric}")
    table.add_column("")
    for b in bands:
        table.add_column(f"{b} λ/Δλ", justify="right")
    for col in (metric, "robust_rms" if metric == "rms" else "overall_accuracy_pct", "failed_fraction"):
        table.add_column(col, justify="right")
    if metric == "rms":
        table.add_column("bound_fraction", justify="right")
        table.add_column("converged", justify="right")
    rows = [("reference", summary["reference"])] if "reference" in summary else []
    rows += [(f"#{i + 1}", e) for i, e in enumerate(summary["top"][:5])]
    for label, e in rows:
        cells = [f"{e['bands'][b][0]:g}/{e['bands'][b][1]:g}" for b in bands]
        cells += [f"{e[metric]:.3g}", f"{e.get('robust_rms', e.get('overall_accuracy_pct', float('nan'))):.3g}",
                  f"{e['failed_fraction']:.2%}"]
        if metric == "rms":
            cells.append(f"{e['bound_fraction']:.2%}")
            cells.append(f"{e['converged_fraction']:.2%}" if "converged_fraction" in e else "")
        table.add_row(label, *cells)
    _console().print(table)
    u = summary.get("underdetermined", {})
    if u.get("count"):
        which = ", ".join(f"{k} ({v:,})" for k, v in u.get("coincident_centres", {}).items())
        fate = "kept in the ranking, flagged" if u.get("ranking") == "keep" else "left out of the ranking"
        click.echo(f"{u['count']:,} configurations are underdetermined (the analysis cannot fit them"
                   + (f"; bands on one centre: {which}" if which else "") + f"): {fate}")
    if "reference" in summary:
        click.echo(f"reference = the sensor's own bands; {summary['reference']['configurations_better']:,} "
                   "configurations do better")


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
    from s2cl.sweep.report import bands_of, check_band, load, rankable, read_summary, reference_of, summarise

    df, meta = load(results)
    folder = results if results.is_dir() else results.parent
    bands = [check_band(df, band, results)] if band else bands_of(df)
    check_output_dir(folder)
    with claim(folder):
        previous = folder / "summary.json"
        # the reference row (the sensor's own bands), run time and warnings come from the run, not the table
        kept = read_summary(previous) if previous.exists() else {}
        summary = summarise(df, meta, reference_of(kept))
        for key in ("seconds", "warnings"):
            if key in kept:
                summary[key] = kept[key]
        written = _report(rankable(df, meta), summary, folder, bands)
    if not quiet:
        for p in written:
            click.echo(f"wrote {p}")


@cli.command()
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


cli.add_command(study)


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning s2cl errors into one line and exit code 2.

    The safety nets below catch what a user's environment can still cause after every check (a disk
    filled by another process, memory taken by another process, a file removed during the run): one
    line naming the file where there is one, exit code 2, never a traceback.
    """
    try:
        cli.main(args=argv, prog_name="s2cl", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    except click.ClickException as err:
        err.show()
        sys.exit(err.exit_code)
    except S2CLError as err:
        _fail(str(err))
    except OSError as err:
        where = f"{err.filename}: " if err.filename else ""
        _fail(f"{where}{err.strerror or type(err).__name__} (errno {err.errno})")
    except MemoryError:
        _fail("out of memory: another process took the memory this run was estimated to need; lower --max-memory "
              "or free memory and run again")
    except RecursionError:
        _fail("input nested too deeply")


def _fail(message: str) -> None:
    """Print ``error: MESSAGE`` as one line (further lines, e.g. a build log, go to the DEBUG log) and exit 2."""
    from s2cl.logs import LOGGER

    first, _, rest = message.partition("\n")
    if rest:
        LOGGER.debug("%s", rest)
    click.echo(f"error: {first}" + (" (s2cl -v shows the details)" if rest else ""), err=True)
    sys.exit(2)


if __name__ == "__main__":
    main()
