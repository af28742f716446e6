"""Linear interpolation of a cube's native samples onto the spectral grid, as a table the resampling kernel reads
(``kernels/resample.cl.mako``): per grid wavelength, the index of the native sample at or below it, the index of the
one above it, and the fraction of the way between them.

The kernel puts each pixel on the grid itself, one grid wavelength at a time, just before it turns reflectance into
TOA radiance there (the atmosphere is nonlinear in reflectance, so the interpolation cannot be folded into the band
weights): a product of 224 bands is read as 224 samples per pixel, not as the 2,000-odd of the 1 nm grid.

**Rule** (``numpy.interp``'s): grid wavelength ``x`` between native wavelengths ``w[j] <= x < w[j+1]`` takes
``v[j] + f · (v[j+1] − v[j])`` with ``f = (x − w[j]) / (w[j+1] − w[j])``; on a native wavelength (``f`` exactly 0)
it takes ``v[j]`` alone and never reads ``v[j+1]`` (the table names ``j`` twice: ``0 · inf`` would be NaN); below
the first or above the last native wavelength it takes the end value (the chain never gets there: a cube must
cover the grid, :func:`s2cl.libraries.library.check_coverage`, checked by :meth:`GridInterpolation.covering`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.grid import SpectralGrid, check_wavelengths
from s2cl.libraries.library import check_coverage


@dataclass(frozen=True, eq=False)
class GridInterpolation:
    """The table: ``lower``, ``upper`` (native sample indices, int32) and ``fraction`` (float64 in [0, 1)) per grid
    wavelength, for samples at ``n_native`` native wavelengths."""

    lower: np.ndarray
    upper: np.ndarray
    fraction: np.ndarray
    n_native: int

    @classmethod
    def of(cls, native_nm: np.ndarray, grid_nm: np.ndarray) -> GridInterpolation:
        """The table from strictly increasing ``native_nm`` onto ``grid_nm`` (nm), ends clamped (module rule)."""
        w = np.asarray(native_nm, dtype=np.float64)
        x = np.asarray(grid_nm, dtype=np.float64)
        j = np.clip(np.searchsorted(w, x, side="right") - 1, 0, w.size - 2)
        f = (x - w[j]) / (w[j + 1] - w[j])
        lower, upper = j.copy(), j + 1
        below, above = f <= 0.0, f >= 1.0  # on a native wavelength (or before the first): that sample alone
        upper[below] = j[below]
        lower[above] = upper[above]  # on the next native wavelength (or past the last): that sample alone
        f = np.where(below | above, 0.0, f)
        return cls(lower.astype(np.int32), upper.astype(np.int32), f, int(w.size))

    @classmethod
    def covering(cls, native_nm: np.ndarray, grid: SpectralGrid, source: str | None = None) -> GridInterpolation:
        """:meth:`of` for a cube's wavelengths, checked as :func:`s2cl.libraries.library.resample_to_grid` checks
        them (1-D, finite, strictly increasing, covering the grid): a one-line :class:`InputError` naming ``source``."""
        w = check_wavelengths(native_nm, source=source)
        check_coverage(w, grid, source=source)
        return cls.of(w, grid.wavelengths)

    @property
    def n_grid(self) -> int:
        return int(self.fraction.size)


def on_grid(wavelengths_nm: np.ndarray, grid: SpectralGrid) -> bool:
    """Whether a cube's wavelengths (nm) are the grid's (within 1e-6 nm): its spectra then go in as they are, with
    no table."""
    w = np.asarray(wavelengths_nm, dtype=np.float64)
    return w.size == grid.size and bool(np.allclose(w, grid.wavelengths, atol=1e-6))
