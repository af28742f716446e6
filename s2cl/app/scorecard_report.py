"""A scorecard's outputs: ``scorecard.csv`` (one row per application × sensor), ``scorecard.json`` (the cells, the
sensors' cards, the role tolerance) and ``scorecard.png`` (applications × sensors, each cell the score over the
best sensor's for that application; n/a cells grey, with the reason)."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.app.scorecard import Cell, Scorecard
from s2cl.io.output import write_json, write_text
from s2cl.io.plots import pyplot, save_png

FILES = ("scorecard.csv", "scorecard.json", "scorecard.png")
CSV_COLUMNS = ("application", "sensor", "metric", "units", "score", "relative_to_best", "n/a", "bands")


def bands_text(cell: Cell) -> str:
    """The bands that played the cell's roles, e.g. ``B4=B8 665/30 B5=B9 705/15`` (role=band centre/width, nm)."""
    return " ".join(f"{role}={b['band']} {b['centre_nm']:g}/{b['width_nm']:g}" for role, b in cell.bands.items())


def csv_rows(card: Scorecard) -> list[dict[str, Any]]:
    """One row per application × sensor, in :data:`CSV_COLUMNS`."""
    info = {a.name: a for a in card.applications}
    return [{"application": c.application, "sensor": c.sensor, "metric": info[c.application].metric,
             "units": info[c.application].units, "score": c.score, "relative_to_best": card.relative(c),
             "n/a": c.na or "", "bands": bands_text(c)} for c in card.cells]


def record(card: Scorecard) -> dict[str, Any]:
    """``scorecard.json``'s content."""
    return {"scene": card.scene, "tolerance_nm": card.tolerance_nm,
            "relative_to_best": "score / the lowest score of the application over the sensors (1 = the best)",
            "applications": [vars(a) for a in card.applications],
            "sensors": [s.card() for s in card.sensors],
            "cells": [{"application": c.application, "sensor": c.sensor, "score": c.score,
                       "relative_to_best": card.relative(c), "n/a": c.na, "bands": c.bands, "row": c.row}
                      for c in card.cells]}


def relative_grid(card: Scorecard) -> np.ndarray:
    """(applications × sensors) of each cell's score over the best sensor's for its application; NaN where n/a."""
    out = np.full((len(card.applications), len(card.sensors)), np.nan)
    for i, a in enumerate(card.applications):
        for j, s in enumerate(card.sensors):
            value = card.relative(card.cell(a.name, s.name))
            out[i, j] = np.nan if value is None else value
    return out


def heatmap(card: Scorecard) -> Any:
    """The heatmap figure: applications (rows) × sensors (columns), each cell its score relative to the best sensor
    for the application and the score itself; n/a cells grey with the reason."""
    values = relative_grid(card)
    n_app, n_sensor = values.shape
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(2.0 + 1.6 * n_sensor, 1.6 + 0.9 * n_app), dpi=120)
    cmap = plt.get_cmap("viridis_r").with_extremes(bad="0.85")
    finite = values[np.isfinite(values)]
    top = max(float(finite.max()), 1.0 + 1e-6) if finite.size else 2.0
    im = ax.imshow(np.ma.masked_invalid(values), cmap=cmap, vmin=1.0, vmax=top, aspect="auto",
                   interpolation="nearest")
    ax.set_xticks(range(n_sensor), [s.name for s in card.sensors], fontsize=8, rotation=30, ha="right")
    ax.set_yticks(range(n_app), [f"{a.name}\n({a.metric})" for a in card.applications], fontsize=8)
    for i, a in enumerate(card.applications):
        for j, s in enumerate(card.sensors):
            cell = card.cell(a.name, s.name)
            if cell.score is None:
                text = "n/a\n" + _wrap(cell.na or "", 22)
                colour = "black"
            else:
                rel = values[i, j]
                text = f"{rel:.3f}\n({cell.score:.3g})" if np.isfinite(rel) else f"({cell.score:.3g})"
                colour = "white" if np.isfinite(rel) and rel > 1.0 + 0.5 * (top - 1.0) else "black"
            ax.text(j, i, text, ha="center", va="center", fontsize=6.5, color=colour)
    bar = fig.colorbar(im, ax=ax)
    bar.set_label("score / the best sensor's", fontsize=8)
    ax.set_title(f"{card.scene}: each application's score relative to its best sensor (grey: n/a)", fontsize=8)
    fig.tight_layout()
    return fig


def _wrap(text: str, width: int) -> str:
    """``text`` broken into lines of at most ``width`` characters at spaces (at most three lines)."""
    lines: list[str] = []
    for word in text.split():
        if lines and len(lines[-1]) + 1 + len(word) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    return "\n".join(lines[:3]) + (" …" if len(lines) > 3 else "")


def write_scorecard(card: Scorecard, folder: Path) -> list[Path]:
    """Write :data:`FILES` into ``folder`` (each atomically); the paths written."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in csv_rows(card):
        writer.writerow({k: ("" if v is None else repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    return [write_text(folder / FILES[0], buffer.getvalue()), write_json(folder / FILES[1], record(card)),
            save_png(heatmap(card), folder / FILES[2])]
