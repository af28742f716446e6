"""The bands of a product as a reader keeps them: the good ones in increasing wavelength, and where each lies in
the file; and the per-band conversion of stored numbers to reflectance (no-data, gain, offset)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from s2cl.errors import InputError
from s2cl.grid import check_wavelengths
from s2cl.io.inputs import parse_number


@dataclass(frozen=True)
class BandSelection:
    """The bands kept: ``index`` (their positions in the file, 0-based, in increasing wavelength),
    ``wavelengths_nm`` (nm, increasing) and the wavelengths of the bands dropped as bad (``bad_nm``)."""

    index: np.ndarray
    wavelengths_nm: np.ndarray
    bad_nm: np.ndarray

    @classmethod
    def of(cls, wavelengths_nm: np.ndarray, good: np.ndarray, source: str | Path, key: str) -> BandSelection:
        """Keep the ``good`` bands of ``wavelengths_nm`` (file order, nm), sorted by wavelength; refuse when none is
        good, or two good bands share a wavelength (:func:`s2cl.grid.check_wavelengths`). A bad band without a
        wavelength (0 or less: PRISMA's unused slots) is not listed among the bad."""
        w = np.asarray(wavelengths_nm, dtype=np.float64)
        good = np.asarray(good, dtype=bool)
        if not good.any():
            raise InputError("marks every band bad", source=source, key=key)
        kept = np.flatnonzero(good)
        order = kept[np.argsort(w[kept], kind="stable")]
        wl = check_wavelengths(w[order], source=str(source), key=key)
        bad = w[~good]
        return cls(order, wl, np.sort(bad[bad > 0]))


def bad_band_flags(values: list | None, bands: int, source: str | Path) -> np.ndarray:
    """A bad band list (ENVI's ``bbl``: one 0 (bad) or 1 (good) per band, as text or numbers) as booleans, True for
    a good band; all good when absent (None). Refused in one line naming ``bbl``: another count, another value,
    every band bad."""
    if values is None:
        return np.ones(bands, bool)
    if len(values) != bands:
        raise InputError(f"lists {len(values)} values for bands = {bands}", source=source, key="bbl")
    try:
        flags = np.array([parse_number(str(x).strip()) for x in values])
    except ValueError:
        raise InputError("holds a value that is not 0 or 1", source=source, key="bbl") from None
    if not np.isin(flags, (0.0, 1.0)).all():
        raise InputError(f"holds {flags[~np.isin(flags, (0.0, 1.0))][0]:g}; bad band list values are 0 (bad) or "
                         "1 (good)", source=source, key="bbl")
    if not flags.any():
        raise InputError("marks every band bad", source=source, key="bbl")
    return flags == 1.0


def scaled(raw: np.ndarray, nodata: np.ndarray | float | None, gain: np.ndarray | float,
           offset: np.ndarray | float) -> np.ndarray:
    """Stored numbers ``raw`` ``(..., bands)`` as values: ``raw · gain + offset`` (float32 for 8/16-bit integers and
    float32, float64 otherwise), NaN where ``raw`` equals the band's ``nodata`` (compared before scaling, at the
    stored precision)."""
    small = raw.dtype == np.float32 or (raw.dtype.kind in "iu" and raw.dtype.itemsize <= 2)
    values = np.array(raw, dtype=np.float32 if small else np.float64)
    if nodata is not None:
        nd = np.broadcast_to(np.asarray(nodata, dtype=np.float64), raw.shape[-1:])
        fin = np.isfinite(nd)  # a NaN no-data value: NaN is no data already
        if fin.any():
            target = np.where(fin, nd, 0).astype(raw.dtype) if raw.dtype.kind == "f" else np.where(fin, nd, 0)
            values[(raw == target) & fin] = np.nan
    g = np.asarray(gain, dtype=values.dtype)
    o = np.asarray(offset, dtype=values.dtype)
    if not (np.all(g == 1) and np.all(o == 0)):
        values *= g
        values += o
    return values
