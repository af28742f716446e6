"""Atmosphere at run time: states, the shipped 6S look-up table, and float64 forward/inverse terms.

No Fortran is needed here: the LUT (``s2cl/data/atmosphere_lut.npz``) was built once with 6S
(:mod:`s2cl.atmos.lut_build`). For a state and a spectral grid, :meth:`AtmosphereLUT.terms` returns
per-wavelength terms with which

    L = Lp + G rho / (1 - S rho)            (W m-2 sr-1 um-1)

reproduces 6S's apparent radiance of a Lambertian target of reflectance rho:
``Lp = mu_s E0 rho_path / pi`` is the path radiance, ``G = mu_s E0 t_gas Td Tu / pi`` the ground
term, ``S`` the spherical albedo. The path reflectance is recombined as 6S does it (water vapour
above the aerosol): ``rho_path = R_R t_nw + (R - R_R) t_gas``, where ``R``/``R_R`` are the gas-free
path reflectances with and without aerosol, ``t_nw`` the two-way transmittance of all gases but
water and ``t_gas = t_water t_nw``.

Interpolation between LUT nodes (``method="linear"``):

- aerosol optical thickness: linear in AOT550 (``ln`` of the transmittances Td, Tu);
- solar zenith: linear in sec(theta_s) (``ln`` of Td and of the fixed-gas transmittances, i.e.
  Beer-like in airmass);
- water vapour: ``ln t_water`` linear in ``sqrt(u_eff)``, where ``u_eff = u * m(theta_s) / m(40 deg)``
  is the column with the same slant path at the reference zenith (6S's H2O band model depends on
  the slant column only);
- ozone: Beer's law, ``t_ozone = t_ref ** ((O3 / O3_ref) * (m / m_ref))`` (exact for 6S);
- profile: categorical (no interpolation).

``method="nearest"`` takes the nearest node in each axis instead (ozone stays Beer's law, mu_s
stays the state's): an accuracy/time knob. A state outside the LUT's axes raises
:class:`~s2cl.errors.InputError`; nothing is extrapolated.
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import json
import math
import numbers
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Literal

import numpy as np

from s2cl.atmos.lut_format import (
    ALBEDO_KEYS,
    AXIS_KEYS,
    FIXED_GASES,
    FORMAT_NAME,
    FORMAT_VERSION,
    SCATTERING_KEYS,
    fixed_gas_key,
)
from s2cl.atmos.sixs_profiles import PROFILES
from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid

Method = Literal["linear", "nearest"]
GAS_NAMES: tuple[str, ...] = ("water", "ozone", *FIXED_GASES)

DEFAULT_LUT_NAME = "atmosphere_lut.npz"
REBUILD_HINT = 'rebuild it with `python -m s2cl.atmos.lut_build -o FILE` (needs `pip install "s2cl[sixs]"`)'

# Visibility (km) -> AOT550 of 6S V1.1's continental aerosol, read from 6S's printed aerosol optical
# depth at 550 nm (5 decimals) for each visibility. Interpolated linearly in 1/visibility, which
# reproduces 6S within 4e-5 between these nodes (checked at 5.5-90 km).
_VISIBILITY_KM = (
    5,
    6,
    7,
    8,
    9,
    10,
    12,
    14,
    16,
    18,
    20,
    23,
    26,
    30,
    35,
    40,
    50,
    60,
    70,
    80,
    100,
    120,
    150,
    200,
    250,
    300,
)
_VISIBILITY_AOT550 = (
    0.77998, 0.66409, 0.58127, 0.51913, 0.47078, 0.43208, 0.37399, 0.33246, 0.30128, 0.27701, 0.25757,
    0.23472, 0.21711, 0.19906, 0.18226, 0.16961, 0.15180, 0.13982, 0.13117, 0.12462, 0.11527, 0.10887,
    0.10219, 0.09494, 0.08986, 0.08535,
)  # fmt: skip

PAPER_VISIBILITY_KM = 23.0
"""The paper's standard atmosphere: rural (here: 6S continental) aerosol, visibility 23 km."""


def visibility_to_aot550(visibility_km: float) -> float:
    """AOT at 550 nm of 6S's continental aerosol for a horizontal visibility (5-300 km).

    6S's own conversion (a Koschmieder extinction 3.912/V spread over its aerosol profile),
    tabulated from 6S V1.1 and interpolated linearly in 1/V.

    :raises InputError: outside 5-300 km.
    """
    v = float(visibility_km)
    if not (_VISIBILITY_KM[0] <= v <= _VISIBILITY_KM[-1]):
        raise InputError(
            f"{v:g} km is outside the tabulated {_VISIBILITY_KM[0]}-{_VISIBILITY_KM[-1]} km", key="visibility_km"
        )
    inv = 1.0 / np.asarray(_VISIBILITY_KM, dtype=np.float64)
    return float(np.interp(1.0 / v, inv[::-1], np.asarray(_VISIBILITY_AOT550)[::-1]))


def aot550_to_visibility(aot550: float) -> float:
    """Inverse of :func:`visibility_to_aot550` (km), for AOT550 in 0.08535-0.77998."""
    a = np.asarray(_VISIBILITY_AOT550)
    if not (a[-1] <= aot550 <= a[0]):
        raise InputError(f"{aot550:g} is outside {a[-1]}-{a[0]} (5-300 km)", key="aot550")
    inv = 1.0 / np.asarray(_VISIBILITY_KM, dtype=np.float64)
    return float(1.0 / np.interp(aot550, a[::-1], inv[::-1]))


PAPER_AOT550 = visibility_to_aot550(PAPER_VISIBILITY_KM)


def airmass(solar_zenith_deg: float, view_zenith_deg: float = 0.0) -> float:
    """Two-way geometric airmass 1/cos(theta_s) + 1/cos(theta_v)."""
    return 1.0 / math.cos(math.radians(solar_zenith_deg)) + 1.0 / math.cos(math.radians(view_zenith_deg))


@dataclass(frozen=True)
class AtmosphereState:
    """An atmospheric state; the defaults are the paper's standard atmosphere.

    :param profile: ``"midlatitude_summer"`` or ``"midlatitude_winter"``.
    :param water_vapour: water-vapour column, g/cm2 (paper: 1.5).
    :param aot550: aerosol optical thickness at 550 nm, continental aerosol (paper: visibility
        23 km, i.e. 0.2347; see :meth:`from_visibility`).
    :param ozone: ozone column, Dobson units (the paper's assumed 330 DU).
    :param solar_zenith: solar zenith angle, deg (paper: 40). Sensor at nadir, target at sea level.
    """

    profile: str = "midlatitude_summer"
    water_vapour: float = 1.5
    aot550: float = PAPER_AOT550
    ozone: float = 330.0
    solar_zenith: float = 40.0

    def __post_init__(self) -> None:
        if self.profile not in PROFILES:
            raise InputError(f"unknown profile {self.profile!r}; allowed: {', '.join(PROFILES)}", key="profile")
        limits = {
            "water_vapour": (0.0, math.inf, "g/cm2"),
            "aot550": (0.0, math.inf, ""),
            "ozone": (0.0, math.inf, "DU"),
            "solar_zenith": (0.0, 89.0, "deg"),
        }
        for key, (lo, hi, unit) in limits.items():
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
                raise InputError(f"must be a finite number in {lo:g}-{hi:g} {unit}, got {value!r}", key=key)
            if not lo <= value <= hi:
                raise InputError(f"must be in {lo:g}-{hi:g} {unit}, got {value!r}", key=key)
            object.__setattr__(self, key, float(value))  # numpy scalars become plain floats

    @classmethod
    def from_visibility(cls, visibility_km: float, **kwargs) -> AtmosphereState:
        """State with the AOT550 that 6S's continental aerosol has at ``visibility_km``."""
        return cls(aot550=visibility_to_aot550(visibility_km), **kwargs)

    @classmethod
    def paper_standard(cls) -> AtmosphereState:
        """Mid-latitude summer, 1.5 g/cm2 water vapour, visibility 23 km, 330 DU, SZA 40 deg."""
        return cls()

    @property
    def visibility_km(self) -> float:
        """Visibility equivalent to ``aot550`` (km)."""
        return aot550_to_visibility(self.aot550)

    def replace(self, **changes) -> AtmosphereState:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)


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
        return self.transmittance["water"]

    @property
    def t_ozone(self) -> np.ndarray:
        return self.transmittance["ozone"]

    @property
    def t_methane(self) -> np.ndarray:
        return self.transmittance["methane"]

    def _along_grid(self, values, name: str) -> np.ndarray:
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
        r = self._along_grid(rho, "rho")
        return self.path_radiance + self.ground_term * r / (1.0 - self.spherical_albedo * r)

    def surface_reflectance(self, radiance) -> np.ndarray:
        """Inverse: Lambertian surface reflectance from TOA radiance ``(..., n_wl)``.

        ``y = (L - Lp) / G``, ``rho = y / (1 + S y)``. Where G is 0 (fully absorbed) the result is NaN.
        """
        radiance = self._along_grid(radiance, "radiance")
        with np.errstate(divide="ignore", invalid="ignore"):
            y = (radiance - self.path_radiance) / self.ground_term
            rho = y / (1.0 + self.spherical_albedo * y)
        return np.where(self.ground_term > 0, rho, np.nan)

    def toa_reflectance(self, rho) -> np.ndarray:
        """Forward in reflectance units: pi L / (mu_s E0)."""
        return np.pi * self.toa_radiance(rho) / (self.mu_s * self.e0)


@dataclass(frozen=True, eq=False)
class LUTAxesInfo:
    """The axes of a loaded LUT (float64 arrays)."""

    profiles: tuple[str, ...]
    aot550: np.ndarray
    solar_zenith: np.ndarray
    water_vapour: np.ndarray
    reference_zenith: float
    ozone_reference: float
    ozone_range: tuple[float, float]
    wavelength_nm: np.ndarray


def default_lut_path() -> Path:
    """The LUT shipped inside the package."""
    return Path(str(importlib.resources.files("s2cl") / "data" / DEFAULT_LUT_NAME))


def _bracket(nodes: np.ndarray, x: float, method: Method) -> list[tuple[int, float]]:
    """(index, weight) pairs interpolating ``x`` on increasing ``nodes`` (x inside the nodes)."""
    if nodes.size == 1:
        return [(0, 1.0)]
    if method == "nearest":
        return [(int(np.argmin(np.abs(nodes - x))), 1.0)]
    k = int(np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2))
    f = (x - nodes[k]) / (nodes[k + 1] - nodes[k])
    if f <= 0.0:
        return [(k, 1.0)]
    if f >= 1.0:
        return [(k + 1, 1.0)]
    return [(k, 1.0 - f), (k + 1, f)]


def _mix(table: np.ndarray, weights: list[tuple[int, float]], log: bool = False) -> np.ndarray:
    """Weighted sum over the first axis of ``table`` (in ln space when ``log``)."""
    if log:
        return np.exp(sum(w * np.log(np.maximum(table[i], 1e-30)) for i, w in weights))
    return sum(w * table[i].astype(np.float64) for i, w in weights)


class AtmosphereLUT:
    """A 6S look-up table loaded from disk (read-only arrays). Use :meth:`load`."""

    def __init__(self, arrays: dict[str, np.ndarray], provenance: dict, source: str):
        self._a = arrays
        self._provenance = provenance
        self.source = source
        ref = arrays["reference"]
        self.axes = LUTAxesInfo(
            profiles=tuple(str(p) for p in arrays["profiles"]),
            aot550=arrays["aot550"].astype(np.float64),
            solar_zenith=arrays["solar_zenith"].astype(np.float64),
            water_vapour=arrays["water_vapour"].astype(np.float64),
            reference_zenith=float(ref[0]),
            ozone_reference=float(ref[1]),
            ozone_range=(float(arrays["ozone_range"][0]), float(arrays["ozone_range"][1])),
            wavelength_nm=arrays["wavelength_nm"].astype(np.float64),
        )

    @property
    def provenance(self) -> dict:
        """Provenance stored in the file (6S version, settings, date, builder command, ...)."""
        return json.loads(json.dumps(self._provenance))

    @classmethod
    def load(cls, path: str | Path | None = None) -> AtmosphereLUT:
        """Load and validate a LUT; ``None`` loads the one shipped with s2cl (cached).

        :raises InputError: naming the file when it is missing, corrupt, of another format
            version, or lacks an array of the right shape.
        """
        if path is None:
            return _default_lut()
        return _read_lut(Path(path))

    # ------------------------------------------------------------ ranges

    def water_vapour_range(self, solar_zenith: float) -> tuple[float, float]:
        """Water-vapour columns (g/cm2) this LUT covers at ``solar_zenith``."""
        scale = airmass(self.axes.reference_zenith) / airmass(solar_zenith)
        return float(self.axes.water_vapour[0] * scale), float(self.axes.water_vapour[-1] * scale)

    def check_state(self, state: AtmosphereState) -> None:
        """Raise :class:`InputError` naming parameter, value and range if ``state`` is outside the LUT."""
        ax = self.axes
        if state.profile not in ax.profiles:
            raise InputError(
                f"profile {state.profile!r} is not in this LUT (has {', '.join(ax.profiles)})",
                source=self.source,
                key="profile",
            )
        ranges = {
            "aot550": (state.aot550, ax.aot550[0], ax.aot550[-1], ""),
            "solar_zenith": (state.solar_zenith, ax.solar_zenith[0], ax.solar_zenith[-1], " deg"),
            "ozone": (state.ozone, ax.ozone_range[0], ax.ozone_range[1], " DU"),
        }
        for key, (value, lo, hi, unit) in ranges.items():
            if not (lo - 1e-6 <= value <= hi + 1e-6):
                raise InputError(
                    f"{key} = {value:g}{unit} is outside the LUT's range {lo:g}-{hi:g}{unit}",
                    source=self.source,
                    key=key,
                )
        lo, hi = self.water_vapour_range(state.solar_zenith)
        if not (lo * (1 - 1e-6) <= state.water_vapour <= hi * (1 + 1e-6)):
            raise InputError(
                f"water_vapour = {state.water_vapour:g} g/cm2 is outside the LUT's range {lo:.3g}-{hi:.3g} g/cm2 "
                f"at solar_zenith {state.solar_zenith:g} deg (same slant column as "
                f"{ax.water_vapour[0]:g}-{ax.water_vapour[-1]:g} g/cm2 at {ax.reference_zenith:g} deg)",
                source=self.source,
                key="water_vapour",
            )

    # ------------------------------------------------------------ terms

    def terms(
        self, state: AtmosphereState, grid: SpectralGrid = DEFAULT_GRID, method: Method = "linear"
    ) -> AtmosphericTerms:
        """Atmospheric terms for ``state`` on ``grid`` (float64).

        :param grid: any grid inside the LUT's wavelengths (400-2500 nm); other steps than 1 nm
            are interpolated linearly in wavelength from the LUT's 1 nm grid.
        :param method: ``"linear"`` (documented per axis in this module) or ``"nearest"``.
        :raises InputError: state outside the LUT's axes, grid outside its wavelengths, bad method.
        """
        if method not in ("linear", "nearest"):
            raise InputError(f"method must be 'linear' or 'nearest', got {method!r}", key="method")
        self.check_state(state)
        native = self._native_terms(state, method)
        return _regrid(native, self.axes.wavelength_nm, grid, self.source)

    def _native_terms(self, state: AtmosphereState, method: Method) -> dict[str, np.ndarray]:
        a, ax = self._a, self.axes
        ip = ax.profiles.index(state.profile)
        sec = 1.0 / np.cos(np.radians(ax.solar_zenith))
        w_sza = _bracket(sec, 1.0 / math.cos(math.radians(state.solar_zenith)), method)
        w_aot = _bracket(ax.aot550, state.aot550, method)
        m, m_ref = airmass(state.solar_zenith), airmass(ax.reference_zenith)
        u_eff = state.water_vapour * m / m_ref
        w_wv = _bracket(np.sqrt(ax.water_vapour), math.sqrt(u_eff), method)

        refl = a["path_reflectance_scattering"][ip]  # (n_sza, n_aot, n_wl)
        r_mix = _mix(np.stack([_mix(refl[:, j], w_sza) for j in range(refl.shape[1])]), w_aot)
        r_ray = _mix(refl[:, 0], w_sza)
        td = a["t_down"][ip]
        t_down = _mix(np.stack([_mix(td[:, j], w_sza, log=True) for j in range(td.shape[1])]), w_aot, log=True)
        t_up = _mix(a["t_up"][ip], w_aot, log=True)
        s_alb = _mix(a["spherical_albedo"][ip], w_aot)

        gas = {"water": _mix(a["t_water"][ip], w_wv, log=True)}
        exponent = (state.ozone / ax.ozone_reference) * (m / m_ref)
        gas["ozone"] = np.power(a["t_ozone"][ip].astype(np.float64), exponent)
        for g in FIXED_GASES:
            gas[g] = _mix(a[fixed_gas_key(g)][ip], w_sza, log=True)
        t_nw = np.prod([gas[g] for g in GAS_NAMES if g != "water"], axis=0)
        t_gas = gas["water"] * t_nw

        mu_s = math.cos(math.radians(state.solar_zenith))
        e0 = a["e0"].astype(np.float64)
        rho_path = r_ray * t_nw + (r_mix - r_ray) * t_gas
        scale = mu_s * e0 / np.pi
        return {
            "path_radiance": scale * rho_path,
            "ground_term": scale * t_gas * t_down * t_up,
            "spherical_albedo": s_alb,
            "e0": e0,
            "path_reflectance": rho_path,
            "t_gas": t_gas,
            "t_down": t_down,
            "t_up": t_up,
            **{"t_" + g: v for g, v in gas.items()},
            "_mu_s": np.float64(mu_s),
            "_state": state,
            "_method": method,
        }


def _regrid(native: dict, lut_wl: np.ndarray, grid: SpectralGrid, source: str) -> AtmosphericTerms:
    wl = grid.wavelengths
    if wl[0] < lut_wl[0] - 1e-9 or wl[-1] > lut_wl[-1] + 1e-9:
        raise InputError(
            f"grid {grid.describe()} reaches outside the LUT's {lut_wl[0]:g}-{lut_wl[-1]:g} nm",
            source=source,
            key="grid",
        )
    same = wl.size == lut_wl.size and np.allclose(wl, lut_wl)

    def on_grid(values: np.ndarray) -> np.ndarray:
        values = np.asarray(values, dtype=np.float64)
        return values.copy() if same else np.interp(wl, lut_wl, values)

    arrays = {k: on_grid(v) for k, v in native.items() if not k.startswith("_")}
    transmittance = {g: arrays.pop("t_" + g) for g in GAS_NAMES}
    for arr in (*arrays.values(), *transmittance.values()):
        arr.setflags(write=False)
    return AtmosphericTerms(
        wavelength_nm=wl.copy(),
        mu_s=float(native["_mu_s"]),
        transmittance=transmittance,
        state=native["_state"],
        method=native["_method"],
        **arrays,
    )


_SHAPES = {
    "path_reflectance_scattering": ("p", "sza", "aot", "wl"),
    "t_down": ("p", "sza", "aot", "wl"),
    "t_up": ("p", "aot", "wl"),
    "spherical_albedo": ("p", "aot", "wl"),
    "t_water": ("p", "wv", "wl"),
    "t_ozone": ("p", "wl"),
    "e0": ("wl",),
    **{fixed_gas_key(g): ("p", "sza", "wl") for g in FIXED_GASES},
}


def _read_lut(path: Path) -> AtmosphereLUT:
    source = str(path)
    if not path.is_file():
        raise InputError(f"atmosphere LUT file not found; {REBUILD_HINT}", source=source)
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {key: np.asarray(npz[key]) for key in npz.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError) as err:
        raise InputError(f"not a readable s2cl atmosphere LUT (corrupt or not .npz): {err}", source=source) from err
    provenance = _check_provenance(arrays, source)
    _check_arrays(arrays, source)
    for arr in arrays.values():
        arr.setflags(write=False)
    return AtmosphereLUT(arrays, provenance, source)


def _check_provenance(arrays: dict[str, np.ndarray], source: str) -> dict:
    if "provenance" not in arrays:
        raise InputError("no provenance record: not an s2cl atmosphere LUT", source=source, key="provenance")
    try:
        provenance = json.loads(str(arrays["provenance"]))
    except json.JSONDecodeError as err:
        raise InputError(f"provenance is not valid JSON: {err}", source=source, key="provenance") from err
    if not isinstance(provenance, dict) or provenance.get("format") != FORMAT_NAME:
        raise InputError(f"format is not {FORMAT_NAME!r}", source=source, key="provenance.format")
    version = provenance.get("format_version")
    if version != FORMAT_VERSION:
        raise InputError(
            f"format version {version!r}; this s2cl reads version {FORMAT_VERSION}: {REBUILD_HINT}",
            source=source,
            key="provenance.format_version",
        )
    return provenance


def _check_arrays(arrays: dict[str, np.ndarray], source: str) -> None:
    missing = [k for k in (*AXIS_KEYS, *SCATTERING_KEYS, *ALBEDO_KEYS, *_SHAPES) if k not in arrays]
    if missing:
        raise InputError(f"missing arrays: {', '.join(missing)}", source=source)
    sizes = {
        "p": arrays["profiles"].size,
        "sza": arrays["solar_zenith"].size,
        "aot": arrays["aot550"].size,
        "wv": arrays["water_vapour"].size,
        "wl": arrays["wavelength_nm"].size,
    }
    for key, dims in _SHAPES.items():
        expected = tuple(sizes[d] for d in dims)
        arr = arrays[key]
        if arr.shape != expected or arr.dtype.kind != "f":
            raise InputError(
                f"expected float array of shape {expected}, got {arr.dtype} {arr.shape}", source=source, key=key
            )
        if not np.all(np.isfinite(arr)):
            raise InputError("holds non-finite values", source=source, key=key)
    for key in ("aot550", "solar_zenith", "water_vapour", "wavelength_nm"):
        if np.any(np.diff(arrays[key]) <= 0):
            raise InputError("axis is not strictly increasing", source=source, key=key)


@cache
def _default_lut() -> AtmosphereLUT:
    return _read_lut(default_lut_path())
