"""Small CSV reader for s2cl's data tables (comment lines start with ``#``)."""

from __future__ import annotations

import csv
from pathlib import Path

from .errors import InputError


def read_csv_table(path: str | Path) -> tuple[list[str], list[list[str]]]:
    """Header and rows of a CSV file, comments skipped.

    :raises InputError: the file is missing, unreadable, empty, or rows have the wrong length.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError as err:
        raise InputError("file not found", source=p) from err
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read file ({err})", source=p) from err
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InputError("file holds no table", source=p)
    reader = list(csv.reader(lines))
    header = [h.strip() for h in reader[0]]
    rows = reader[1:]
    for i, row in enumerate(rows, start=2):
        if len(row) != len(header):
            raise InputError(f"data row {i - 1} has {len(row)} fields, the header has {len(header)}", source=p)
    return header, rows
