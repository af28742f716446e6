"""Band-effective atmospheric terms and the inverse effect: calibrated band radiance → reflectance.

The atmosphere acts per wavelength (``L = Lp + G·ρ / (1 − S·ρ)``); a sensor only sees band
averages. The correction uses band-effective terms, SRF-weighted from the per-wavelength terms
of the (assumed) atmospheric state::

    Lp_k = Σ w·Lp,   G_k = Σ w·G,   S_k = Σ w·G·S / Σ w·G   (S weighted by the ground signal)

and inverts ``y = (L − Lp_k) / G_k``, ``ρ_k = y / (1 + S_k·y)``. For spectrally flat targets this
recovers ρ up to the covariance of G and S inside the band (the "band-averaging residual",
reported by ``s2cl residuals``). A denominator ``1 + S·y`` below 1e-6 (unphysical
radiance far below the path radiance) is clamped, so the result stays finite.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from s2cl.sensor.srf import BandWeights

MIN_DENOMINATOR = 1e-6


class Terms(Protocol):
    path_radiance: np.ndarray
    ground_term: np.ndarray
    spherical_albedo: np.ndarray


@dataclass(frozen=True, eq=False)
class BandAtmosphere:
    """Band-effective terms, float64 arrays ``(n_bands,)``; radiances in W m⁻² sr⁻¹ µm⁻¹."""

    path_radiance: np.ndarray
    ground_term: np.ndarray
    spherical_albedo: np.ndarray

    @classmethod
    def of(cls, terms: Terms, weights: list[BandWeights] | tuple[BandWeights, ...]) -> BandAtmosphere:
        lp, g, s = (np.asarray(getattr(terms, n), dtype=np.float64)
                    for n in ("path_radiance", "ground_term", "spherical_albedo"))
        out_lp, out_g, out_s = [], [], []
        for w in weights:
            sl = slice(w.start, w.stop)
            gw = w.weights * g[sl]
            out_lp.append(w.weights @ lp[sl])
            out_g.append(gw.sum())
            out_s.append(gw @ s[sl] / gw.sum() if gw.sum() > 0 else w.weights @ s[sl])
        return cls(np.array(out_lp), np.array(out_g), np.array(out_s))

    @property
    def n_bands(self) -> int:
        return int(self.path_radiance.size)

    def reflectance(self, radiance: np.ndarray) -> np.ndarray:
        """Band reflectance from band radiance ``(n_bands, …)`` (:func:`correct`, float64)."""
        shape = (-1,) + (1,) * (np.ndim(radiance) - 1)
        return correct(radiance, self.path_radiance.reshape(shape), self.ground_term.reshape(shape),
                       self.spherical_albedo.reshape(shape))

    def radiance(self, reflectance: np.ndarray) -> np.ndarray:
        """Band radiance of a band reflectance (the band-level forward model, :func:`toa`)."""
        shape = (-1,) + (1,) * (np.ndim(reflectance) - 1)
        return toa(reflectance, self.path_radiance.reshape(shape), self.ground_term.reshape(shape),
                   self.spherical_albedo.reshape(shape))


def toa(rho: np.ndarray, lp: np.ndarray, g: np.ndarray, s: np.ndarray) -> np.ndarray:
    """TOA radiance ``Lp + G·ρ / (1 − S·ρ)`` (W m⁻² sr⁻¹ µm⁻¹, float64; arguments broadcast): per
    wavelength with the 6S terms, or per band with band-effective ones. The resampling kernel's
    atmosphere effect computes the same per wavelength."""
    rho = np.asarray(rho, dtype=np.float64)
    return lp + g * rho / (1.0 - s * rho)


def correct(radiance: np.ndarray, lp: np.ndarray, g: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The correction inverse on the host, float64: ``ρ = y / max(1 + S·y, 1e-6)``, ``y = (L − Lp) / G``
    (arguments broadcast). The same rule as the device stage ``s2_correct`` (kernels/common/stages.mako),
    including the clamp that keeps unphysical radiance far below the path radiance finite; NaN stays NaN."""
    y = (np.asarray(radiance, dtype=np.float64) - lp) / g
    d = 1.0 + s * y
    with np.errstate(invalid="ignore"):
        return y / np.where(d > MIN_DENOMINATOR, d, MIN_DENOMINATOR)
