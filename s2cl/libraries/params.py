"""Per-spectrum parameters in user library files (the values an [analysis] regresses on, e.g. ``cab``).

One rule for every format: a name is 1-32 ASCII letters, digits or ``_`` starting with a letter, names
differ in more than case, and every spectrum has one finite value per parameter. Where they are written:

- CSV (:class:`CsvParameters`): rows right after the header whose first cell is ``param:NAME``, one value
  per spectrum column, e.g. ``param:cab,45.2,30.1``;
- ENVI (:func:`envi_parameters`): header fields ``s2cl parameter NAME = {v1, v2, ...}``, one value per line
  (spectrum) of the library;
- s2cl ``.npz`` (:func:`s2cl.libraries.npz.load_npz_library`): arrays ``param__NAME``, ``(n_spectra,)``.

Errors are one line naming the file, the parameter (``param:cab``, ``s2cl parameter cab``) and the line.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError, key_token, token
from s2cl.io.inputs import parse_number

#: units of the built-in libraries' parameters (user parameters carry none: labels then say "parameter units")
PARAMETER_UNITS = {"cab": "µg/cm²", "ewt": "µm", "lai": "m²/m²"}

#: a parameter name: it becomes ``analysis.parameter`` and the NetCDF coordinate ``param_NAME``
PARAM_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,31}")
NAME_RULE = "1-32 letters, digits or _, starting with a letter"
#: first cell of a CSV parameter row (case-insensitive), followed by the name
CSV_PREFIX = "param:"
#: ENVI header key of a parameter (lower case: SPy reads header keys in lower case), followed by the name
ENVI_PREFIX = "s2cl parameter"


def check_name(name: str, *, source: str | Path, key: str) -> str:
    """``name`` when it follows :data:`PARAM_NAME`, else :class:`InputError`."""
    if not PARAM_NAME.fullmatch(name):
        raise InputError(f"parameter name {token(name)} must be {NAME_RULE}", source=source, key=key)
    return name


def check_new(name: str, seen: dict[str, str], here: str, *, source: str | Path, key: str) -> None:
    """Refuse ``name`` if a name equal to it but for case was given before (``seen``: lower-cased name -> where,
    e.g. ``line 3``); else record it as given ``here``."""
    if name.lower() in seen:
        raise InputError(f"is given twice ({seen[name.lower()]} and {here}); parameter names must differ in more "
                         "than case", source=source, key=key)
    seen[name.lower()] = here


def check_values(values: np.ndarray, names: list[str], *, source: str | Path, key: str, where: str = "") -> np.ndarray:
    """``values`` (float64, one per spectrum of ``names``) when all are finite; else the first bad one is named."""
    bad = ~np.isfinite(values)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        raise InputError(f"{where}value {values[j]} for spectrum {token(names[j])} is not finite; every spectrum "
                         "needs a finite value of each parameter", source=source, key=key)
    return values


class CsvParameters:
    """Collects the ``param:NAME`` rows of a CSV library (:func:`s2cl.libraries.files.load_csv_library`).

    :param header: the header row (wavelength column, then one column per spectrum).
    """

    def __init__(self, header: list[str], source: str | Path):
        self.names = [h.strip() for h in header[1:]]
        self.source = source
        self.params: dict[str, np.ndarray] = {}
        self._seen: dict[str, str] = {}
        self._first_data: int | None = None

    def take(self, line_no: int, row: list[str]) -> bool:
        """Read ``row`` if it is a parameter row (True), else note that the wavelength rows have begun (False)."""
        first = row[0].strip() if row else ""
        if not first.lower().startswith(CSV_PREFIX):
            if self._first_data is None:
                self._first_data = line_no
            return False
        name = first[len(CSV_PREFIX):].strip()
        key = f"{CSV_PREFIX}{key_token(name)}"
        if self._first_data is not None:
            raise InputError(f"line {line_no}: parameter rows come before the first wavelength row (line "
                             f"{self._first_data})", source=self.source, key=key)
        check_name(name, source=self.source, key=key)
        check_new(name, self._seen, f"line {line_no}", source=self.source, key=key)
        self.params[name] = self._values(line_no, row[1:], key)
        return True

    def _values(self, line_no: int, cells: list[str], key: str) -> np.ndarray:
        if len(cells) != len(self.names):
            raise InputError(f"line {line_no}: {len(cells)} values for {len(self.names)} spectra (one per spectrum "
                             "column)", source=self.source, key=key)
        out = np.empty(len(cells))
        for j, cell in enumerate(cells):
            text = cell.strip()
            try:
                out[j] = parse_number(text)
            except ValueError as err:
                got = "no value" if not text else f"{token(text)}, not a number,"
                raise InputError(f"line {line_no}: {got} for spectrum {token(self.names[j])}; every spectrum "
                                 "needs a finite value of each parameter", source=self.source, key=key) from err
        return check_values(out, self.names, source=self.source, key=key, where=f"line {line_no}: ")


def envi_parameters(hdr: Path, meta: dict[str, Any], n_spectra: int) -> dict[str, np.ndarray]:
    """The ``s2cl parameter NAME = {...}`` fields of an ENVI library header, each checked: one finite value
    per spectrum (``lines``), no name twice (SPy keeps only the last of two equal keys: the header's text is
    scanned for them first)."""
    names = [str(n).strip() for n in meta.get("spectra names", [])] or [f"#{i}" for i in range(n_spectra)]
    names += [f"#{i}" for i in range(len(names), n_spectra)]
    seen: dict[str, str] = {}
    params: dict[str, np.ndarray] = {}
    for line_no, key in _s2cl_keys(hdr):
        words = key.split()
        if len(words) != 3 or " ".join(words[:2]) != ENVI_PREFIX:
            raise InputError(f"line {line_no}: unknown s2cl header field; s2cl reads "
                             f"'{ENVI_PREFIX} NAME = {{v1, v2, ...}}' (one value per spectrum)", source=hdr,
                             key=key_token(key))
        name = words[2]
        where = f"{ENVI_PREFIX} {key_token(name)}"
        check_name(name, source=hdr, key=where)
        check_new(name, seen, f"line {line_no}", source=hdr, key=where)
        params[name] = _envi_values(meta.get(key), names, n_spectra, hdr, where)
    return params


def _envi_values(value: Any, names: list[str], n_spectra: int, hdr: Path, key: str) -> np.ndarray:
    if not isinstance(value, list):
        raise InputError(f"must be a list in braces, {{v1, v2, ...}}, one value per spectrum (lines = {n_spectra})",
                         source=hdr, key=key)
    if len(value) != n_spectra:
        raise InputError(f"lists {len(value)} values for lines = {n_spectra} (one value per spectrum)", source=hdr,
                         key=key)
    out = np.empty(n_spectra)
    for j, text in enumerate(value):
        try:
            out[j] = parse_number(str(text).strip())
        except ValueError as err:
            raise InputError(f"value {j + 1} ({token(str(text))}) for spectrum {token(names[j])} is not a number",
                             source=hdr, key=key) from err
    return check_values(out, names, source=hdr, key=key)


def _s2cl_keys(hdr: Path) -> list[tuple[int, str]]:
    """(line number, key) of each header field whose key starts with ``s2cl``, keys split off as SPy does
    (stripped, lower case; a value in braces may span lines)."""
    lines = hdr.read_text(encoding="utf-8", errors="replace").splitlines()
    found: list[tuple[int, str]] = []
    i = 1  # line 1 is 'ENVI'
    while i < len(lines):
        line_no, line = i + 1, lines[i]
        i += 1
        if "=" not in line or line.startswith(";"):
            continue
        key, _, value = line.partition("=")
        value = value.strip()
        if value.startswith("{"):
            while not value.endswith("}") and i < len(lines):
                if not lines[i].startswith(";"):
                    value += lines[i].strip()
                i += 1
        key = key.strip().lower()
        if key.split()[:1] == ["s2cl"]:
            found.append((line_no, key))
    return found
