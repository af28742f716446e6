"""CSV reading for s2cl's tables and user files (comment lines start with ``#``)."""

from __future__ import annotations

import csv
from pathlib import Path

from s2cl.errors import InputError
from s2cl.io.inputs import input_file

#: largest CSV file read (bytes): parsing takes about ten times its size in memory
MAX_CSV_BYTES = 256 * 2**20


def read_csv_rows(path: str | Path, *, min_rows: int = 1, what: str = "file",
                  rows_are: str = "data rows") -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and data rows (with their line numbers) of a CSV file.

    Comment and blank lines are skipped, a UTF-8 byte-order mark is ignored, and ``;`` is taken as
    the delimiter when the header holds more of them than commas.

    :raises InputError: the file is missing, unreadable, or has fewer than ``min_rows`` data rows.
    """
    p = input_file(path, what=what)
    try:
        if p.stat().st_size > MAX_CSV_BYTES:
            raise InputError(f"{what} is larger than {MAX_CSV_BYTES >> 20} MiB", source=p)
        text = p.read_text(encoding="utf-8-sig")
    except FileNotFoundError as err:
        raise InputError(f"{what} not found", source=p) from err
    except UnicodeDecodeError as err:
        raise InputError("cannot read the file as UTF-8 text", source=p) from err
    except OSError as err:
        raise InputError(f"cannot read the file ({err.strerror or type(err).__name__})", source=p) from err
    lines = [(i + 1, ln) for i, ln in enumerate(text.splitlines()) if ln.strip() and not ln.lstrip().startswith("#")]
    if len(lines) < 1 + min_rows:
        raise InputError(f"needs a header row and at least {min_rows} {rows_are}", source=p)
    delimiter = ";" if lines[0][1].count(";") > lines[0][1].count(",") else ","
    try:
        rows = list(csv.reader([ln for _, ln in lines], delimiter=delimiter))
    except csv.Error as err:
        raise InputError(f"not a readable CSV file ({err})", source=p) from None
    if len(rows) != len(lines):  # a quote opened and not closed joins lines into one field
        raise InputError("holds a quoted field that is not closed", source=p)
    if not rows[0]:
        raise InputError("the header row is empty", source=p)
    header = [h.strip() for h in rows[0]]
    return header, [(n, row) for (n, _), row in zip(lines[1:], rows[1:], strict=True)]


def read_csv_table(path: str | Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and (line number, fields) of each row of a CSV table whose rows all have the header's length."""
    header, rows = read_csv_rows(path)
    for line_no, row in rows:
        if len(row) != len(header):
            raise InputError(f"line {line_no} has {len(row)} fields, the header has {len(header)}", source=path)
    return header, rows
