"""The 6S look-up table at run time (:class:`AtmosphereLUT`): read and checked from disk, interpolated to a state.

No Fortran is needed here: the LUT (``s2cl/data/atmosphere_lut.npz``) was built once with 6S
(``s2cl lut build``, :mod:`s2cl.atmos.lut_build`). For a state (:class:`~s2cl.atmos.state.AtmosphereState`)
and a spectral grid, :meth:`AtmosphereLUT.terms` returns per-wavelength terms
(:class:`~s2cl.atmos.terms.AtmosphericTerms`, float64) with which

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

import importlib.resources
import json
import math
import zipfile
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Literal

import numpy as np

from s2cl.atmos.lut_format import (
    ALBEDO_KEYS,
    ARRAY_DIMS,
    AXIS_KEYS,
    FIXED_GASES,
    FORMAT_NAME,
    FORMAT_VERSION,
    LUT_KEYS,
    SCATTERING_KEYS,
    check_declared,
    fixed_gas_key,
)
from s2cl.atmos.state import AtmosphereState, airmass
from s2cl.atmos.terms import GAS_NAMES, AtmosphericTerms
from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.io.npz import npz_members

Method = Literal["linear", "nearest"]

DEFAULT_LUT_NAME = "atmosphere_lut.npz"
REBUILD_HINT = 'rebuild it with `s2cl lut build -o FILE` (needs `pip install "s2cl[sixs]"`)'


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
        """The terms of ``state`` on the LUT's own 1 nm grid (float64), plus ``_mu_s``, ``_state``, ``_method``."""
        ax = self.axes
        ip = ax.profiles.index(state.profile)
        sec = 1.0 / np.cos(np.radians(ax.solar_zenith))
        w_sza = _bracket(sec, 1.0 / math.cos(math.radians(state.solar_zenith)), method)
        w_aot = _bracket(ax.aot550, state.aot550, method)
        r_ray, r_mix, t_down, t_up, s_alb = self._scattering(ip, w_sza, w_aot)
        gas = self._gases(ip, state, w_sza, method)
        t_nw = np.prod([gas[g] for g in GAS_NAMES if g != "water"], axis=0)
        t_gas = gas["water"] * t_nw

        mu_s = math.cos(math.radians(state.solar_zenith))
        e0 = self._a["e0"].astype(np.float64)
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

    def _scattering(self, ip: int, w_sza: list[tuple[int, float]],
                    w_aot: list[tuple[int, float]]) -> tuple[np.ndarray, ...]:
        """Gas-free scattering of profile ``ip``: Rayleigh and total path reflectance, Td, Tu, S."""
        a = self._a
        refl = a["path_reflectance_scattering"][ip]  # (n_sza, n_aot, n_wl)
        r_mix = _mix(np.stack([_mix(refl[:, j], w_sza) for j in range(refl.shape[1])]), w_aot)
        r_ray = _mix(refl[:, 0], w_sza)
        td = a["t_down"][ip]
        t_down = _mix(np.stack([_mix(td[:, j], w_sza, log=True) for j in range(td.shape[1])]), w_aot, log=True)
        t_up = _mix(a["t_up"][ip], w_aot, log=True)
        s_alb = _mix(a["spherical_albedo"][ip], w_aot)
        return r_ray, r_mix, t_down, t_up, s_alb

    def _gases(self, ip: int, state: AtmosphereState, w_sza: list[tuple[int, float]],
               method: Method) -> dict[str, np.ndarray]:
        """Two-way transmittance of each gas (:data:`GAS_NAMES`) of profile ``ip`` for ``state``."""
        a, ax = self._a, self.axes
        m, m_ref = airmass(state.solar_zenith), airmass(ax.reference_zenith)
        u_eff = state.water_vapour * m / m_ref
        w_wv = _bracket(np.sqrt(ax.water_vapour), math.sqrt(u_eff), method)
        gas = {"water": _mix(a["t_water"][ip], w_wv, log=True)}
        exponent = (state.ozone / ax.ozone_reference) * (m / m_ref)
        gas["ozone"] = np.power(a["t_ozone"][ip].astype(np.float64), exponent)
        for g in FIXED_GASES:
            gas[g] = _mix(a[fixed_gas_key(g)][ip], w_sza, log=True)
        return gas


def _regrid(native: dict, lut_wl: np.ndarray, grid: SpectralGrid, source: str) -> AtmosphericTerms:
    """Terms on the LUT's grid ``lut_wl`` onto ``grid`` (linear in wavelength), as read-only arrays."""
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


def _read_lut(path: Path) -> AtmosphereLUT:
    """Load the ``.npz`` at ``path`` and check its provenance and arrays; arrays become read-only. What each
    array declares (its ``.npy`` header) is checked first (:func:`check_declared`): nothing is loaded
    from a file that declares more than the LUT format allows."""
    source = str(path)
    if not path.is_file():
        raise InputError(f"atmosphere LUT file not found; {REBUILD_HINT}", source=source)
    check_declared(npz_members(path, "s2cl atmosphere LUT"), source)
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {key: np.asarray(npz[key]) for key in LUT_KEYS}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError) as err:
        raise InputError(f"not a readable s2cl atmosphere LUT (corrupt or not .npz): {err}", source=source) from err
    provenance = _check_provenance(arrays, source)
    _check_arrays(arrays, source)
    for arr in arrays.values():
        arr.setflags(write=False)
    return AtmosphereLUT(arrays, provenance, source)


def _check_provenance(arrays: dict[str, np.ndarray], source: str) -> dict:
    """The file's provenance record, refused unless it is an s2cl LUT of this format version."""
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
    """Every array present, float, of the shape its axes give (:data:`ARRAY_DIMS`), finite; axes increasing."""
    missing = [k for k in (*AXIS_KEYS, *SCATTERING_KEYS, *ALBEDO_KEYS, *ARRAY_DIMS) if k not in arrays]
    if missing:
        raise InputError(f"missing arrays: {', '.join(missing)}", source=source)
    sizes = {
        "p": arrays["profiles"].size,
        "sza": arrays["solar_zenith"].size,
        "aot": arrays["aot550"].size,
        "wv": arrays["water_vapour"].size,
        "wl": arrays["wavelength_nm"].size,
    }
    for key, dims in ARRAY_DIMS.items():
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
    """The shipped LUT, read once per process."""
    return _read_lut(default_lut_path())
