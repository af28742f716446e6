"""The ``s2cl`` command line. Every command has ``--help``; errors print one line and exit 2."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click

from .errors import S2CLError

DEVICE_HELP = ("OpenCL device: PLATFORM:DEVICE indices or part of its name (default: $PYOPENCL_CTX, "
               "else the PoCL CPU); see `s2cl devices`")


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="s2cl")
def cli() -> None:
    """s2cl: end-to-end optical sensor simulation for spectral band selection.

    \b
    Start here:
      s2cl simulate              run the built-in default scene, write NetCDF + summary
      s2cl scenes                list built-in scenes
      s2cl sensor                show the sensor table and its noise model
      s2cl srf B1 --plot srf.png model vs measured SRF of a band (paper Fig. 2)
      s2cl devices               list OpenCL devices
    """


@contextmanager
def progress_bar(total: int, label: str, enabled: bool = True) -> Iterator[Callable[[int], None]]:
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
            bar.update(task, rate=f"{done / elapsed:,.0f} px/s")

        yield advance


def _console(stderr: bool = False) -> Any:
    from rich.console import Console

    console = Console(stderr=stderr)
    if not console.is_terminal:
        console = Console(stderr=stderr, width=160)
    return console


@cli.command()
@click.argument("scene", default="default")
@click.option("--output", "-o", type=click.Path(file_okay=False, path_type=Path),
              help="output folder (default: the scene's output.directory, else s2cl-out/<scene name>)")
@click.option("--device", "-d", help=DEVICE_HELP)
@click.option("--quiet", "-q", is_flag=True, help="no progress bar and no table")
def simulate(scene: str, output: Path | None, device: str | None, quiet: bool) -> None:
    """Simulate SCENE (a .toml file or a built-in scene name; default: `default`).

    Writes OUTPUT/simulation.nc (per-band images: noise-free radiance, noisy radiance, DN,
    calibrated radiance; band metadata as attributes) and OUTPUT/summary.json, and prints a
    per-band summary (radiance, SNR measured against the model, clipping, calibration error).
    """
    from .output import write_json, write_netcdf
    from .scene import Scene
    from .simulate import scene_library
    from .simulate import simulate as run

    sc = Scene.load(scene)
    out = output or sc.output_dir
    if sc.spec.surface.cube is not None:
        from .cube import simulate_cube

        with progress_bar(1, f"{sc.name}: cube", not quiet) as advance:
            ds = simulate_cube(sc, runtime=_runtime(device), progress=lambda n: advance(1))
        write_netcdf(out / "simulation.nc", ds)
        click.echo(f"wrote {out / 'simulation.nc'}")
        return
    library = scene_library(sc)
    total = library.size * sc.spec.surface.copies
    t0 = time.perf_counter()
    with progress_bar(total, f"{sc.name}: {library.size} spectra × {sc.spec.surface.copies}", not quiet) as adv:
        result = run(sc, device=device, progress=adv, library=library)
    seconds = time.perf_counter() - t0
    rows = result.summary()
    write_netcdf(out / "simulation.nc", result.to_dataset(sc.spec.surface.layout))
    write_json(out / "summary.json", {"scene": sc.name, "attrs": result.attrs, "pixels": total,
                                      "seconds": seconds, "stage_seconds": result.seconds, "bands": rows})
    if not quiet:
        _print_summary(rows, result.attrs, total, seconds)
    click.echo(f"wrote {out / 'simulation.nc'} and {out / 'summary.json'}")


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


def _runtime(device: str | None) -> Any:
    from .runtime import get_runtime

    return get_runtime(device)


@cli.command()
def scenes() -> None:
    """List the built-in scenes."""
    import tomllib

    from .scene import builtin_scenes

    for name, path in builtin_scenes().items():
        meta = tomllib.loads(path.read_text(encoding="utf-8")).get("scene", {})
        click.echo(f"{name:24s} {meta.get('description', '')}")


@cli.command()
def devices() -> None:
    """List the OpenCL devices (use with --device or $PYOPENCL_CTX)."""
    from .runtime import get_runtime, list_devices

    infos = list_devices()
    if not infos:
        get_runtime()  # raises the error with the install hint
    default = get_runtime()
    for info in infos:
        mark = "*" if info == default.info else " "
        click.echo(f"{mark} {info}")


@cli.command()
@click.option("--file", "sensor_file", type=click.Path(dir_okay=False, path_type=Path),
              help="sensor CSV (default: the built-in Sentinel-2 MRD table)")
def sensor(sensor_file: Path | None) -> None:
    """Show the sensor table: bands, radiometry, and the fitted shot-noise model.

    The model is sigma^2 = a + b*L (a, b in radiance units) fitted to the table's SNR points;
    "SNR table" and "SNR model" give both at Lmin / Lref / Lmax ("–": not given).
    """
    from rich.table import Table

    from .sensor import Sensor

    s = Sensor.from_csv(sensor_file) if sensor_file else Sensor.sentinel2()
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
def srf(band: str, platform: str, plot_path: Path | None) -> None:
    """Plot the model SRF (paper eq. 1) of BAND against the measured Sentinel-2 response (Fig. 2)."""
    from .plots import plot_srf

    path = plot_srf(band, None if platform == "none" else platform, plot_path or Path(f"srf_{band}.png"))
    click.echo(f"wrote {path}")


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning s2cl errors into one line and exit code 2."""
    try:
        cli.main(args=argv, prog_name="s2cl", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    except click.ClickException as err:
        err.show()
        sys.exit(err.exit_code)
    except S2CLError as err:
        click.echo(f"error: {err}", err=True)
        sys.exit(2)


if __name__ == "__main__":
    main()
