"""``s2cl simulate``: one scene through the sensor chain, images to NetCDF, a per-band summary printed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from s2cl.cli.console import progress_bar, rich_console
from s2cl.cli.options import DEVICE_HELP, MAX_MEMORY_HELP, quiet_option


@click.command()
@click.argument("scene", default="default")
@click.option("--output", "-o", type=click.Path(file_okay=False, path_type=Path),
              help="output folder (default: the scene's output.directory, else s2cl-out/<scene name>)")
@click.option("--device", "-d", help=DEVICE_HELP)
@click.option("--max-memory", help=MAX_MEMORY_HELP)
@click.option("--format", "fmt", type=click.Choice(["netcdf", "cog"]), default=None,
              help="netcdf: simulation.nc (default: the scene's output.format); cog: also Cloud-Optimised GeoTIFFs "
                   "of an image, one per GSD group and one per retrieval map, on the input's map grid (geo extra)")
@quiet_option
def simulate(scene: str, output: Path | None, device: str | None, max_memory: str | None, fmt: str | None,
             quiet: bool) -> None:
    """Simulate SCENE (a .toml file or a built-in scene name; default: `default`).

    Writes OUTPUT/simulation.nc (per-band images: noise-free radiance, noisy radiance, DN,
    calibrated radiance; band metadata as attributes) and OUTPUT/simulation.json (per-band summary,
    the scene's analysis, warnings), and prints the summary (radiance, SNR measured against the
    model, clipping, calibration error). Its files never replace a sweep's (results.parquet,
    summary.json). Memory stays bounded whatever surface.copies: images are written chunk by chunk.
    An image cube is written in row blocks that fit --max-memory; with an [analysis], its map, status and
    (where the scene knows the truth, as cube-fields does) error go into simulation.nc, and
    OUTPUT/quicklook.png shows them. With --format cog (an image), also OUTPUT/bands_10m.tif … (Sentinel-2 L2A
    encoding where the chain corrects, else TOA radiance) and the retrieval maps as GeoTIFFs, on the input's map
    grid.
    """
    from s2cl.app.simulate_scene import simulate_scene

    with progress_bar(None, "simulate", not quiet) as advance:
        run = simulate_scene(scene, output, device=device, max_memory=max_memory, progress=advance,
                             on_start=lambda label, total: advance.start(total, label=label), fmt=fmt)
    if not quiet and run.rows:
        _print_summary(run.rows, run.attrs, run.pixels, run.seconds)
        if run.analysis:
            _print_analysis(run.analysis)
    elif not quiet and run.analysis:
        _print_image_analysis(run.analysis)
    click.echo("wrote " + " and ".join(str(p) for p in run.written))


def _print_summary(rows: list[dict[str, Any]], attrs: dict[str, Any], pixels: int, seconds: float) -> None:
    """The per-band summary as a table (only the columns some band has), then units and effects."""
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
    rich_console().print(table)
    click.echo("radiance in W m-2 sr-1 um-1; effects: " + str(attrs.get("effects")))


def _print_analysis(a: dict[str, Any]) -> None:
    """The scene's analysis in one line (its family's :meth:`~s2cl.retrieve.family.Family.summary_line`)."""
    click.echo(a["summary"])


def _print_image_analysis(a: dict[str, Any]) -> None:
    """An image's analysis in two lines: the fit accounting, then the map against the truth where there is one."""
    click.echo(f"{a['kind'].upper()} on {' '.join(a['bands'])} at {a['gsd_m']:g} m: {a['pixels']:,} pixels, "
               f"{a['fitted_pixels']:,} fitted, {a['degenerate_pixels']:,} degenerate, {a['invalid_pixels']:,} "
               f"invalid, {a['bound_pixels']:,} on a bound")
    if "rms" in a:
        click.echo(f"{a['parameter']} map against the truth over {a['scored_pixels']:,} pixels: RMS {a['rms']:.3g}, "
                   f"bias {a['bias']:.3g}, R² {a['r2']:.3f} (calibration on {a['calibration_pixels']:,} pure pixels: "
                   f"RMS {a['calibration_rms']:.3g})")
