"""No-data pixels of an image cube: which input pixels they are, which output pixels they reach, and which
bands draw on wavelengths a bad band list dropped.

**Rule.** An input pixel is NODATA when any of its spectral samples is NaN (the file readers of
:mod:`s2cl.io.cubes` turn every marked no-data value into NaN). An output pixel of a band is NODATA when
any input pixel inside its footprint is: the ``factor × factor`` box it averages, widened on each side by
the reach of the spatial filters that run before the box average (:meth:`s2cl.forward.instrument.Instrument.reach`:
the Gaussian PSF's kernel radius, as ``scipy.ndimage.gaussian_filter`` truncates it, and the finite filter of
the [instrument] MTF and shift, :func:`s2cl.forward.instrument.fir_radius`). Every one of these filters has a
finite support, and the footprint is exactly that support: no input pixel beyond it enters the output pixel.
A mean of the valid inputs alone would be a different pixel (the footprint's missing ground is assumed to
look like the rest, and the PSF weights no longer sum to one), so a valid output pixel is always the pixel
the instrument would see, bit for bit the same as from a cube without holes, and an output pixel the holes
touch is reported as no data (flag :attr:`s2cl.status.PixelFlag.NODATA`, NaN radiance), never as a biased
value. The kernels never see NaN spectra: no-data spectra enter them as zeros and their radiance is set to
NaN after, so no kernel (or PSF) spreads NaN into valid neighbours.
"""

from __future__ import annotations

import logging

import numpy as np

from s2cl.errors import InputError
from s2cl.grid import SpectralGrid
from s2cl.io.cube_reader import BBL
from s2cl.sensor.srf import BandWeights

#: a band drawing more than this fraction of its SRF weight from a bad-band gap is reported
GAP_WEIGHT_REPORTED = 0.01

_log = logging.getLogger(__name__)


def nodata_rows(flat: np.ndarray, step: int = 4096) -> np.ndarray:
    """The NODATA mask ``(n,)`` of spectra ``flat`` ``(n, wavelengths)``: any sample not finite (checked a
    block of rows at a time: no cube-size temporaries)."""
    mask = np.zeros(flat.shape[0], bool)
    if flat.dtype.kind in "iu":
        return mask
    for a in range(0, flat.shape[0], step):
        mask[a : a + step] = ~np.isfinite(flat[a : a + step]).all(axis=1)
    return mask


def footprint_nodata(nodata: np.ndarray, factor: int, reach: tuple[int, int], top: int,
                     out_rows: int) -> np.ndarray:
    """Output-pixel NODATA mask: any NODATA input pixel within ``reach`` ``(rows, cols)`` input pixels of the
    ``factor × factor`` box (trailing partial boxes dropped, as the box average drops them).

    ``nodata`` may be a band of an image's rows (a row block read with its halo, at least ``reach[0]`` rows beyond
    the boxes on each side where the image goes on): ``out_rows`` output rows whose boxes start at its row ``top``,
    the same as those rows of the whole image's mask."""
    rows, cols = reach
    near = nodata
    if rows or cols:  # scipy.ndimage takes ~0.3 s to import: only where a spatial effect reaches past the box
        from scipy.ndimage import maximum_filter

        near = maximum_filter(nodata, size=(2 * rows + 1, 2 * cols + 1), mode="nearest")
    nx = (near.shape[1] // factor) * factor
    return near[top : top + out_rows * factor, :nx].reshape(out_rows, factor, nx // factor, factor).any(axis=(1, 3))


def gap_weights(weights: list[BandWeights], grid: SpectralGrid, kept_nm: np.ndarray,
                bad_nm: np.ndarray) -> np.ndarray:
    """Fraction of each band's SRF weight on ``grid`` lying in a bad-band gap: strictly between the two kept
    wavelengths around a dropped one, where the cube's spectrum is interpolated."""
    wl = grid.wavelengths
    in_gap = np.zeros(wl.size, bool)
    for b in np.asarray(bad_nm, dtype=np.float64):
        below, above = kept_nm[kept_nm < b], kept_nm[kept_nm > b]
        lo = below[-1] if below.size else -np.inf
        hi = above[0] if above.size else np.inf
        in_gap |= (wl > lo) & (wl < hi)
    return np.array([float(w.weights[in_gap[w.start : w.stop]].sum()) for w in weights])


def check_bad_band_gaps(names: list[str], fractions: np.ndarray, quantity: str, source: str,
                        marked_by: tuple[str, str] = BBL) -> None:
    """Bands that draw on a bad-band gap: interpolated over it (a reflectance cube: surface reflectance is
    smooth across the absorption windows cubes mark bad, and the atmosphere is simulated on top), with a
    warning naming them; an :class:`InputError` for a radiance cube, whose radiance in such a window is the
    absorption itself and cannot be interpolated. ``marked_by``: what marked the bad bands, (key, words)
    (:attr:`s2cl.io.cube_reader.CubeReader.bad_bands_by`: ENVI's bad band list, or a product's own flags)."""
    hit = [(n, f) for n, f in zip(names, fractions, strict=True) if f > GAP_WEIGHT_REPORTED]
    if not hit:
        return
    listed = ", ".join(f"{n} {100 * f:.0f} %" for n, f in hit)
    key, words = marked_by
    what = f"SRF weight on wavelengths {words} dropped: {listed}"
    if quantity == "radiance":
        raise InputError(f"{what}; a radiance cube cannot be interpolated over them: leave these bands out "
                         "(sensor.bands)", source=source, key=key)
    _log.warning("%s: %s: %s; reflectance interpolated linearly over the gap", source, key, what)
