"""The reader of an image cube's rows that every format's reader returns (:class:`CubeReader`), and the conventions
they share: wavelength units, real values only, stored numbers as floating values."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError, token
from s2cl.io.georef import GeoRef

_NANOMETRES = ("nanometers", "nanometer", "nanometres", "nanometre", "nm", "unknown", "")
_MICROMETRES = ("micrometers", "micrometer", "micrometres", "micrometre", "microns", "micron", "um", "µm", "μm")

#: what marked a cube's bad bands, as messages name it: (the metadata key, its words); ENVI's and GDAL's bad band list
BBL = ("bbl", "the bad band list (bbl)")


@dataclass(frozen=True)
class CubeReader:
    """A cube file opened for reading a band of rows at a time: its shape and wavelengths from the metadata, every
    rule of :func:`s2cl.io.cubes.load_cube` checked; :meth:`read` gives rows ``start … stop-1`` exactly as
    ``load_cube`` gives them within the whole cube (the same function reads both).

    :param wavelengths_nm: the kept bands' wavelengths (nm, increasing).
    :param bad_nm: wavelengths (nm) of the bands the file's bad band list dropped (empty when none)."""

    path: Path
    rows: int
    cols: int
    wavelengths_nm: np.ndarray
    bad_nm: np.ndarray
    _read: Callable[[int, int], np.ndarray]
    #: the grid of the cube's pixels on the map (None: the file has none)
    georef: GeoRef | None = None
    #: what the file is (``ENVI``, ``NetCDF``, ``EnMAP L2A``, ``EMIT L2A``, ``PRISMA L2D``, ``GeoTIFF``)
    product: str = "NetCDF"
    #: what the values are where the product says so (``reflectance``); None: the scene's ``surface.quantity``
    quantity: str | None = None
    #: the kept bands' FWHM (nm) where the product gives them
    fwhm_nm: np.ndarray | None = None
    #: one line each about what the reader chose (bands dropped, geometry), for the run's record
    notes: tuple[str, ...] = ()
    #: bands stored per pixel and read with each row (0: the kept and the bad bands), for the memory rule
    stored_bands: int = 0
    #: what marked the bad bands (:data:`BBL`, or the product's own flags), for the messages about them
    bad_bands_by: tuple[str, str] = BBL

    @property
    def bands_read(self) -> int:
        """Bands read per pixel with each row (kept, bad and any other stored band)."""
        return self.stored_bands or self.wavelengths_nm.size + self.bad_nm.size

    def read(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start … stop-1`` ``(stop-start, cols, wavelengths)``: floating values, NaN where the file marks no
        data."""
        return self._read(start, stop)


def real(dtype: np.dtype, p: Path, key: str) -> None:
    """Refuse a cube of complex (or non-numeric) values: casting would drop the imaginary part silently."""
    if np.dtype(dtype).kind not in "fiu":
        raise InputError(f"holds {np.dtype(dtype)} values; a cube holds real numbers (radiance or reflectance)",
                         source=p, key=key)


def wavelength_scale(units: Any, p: Path, key: str) -> float:
    """nm per unit of a file's wavelength ``units`` (1 for nanometres, 1000 for micrometres)."""
    text = str(units if units is not None else "").strip().lower()
    if text in _NANOMETRES:
        return 1.0
    if text in _MICROMETRES:
        return 1000.0
    raise InputError(f"wavelength units {token(str(units))} are not known; write Nanometers or Micrometers",
                     source=p, key=key)


def floating(values: np.ndarray) -> np.ndarray:
    """``values`` as a writable floating array: float32 for float32 and 8/16-bit integers (exact), else float64."""
    small = values.dtype == np.float32 or (values.dtype.kind in "iu" and values.dtype.itemsize <= 2)
    out = np.asarray(values, dtype=np.float32 if small else np.float64)
    return out if out.flags.writeable else out.copy()
