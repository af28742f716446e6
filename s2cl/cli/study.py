"""``s2cl study NAME``: the paper's atmospheric-band studies (registered by :mod:`s2cl.cli.main`)."""

from __future__ import annotations

from pathlib import Path

import click

from s2cl.cli.console import rich_console


@click.command("study")
@click.argument("name")
@click.option("--quick", is_flag=True, help="small setting (fewer pixels, spectra and states) from the scene's "
              "[study.quick]")
@click.option("--output", "-o", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="output folder (default: s2cl-out/study-NAME)")
@click.option("--quiet", "-q", is_flag=True, help="no tables or notes: only the files written")
def study(name: str, quick: bool, output: Path | None, quiet: bool) -> None:
    """Run a study: the paper's atmospheric-band studies (Sec. 3) or the spectral-stability requirement per
    band; prints a table, writes NAME.json + NAME.png.

    \b
    NAME: cirrus (B10, Fig. 4), water-vapour (B9 APDA), water-vapour-1020
          (three-channel APDA with a 1020 nm window), aerosol (DDV, B1),
          ozone (B1-B5, Fig. 5), methane (B11), stability (band drift vs
          IGRM, GVMI, SAM errors), cellulose (a 2.1 um band for the NPV
          fraction, Sec. 5), instrument (each instrument effect alone on
          an image: its RMS against the ideal instrument and its time);
          or a scene file with a [study] section.
    """
    from rich.table import Table

    from s2cl.studies import run_study

    result, js, png = run_study(name, quick=quick, output=output)
    if quiet:
        click.echo(f"wrote {js} and {png}")
        return
    console = rich_console()
    table = Table(title=result.title)
    for c in result.columns:
        table.add_column(c, justify="right")
    for row in result.rows:
        table.add_row(*(str(v) for v in row))
    console.print(table)
    if result.key_figures:
        figs = Table(title="s2cl vs Segl et al. 2012")
        for c in ("quantity", "s2cl", "paper", "unit", "note"):
            figs.add_column(c)
        for k in result.key_figures:
            figs.add_row(k.quantity, f"{k.s2cl:g}", "–" if k.paper is None else f"{k.paper:g}", k.unit, k.note)
        console.print(figs)
    for note in result.notes:
        console.print(f"note: {note}")
    console.print(f"wrote {js} and {png}")
