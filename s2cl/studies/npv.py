"""Non-photosynthetic vegetation (NPV: litter, dry leaves, wood) against soil: linear mixtures of measured
end-members and the two indices that estimate the NPV fraction from SWIR reflectance.

- **CAI**, the cellulose absorption index (Nagler, Daughtry & Goward 2000, *Remote Sens. Environ.* 71,
  207–215; Daughtry 2001): ``CAI = 0.5 (ρ2.0 + ρ2.2) − ρ2.1``, the depth of the cellulose/lignin absorption
  near 2.1 µm below the line of its shoulders at 2.0 and 2.2 µm (Nagler's bands 2019–2039, 2091–2111 and
  2199–2219 nm; reflectance unitless, so the CAI is too). Dry plant material has a positive CAI, soils a
  CAI near zero or negative, green vegetation a negative one (its water absorbs at 2.0 µm).
- **NDTI**, the normalised difference tillage index (van Deventer et al. 1997, *Photogramm. Eng. Remote
  Sens.* 63, 87–93): ``(ρ_B11 − ρ_B12) / (ρ_B11 + ρ_B12)`` with the Landsat TM/Sentinel-2 SWIR bands, what a
  sensor without a 2.1 µm band has.

Mixtures are linear in reflectance (a checkerboard of pure patches below the sensor's resolution).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from s2cl.atmos.correction import toa
from s2cl.atmos.terms import AtmosphericTerms
from s2cl.sensor.srf import BandWeights


@dataclass(frozen=True)
class Mixtures:
    """Linear mixtures: ``reflectance (n, n_wl)`` with the true fractions ``f_npv``, ``f_green`` (and soil
    ``1 − f_npv − f_green``), each ``(n,)``, and which soil / NPV / green spectrum each mixture holds."""

    reflectance: np.ndarray
    f_npv: np.ndarray
    f_green: np.ndarray
    soil: np.ndarray
    npv: np.ndarray
    green: np.ndarray

    @property
    def size(self) -> int:
        return int(self.f_npv.size)


def linear_mixtures(soil: np.ndarray, npv: np.ndarray, green: np.ndarray | None, npv_fractions: Sequence[float],
                    green_fractions: Sequence[float] = (0.0,)) -> Mixtures:
    """Every soil × NPV spectrum × NPV fraction × green fraction (in that order, the last fastest):
    ``ρ = f_npv ρ_npv + f_green ρ_green + (1 − f_npv − f_green) ρ_soil``.

    The soil–NPV pair ``p = i_soil · n_npv + i_npv`` takes green spectrum ``p mod n_green`` (each green
    spectrum in turn), so green vegetation adds variety without multiplying the count.

    :param soil, npv, green: reflectance spectra ``(n_k, n_wl)``; ``green`` may be None when every green
        fraction is 0.
    :raises ValueError: fractions outside [0, 1], or NPV + green above 1, or green fractions without spectra.
    """
    soil, npv = np.asarray(soil, dtype=np.float64), np.asarray(npv, dtype=np.float64)
    fn, fg = np.asarray(npv_fractions, dtype=np.float64), np.asarray(green_fractions, dtype=np.float64)
    if fn.size == 0 or fg.size == 0:
        raise ValueError("need at least one NPV fraction and one green fraction")
    if ((fn < 0) | (fn > 1)).any() or ((fg < 0) | (fg > 1)).any() or fn.max() + fg.max() > 1 + 1e-12:
        raise ValueError("fractions must lie in [0, 1] and NPV + green at most 1")
    if green is None:
        if (fg > 0).any():
            raise ValueError("green fractions above 0 need green spectra")
        green = np.zeros((1, soil.shape[1]))
    green = np.asarray(green, dtype=np.float64)
    i_soil, i_npv, k_n, k_g = np.meshgrid(np.arange(len(soil)), np.arange(len(npv)), np.arange(fn.size),
                                          np.arange(fg.size), indexing="ij")
    i_soil, i_npv, k_n, k_g = (a.ravel() for a in (i_soil, i_npv, k_n, k_g))
    i_green = (i_soil * len(npv) + i_npv) % len(green)
    f_npv, f_green = fn[k_n], fg[k_g]
    rho = (f_npv[:, None] * npv[i_npv] + f_green[:, None] * green[i_green]
           + (1.0 - f_npv - f_green)[:, None] * soil[i_soil])
    return Mixtures(rho, f_npv, f_green, i_soil, i_npv, i_green)


def cai(rho_20: np.ndarray, rho_21: np.ndarray, rho_22: np.ndarray) -> np.ndarray:
    """Cellulose absorption index ``0.5 (ρ2.0 + ρ2.2) − ρ2.1`` (Nagler et al. 2000), unitless."""
    return 0.5 * (np.asarray(rho_20, dtype=np.float64) + np.asarray(rho_22, dtype=np.float64)) - np.asarray(
        rho_21, dtype=np.float64)


def ndti(rho_b11: np.ndarray, rho_b12: np.ndarray) -> np.ndarray:
    """Normalised difference tillage index ``(ρ11 − ρ12) / (ρ11 + ρ12)`` (van Deventer et al. 1997); NaN
    where the sum is not positive (such a pixel is left out of the regression)."""
    a, b = np.asarray(rho_b11, dtype=np.float64), np.asarray(rho_b12, dtype=np.float64)
    s = a + b
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(s > 0, (a - b) / np.where(s > 0, s, 1.0), np.nan)


def band_radiance(terms: AtmosphericTerms, reflectance: np.ndarray, weights: BandWeights) -> np.ndarray:
    """Band TOA radiance (W m⁻² sr⁻¹ µm⁻¹) of reflectance spectra ``(..., n_wl)`` under ``terms``: the
    forward model ``Lp + Gρ/(1 − Sρ)`` (:func:`s2cl.atmos.correction.toa`) per wavelength, then the SRF
    weights; computed on the band's support only."""
    sl = slice(weights.start, weights.stop)
    L = toa(np.asarray(reflectance, dtype=np.float64)[..., sl], terms.path_radiance[sl], terms.ground_term[sl],
            terms.spherical_albedo[sl])
    return L @ weights.weights


def gas_signal_fraction(terms: AtmosphericTerms, gas: str, weights: BandWeights) -> float:
    """The fraction of a band's ground-reflected signal that ``gas`` lets through: ``Σ w G / Σ w G₀`` with
    ``G₀`` the ground term without the gas (:meth:`AtmosphericTerms.with_gas_column`), unitless."""
    sl = slice(weights.start, weights.stop)
    free = terms.with_gas_column(gas, 0.0)
    return float(weights.weights @ terms.ground_term[sl] / (weights.weights @ free.ground_term[sl]))
