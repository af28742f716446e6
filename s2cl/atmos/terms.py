"""Atmospheric terms of one state on a spectral grid (:class:`AtmosphericTerms`), float64, and the forward
(reflectance -> TOA radiance, W m-2 sr-1 um-1) and inverse (radiance -> reflectance) they give.

    L = Lp + G rho / (1 - S rho)

``Lp`` is the path radiance, ``G`` the ground term, ``S`` the spherical albedo (see :mod:`s2cl.atmos.atmosphere`
for how the LUT gives them).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from s2cl.atmos.correction import correct, toa
from s2cl.atmos.lut_format import FIXED_GASES
from s2cl.atmos.state import AtmosphereState
from s2cl.errors import InputError

GAS_NAMES: tuple[str, ...] = ("water", "ozone", *FIXED_GASES)
"""The gases of :attr:`AtmosphericTerms.transmittance`."""


@dataclass(frozen=True, eq=False)
class AtmosphericTerms:
    """Atmospheric terms on a spectral grid, all float64 arrays of shape ``(n_wl,)``.

    :param wavelength_nm: wavelengths, nm.
    :param path_radiance: Lp, W m-2 sr-1 um-1.
    :param ground_term: G, W m-2 sr-1 um-1 (per unit reflectance).
    :param spherical_albedo: S, unitless.
    :param e0: exo-atmospheric irradiance at 1 AU, W m-2 um-1.
    :param mu_s: cosine of the solar zenith angle.
    :param path_reflectance: rho_path = pi Lp / (mu_s E0).
    :param t_gas: two-way transmittance of all gases.
    :param t_down: downward (sun to ground) scattering transmittance, direct + diffuse.
    :param t_up: upward (ground to nadir sensor) scattering transmittance, direct + diffuse.
    :param transmittance: two-way transmittance per gas (:data:`GAS_NAMES`).
    :param state: the state these terms are for.
    :param method: the interpolation used.
    """

    wavelength_nm: np.ndarray
    path_radiance: np.ndarray
    ground_term: np.ndarray
    spherical_albedo: np.ndarray
    e0: np.ndarray
    mu_s: float
    path_reflectance: np.ndarray
    t_gas: np.ndarray
    t_down: np.ndarray
    t_up: np.ndarray
    transmittance: Mapping[str, np.ndarray]
    state: AtmosphereState
    method: str

    @property
    def t_water(self) -> np.ndarray:
        """Two-way water-vapour transmittance."""
        return self.transmittance["water"]

    @property
    def t_ozone(self) -> np.ndarray:
        """Two-way ozone transmittance."""
        return self.transmittance["ozone"]

    @property
    def t_methane(self) -> np.ndarray:
        """Two-way methane transmittance."""
        return self.transmittance["methane"]

    def _along_grid(self, values, name: str) -> np.ndarray:
        """``values`` as float64, refused unless its last axis is the grid (or it is a scalar)."""
        arr = np.asarray(values, dtype=np.float64)
        if arr.ndim > 0 and arr.shape[-1] != self.wavelength_nm.size:
            raise InputError(
                f"last axis must have the grid's {self.wavelength_nm.size} wavelengths, got shape {arr.shape}", key=name
            )
        return arr

    def toa_radiance(self, rho) -> np.ndarray:
        """Forward: TOA radiance (W m-2 sr-1 um-1) of Lambertian reflectance ``rho``.

        :param rho: reflectance, scalar or array ``(..., n_wl)``.
        :returns: float64 array broadcast to ``(..., n_wl)``.
        """
        return toa(self._along_grid(rho, "rho"), self.path_radiance, self.ground_term, self.spherical_albedo)

    def surface_reflectance(self, radiance) -> np.ndarray:
        """Inverse: Lambertian surface reflectance from TOA radiance ``(..., n_wl)``.

        ``y = (L - Lp) / G``, ``rho = y / (1 + S y)`` (:func:`s2cl.atmos.correction.correct`, per wavelength).
        Where G is 0 (fully absorbed) the result is NaN.
        """
        radiance = self._along_grid(radiance, "radiance")
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = correct(radiance, self.path_radiance, self.ground_term, self.spherical_albedo)
        return np.where(self.ground_term > 0, rho, np.nan)

    def toa_reflectance(self, rho) -> np.ndarray:
        """Forward in reflectance units: pi L / (mu_s E0)."""
        return np.pi * self.toa_radiance(rho) / (self.mu_s * self.e0)


    def with_gas_column(self, gas: str, factor: float) -> AtmosphericTerms:
        """These terms with the column of ``gas`` scaled by ``factor`` (unitless; 0 removes the gas, see below): its
        optical depth −ln T scales by ``factor``, i.e. ``T → T**factor``.

        Only a gas that all of the path radiance and the ground term carry (every gas but water: the LUT's
        formula puts water above the aerosol, :mod:`s2cl.atmos.atmosphere`): then Lp, ρ_path and G scale by
        ``T**(factor − 1)`` and S is unchanged, exactly for that formula. Scaling the optical depth is the
        same assumption the LUT makes between solar-zenith nodes (ln T linear in the air mass); 6S's band
        model is not exactly Beer's law, so a factor far from 1 is an approximation. Where 6S gives the gas a
        transmittance of exactly 0, the terms there hold nothing to restore: they stay 0 for every factor
        (``factor = 0`` removes the gas everywhere else).
        """
        if gas not in self.transmittance or gas == "water":
            allowed = ", ".join(g for g in self.transmittance if g != "water")
            raise InputError(f"cannot scale {gas!r}; gases: {allowed}", key="gas")
        if not (math.isfinite(factor) and factor >= 0):
            raise InputError(f"must be a finite number >= 0, got {factor}", key="factor")
        t = np.asarray(self.transmittance[gas], dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(t > 0, np.power(np.where(t > 0, t, 1.0), factor - 1.0), 0.0 if factor > 0 else 1.0)
        trans = dict(self.transmittance)
        trans[gas] = t * ratio
        return replace(self, path_radiance=self.path_radiance * ratio, ground_term=self.ground_term * ratio,
                       path_reflectance=self.path_reflectance * ratio, t_gas=self.t_gas * ratio, transmittance=trans)
