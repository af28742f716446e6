"""Commands that show what s2cl has: scenes, libraries, devices, the sensor table, an SRF, correction residuals."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import click

from s2cl.cl.devices import builds_at_all, device_of, list_devices, select, widths_of
from s2cl.cl.probe import describe, target
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.cli.console import rich_console
from s2cl.cli.options import quiet_option
from s2cl.errors import DeviceError, token
from s2cl.io.outdir import check_output_file
from s2cl.libraries.registry import available_libraries
from s2cl.logs import LOGGER
from s2cl.scene.scene import builtin_scenes, read_toml
from s2cl.sensor.sensor import Sensor


@click.command()
@quiet_option
def scenes(quiet: bool) -> None:
    """List the built-in scenes (-q: names only)."""
    for name, path in builtin_scenes().items():
        meta = {} if quiet else read_toml(path).get("scene", {})
        click.echo(name if quiet else f"{name:24s} {meta.get('description', '')}")


@click.command()
@quiet_option
def libraries(quiet: bool) -> None:
    """List the built-in spectral libraries (use as surface.library = "builtin:NAME"; -q: names only)."""
    for name, description in available_libraries().items():
        click.echo(f"builtin:{name}" if quiet else f"builtin:{name:18s} {description}")
    if not quiet:
        click.echo("or a file: .csv (wavelength_nm column + one column per spectrum), an ENVI .sli/.hdr library or an "
                   "s2cl .npz library")
        click.echo("  per-spectrum parameters ([analysis] parameter): param:NAME rows (CSV), "
                   "'s2cl parameter NAME = {...}' header fields (ENVI), param__NAME arrays (.npz)")


@click.command()
@quiet_option
@click.option("--json", "as_json", is_flag=True, help="print the devices and their widths as JSON (for scripts)")
def devices(quiet: bool, as_json: bool) -> None:
    """List the OpenCL devices with the vector width each builds per precision, and why (use with --device or
    $PYOPENCL_CTX; -q: PLATFORM:DEVICE of the default).

    Widths are decided by building (a reported width the compiler cannot build cleanly steps down); works
    whatever $PYOPENCL_CTX holds: a value that matches no device is reported, and the default without it is marked.
    """
    infos = list_devices()
    if not infos:
        get_runtime()  # raises the error with the install hint
    try:
        default = _default_runtime()
    except DeviceError as err:  # no device builds: list them all with their compilers' words, then say so
        default, failure = None, err
    if quiet:
        if default is None:
            raise failure
        click.echo(default.info.spec)
        return
    rows = []
    for info in infos:
        device, chosen = device_of(info), default is not None and info == default.info
        said, widths = builds_at_all(info), widths_of(info)
        rows.append({"spec": info.spec, "name": info.name, "platform": info.platform, "kind": info.kind,
                     "default": chosen, "driver": describe(device)["driver"], "target": target(device),
                     "builds": said is None, "why_not": said, **widths.to_json(),
                     "lanes": {r: default.lanes(r) for r in ("float32", "float64")} if chosen else None})
    if as_json:
        click.echo(json.dumps(rows, indent=1))
    else:
        for row, info in zip(rows, infos, strict=True):
            compiler = f"driver {row['driver']}" + (f", code target {row['target']}" if row["target"] else "")
            click.echo(f"{'*' if row['default'] else ' '} {info} — {compiler}")
            if not row["builds"]:
                click.echo(f"    cannot compile: {row['why_not']}")
                continue
            widths = widths_of(info)
            for real_t in ("float32", "float64"):
                lanes = widths.clean.get(real_t, 0)
                click.echo(f"    {real_t}: {f'{lanes} lanes' if lanes else 'no'} ({widths.why(real_t)})")
    if default is None:
        raise failure
    if not as_json:
        click.echo(f"* = default; pixels per work-item there: {default.lanes('float32')} (float32), "
                   f"{default.lanes('float64')} (float64); set $S2CL_LANES to change")


def _default_runtime() -> Any:
    """The default device's runtime; when $PYOPENCL_CTX matches no device, a warning and the default without it."""
    try:
        return get_runtime()
    except DeviceError:
        env = os.environ.get("PYOPENCL_CTX")
        if not env:
            raise

        try:
            select(env)
        except DeviceError:
            pass
        else:
            raise  # it names a device, which cannot compile: that is the error to show
        LOGGER.warning("$PYOPENCL_CTX=%s matches no device: unset it, or set it to a PLATFORM:DEVICE index "
                       "listed here", token(env))
        return Runtime(None)


@click.command()
@click.option("--library", "-l", "libraries", multiple=True,
              help="builtin:NAME or a .csv/.sli/.npz library file (repeatable; default: builtin:flat, "
                   "builtin:lib1, builtin:lib2, builtin:minerals)")
@quiet_option
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
    rich_console().print(table)


@click.command()
@click.option("--file", "sensor_file", type=click.Path(dir_okay=False, path_type=Path),
              help="sensor CSV (default: the built-in Sentinel-2 MRD table)")
@quiet_option
def sensor(sensor_file: Path | None, quiet: bool) -> None:
    """Show the sensor table: bands, radiometry, and the fitted shot-noise model.

    The model is sigma^2 = a + b*L (a, b in radiance units) fitted to the table's SNR points;
    "SNR table" and "SNR model" give both at Lmin / Lref / Lmax ("–": not given).
    """
    from rich.table import Table

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
    rich_console().print(table)
    click.echo(f"source: {s.source}")


@click.command()
@click.argument("band")
@click.option("--platform", type=click.Choice(["S2A", "S2B", "none"]), default="S2A", show_default=True,
              help="measured response to compare with (from Py6S; `pip install \"s2cl[sixs]\"`)")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="PNG to write (default: srf_<BAND>.png)")
@quiet_option
def srf(band: str, platform: str, plot_path: Path | None, quiet: bool) -> None:
    """Plot the model SRF (paper eq. 1) of BAND against the measured Sentinel-2 response (Fig. 2)."""
    from s2cl.sensor.srf_plot import plot_srf

    band = Sensor.sentinel2().band(band).name  # an unknown band is refused before anything is written
    path = plot_path or Path(f"srf_{band}.png")
    check_output_file(path, where="--plot")
    path = plot_srf(band, None if platform == "none" else platform, path)
    click.echo(f"wrote {path}")
