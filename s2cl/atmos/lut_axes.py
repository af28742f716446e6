"""What an atmosphere LUT covers (:class:`LUTAxes`): profiles, AOT550, solar zenith (deg), water vapour (g/cm2),
ozone (DU) and the wavelength range (nm, on 6S's 2.5 nm grid), with the shipped LUT's nodes as defaults."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.atmos.sixs import SIXS_GRID_START_UM, SIXS_GRID_STEP_UM, on_sixs_grid
from s2cl.atmos.sixs_profiles import PROFILES, get_profile
from s2cl.errors import InputError

DEFAULT_AOT550: tuple[float, ...] = (0.0, 0.05, 0.1, 0.15, 0.2, 0.23472, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0)
"""AOT nodes; 0.23472 is 6S's continental AOT550 for the paper's 23 km visibility."""

DEFAULT_SOLAR_ZENITH: tuple[float, ...] = (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0)
"""Solar zenith nodes (deg)."""

DEFAULT_WATER_VAPOUR: tuple[float, ...] = (
    0.17, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.25, 1.5, 1.75,
    2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.75, 6.6,
)  # fmt: skip
"""Water-vapour nodes (g/cm2) at the reference zenith 40 deg: 0.2-5 g/cm2 at any zenith 0-60 deg
maps into 0.17-6.6 g/cm2 there (equal slant column)."""


@dataclass(frozen=True)
class LUTAxes:
    """What a LUT covers.

    :param profiles: atmospheric profiles.
    :param aot550: aerosol optical thickness nodes (continental aerosol); the first must be 0.
    :param solar_zenith: solar zenith nodes (deg); must contain ``reference_zenith``.
    :param water_vapour: water-vapour column nodes (g/cm2) at ``reference_zenith``.
    :param reference_zenith: zenith (deg) of the water and ozone tables.
    :param ozone_reference: ozone column (DU) of the ozone table; others follow Beer's law.
    :param ozone_range: ozone columns (DU) a state may ask for.
    :param wavelength_range_nm: first and last wavelength (nm), both on 6S's 2.5 nm grid.
    :param month: month of the runs' date; day: its day (E0 is rescaled to 1 AU anyway).
    """

    profiles: tuple[str, ...] = PROFILES
    aot550: tuple[float, ...] = DEFAULT_AOT550
    solar_zenith: tuple[float, ...] = DEFAULT_SOLAR_ZENITH
    water_vapour: tuple[float, ...] = DEFAULT_WATER_VAPOUR
    reference_zenith: float = 40.0
    ozone_reference: float = 330.0
    ozone_range: tuple[float, float] = (200.0, 500.0)
    wavelength_range_nm: tuple[float, float] = (400.0, 2500.0)
    month: int = 4
    day: int = 5

    def __post_init__(self) -> None:
        for name in self.profiles:
            get_profile(name)
        for key in ("aot550", "solar_zenith", "water_vapour"):
            values = np.asarray(getattr(self, key), dtype=np.float64)
            if values.ndim != 1 or values.size < 1 or not np.all(np.isfinite(values)):
                raise InputError("needs one or more finite values", key=f"axes.{key}")
            if np.any(np.diff(values) <= 0):
                raise InputError(f"must be strictly increasing, got {list(values)}", key=f"axes.{key}")
        if self.aot550[0] != 0.0:
            raise InputError(f"must start at 0 (the Rayleigh-only node), got {self.aot550[0]}", key="axes.aot550")
        if not (0.0 <= self.solar_zenith[0] and self.solar_zenith[-1] <= 75.0):
            raise InputError(f"allowed 0-75 deg, got {list(self.solar_zenith)}", key="axes.solar_zenith")
        if self.reference_zenith not in self.solar_zenith:
            raise InputError(f"{self.reference_zenith} is not a solar_zenith node", key="axes.reference_zenith")
        if self.water_vapour[0] <= 0:
            raise InputError("must be > 0 g/cm2", key="axes.water_vapour")
        lo, hi = self.wavelength_range_nm
        if not (400.0 <= lo < hi <= 2500.0) or not (on_sixs_grid(lo / 1000) and on_sixs_grid(hi / 1000)):
            raise InputError(
                f"needs 400 <= first < last <= 2500 nm, both multiples of 2.5 nm; got {lo}-{hi}",
                key="axes.wavelength_range_nm",
            )
        if not 0 < self.ozone_range[0] <= self.ozone_reference <= self.ozone_range[1]:
            raise InputError("needs 0 < min <= ozone_reference <= max", key="axes.ozone_range")

    @property
    def sixs_wavelengths_um(self) -> np.ndarray:
        """6S grid wavelengths (um) covering the range, float64."""
        lo, hi = (w / 1000 for w in self.wavelength_range_nm)
        k0 = round((lo - SIXS_GRID_START_UM) / SIXS_GRID_STEP_UM)
        k1 = round((hi - SIXS_GRID_START_UM) / SIXS_GRID_STEP_UM)
        return np.round(SIXS_GRID_START_UM + SIXS_GRID_STEP_UM * np.arange(k0, k1 + 1), 6)

    @property
    def wavelengths_nm(self) -> np.ndarray:
        """The LUT's 1 nm grid, float64."""
        lo, hi = self.wavelength_range_nm
        return np.arange(round(lo), round(hi) + 1, dtype=np.float64)

