"""``s2cl scorecard``: a scene's applications scored on several sensors' own bands, as a table and a heatmap."""

from __future__ import annotations

from pathlib import Path

import click
from rich.table import Table

from s2cl.app.scorecard import Cell, Scorecard
from s2cl.app.scorecard import scorecard as run_scorecard
from s2cl.app.scorecard_report import FILES, write_scorecard
from s2cl.cli.console import rich_console
from s2cl.cli.options import DEVICE_HELP, quiet_option
from s2cl.io.outdir import check_output_dir, claim
from s2cl.scene.scene import Scene
from s2cl.sensor.catalogue import known_sensors
from s2cl.sensor.roles import DEFAULT_TOLERANCE_NM

_SENSOR_HELP = ("a sensor to score, repeatable: " + ", ".join(known_sensors()) + "; a sensor table FILE.csv (the "
                "columns of [sensor] file); or results:FOLDER, the #1 design of a finished sweep on the scene's "
                "sensor, or results:FOLDER:balanced, the best design of its Pareto front by relative sum "
                "(default: sentinel2 S2A S2B OLI OLI-2 landsat-next, and where the scene's output folder holds its "
                "finished sweep, that sweep's #1 design and, with a Pareto front, its balanced design)")


@click.command()
@click.argument("scene", default="default")
@click.option("--sensor", "-s", "sensors", multiple=True, metavar="NAME", help=_SENSOR_HELP)
@click.option("--output", "-o", type=click.Path(file_okay=False, path_type=Path),
              help="output folder (default: the scene's output.directory, else s2cl-out/<scene name>)")
@click.option("--tolerance", type=float, default=DEFAULT_TOLERANCE_NM, show_default=True,
              help="how far (nm) a sensor band's centre may lie from the centre of the scene's band it stands for")
@click.option("--device", "-d", help=DEVICE_HELP)
@quiet_option
def scorecard(scene: str, sensors: tuple[str, ...], output: Path | None, tolerance: float, device: str | None,
              quiet: bool) -> None:
    """Score SCENE's applications on several sensors' own bands (no sweep).

    Each application (the scene's [analysis], or each [[application]]) is scored on each sensor's bands through
    the path that scores a sweep's reference row: the scene's own sensor gives exactly the reference row of
    `s2cl optimise`. Each band the application uses (e.g. B5 at 705 nm) is played by the sensor's band whose
    centre is nearest, within --tolerance nm; a sensor without one is "n/a (no band near 705 nm)". Sensors
    without SNR tables in s2cl (OLI, OLI-2, Landsat Next) take a stand-in radiometry: the nearest Sentinel-2
    band's, SNR scaled by the square root of the width ratio (docs/scorecard.md).

    Prints the table and writes OUTPUT/scorecard.csv, scorecard.json and scorecard.png (applications × sensors,
    each cell the score relative to the best sensor for that application).
    """
    sc = Scene.load(scene)
    folder = output or sc.output_dir
    check_output_dir(folder, where="--output" if output else "", writes=FILES)

    def progress(cell: Cell) -> None:
        if not quiet:
            what = f"{cell.score:.4g}" if cell.score is not None else f"n/a ({cell.na})"
            click.echo(f"scorecard: {cell.application} on {cell.sensor}: {what}", err=True)

    card = run_scorecard(sc, list(sensors) or None, tolerance_nm=tolerance, device=device, progress=progress)
    with claim(folder):
        written = write_scorecard(card, folder)
    if not quiet:
        _print_table(card)
    click.echo("wrote " + " and ".join(str(p) for p in written))


def _print_table(card: Scorecard) -> None:
    """Applications (rows) × sensors (columns): score and relative to the best, or n/a with the reason; then each
    sensor's source, SRFs and radiometry."""
    table = Table(title=f"{card.scene}: scorecard (score, and over the best sensor's; roles within "
                        f"{card.tolerance_nm:g} nm)")
    table.add_column("application")
    for s in card.sensors:
        table.add_column(s.name, justify="right", max_width=28)
    for a in card.applications:
        cells = []
        for s in card.sensors:
            c = card.cell(a.name, s.name)
            rel = card.relative(c)
            cells.append(f"n/a ({c.na})" if c.score is None
                         else f"{c.score:.4g}" + (f" ({rel:.3f})" if rel is not None else ""))
        table.add_row(f"{a.name}: {a.kind} {a.metric} ({a.units})", *cells)
    console = rich_console()
    console.print(table)
    for s in card.sensors:
        console.print(f"{s.name}: {s.title}; bands: {s.source}; SRFs: {s.srf}; radiometry: {s.radiometry}"
                      + (f"; unavailable: {s.unavailable}" if s.unavailable else ""), highlight=False,
                      markup=False)
