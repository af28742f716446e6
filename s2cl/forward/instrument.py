"""The instrument's own artefacts on an image cube (the ``[effects]`` keys psf, coregistration, smile and
nonuniformity; stages of :mod:`s2cl.forward.stages` that act on images), each off unless asked for.

Where each acts in :func:`s2cl.forward.cube.simulate_cube`'s chain:

* **smile** — at resampling: the SRF of band ``k`` at column position ``x`` (−1 … 1 across the image) is the
  nominal one moved by ``Δλ(x)`` and widened by ``ΔFWHM(x)/FWHM``, both polynomials in ``x``. Rather than one SRF
  per column (one kernel build, or a dense weight matrix, per column), the resampling kernel integrates each band at
  :data:`SMILE_NODES` node SRFs spanning the smile's range (per axis: their product when the width varies too) in
  one pass, and each column takes the Lagrange interpolation (cubic) between its band's nodes (:func:`lagrange`).
  Its error against the exact per-column integral (:func:`smile_twin`) is tested. Off: no node band is in the kernel.
* **psf** and **coregistration** — on the input grid before the box average: the band's image goes through a
  Gaussian's transfer function (of the given FWHM, or whose product with the box average's sinc gives the band's
  MTF at Nyquist, :func:`gaussian_sigma`) and the phase ramp of the band's sub-pixel shift (a band-limited shift:
  it moves the image without blurring it, as linear interpolation would, whose own MTF at Nyquist drops to 0 at
  half a pixel), as a finite filter along each axis (:func:`fir_kernel`: the transfer function's inverse DFT, kept
  whole over the Gaussian's reach around the shifted centre and tapered to 0 over a few more taps,
  :func:`taper_taps`; borders act as a half-sample mirror). The filter reaches :func:`fir_radius` pixels and no
  further: that is the halo of a block of rows (so blocks give the same bands as the whole image, bit for bit) and
  how far a NODATA input pixel reaches (so a valid pixel is the same as from a cube without the hole). The twin
  :func:`spatial_twin` applies the transfer function exactly, by FFTs of the mirrored image along both axes. Off:
  the band's image is returned as it is, no filter runs. The one PSF: there is no other.
* **nonuniformity** — on each band's grid after the box average: per-column gain ``g`` and offset ``o``; a relative
  calibration estimates them with errors ``ε`` (relative) and ``δ``, so the product holds
  ``(g·L + o − (o + δ)) / (g·(1 + ε))`` (or ``g·L + o`` without equalisation). Drawn from the scene's seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from s2cl.cl.runtime import Runtime
from s2cl.forward.grid_interpolation import GridInterpolation
from s2cl.forward.parts import ChainParts
from s2cl.forward.resample import ResamplePlan, Resampler
from s2cl.grid import SpectralGrid
from s2cl.scene.instrument_schema import (
    BOX_MTF_NYQUIST,
    CoregistrationSpec,
    NonUniformitySpec,
    PsfSpec,
    SmileSpec,
    setting,
)
from s2cl.sensor.sensor import Band
from s2cl.sensor.srf import BandWeights, TabulatedResponse, band_weights

#: node SRFs per varying smile axis (cubic interpolation): against the per-column integral the default smile's
#: largest relative error was ~1e-7 with 4 nodes and ~1e-5 with 3 when chosen; tests/test_instrument.py holds it
#: below 1e-6
SMILE_NODES = 4
#: how far the Gaussian is taken to reach (σ), as scipy.ndimage truncates it
GAUSSIAN_TRUNCATE = 4.0
#: taps of an axis's filter beyond the Gaussian's reach and the shift, over which its window tapers to 0 (a
#: cosine), when the Gaussian leaves the signal at Nyquist whole: room for the tails of the shift's band-limited
#: (sinc) interpolation (:func:`taper_taps`)
TAPER_TAPS = 8
#: a Gaussian's σ per unit FWHM
FWHM_TO_SIGMA = 1.0 / (2.0 * math.sqrt(2.0 * math.log(2.0)))
#: random-stream tags (the second word of each generator's seed), one per effect
_COREG_TAG, _NU_TAG = 0x636F7267, 0x6E756E69


def gaussian_sigma(mtf_nyquist: float) -> float:
    """σ (band pixels) of the Gaussian PSF whose MTF times the box average's (sinc(f), 2/π at Nyquist) equals
    ``mtf_nyquist`` at the band's Nyquist frequency 1/2 cycle per band pixel: exp(−2π²σ²/4)·2/π = m."""
    if not 0 < mtf_nyquist < BOX_MTF_NYQUIST:
        raise ValueError(f"MTF at Nyquist must be in (0, {BOX_MTF_NYQUIST:.4f}), got {mtf_nyquist}")
    return math.sqrt(-2.0 * math.log(mtf_nyquist / BOX_MTF_NYQUIST)) / math.pi


def _transfer(f: np.ndarray, sigma: float, d: float) -> np.ndarray:
    """The Gaussian's transfer function times the shift's phase ramp at frequencies ``f`` (cycles per pixel)."""
    return np.exp(-2.0 * math.pi**2 * sigma**2 * f**2 - 2j * math.pi * f * d)


def _fft_axis(a: np.ndarray, sigma: float, d: float, axis: int) -> np.ndarray:
    """``a`` filtered along ``axis`` by a real FFT of ``a`` mirrored along it (the mirrored line's periodic
    extension is continuous, so the wrap-around adds no step; borders act as a half-sample mirror)."""
    if sigma == 0.0 and d == 0.0:
        return a
    from scipy import fft as sfft  # ~0.24 s: the float64 twin's filter, not the product's
    n = a.shape[axis]
    tile = np.concatenate([a, np.flip(a, axis=axis)], axis=axis)
    shape = [1, 1]
    shape[axis] = -1
    out = sfft.irfft(sfft.rfft(tile, axis=axis) * _transfer(sfft.rfftfreq(2 * n), sigma, d).reshape(shape),
                     n=2 * n, axis=axis)
    return out[:, :n] if axis == 1 else out[:n]


def taper_taps(sigma: float) -> int:
    """Taps over which the filter of a Gaussian of ``sigma`` (pixels) and a shift tapers to 0 beyond the Gaussian's
    reach: the shift's band-limited interpolation has tails only as strong as the signal near Nyquist, which the
    Gaussian keeps in the proportion exp(−π²σ²/2), so :data:`TAPER_TAPS` times that, rounded (8 for a pure shift,
    2 at σ = 0.54, none from σ ≈ 0.8 on, where the Gaussian truncated at 4 σ is within 1e-2 of its transfer
    function)."""
    return round(TAPER_TAPS * math.exp(-(math.pi**2) * sigma**2 / 2.0))


def fir_radius(sigma: float, d: float) -> int:
    """Half-length R (pixels) of the filter along one axis of a Gaussian of ``sigma`` and a shift ``d`` (pixels):
    the farthest tap its window (:func:`fir_kernel`) leaves non-zero, ``|d|`` + 4 σ + :func:`taper_taps` + 1 rounded
    up, less one; 0 when both are 0 (no filter runs along that axis). An output pixel depends on the input pixels
    within R of it and on no other."""
    if sigma == 0.0 and d == 0.0:
        return 0
    return math.ceil(abs(d) + GAUSSIAN_TRUNCATE * sigma + taper_taps(sigma) + 1) - 1


def fir_kernel(sigma: float, d: float) -> np.ndarray:
    """Taps ``h[-R … R]`` (R = :func:`fir_radius`) of the transfer function of a Gaussian of ``sigma`` and a shift
    ``d`` (pixels): its inverse DFT on a fine grid times a window centred on the shift, 1 over the Gaussian's reach
    (:data:`GAUSSIAN_TRUNCATE` σ) and a cosine down to 0 over :func:`taper_taps` + 1 taps beyond, normalised to a
    sum of 1 (``[1]`` when both are 0). The taps on the side away from the shift that the window does not reach
    are 0."""
    radius = fir_radius(sigma, d)
    if radius == 0:
        return np.ones(1)
    core, margin = GAUSSIAN_TRUNCATE * sigma, taper_taps(sigma)
    n = max(4096, 8 * radius)
    full = np.real(np.fft.ifft(_transfer(np.fft.fftfreq(n), sigma, d)))
    taps = np.arange(-radius, radius + 1)
    beyond = np.clip(np.abs(taps - d) - core, 0.0, None)
    h = full[taps % n] * 0.5 * (1.0 + np.cos(np.pi * np.minimum(beyond / (margin + 1), 1.0)))
    return h / h.sum()


def _fir_axis(a: np.ndarray, sigma: float, d: float, axis: int) -> np.ndarray:
    """``a`` filtered along ``axis`` by :func:`fir_kernel` (content at ``i`` goes to ``i + d``), borders as a
    half-sample mirror; ``a`` itself when the filter is the identity."""
    if fir_radius(sigma, d) == 0:
        return a
    from scipy.ndimage import correlate1d  # ~0.3 s: only scenes with a spatial effect
    return correlate1d(a, fir_kernel(sigma, d)[::-1], axis=axis, mode="reflect")


def spatial_twin(image: np.ndarray, sigma: float, dx: float, dy: float) -> np.ndarray:
    """float64 twin of :func:`spatial_response` (finite images): the transfer function applied exactly, by FFTs
    along both axes, no finite filter."""
    img = np.asarray(image, dtype=np.float64)
    return _fft_axis(_fft_axis(img, sigma, dx, 1), sigma, dy, 0)


def spatial_response(image: np.ndarray, sigma: float, dx: float, dy: float) -> np.ndarray:
    """``image`` (rows, cols) blurred by a Gaussian of ``sigma`` and moved by ``(dx, dy)`` (content at x goes to
    x + dx), all in input pixels, in float64: the finite filter :func:`fir_kernel` along rows (``sigma``, ``dx``),
    then along columns (``sigma``, ``dy``); borders act as a half-sample mirror (``scipy.ndimage`` mode
    ``reflect``). An output pixel depends on the input pixels within :func:`fir_radius` of it along each axis and
    on no other: a NaN input pixel makes NaN exactly the output pixels that reach it."""
    img = np.asarray(image, dtype=np.float64)
    return _fir_axis(_fir_axis(img, sigma, dx, 1), sigma, dy, 0)


def lagrange(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Lagrange basis ``(len(nodes), len(x))``: row j is l_j(x), so Σ_j l_j(x)·f(nodes_j) interpolates f."""
    nodes, x = np.asarray(nodes, dtype=np.float64), np.asarray(x, dtype=np.float64)
    out = np.ones((nodes.size, x.size))
    for j, nj in enumerate(nodes):
        for m, nm in enumerate(nodes):
            if m != j:
                out[j] *= (x - nm) / (nj - nm)
    return out


def moved_weights(band: Band, grid: SpectralGrid, shift_nm: float, width_factor: float, support: float,
                  source: str | None = None) -> BandWeights:
    """Weights of ``band``'s SRF moved by ``shift_nm`` and stretched about its centre by ``width_factor``
    (a tabulated SRF has its wavelength axis moved and stretched)."""
    c = band.centre_nm
    tab = band.tabulated
    if tab is not None:
        tab = TabulatedResponse(c + (tab.wavelengths_nm - c) * width_factor + shift_nm, tab.response, tab.origin)
    return band_weights(grid, name=band.name, centre_nm=c + shift_nm, fwhm_nm=band.fwhm_nm * width_factor,
                        tabulated=tab, support=support, source=source)


def _nodes(values: np.ndarray) -> np.ndarray:
    """Interpolation nodes spanning ``values``: one when they do not vary, else :data:`SMILE_NODES` Chebyshev
    (Lobatto) nodes from min to max."""
    lo, hi = float(values.min()), float(values.max())
    if hi - lo < 1e-12:
        return np.array([lo])
    return 0.5 * (lo + hi) - 0.5 * (hi - lo) * np.cos(np.pi * np.arange(SMILE_NODES) / (SMILE_NODES - 1))


@dataclass(frozen=True)
class Smile:
    """Centre shift (nm) and width factor per column of an image ``cols`` wide."""

    shift_nm: np.ndarray
    width_factor: np.ndarray

    @classmethod
    def of(cls, spec: SmileSpec, cols: int) -> Smile:
        x = 2.0 * (np.arange(cols) + 0.5) / cols - 1.0
        shift = np.polynomial.polynomial.polyval(x, spec.centre_nm)
        width = 1.0 + np.polynomial.polynomial.polyval(x, spec.width_pct) / 100.0
        return cls(np.atleast_1d(shift), np.atleast_1d(width))

    def node_grid(self) -> tuple[np.ndarray, np.ndarray]:
        """(centre-shift nodes, width-factor nodes)."""
        return _nodes(self.shift_nm), _nodes(self.width_factor)

    def plan(self, bands: tuple[Band, ...], grid: SpectralGrid, support: float) -> ResamplePlan:
        """Every band at every node SRF on ``grid`` (band-major, then centre node, then width node): ``B4~smile3``."""
        cn, wn = self.node_grid()
        names, weights = [], []
        for band in bands:
            for i, (c, w) in enumerate((c, w) for c in cn for w in wn):
                names.append(f"{band.name}~smile{i}")
                weights.append(moved_weights(band, grid, c, w, support))
        return ResamplePlan(tuple(names), tuple(weights), grid.size)

    def combine(self, nodes: np.ndarray, n_bands: int, rows: int, cols: int) -> np.ndarray:
        """Band radiance ``(n_bands, rows, cols)`` from the node values ``(n_bands · n_nodes, rows · cols)``."""
        cn, wn = self.node_grid()
        lc, lw = lagrange(cn, self.shift_nm), lagrange(wn, self.width_factor)  # (nodes, cols)
        coef = (lc[:, None, :] * lw[None, :, :]).reshape(cn.size * wn.size, cols)
        v = nodes.reshape(n_bands, cn.size * wn.size, rows, cols)
        return np.einsum("knrc,nc->krc", v.astype(np.float64), coef).astype(nodes.dtype)


class SmileResampler:
    """The smile's node bands compiled once for an image ``cols`` wide: :meth:`nodes` resamples spectra to every
    band's node values, :meth:`combine` interpolates each column's bands from them."""

    def __init__(self, rt: Runtime, parts: ChainParts, cols: int, table: GridInterpolation | None = None):
        self.smile = Smile.of(Instrument.of(parts.settings, parts.run.seed, parts.sensor.bands).smile_spec, cols)
        self.n_bands, self.cols = parts.sensor.size, cols
        plan = self.smile.plan(parts.sensor.bands, parts.grid, parts.run.support)
        self.resampler = Resampler(rt, plan, parts.run.precision, parts.atmosphere, interpolation=table)

    def nodes(self, spectra: np.ndarray) -> np.ndarray:
        """Node band values ``(n_bands · n_nodes, n)`` of spectra on the grid (at the native wavelengths: ``table``)."""
        return self.resampler(spectra)

    def combine(self, nodes: np.ndarray) -> np.ndarray:
        """Band radiance ``(n_bands, rows, cols)`` from node values of whole rows (any shape holding
        ``n_bands · n_nodes × rows × cols`` values in that order)."""
        rows = nodes.size // (nodes.shape[0] * self.cols)
        return self.smile.combine(nodes.reshape(nodes.shape[0], rows * self.cols), self.n_bands, rows, self.cols)


def smile_radiance(rt: Runtime, parts: ChainParts, spectra: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Band radiance ``(n_bands, rows, cols)`` of the spectra ``(rows · cols, n_wavelengths)`` with the chain's
    smile (and its atmosphere, :attr:`ChainParts.atmosphere`): one resampling pass over the node SRFs, then
    per-column interpolation."""
    smile = SmileResampler(rt, parts, cols)
    return smile.combine(smile.nodes(spectra))


def smile_twin(parts: ChainParts, spectra: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """float64 numpy twin of :func:`smile_radiance` (spectra already radiance): each column integrated over its
    own moved SRF, no interpolation."""
    smile = Smile.of(Instrument.of(parts.settings, parts.run.seed, parts.sensor.bands).smile_spec, cols)
    cube = np.asarray(spectra, dtype=np.float64).reshape(rows, cols, -1)
    out = np.empty((parts.sensor.size, rows, cols))
    for k, band in enumerate(parts.sensor.bands):
        for c in range(cols):
            w = moved_weights(band, parts.grid, smile.shift_nm[c], smile.width_factor[c], parts.run.support)
            out[k, :, c] = w.apply(cube[:, c, :])
    return out


@dataclass(frozen=True)
class Instrument:
    """The image effects (a scene's ``[effects]`` psf, coregistration, smile, nonuniformity), resolved per band
    (band order of the sensor)."""

    effects: Any
    seed: int
    band_names: tuple[str, ...]
    lref: tuple[float, ...]

    @classmethod
    def of(cls, settings: Any, seed: int, bands: tuple[Band, ...] | list[Band]) -> Instrument:
        """The effects of the ``[effects]`` section ``settings`` on ``bands``, drawn from the noise ``seed``."""
        return cls(settings, seed, tuple(b.name for b in bands), tuple(b.lref for b in bands))

    @property
    def psf(self) -> PsfSpec | None:
        return setting(self.effects.psf, PsfSpec)  # type: ignore[return-value]

    @property
    def coregistration(self) -> CoregistrationSpec | None:
        return setting(self.effects.coregistration, CoregistrationSpec)  # type: ignore[return-value]

    @property
    def smile_spec(self) -> SmileSpec | None:
        return setting(self.effects.smile, SmileSpec)  # type: ignore[return-value]

    @property
    def nonuniformity(self) -> NonUniformitySpec | None:
        return setting(self.effects.nonuniformity, NonUniformitySpec)  # type: ignore[return-value]

    def describe(self) -> str:
        """The image effects that are on, or ``ideal``."""
        on = [n for n, v in (("psf", self.psf), ("coregistration", self.coregistration), ("smile", self.smile_spec),
                             ("nonuniformity", self.nonuniformity)) if v is not None]
        return ", ".join(on) if on else "ideal"

    def _lookup(self, table: dict, k: int):
        name = self.band_names[k].lower()
        return next((v for b, v in table.items() if b.lower() == name), None)

    def psf_sigma(self, k: int) -> float | None:
        """Band ``k``'s Gaussian PSF σ in band pixels (from its FWHM, or from its MTF at Nyquist with the box
        average), None when the PSF is off."""
        psf = self.psf
        if psf is None:
            return None
        v = psf.value(self.band_names[k])
        return v * FWHM_TO_SIGMA if psf.unit == "fwhm" else gaussian_sigma(v)

    def shift(self, k: int) -> tuple[float, float] | None:
        """Band ``k``'s shift (dx, dy) in band pixels, None when co-registration error is off."""
        spec = self.coregistration
        if spec is None:
            return None
        given = self._lookup(spec.shifts, k)
        if given is not None:
            return float(given[0]), float(given[1])
        angle = np.random.default_rng([self.seed, _COREG_TAG, k]).uniform(0.0, 2.0 * math.pi)
        r = spec.px
        return r * math.cos(angle), r * math.sin(angle)

    @property
    def spatial_on(self) -> bool:
        return self.psf is not None or self.coregistration is not None

    def response(self, k: int, factor: int) -> tuple[float, float, float]:
        """Band ``k``'s Gaussian σ and shift ``(dx, dy)`` in input pixels (``factor`` input pixels per band pixel),
        0 for an effect that is off: what its filter (:func:`spatial_response`) and its reach are made of."""
        sigma, (dx, dy) = self.psf_sigma(k) or 0.0, self.shift(k) or (0.0, 0.0)
        return sigma * factor, dx * factor, dy * factor

    def reach(self, ids: list[int], factor: int) -> tuple[int, int]:
        """Input pixels ``(rows, cols)`` the filters of bands ``ids`` (``factor`` input pixels per band pixel) reach
        on each side along columns and along rows: the longest :func:`fir_radius` per axis, ``(0, 0)`` when the
        spatial effects are off. No input pixel farther away enters an output pixel."""
        if not self.spatial_on:
            return 0, 0
        rows = cols = 0
        for k in ids:
            sigma, dx, dy = self.response(k, factor)
            rows, cols = max(rows, fir_radius(sigma, dy)), max(cols, fir_radius(sigma, dx))
        return rows, cols

    def spatial(self, image: np.ndarray, k: int, factor: int) -> np.ndarray:
        """Band ``k``'s image on the input grid through its PSF and shift (``factor`` input pixels per band
        pixel), in ``image``'s dtype; returned untouched when both are off."""
        if not self.spatial_on:
            return image
        return spatial_response(image, *self.response(k, factor)).astype(image.dtype, copy=False)

    def column_response(self, k: int, cols: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Band ``k``'s per-column (gain, offset) as the product sees them — ``L' = gain · L + offset`` on the
        band's grid of ``cols`` columns — or None when non-uniformity is off."""
        s = self.nonuniformity
        if s is None:
            return None
        z = np.random.default_rng([self.seed, _NU_TAG, k]).standard_normal((4, cols))
        lref = self.lref[k]
        g = 1.0 + s.gain_pct / 100.0 * z[0]
        o = s.offset_pct / 100.0 * lref * z[1]
        if not s.equalised:
            return g, o
        eps = s.residual_gain_pct / 100.0 * z[2]
        delta = s.residual_offset_pct / 100.0 * lref * z[3]
        return 1.0 / (1.0 + eps), -delta / (g * (1.0 + eps))

    def band_attrs(self, k: int) -> dict[str, float | str]:
        """What the image effects did to band ``k``, as attributes of its variables (empty when ideal)."""
        attrs: dict[str, float | str] = {}
        sigma, shift, psf = self.psf_sigma(k), self.shift(k), self.psf
        if psf is not None and sigma is not None:
            v = psf.value(self.band_names[k])
            attrs.update({"psf_fwhm_px" if psf.unit == "fwhm" else "mtf_nyquist": v, "psf_sigma_px": sigma})
        if shift is not None:
            attrs.update(shift_x_px=shift[0], shift_y_px=shift[1])
        smile = self.smile_spec
        if smile is not None:
            attrs.update(smile_centre_nm=", ".join(f"{c:g}" for c in smile.centre_nm),
                         smile_width_pct=", ".join(f"{c:g}" for c in smile.width_pct))
        return attrs

    def columns(self, images: np.ndarray, ids: list[int]) -> np.ndarray:
        """Band images ``(len(ids), rows, cols)`` with their per-column response; returned untouched when off."""
        if self.nonuniformity is None:
            return images
        out = np.empty_like(images)
        for j, k in enumerate(ids):
            gain, offset = self.column_response(k, images.shape[2])  # type: ignore[misc]
            out[j] = (images[j].astype(np.float64) * gain[None, :] + offset[None, :]).astype(images.dtype)
        return out
