"""s2cl's own spectral-library data file: one ``.npz`` holding spectra, names, groups, parameters, metadata.

Layout (all arrays, ``allow_pickle=False`` safe):

===================  ===========================  =============================================
key                  dtype / shape                meaning
===================  ===========================  =============================================
``wavelength_nm``    float64 ``(m,)``             strictly increasing wavelengths in nm
``spectra``          float32/64 ``(n, m)``        reflectance; NaN where not measured
``names``            unicode ``(n,)``             one name per spectrum
``groups``           unicode ``(n,)``             class/group label per spectrum
``param__<key>``     float64 ``(n,)``             generating parameter ``<key>`` per spectrum
``metadata``         unicode scalar               JSON object: format, quantity, source, citation…
===================  ===========================  =============================================

:func:`read_library_file` checks what each array declares (its ``.npy`` header: kind and shape, at most
:data:`MAX_LIBRARY_BYTES` in all) before it loads any; :func:`load_npz_library` reads such a file named by a
scene (``[surface] library = "lib.npz"``) with the checks of the other user files.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from s2cl.errors import InputError, key_token, token
from s2cl.grid import SpectralGrid, check_wavelengths
from s2cl.io.budget import Budget
from s2cl.io.cache import write_npz_atomic
from s2cl.io.inputs import input_file
from s2cl.io.npz import declared_bytes, npz_members
from s2cl.libraries import files
from s2cl.libraries.library import QUANTITY_UNITS, SpectralLibrary, resample_to_grid
from s2cl.libraries.params import check_name, check_new, check_values

FORMAT = "s2cl-spectral-library"
FORMAT_VERSION = 1
_PARAM_PREFIX = "param__"
#: the arrays every library file holds (``param__<key>`` arrays are optional)
REQUIRED_KEYS = ("wavelength_nm", "spectra", "names", "groups", "metadata")
#: largest library file read: bytes of its arrays once loaded, as their headers declare them
MAX_LIBRARY_BYTES = 256 * 2**20


@dataclass
class LibraryFile:
    """The raw content of an s2cl library file, on its own wavelength axis (nm)."""

    wavelength_nm: np.ndarray
    spectra: np.ndarray
    names: list[str]
    groups: list[str]
    params: dict[str, np.ndarray] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)
    path: str = ""

    @property
    def size(self) -> int:
        return int(self.spectra.shape[0])

    def measured_range(self, index: int) -> tuple[float, float]:
        """First and last wavelength (nm) of the contiguous finite run of spectrum ``index``.

        Raises :class:`InputError` when the finite values of the spectrum have holes.
        """
        finite = np.isfinite(self.spectra[index])
        idx = np.flatnonzero(finite)
        if idx.size == 0:
            raise InputError(f"spectrum {token(self.names[index])} holds no finite value", source=self.path)
        if idx[-1] - idx[0] + 1 != idx.size:
            raise InputError(f"spectrum {token(self.names[index])} has holes inside its measured range",
                             source=self.path)
        return float(self.wavelength_nm[idx[0]]), float(self.wavelength_nm[idx[-1]])

    def to_library(self, grid: SpectralGrid, index: list[int] | np.ndarray | None = None) -> SpectralLibrary:
        """The spectra at ``index`` (all by default) interpolated onto ``grid`` as float64.

        Every selected spectrum must have finite values over the whole grid; otherwise
        :class:`InputError` names the spectrum and its measured range (s2cl never pads).
        """
        idx = np.arange(self.size) if index is None else np.asarray(index, dtype=np.intp)
        lo, hi = grid.wavelengths[0], grid.wavelengths[-1]
        for i in idx:
            first, last = self.measured_range(int(i))
            if first > lo + 1e-6 or last < hi - 1e-6:
                raise InputError(
                    f"spectrum {token(self.names[i])} is measured only over {first:g}–{last:g} nm, "
                    f"the grid needs {lo:g}–{hi:g} nm",
                    source=self.path,
                )
        sel = self.spectra[idx].astype(np.float64)
        inside = (self.wavelength_nm >= lo - 1e-6) & (self.wavelength_nm <= hi + 1e-6)
        cols = np.flatnonzero(inside)
        # widen by one sample each side so that interpolation brackets every grid point
        a, b = max(cols[0] - 1, 0), min(cols[-1] + 1, self.wavelength_nm.size - 1)
        sub_w = self.wavelength_nm[a : b + 1]
        sub = sel[:, a : b + 1]
        if not np.all(np.isfinite(sub)):
            sub = _fill_edge_nan(sub)
        spectra = resample_to_grid(sub_w, sub, grid, source=self.path)
        return SpectralLibrary(
            grid=grid,
            spectra=spectra,
            names=[self.names[i] for i in idx],
            quantity=self.metadata.get("quantity", "reflectance"),
            groups=[self.groups[i] for i in idx],
            params={k: v[idx] for k, v in self.params.items()},
            source=self.metadata.get("source", self.path),
        )


def _fill_edge_nan(sub: np.ndarray) -> np.ndarray:
    """Replace NaN in the one-sample margins (outside the grid) by the nearest finite value.

    Only the widened margin samples can be non-finite here (coverage was checked), and they
    carry zero interpolation weight at grid points that coincide with data samples.
    """
    out = sub.copy()
    for row in out:
        bad = ~np.isfinite(row)
        if bad.any():
            good = np.flatnonzero(~bad)
            row[bad] = np.interp(np.flatnonzero(bad), good, row[good])
    return out


def write_library_file(
    path: str | Path,
    *,
    wavelength_nm: np.ndarray,
    spectra: np.ndarray,
    names: list[str],
    groups: list[str],
    params: dict[str, np.ndarray] | None = None,
    metadata: dict[str, Any] | None = None,
    dtype: Any = np.float32,
) -> Path:
    """Write a library file atomically (see module docstring); spectra stored as ``dtype``."""
    w = check_wavelengths(wavelength_nm, source=str(path), key="wavelength_nm")
    s = np.asarray(spectra, dtype=dtype)
    n = s.shape[0]
    if s.shape != (n, w.size) or len(names) != n or len(groups) != n:
        raise ValueError(f"inconsistent library: spectra {s.shape}, {len(names)} names, {len(groups)} groups")
    meta = {"format": FORMAT, "format_version": FORMAT_VERSION, "quantity": "reflectance"}
    meta.update(metadata or {})
    arrays: dict[str, np.ndarray] = {
        "wavelength_nm": w,
        "spectra": s,
        "names": np.asarray(names, dtype=np.str_),
        "groups": np.asarray(groups, dtype=np.str_),
        "metadata": np.asarray(json.dumps(meta, sort_keys=True)),
    }
    for key, values in (params or {}).items():
        arr = np.asarray(values, dtype=np.float64)
        if arr.shape != (n,):
            raise ValueError(f"parameter {key} has shape {arr.shape}, expected ({n},)")
        arrays[_PARAM_PREFIX + key] = arr
    return write_npz_atomic(path, arrays)


def read_library_file(path: str | Path) -> LibraryFile:
    """Read a library file written by :func:`write_library_file`; what its arrays declare is checked first
    (:func:`check_declared`), and a file that is not one is a one-line :class:`InputError` naming it."""
    path = Path(path)
    if not path.exists():
        raise InputError("library data file not found", source=path)
    keys = check_declared(npz_members(path, "s2cl library file"), str(path)).keys
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in keys}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as err:
        raise InputError(f"not a readable s2cl library file (corrupt or not .npz: {type(err).__name__})",
                         source=path) from err
    metadata = _metadata(data["metadata"], path)
    params = {k[len(_PARAM_PREFIX) :]: np.asarray(v, dtype=np.float64) for k, v in data.items()
              if k.startswith(_PARAM_PREFIX)}
    return LibraryFile(
        wavelength_nm=check_wavelengths(data["wavelength_nm"], source=str(path), key="wavelength_nm"),
        spectra=data["spectra"],
        names=[str(s) for s in data["names"]],
        groups=[str(s) for s in data["groups"]],
        params=params,
        metadata=metadata,
        path=str(path),
    )


class Declared(NamedTuple):
    """What a library file's arrays declare: sizes, the arrays to load, and their bytes once loaded."""

    spectra: int
    wavelengths: int
    keys: list[str]
    nbytes: int


def check_declared(members: dict[str, tuple[tuple[int, ...], np.dtype]], source: str) -> Declared:
    """What a library file holds, from its arrays' headers (:func:`s2cl.io.npz.npz_members`): every required
    array there, of its kind and of shapes that agree, at most :data:`MAX_LIBRARY_BYTES` in all (other members
    are never loaded)."""
    missing = [k for k in REQUIRED_KEYS if k not in members]
    if missing:
        raise InputError(f"library file lacks the arrays {', '.join(missing)} (is it an s2cl library file?)",
                         source=source)
    w_shape, s_shape = members["wavelength_nm"][0], members["spectra"][0]
    m = w_shape[0] if len(w_shape) == 1 else 0
    n = s_shape[0] if len(s_shape) == 2 else 0
    params = [k for k in members if k.startswith(_PARAM_PREFIX)]
    rules = [("wavelength_nm", "fiu", (m,), "numbers of shape (wavelengths,)"),
             ("spectra", "f", (n, m), f"floats of shape (spectra, {m})"),
             ("names", "U", (n,), f"text of shape ({n},)"), ("groups", "U", (n,), f"text of shape ({n},)"),
             ("metadata", "U", (), "one text (JSON)"), *((k, "fiu", (n,), f"numbers of shape ({n},)") for k in params)]
    for key, kinds, want, what in rules:
        got, dtype = members[key]
        if dtype.kind not in kinds or got != want:
            raise InputError(f"declares {dtype} of shape {got}; an s2cl library file holds {what} here",
                             source=source, key=key_token(key))
    keys = [*REQUIRED_KEYS, *params]
    total = sum(declared_bytes(*members[k]) for k in keys)
    if total > MAX_LIBRARY_BYTES:
        raise InputError(f"its arrays declare {total:,} bytes (at most {MAX_LIBRARY_BYTES:,})", source=source)
    return Declared(n, m, keys, total)


def _metadata(value: np.ndarray, path: Path) -> dict[str, Any]:
    """The ``metadata`` JSON object, in the format and version this reader knows."""
    try:
        metadata = json.loads(str(value))
    except (ValueError, RecursionError) as err:
        raise InputError("is not JSON", source=path, key="metadata") from err
    if not isinstance(metadata, dict):
        raise InputError("must be a JSON object", source=path, key="metadata")
    if metadata.get("format") != FORMAT or metadata.get("format_version") != FORMAT_VERSION:
        raise InputError(f"library file format {token(metadata.get('format'))} "
                         f"v{token(metadata.get('format_version'))} is not {FORMAT!r} v{FORMAT_VERSION}", source=path)
    if metadata.get("quantity", "reflectance") not in QUANTITY_UNITS:
        raise InputError(f"quantity {token(metadata.get('quantity'))} is not one of {', '.join(QUANTITY_UNITS)}",
                         source=path, key="metadata")
    return metadata


def load_npz_library(path: str | Path, grid: SpectralGrid, *, max_gap_nm: float | None = None,
                     budget: Budget | None = None) -> SpectralLibrary:
    """An s2cl library file named by the user (``[surface] library = "lib.npz"``) on ``grid``.

    Sized from its arrays' headers against ``budget`` before any is loaded; its parameters (``param__NAME``)
    must have valid names and finite values, and its spectra the plausible values of its ``quantity``
    (metadata; reflectance by default) and no gap wider than ``max_gap_nm`` inside ``grid``, as for CSV and
    ENVI files (:mod:`s2cl.libraries.files`). NaN marks unmeasured wavelengths: an error where ``grid`` needs
    them.
    """
    source = str(path)
    path = input_file(path, what="s2cl library file (.npz)")
    declared = check_declared(npz_members(path, "s2cl library file"), source)
    # the arrays as loaded, and the float64 copy of the spectra that interpolation makes
    read = declared.nbytes + 8.0 * declared.spectra * declared.wavelengths
    files.require_library_memory(budget, declared.spectra, read, grid, source=source)
    f = read_library_file(path)
    seen: dict[str, str] = {}
    for name, values in f.params.items():
        key = _PARAM_PREFIX + key_token(name)
        check_name(name, source=source, key=key)
        check_new(name, seen, f"array {key}", source=source, key=key)
        check_values(values, f.names, source=source, key=key)
    lib = f.to_library(grid)
    files.check_gaps(f.wavelength_nm, grid, source=source,
                     max_gap_nm=files.DEFAULT_MAX_GAP_NM if max_gap_nm is None else max_gap_nm)
    files.check_values(grid.wavelengths, lib.spectra, lib.names, slice(None), source=source, quantity=lib.quantity)
    return lib
