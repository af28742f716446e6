"""What a finished sweep prints: the ranking and the paper's table beside s2cl's."""

from __future__ import annotations

from typing import Any

import click

from s2cl.cli.console import rich_console
from s2cl.retrieve.metric import metric_in


def print_sweep(summary: dict[str, Any]) -> None:
    """Print a finished sweep's ranking (the reference row and the best configurations, with notes) and, for the
    paper's scenes, the paper-style table beside s2cl's (the report itself: :func:`s2cl.app.optimise.write_report`)."""
    _print_sweep(summary)
    _print_applications(summary)
    _print_paper(summary)


def _print_applications(summary: dict[str, Any]) -> None:
    """A scene with several applications: one line each (its score column, the sensor's own bands' score, its
    target); the ranking above is the first application's."""
    apps = summary.get("applications")
    if not apps:
        return
    click.echo(f"ranked by the first application ({apps[0]['name']}); each application's score is its column of "
               "results.parquet:")
    for a in apps:
        ref = "–" if a.get("reference") is None else f"{a['reference']:.4g}"
        target = "" if a.get("target") is None else f", target {a['target']:g}"
        click.echo(f"  {a['name']}: {a['kind']} → {a.get('parameter') or a['metric']}, column {a['column']} "
                   f"({a['units'] or 'no unit'}), sensor's own bands {ref}{target}")


def _print_paper(summary: dict[str, Any]) -> None:
    """The paper-style table: s2cl beside Segl et al. (2012)."""
    p = summary.get("paper")
    if p is None:
        return
    if p["table"] == "table3":
        _print_table3(p, summary)
    else:
        _print_grid(p)


def _print_table3(p: dict[str, Any], summary: dict[str, Any]) -> None:
    """Table 3 (RMS of the ESA bands and of the best design, best bands) for the paper and for s2cl."""
    from rich.table import Table

    bands = summary["bands"]
    table = Table(title=f"Table 3 ({p['library']}, {' '.join(bands)}): s2cl beside Segl et al. 2012")
    for title in ("", "RMS ESA", "RMS best", *(f"{b} λ/Δλ" for b in bands)):
        table.add_column(title, justify="right")
    for label, e in (("paper", p["paper"]), ("s2cl", p["s2cl"])):
        esa = "–" if e["rms_esa"] is None else f"{e['rms_esa']:.1f}"
        table.add_row(label, esa, f"{e['rms_best']:.1f}",
                      *(f"{e['best'][b][0]:g}/{e['best'][b][1]:g}" for b in bands))
    rich_console().print(table)
    if "paper_best_in_s2cl" in p:
        q = p["paper_best_in_s2cl"]
        click.echo(f"the paper's best bands in s2cl: rms {q[summary['metric']]:.2f}, rank {q['rank']:,} of "
                   f"{summary['configurations']:,}")


def _print_grid(p: dict[str, Any]) -> None:
    """Tables 4-6: one band's centre × FWHM grid, s2cl's value with the paper's in brackets; the best of each."""
    from rich.table import Table

    band, unit = p["band"], p["unit"]
    table = Table(title=f"Table {p['table'][5:]} ({band}, {p['metric']} {unit}): s2cl (paper)")
    table.add_column(f"{band} centre ↓ FWHM →", justify="right")
    for w in p["widths_nm"]:
        table.add_column(f"{w:g}", justify="right")
    for c, ours, theirs in zip(p["centres_nm"], p["s2cl"], p["paper"], strict=True):
        cells = ("–" if o is None else f"{o:.1f} ({t:.1f})" for o, t in zip(ours, theirs, strict=True))
        table.add_row(f"{c:g}", *cells)
    rich_console().print(table)
    pb, sb = p["paper_best"], p.get("s2cl_best")
    line = f"paper best {pb['bands'][0]:g}/{pb['bands'][1]:g} ({pb['value']:.1f})"
    if sb:
        line += f"; s2cl best {sb['bands'][0]:g}/{sb['bands'][1]:g} ({sb['value']:.2f})"
    if p.get("rank_correlation") is not None:
        line += f"; rank correlation of the {p['cells']} cells {p['rank_correlation']:.2f}"
    click.echo(line)


def _print_sweep(summary: dict[str, Any]) -> None:
    """The ranking: the sensor's own bands (the reference) and the five best configurations; then notes."""
    from rich.table import Table

    metric, bands = summary["metric"], summary["bands"]
    table = Table(title=f"{summary['scene']}: best of {summary['configurations']:,} configurations by {metric}")
    table.add_column("")
    for b in bands:
        table.add_column(f"{b} λ/Δλ", justify="right")
    table.add_column(metric, justify="right")
    for _, heading, _ in metric_in([metric]).ranking_columns:
        table.add_column(heading, justify="right")
    tested = "within_noise" in summary
    if tested:
        table.add_column("within noise of #1", justify="center")
    label = "base" if "addition" in summary else "reference"
    rows = [(label, summary["reference"])] if "reference" in summary else []
    rows += [(f"#{i + 1}", e) for i, e in enumerate(summary["top"][:5])]
    for label, e in rows:
        cells = _ranking_cells(e, bands, metric)
        if tested:
            cells.append({True: "yes", False: "no"}.get(e.get("within_noise"), ""))
        table.add_row(label, *cells)
    rich_console().print(table)
    _print_within_noise(summary.get("within_noise"))
    _print_ranking_notes(summary)


def _print_within_noise(wn: dict[str, Any] | None) -> None:
    """How many of the designs tested are within noise of #1, and how that was decided."""
    if not wn:
        return
    more = "" if wn["complete"] else " (the last one tested too: more may be; raise sweep.within_noise_top)"
    click.echo(f"within noise of #1: {wn['count']:,} of the {wn['candidates']:,} best designs{more} — a paired "
               f"bootstrap of the {wn['metric']} difference over {wn['spectra']:,} {wn['resampled']} "
               f"({wn['replicates']:,} replicates, {wn['level']:.0%} interval)")


def _ranking_cells(e: dict[str, Any], bands: list[str], metric: str) -> list[str]:
    """One ranking row: each band's centre/width, the metric, then what its :class:`~s2cl.retrieve.metric.Metric`
    prints beside it (a robust twin, the failure fractions; empty where the row has no such column)."""
    cells = band_cells(e["bands"], bands)
    cells.append(f"{e[metric]:.3g}")
    cells += [format(e[column], spec) if column in e else "" for column, _, spec in metric_in([metric]).ranking_columns]
    return cells


def band_cells(shapes: dict[str, Any], bands: list[str]) -> list[str]:
    """Each band's ``centre/width`` (nm) of a design's ``bands`` record, ``–`` where it has none."""
    return ["–" if shapes.get(b, [None])[0] is None else f"{shapes[b][0]:g}/{shapes[b][1]:g}" for b in bands]


def _print_ranking_notes(summary: dict[str, Any]) -> None:
    """Underdetermined configurations and how many do better than the sensor's own bands."""
    u = summary.get("underdetermined", {})
    if u.get("count"):
        which = ", ".join(f"{k} ({v:,})" for k, v in u.get("coincident_centres", {}).items())
        fate = "kept in the ranking, flagged" if u.get("ranking") == "keep" else "left out of the ranking"
        click.echo(f"{u['count']:,} configurations are underdetermined (the analysis cannot fit them"
                   + (f"; bands on one centre: {which}" if which else "") + f"): {fate}")
    add = summary.get("addition")
    if add is not None:
        click.echo(f"base = {', '.join(add['base_bands'])} alone: {add['metric']} {add['base_score']:.4g}; "
                   f"{add['candidates_better']:,} of {add['candidates']:,} added {add['band']} bands do better")
        if "best" in add:
            b = add["best"]
            click.echo(f"best added band: {add['band']} {b['centre_nm']:g}/{b['width_nm']:g} nm, {add['metric']} "
                       f"{b[add['metric']]:.4g}, gain {b['gain']:.4g} over the base set")
    elif "reference" in summary:
        click.echo(f"reference = the sensor's own bands; {summary['reference']['configurations_better']:,} "
                   "configurations do better" + (" (of those scored on every pixel)" if "search" in summary else ""))
    search = summary.get("search")
    if search is not None:
        click.echo(f"searched ({search['strategy']}): {search['evaluations']:,} design evaluations, "
                   f"{search['pixel_evaluation_fraction']:.3g} of the {search['exhaustive_configurations']:,} "
                   f"designs' pixel-evaluations, {search['seconds']:.1f} s; ranked: the designs scored on every pixel")
