"""What a multi-application sweep prints of its trade-off: the Pareto front as a table (the sensor's own bands
first), then the designs meeting every requirement and the noise margins (``summary["pareto"]``,
:func:`s2cl.sweep.pareto.pareto_record`)."""

from __future__ import annotations

from typing import Any

import click

from s2cl.cli.console import rich_console
from s2cl.cli.ranking import band_cells

#: front designs printed (summary.json lists more)
SHOWN = 10


def front_headings(summary: dict[str, Any]) -> list[str]:
    """The table's column headings: the row label, each band's ``λ/Δλ``, each application's score column, whether
    the design meets every requirement and its relative sum."""
    p = summary["pareto"]
    return ["", *(f"{b} λ/Δλ" for b in summary["bands"]), *p["columns"], "meets", "relative sum"]


def front_rows(summary: dict[str, Any], shown: int = SHOWN) -> list[list[str]]:
    """The table's rows: the sensor's own bands (where the summary has them) and the front's first ``shown``
    designs, in the record's order. A score within noise of the front's best on its application ends in ``≈``."""
    p, bands = summary["pareto"], summary["bands"]
    names = p["applications"]
    rows = []
    own = summary.get("reference")
    if isinstance(own, dict) and all(p["reference"].get(n) is not None for n in names):
        rows.append(["own bands", *band_cells(own.get("bands", {}), bands),
                     *(f"{p['reference'][n]:.3g}" for n in names), _meets(p, p["reference"]),
                     f"{len(names):.3g}" if "missing" not in p["relative_sum"] else "–"])
    for i, d in enumerate(p["front"]["designs"][:shown]):
        cells = ["–" if d["scores"][n] is None else f"{d['scores'][n]:.3g}" + (" ≈" if d["within_noise"][n] else "")
                 for n in names]
        rel = d.get("relative_sum")
        rows.append([f"#{i + 1}", *band_cells(d["bands"], bands), *cells, "yes" if d["meets"] else "no",
                     "–" if rel is None else f"{rel:.3g}"])
    return rows


def _meets(p: dict[str, Any], scores: dict[str, float]) -> str:
    """Whether ``scores`` meet every target of the record (``yes``/``no``)."""
    targets = p["meeting"]["targets"]
    return "yes" if all(t is None or scores[n] <= t for n, t in targets.items()) else "no"


def print_pareto(summary: dict[str, Any]) -> None:
    """Print the front (:func:`front_rows`) and the notes: the front's size, the designs meeting every requirement,
    the margins and what the relative sum is."""
    from rich.table import Table

    p = summary.get("pareto")
    if not p:
        return
    front = p["front"]
    table = Table(title=f"{summary.get('scene', '')}: Pareto front over {len(p['applications'])} applications, "
                        f"{front['count']:,} of {p['designs']:,} designs (by {front['order']})")
    for heading in front_headings(summary):
        table.add_column(heading, justify="right")
    for row in front_rows(summary):
        table.add_row(*row)
    rich_console().print(table)
    more = front["count"] - min(front["count"], SHOWN)
    if more:
        click.echo(f"{more:,} more front designs in summary.json (pareto.front) and results.parquet (column pareto)")
    margins = ", ".join(f"{n} {m['margin']:.3g}" for n, m in p["margins"].items())
    click.echo(f"front: no design beats another by more than the noise margin ({margins}) without being worse "
               "elsewhere; ≈ = within the margin of the front's best on that application")
    wanted = {n: t for n, t in p["meeting"]["targets"].items() if t is not None}
    if wanted:
        click.echo(f"{p['meeting']['count']:,} designs meet every requirement ("
                   + ", ".join(f"{n} ≤ {t:g}" for n, t in wanted.items()) + ")")
    click.echo(f"relative sum: {p['relative_sum']['meaning']}")
