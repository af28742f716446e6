"""float64 numpy oracles of the forward chain: resampling, noise, quantisation, calibration."""

from __future__ import annotations

import numpy as np

from s2cl.atmos.correction import toa
from s2cl.forward.noise import add_noise as host_noise
from s2cl.forward.sense import Radiometry
from s2cl.reference import stages
from s2cl.sensor.srf import BandWeights
from s2cl.status import PixelFlag


def resample(spectra: np.ndarray, weights: list[BandWeights] | tuple[BandWeights, ...]) -> np.ndarray:
    """Band values ``(n_bands, n_pixels)``: Σ w·spectrum over each band's support, float64."""
    return np.stack([w.apply(spectra) for w in weights])


def toa_radiance(rho: np.ndarray, path_radiance: np.ndarray, ground_term: np.ndarray,
                 spherical_albedo: np.ndarray) -> np.ndarray:
    """L = Lp + G·ρ / (1 − S·ρ) per wavelength (W m⁻² sr⁻¹ µm⁻¹), float64 (the product's host formula)."""
    return toa(rho, path_radiance, ground_term, spherical_albedo)


def add_noise(radiance: np.ndarray, r: Radiometry, seed: int, pixel_offset: int = 0, frame: int = 0) -> np.ndarray:
    """Radiance plus σ(L)·z with the kernel's counter-based normals (the product's host noise)."""
    return host_noise(radiance, r.noise_a, r.noise_b, r.band_ids, seed, pixel_offset, frame)


def quantise(radiance: np.ndarray, r: Radiometry) -> tuple[np.ndarray, np.ndarray]:
    """DN (uint16) with ties rounding up, and clipped counts ``(2, n_bands)`` (below Lmin or NaN, above Lmax)."""
    dn, flags = stages.quantise(radiance, r.lmin[:, None], r.lmax[:, None], r.maxdn)
    low = (flags & (PixelFlag.LOW | PixelFlag.NODATA)) != 0
    high = (flags & PixelFlag.HIGH) != 0
    return dn.astype(np.uint16), np.stack([low.sum(axis=1), high.sum(axis=1)])


def calibrate(dn: np.ndarray, r: Radiometry) -> np.ndarray:
    """Radiance from DN: Lmin + DN · gain."""
    return r.lmin[:, None] + np.asarray(dn, dtype=np.float64) * r.gain[:, None]
