"""CSV reading for s2cl's tables and user files (comment lines start with ``#``).

Small tables (sensor, SRF) are read whole by :func:`read_csv_rows` (at most :data:`MAX_TABLE_BYTES`:
Python's strings take about ten times a file's size). Spectral libraries are streamed by
:func:`open_csv`: the header and the number of rows come first (one pass that keeps nothing), so the
caller can size its array and check it against the memory budget before it parses a value, then the
rows one line at a time (at most :data:`MAX_CSV_BYTES`).
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from s2cl.errors import InputError
from s2cl.io.inputs import input_file

#: largest CSV spectral library read (bytes); it is parsed line by line into one float64 array
MAX_CSV_BYTES = 256 * 2**20
#: largest CSV table read whole (sensor table, SRF table; bytes): parsing holds about ten times its size
MAX_TABLE_BYTES = 16 * 2**20


@dataclass(frozen=True)
class CsvStream:
    """A CSV file's header, delimiter and number of data rows; iterating yields (line number, fields) of
    each data row, reading one line at a time."""

    path: Path
    header: list[str]
    delimiter: str
    rows: int

    def __iter__(self) -> Iterator[tuple[int, list[str]]]:
        seen_header = False
        for line_no, line in _lines(self.path):
            if not seen_header:
                seen_header = True
                continue
            yield line_no, _fields(line, self.delimiter, self.path)


def open_csv(path: str | Path, *, min_rows: int = 1, what: str = "file", rows_are: str = "data rows",
             max_bytes: int = MAX_CSV_BYTES) -> CsvStream:
    """The header and row count of a CSV file, read without keeping its content.

    Comment and blank lines are skipped, a UTF-8 byte-order mark is ignored, and ``;`` is taken as
    the delimiter when the header holds more of them than commas.

    :raises InputError: the file is missing, unreadable, larger than ``max_bytes``, or has fewer than
        ``min_rows`` data rows.
    """
    p = input_file(path, what=what)
    try:
        if p.stat().st_size > max_bytes:
            raise InputError(f"{what} is larger than {max_bytes >> 20} MiB", source=p)
    except FileNotFoundError as err:
        raise InputError(f"{what} not found", source=p) from err
    except OSError as err:
        raise InputError(f"cannot read the file ({err.strerror or type(err).__name__})", source=p) from err
    header_line, rows = None, 0
    for _, line in _lines(p):
        if header_line is None:
            header_line = line
        else:
            rows += 1
    if header_line is None or rows < min_rows:
        raise InputError(f"needs a header row and at least {min_rows} {rows_are}", source=p)
    delimiter = ";" if header_line.count(";") > header_line.count(",") else ","
    header = [h.strip() for h in _fields(header_line, delimiter, p)]
    if not header:
        raise InputError("the header row is empty", source=p)
    return CsvStream(p, header, delimiter, rows)


def _lines(path: Path) -> Iterator[tuple[int, str]]:
    """(line number, text) of each line that is neither blank nor a comment."""
    try:
        with open(path, encoding="utf-8-sig") as f:
            for i, line in enumerate(f, start=1):
                text = line.rstrip("\r\n")
                if text.strip() and not text.lstrip().startswith("#"):
                    yield i, text
    except FileNotFoundError as err:
        raise InputError("file not found", source=path) from err
    except UnicodeDecodeError as err:
        raise InputError("cannot read the file as UTF-8 text", source=path) from err
    except OSError as err:
        raise InputError(f"cannot read the file ({err.strerror or type(err).__name__})", source=path) from err


def _fields(line: str, delimiter: str, path: Path) -> list[str]:
    if line.count('"') % 2:  # a quote opened and not closed (a field may not span lines)
        raise InputError("holds a quoted field that is not closed", source=path)
    try:
        return next(csv.reader([line], delimiter=delimiter), [])
    except csv.Error as err:
        raise InputError(f"not a readable CSV file ({err})", source=path) from None


def read_csv_rows(path: str | Path, *, min_rows: int = 1, what: str = "file",
                  rows_are: str = "data rows") -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and data rows (with their line numbers) of a CSV table of at most :data:`MAX_TABLE_BYTES`
    (see :func:`open_csv` for the format).

    :raises InputError: the file is missing, unreadable, too large, or has fewer than ``min_rows`` data rows.
    """
    stream = open_csv(path, min_rows=min_rows, what=what, rows_are=rows_are, max_bytes=MAX_TABLE_BYTES)
    return stream.header, list(stream)


def read_csv_table(path: str | Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and (line number, fields) of each row of a CSV table whose rows all have the header's length."""
    header, rows = read_csv_rows(path)
    for line_no, row in rows:
        if len(row) != len(header):
            raise InputError(f"line {line_no} has {len(row)} fields, the header has {len(header)}", source=path)
    return header, rows
