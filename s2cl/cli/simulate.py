"""``s2cl simulate``: one scene through the sensor chain, images to NetCDF, a per-band summary printed."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import click

from s2cl.cli.console import progress_bar, rich_console
from s2cl.cli.options import DEVICE_HELP, MAX_MEMORY_HELP, output_dir, quiet_option, runtime

SIMULATION_JSON = "simulation.json"

#: bytes per pixel of a cube: per input wavelength (float64 as loaded, and a working copy), per grid
#: wavelength (on the grid, TOA radiance, resampling input) and per band (images, noise, DN, calibration)
CUBE_BYTES_PER_INPUT, CUBE_BYTES_PER_GRID, CUBE_BYTES_PER_BAND = 16, 24, 48


@click.command()
@click.argument("scene", default="default")
@click.option("--output", "-o", type=click.Path(file_okay=False, path_type=Path),
              help="output folder (default: the scene's output.directory, else s2cl-out/<scene name>)")
@click.option("--device", "-d", help=DEVICE_HELP)
@click.option("--max-memory", help=MAX_MEMORY_HELP)
@quiet_option
def simulate(scene: str, output: Path | None, device: str | None, max_memory: str | None, quiet: bool) -> None:
    """Simulate SCENE (a .toml file or a built-in scene name; default: `default`).

    Writes OUTPUT/simulation.nc (per-band images: noise-free radiance, noisy radiance, DN,
    calibrated radiance; band metadata as attributes) and OUTPUT/simulation.json (per-band summary,
    the scene's analysis, warnings), and prints the summary (radiance, SNR measured against the
    model, clipping, calibration error). Its files never replace a sweep's (results.parquet,
    summary.json). Memory stays bounded whatever surface.copies: images are written chunk by chunk.
    """
    from s2cl.forward.stream import require_netcdf_disk, simulate_memory
    from s2cl.io.budget import Budget
    from s2cl.io.outdir import check_output_dir
    from s2cl.scene.scene import Scene
    from s2cl.scene.validate import check_simulate

    budget = Budget.of(max_memory)
    sc = Scene.load(scene)
    out, where = output_dir(sc, output)
    checked = check_simulate(sc, budget=budget)
    check_output_dir(out, where=where)
    if sc.spec.surface.cube is not None:
        _require_cube_memory(sc, budget)
        _simulate_cube(sc, out, device, quiet)
        return
    simulate_memory(checked, budget)
    require_netcdf_disk(checked, out)
    runtime(device or sc.run.device)  # a device that does not exist is refused before the folder is made
    _simulate_library(sc, checked, out, device, quiet)


def _simulate_library(sc: Any, checked: Any, out: Path, device: str | None, quiet: bool) -> None:
    """Stream the scene's library (spectra × copies) into OUTPUT/simulation.nc and write the summary JSON."""
    from s2cl.forward.stream import simulate_to_netcdf
    from s2cl.io.outdir import claim
    from s2cl.io.output import write_json
    from s2cl.scene.caveats import report

    warnings = report(checked.caveats)
    total = checked.library.size * sc.run.copies
    t0 = time.perf_counter()
    with claim(out):
        label = f"{sc.name}: {checked.library.size} spectra × {sc.run.copies}"
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
    """Simulate the scene's image cube (loaded whole, and checked, before the folder is made) into
    OUTPUT/simulation.nc."""
    from s2cl.forward.cube import load_scene_cube, simulate_cube
    from s2cl.io.outdir import claim
    from s2cl.io.output import write_netcdf

    rt = runtime(device or sc.run.device)
    cube = load_scene_cube(sc)
    with claim(out):
        with progress_bar(1, f"{sc.name}: cube", not quiet) as advance:
            ds = simulate_cube(rt, sc, cube=cube, progress=lambda n: advance(1))
        write_netcdf(out / "simulation.nc", ds)
    click.echo(f"wrote {out / 'simulation.nc'}")


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
    """The scene's analysis in one line: SAM accuracy, or the retrieval's RMS and failure fractions."""
    bands = " ".join(a["bands"])
    if a["kind"] == "sam":
        click.echo(f"SAM on {bands}: mean omission error {a['omission_error_pct']:.1f} %, overall accuracy "
                   f"{a['overall_accuracy_pct']:.1f} %, unclassified {a['unclassified_fraction']:.1%}")
        return
    click.echo(f"{a['kind'].upper()} on {bands} -> {a['parameter']}: RMS {a['rms']:.3g}, R² {a['r2']:.3f}, "
               f"robust {a['robust_rms']:.3g}, without fits on a bound {a['rms_unbounded']:.3g}; "
               f"failed {a['failed_fraction']:.2%}, on a bound {a['bound_fraction']:.2%}")
