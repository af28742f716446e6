"""ENVI headers, checked before any data is read: the one place that says which header key lies.

An ENVI file pair is a text header (``.hdr``) and a raw data file. SPy trusts the header: a header that
declares more data than the file holds, a complex data type, or a count written as ``2e1`` ends in a
bare ``ValueError`` deep inside SPy or numpy. :func:`envi_layout` reads the header's layout keys strictly,
names the key at fault, and checks the data file's size against them; :func:`envi_data_file` finds the
data file as SPy would and refuses anything that is not a regular file (a FIFO would block forever).
Used by spectral libraries (:mod:`s2cl.libraries.files`, read by SPy) and image cubes (:mod:`s2cl.io.cubes`, whose
rows are read through a memory map of the data file).
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from s2cl.errors import DependencyError, InputError, token
from s2cl.io.inputs import input_file

#: bytes per value of the ENVI data types s2cl reads (real numbers; 6 and 9 are complex)
ENVI_ITEM_BYTES = {"1": 1, "2": 2, "3": 4, "4": 4, "5": 8, "12": 2, "13": 4, "14": 8, "15": 8}
#: data-file extensions looked for beside a header (lower and upper case, and none): SPy's, and the interleave
#: names image cubes ship with (EnMAP, PRISMA and AVIRIS exports: ``NAME.bsq``)
DATA_EXTENSIONS = ("", ".img", ".dat", ".bsq", ".bil", ".bip", ".sli", ".hyspex", ".raw", ".bin")


@dataclass(frozen=True)
class EnviLayout:
    """What an ENVI header declares about its data file."""

    samples: int
    lines: int
    bands: int
    item_bytes: int
    offset: int

    @property
    def data_bytes(self) -> int:
        return self.offset + math.prod((self.samples, self.lines, self.bands)) * self.item_bytes


def read_envi_header(hdr: Path, what: str = "ENVI header") -> dict[str, Any]:
    """The header's keys (lower case: ENVI keys are case-insensitive) and values, as SPy parses them; a header
    SPy cannot parse is an :class:`InputError` naming it."""
    try:
        from spectral.io import envi
    except ImportError as err:  # spectral is a core dependency, but say so clearly
        raise DependencyError("reading ENVI files needs SPy: pip install spectral") from err
    input_file(hdr, what="ENVI header")
    try:
        with warnings.catch_warnings():  # keys are case-insensitive: SPy's note that it lower-cased one is no news
            warnings.filterwarnings("ignore", "Parameters with non-lowercase names", UserWarning)
            return envi.read_envi_header(str(hdr))
    except Exception as err:  # SPy raises its own types, and OSError/UnicodeDecodeError/ValueError
        raise InputError(f"not a readable {what} ({type(err).__name__})", source=hdr) from err


def header_int(meta: dict[str, Any], key: str, hdr: Path, *, minimum: int, default: int | None = None) -> int:
    """The whole number at ``key`` (``>= minimum``), written as digits; ``default`` when absent."""
    value = meta.get(key)
    if value is None and default is not None:
        return default
    text = str(value).strip() if value is not None else ""
    if not re.fullmatch(r"[+-]?[0-9]+", text):
        got = "nothing" if value is None else token(text)
        raise InputError(f"must be a whole number >= {minimum} written in digits, got {got}", source=hdr, key=key)
    number = int(text)
    if number < minimum:
        raise InputError(f"must be >= {minimum}, got {number}", source=hdr, key=key)
    return number


def envi_layout(meta: dict[str, Any], hdr: Path, data: Path, *, max_bytes: float | None = None) -> EnviLayout:
    """The header's samples, lines, bands, data type and header offset, each checked (the error names the
    key), and the data file's size checked against them (before anything allocates what a header asks)."""
    dims = {k: header_int(meta, k, hdr, minimum=1) for k in ("samples", "lines", "bands")}
    code = str(meta.get("data type", "")).strip()
    if code not in ENVI_ITEM_BYTES:
        kind = "complex numbers" if code in ("6", "9") else f"type {token(code)}"
        raise InputError(f"holds {kind}; s2cl reads the real data types {', '.join(ENVI_ITEM_BYTES)}",
                         source=hdr, key="data type")
    offset = header_int(meta, "header offset", hdr, minimum=0, default=0)
    layout = EnviLayout(dims["samples"], dims["lines"], dims["bands"], ENVI_ITEM_BYTES[code], offset)
    have = data.stat().st_size
    if layout.data_bytes > have:
        raise InputError(f"samples × lines × bands = {dims['samples']} × {dims['lines']} × {dims['bands']} values of "
                         f"{layout.item_bytes} bytes after a {offset}-byte offset need {layout.data_bytes:,} bytes; "
                         f"{data.name} holds {have:,}", source=hdr, key="lines")
    if max_bytes is not None and layout.data_bytes > max_bytes:
        raise InputError(f"the header declares {layout.data_bytes:,} bytes of data (at most {max_bytes:,.0f})",
                         source=hdr, key="lines")
    return layout


def envi_data_file(hdr: Path) -> Path:
    """The data file beside ``hdr`` (same name, no or a known extension: :data:`DATA_EXTENSIONS`), checked to
    be a regular file."""
    stem = hdr.with_suffix("")
    names = [stem.name + ext for ext in DATA_EXTENSIONS] + [stem.name + ext.upper() for ext in DATA_EXTENSIONS[1:]]
    for name in names:
        candidate = hdr.with_name(name)
        if candidate.exists() or candidate.is_symlink():
            return input_file(candidate, what="ENVI data file")
    raise InputError(f"ENVI data file not found (looked for {', '.join(names[:6])}, ...)", source=hdr)
