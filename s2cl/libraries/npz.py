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
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError
from s2cl.grid import SpectralGrid, check_wavelengths
from s2cl.io.cache import write_npz_atomic
from s2cl.libraries.library import SpectralLibrary, resample_to_grid

FORMAT = "s2cl-spectral-library"
FORMAT_VERSION = 1
_PARAM_PREFIX = "param__"


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
            raise InputError(f"spectrum {self.names[index]} holds no finite value", source=self.path)
        if idx[-1] - idx[0] + 1 != idx.size:
            raise InputError(f"spectrum {self.names[index]} has holes inside its measured range", source=self.path)
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
                    f"spectrum {self.names[i]} is measured only over {first:g}–{last:g} nm, "
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
    """Read a library file written by :func:`write_library_file`."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except FileNotFoundError as err:
        raise InputError("library data file not found", source=path) from err
    except (OSError, ValueError) as err:
        raise InputError(f"not a readable s2cl library file ({err})", source=path) from err
    missing = {"wavelength_nm", "spectra", "names", "groups", "metadata"} - set(data)
    if missing:
        raise InputError(f"library file lacks {sorted(missing)}", source=path)
    metadata = json.loads(str(data["metadata"]))
    if metadata.get("format") != FORMAT or int(metadata.get("format_version", -1)) != FORMAT_VERSION:
        raise InputError(
            f"library file format {metadata.get('format')!r} v{metadata.get('format_version')} is not "
            f"{FORMAT!r} v{FORMAT_VERSION}",
            source=path,
        )
    params = {k[len(_PARAM_PREFIX) :]: v for k, v in data.items() if k.startswith(_PARAM_PREFIX)}
    return LibraryFile(
        wavelength_nm=np.asarray(data["wavelength_nm"], dtype=np.float64),
        spectra=data["spectra"],
        names=[str(s) for s in data["names"]],
        groups=[str(s) for s in data["groups"]],
        params=params,
        metadata=metadata,
        path=str(path),
    )
