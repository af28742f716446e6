"""The generated blocks of docs/scorecard.md: each example scorecard's table, from the ``scorecard.json`` that
``s2cl scorecard SCENE [--tolerance NM] -o docs/scorecard/FOLDER`` wrote (committed beside its ``scorecard.png``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from bench.common import ROOT

SCORECARDS = ROOT / "docs" / "scorecard"
#: the folders (under docs/scorecard/) of the scorecards docs/scorecard.md shows
FOLDERS = ("default", "table3-lib1-b4567", "table6-b12", "table6-b12-tolerance-25")
DEFAULT_TOLERANCE_NM = 15.0


def scorecard_table(folder: str) -> str:
    """Applications × sensors of ``docs/scorecard/FOLDER``: the score (relative to the best sensor) or n/a with the
    reason; then the command."""
    path = SCORECARDS / folder / "scorecard.json"
    r: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    tolerance = r["tolerance_nm"]
    option = f" --tolerance {tolerance:g}" if tolerance != DEFAULT_TOLERANCE_NM else ""
    return scorecard_markdown(path, f"Written by `s2cl scorecard {r['scene']}{option} -o docs/scorecard/{folder}` "
                                    f"into `{_rel(path)}` (the heatmap beside it: `scorecard.png`).")


def scorecard_markdown(path: Path, written_by: str) -> str:
    """The table of the scorecard in ``path`` (its scorecard.json): applications × sensors, each cell the score and
    (in brackets) the score over the best sensor's, or n/a with the reason; then ``written_by``."""
    from bench.doc_tables import md_table

    r: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    sensors = [s["name"] for s in r["sensors"]]
    cells = {(c["application"], c["sensor"]): c for c in r["cells"]}
    rows = []
    for a in r["applications"]:
        row = [f"{a['name']}: {a['kind']} {a['metric']} ({a['units']})"]
        for s in sensors:
            c = cells[(a["name"], s)]
            row.append(f"n/a ({c['n/a']})" if c["score"] is None
                       else f"{c['score']:.4g} ({c['relative_to_best']:.3f})")
        rows.append(row)
    return (md_table(["application", *sensors], rows)
            + "\n\nEach cell: the score, and in brackets the score over the best sensor's for the application "
            f"(1 = the best); roles within {r['tolerance_nm']:g} nm. {written_by}")


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


BLOCKS = {f"scorecard.{f}": (lambda f=f: scorecard_table(f)) for f in FOLDERS}
