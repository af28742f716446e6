"""The two atmospheric profiles s2cl's look-up table uses, and their gas columns (no 6S needed).

6S's predefined mid-latitude summer and winter atmospheres (McClatchey et al. 1972) ship as a
table in ``s2cl/data/sixs_profiles.csv`` (34 levels: altitude, pressure, temperature, H2O and O3
density). To vary water vapour and ozone while keeping each profile's vertical shape, the builder
hands 6S this table as a user profile with the H2O and O3 densities scaled; 6S's own
``UserWaterAndOzone`` option would instead rescale the US-1962 shape, which changes path radiance
at 945 and 1375 nm by 11-30 % (see the project notes on 6S).
"""

from __future__ import annotations

import csv
import importlib.resources
from dataclasses import dataclass
from functools import cache

import numpy as np

from s2cl.errors import InputError

PROFILES: tuple[str, ...] = ("midlatitude_summer", "midlatitude_winter")
"""Profile names, as :class:`s2cl.atmos.state.AtmosphereState` takes them."""

_DATA_FILE = "sixs_profiles.csv"

# Constants 6S uses to turn densities into columns: molar masses over the molar volume at STP
# (kg/m3), g in the units that give g/cm2 from a pressure in mb.
_AIR_DENSITY_STP = 0.028964 / 0.0224
_OZONE_DENSITY_STP = 0.048 / 0.0224
_G = 98.1


@dataclass(frozen=True)
class Profile:
    """One atmosphere: arrays of shape ``(34,)``, float64, from the ground (level 0) up.

    :param altitude_km: level altitude (km); the top level is 6S's 99999 km sentinel.
    :param pressure_mb: pressure (mb = hPa).
    :param temperature_k: temperature (K).
    :param h2o_g_m3: water-vapour density (g/m3).
    :param o3_g_m3: ozone density (g/m3).
    """

    name: str
    altitude_km: np.ndarray
    pressure_mb: np.ndarray
    temperature_k: np.ndarray
    h2o_g_m3: np.ndarray
    o3_g_m3: np.ndarray

    @property
    def water_column(self) -> float:
        """Total water-vapour column, g/cm2 (2.93 for summer, 0.857 for winter)."""
        return _column_g_cm2(self, self.h2o_g_m3)

    @property
    def ozone_column(self) -> float:
        """Total ozone column, Dobson units (319 for summer, 397 for winter)."""
        cm_atm = _column_g_cm2(self, self.o3_g_m3) / (_OZONE_DENSITY_STP * 1e-3)
        return 1000.0 * cm_atm

    def sixs_user_profile(self, water_scale: float = 1.0, ozone_scale: float = 1.0) -> str:
        """The profile as 6S input lines (atmospheric model 7, user profile), H2O and O3 scaled.

        With both scales 1 it reproduces 6S's predefined profile exactly (checked in the tests).
        """
        lines = ["7 User's data base profile"]
        for i in range(self.altitude_km.size):
            lines.append(
                f"{np.float32(self.altitude_km[i])} {np.float32(self.pressure_mb[i])} "
                f"{np.float32(self.temperature_k[i])} {self.h2o_g_m3[i] * water_scale:.7e} "
                f"{self.o3_g_m3[i] * ozone_scale:.7e}"
            )
        return "\n".join(lines)


def _column_g_cm2(profile: Profile, density_g_m3: np.ndarray) -> float:
    """Column of a gas (g/cm2) by hydrostatic integration of its mass mixing ratio over pressure.

    The levels below 100 km count (the 99999 km sentinel is left out). This is the integration 6S
    prints for its profiles: 2.93 g/cm2 and 0.319 cm-atm for mid-latitude summer.
    """
    p = profile.pressure_mb[:-1]
    t = profile.temperature_k[:-1]
    air = _AIR_DENSITY_STP * 273.16 * p / (1013.25 * t)
    mixing = density_g_m3[:-1] / (air * 1000.0)
    dp = (p[:-1] - p[1:]) / p[0]
    return float(np.sum(0.5 * (mixing[1:] + mixing[:-1]) * dp) * p[0] * 100.0 / _G)


@cache
def _table() -> dict[str, Profile]:
    text = (importlib.resources.files("s2cl") / "data" / _DATA_FILE).read_text(encoding="utf-8")
    rows = [line for line in text.splitlines() if line and not line.startswith("#")]
    columns: dict[str, dict[str, list[float]]] = {}
    for row in csv.DictReader(rows):
        cols = columns.setdefault(row["profile"], {})
        for key in ("altitude_km", "pressure_mb", "temperature_k", "h2o_g_m3", "o3_g_m3"):
            cols.setdefault(key, []).append(float(row[key]))
    return {
        name: Profile(name=name, **{k: np.asarray(v, dtype=np.float64) for k, v in cols.items()})
        for name, cols in columns.items()
    }


def get_profile(name: str) -> Profile:
    """The profile called ``name`` (one of :data:`PROFILES`).

    :raises InputError: for another name, listing the allowed ones.
    """
    table = _table()
    if name not in table:
        raise InputError(f"unknown atmospheric profile {name!r}; allowed: {', '.join(PROFILES)}", key="profile")
    return table[name]
