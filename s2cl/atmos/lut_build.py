"""Build the atmosphere look-up table from 6S, fast, by separating scattering from gas absorption.

6S evaluates its scattering quantities (path reflectance, transmittances, spherical albedo) only
at 20 fixed wavelengths and interpolates them with a power law in between; gas absorption it
computes on its 2.5 nm grid, independently of aerosol. The builder uses both facts:

1. **Scattering** (stage ``scattering``): per profile, solar zenith and AOT, 19 runs on a gas-free
   copy of the profile, one at a 2.5 nm grid point inside each interval between 6S's fixed
   wavelengths (a point where the fixed gases absorb < 1 %, their printed transmittance divided
   out). The power law is linear in log-log, so the 19 runs give 6S's node values exactly (to
   print rounding) and with them the scattering terms at every wavelength.
2. **Fixed gases and ozone** (stage ``dry gases``): aerosol-free runs on the 2.5 nm grid per profile
   and solar zenith, water removed; their printed two-way transmittances.
3. **Water vapour** (stage ``water``): aerosol-free runs on the 2.5 nm grid per profile and water
   column at the reference zenith with a black-then-white target; the two-way gas transmittance
   comes from the apparent reflectance (7 decimals) and the Rayleigh terms of stage 1. 6S's H2O
   transmittance depends on the slant column only (checked: identical printouts for equal
   column x airmass), so one zenith suffices. Wavelengths where the largest column shows no
   absorption (or where no fixed gas absorbs at the largest zenith) are not run again.

Recombined as 6S does (water vapour above the aerosol, Rayleigh path unabsorbed by it), the
tables reproduce 6S's apparent reflectance to print rounding (:func:`s2cl.atmos.lut_validate.validate`).
Brute force, one 6S run per wavelength and state, costs thousands of times more
(``bench/bench_lut_build.py``).
"""

from __future__ import annotations

import json
import math
import shlex
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import click
import numpy as np

from s2cl import __version__
from s2cl.atmos.lut_format import FIXED_GASES, FORMAT_NAME, FORMAT_VERSION, fixed_gas_key
from s2cl.atmos.sixs import (
    SIXS_GRID_START_UM,
    SIXS_GRID_STEP_UM,
    SIXS_VERSION,
    SixSError,
    SixSInput,
    SixSOutput,
    describe,
    on_sixs_grid,
    run_many,
)
from s2cl.atmos.sixs_profiles import PROFILES, get_profile
from s2cl.errors import InputError
from s2cl.io.cache import write_npz_atomic

SCATTERING_NODES_UM: tuple[float, ...] = (
    0.4, 0.412, 0.443, 0.47, 0.488, 0.515, 0.55, 0.59, 0.633, 0.67,
    0.694, 0.76, 0.86, 1.24, 1.536, 1.65, 1.95, 2.25, 3.75,
)  # fmt: skip
"""6S's fixed wavelengths (um) from 0.4 um up; it power-law interpolates scattering between them."""

SCATTERING_SAMPLES_UM: tuple[float, ...] = (
    0.4, 0.41, 0.4425, 0.4675, 0.4875, 0.5125, 0.5475, 0.5875, 0.6275, 0.6675,
    0.685, 0.7575, 0.8575, 1.2375, 1.52, 1.6225, 1.93, 2.14, 3.125,
)  # fmt: skip
"""One 2.5 nm grid point per interval (plus 0.4 um itself), each the point nearest the interval's
upper end where 6S's fixed gases transmit > 99 % (99.4 % or more in mid-latitude summer)."""

DEFAULT_AOT550: tuple[float, ...] = (0.0, 0.05, 0.1, 0.15, 0.2, 0.23472, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0)
"""AOT nodes; 0.23472 is 6S's continental AOT550 for the paper's 23 km visibility."""

DEFAULT_SOLAR_ZENITH: tuple[float, ...] = (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0)

DEFAULT_WATER_VAPOUR: tuple[float, ...] = (
    0.17, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.25, 1.5, 1.75,
    2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.75, 6.6,
)  # fmt: skip
"""Water-vapour nodes (g/cm2) at the reference zenith 40 deg: 0.2-5 g/cm2 at any zenith 0-60 deg
maps into 0.17-6.6 g/cm2 there (equal slant column)."""

_MIN_SAMPLE_GAS_TRANSMITTANCE = 0.98


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


@dataclass
class BuildReport:
    """What a build did: output path, seconds and 6S runs per stage, total seconds."""

    path: Path
    seconds: float = 0.0
    stage_seconds: dict[str, float] = field(default_factory=dict)
    stage_runs: dict[str, int] = field(default_factory=dict)

    @property
    def runs(self) -> int:
        return sum(self.stage_runs.values())


# ---------------------------------------------------------------- progress


class _Progress:
    """Prints ``stage: done/total runs, elapsed, eta`` to stderr, at most every 2 s."""

    def __init__(self, stage: str, enabled: bool):
        self.stage, self.enabled = stage, enabled
        self.start = time.perf_counter()
        self.last = 0.0

    def __call__(self, done: int, total: int) -> None:
        now = time.perf_counter()
        if not self.enabled or (now - self.last < 2.0 and done < total):
            return
        self.last = now
        elapsed = now - self.start
        eta = elapsed / done * (total - done) if done else math.nan
        print(
            f"[s2cl lut] {self.stage}: {done}/{total} 6S runs ({100 * done / total:.0f} %), "
            f"elapsed {elapsed:.0f} s, eta {eta:.0f} s",
            file=sys.stderr,
            flush=True,
        )


# ---------------------------------------------------------------- scattering


def _log_interp_matrix(wavelengths_um: np.ndarray) -> np.ndarray:
    """Matrix ``B`` (n_wl, n_nodes) with log v(wl) = B @ log v(nodes): 6S's power law between its
    fixed wavelengths, i.e. linear interpolation in log-log.
    """
    x = np.log(np.asarray(wavelengths_um, dtype=np.float64))
    nodes = np.log(np.asarray(SCATTERING_NODES_UM))
    k = np.clip(np.searchsorted(nodes, x, side="left") - 1, 0, nodes.size - 2)
    f = (x - nodes[k]) / (nodes[k + 1] - nodes[k])
    b = np.zeros((x.size, nodes.size))
    b[np.arange(x.size), k] = 1.0 - f
    b[np.arange(x.size), k + 1] = f
    return b


def _scattering_inputs(axes: LUTAxes) -> list[SixSInput]:
    inputs = []
    for profile in axes.profiles:
        for sza in axes.solar_zenith:
            for aot in axes.aot550:
                for wl in SCATTERING_SAMPLES_UM:
                    inputs.append(
                        SixSInput(
                            wavelength_um=wl,
                            profile=profile,
                            water_scale=0.0,
                            ozone_scale=0.0,
                            aerosol="continental" if aot > 0 else "none",
                            aot550=float(aot),
                            solar_zenith=float(sza),
                            month=axes.month,
                            day=axes.day,
                        )
                    )
    return inputs


def _scattering_nodes(axes: LUTAxes, outputs: Sequence[SixSOutput]) -> np.ndarray:
    """log node values, shape (n_p, n_sza, n_aot, 4, n_nodes) for (R, Td, Tu, S)."""
    shape = (len(axes.profiles), len(axes.solar_zenith), len(axes.aot550), len(SCATTERING_SAMPLES_UM))
    samples = np.empty((*shape, 4))
    for i, out in enumerate(outputs):
        t_gas = out.gas["global"]
        if t_gas < _MIN_SAMPLE_GAS_TRANSMITTANCE:
            raise SixSError(
                f"scattering sample at {SCATTERING_SAMPLES_UM[i % len(SCATTERING_SAMPLES_UM)]} um sees gas "
                f"transmittance {t_gas} < {_MIN_SAMPLE_GAS_TRANSMITTANCE}: choose another sample wavelength"
            )
        samples.reshape(-1, 4)[i] = (out.apparent_reflectance / t_gas, out.t_down, out.t_up, out.spherical_albedo)
    a = _log_interp_matrix(np.asarray(SCATTERING_SAMPLES_UM))
    logs = np.log(np.maximum(samples, 1e-30))  # (..., n_samples, 4)
    rhs = np.moveaxis(logs, -2, -1).reshape(-1, len(SCATTERING_SAMPLES_UM)).T  # (n_samples, m)
    nodes, *_ = np.linalg.lstsq(a, rhs, rcond=None)
    return nodes.T.reshape(*shape[:3], 4, len(SCATTERING_NODES_UM))


def _scattering_at(log_nodes: np.ndarray, wavelengths_um: np.ndarray) -> np.ndarray:
    """Scattering quantities at ``wavelengths_um``: shape (..., 4, n_wl)."""
    return np.exp(log_nodes @ _log_interp_matrix(wavelengths_um).T)


# ---------------------------------------------------------------- gases


@dataclass(frozen=True)
class _Screened:
    """Runs of one gas stage: the screening setting at every wavelength, the others where it absorbs.

    :param first: outputs at the screening setting, one per wavelength.
    :param mask: wavelengths where the screening run absorbs, bool (n_wl6s,).
    :param rest: outputs for each other setting, list (n_settings - 1) of lists (mask.sum(),).
    """

    first: list[SixSOutput]
    mask: np.ndarray
    rest: list[list[SixSOutput]]

    @property
    def runs(self) -> int:
        return len(self.first) + sum(len(r) for r in self.rest)


def _screen_then_run(
    make: Callable[[float, float], SixSInput],
    wavelengths_um: np.ndarray,
    settings: Sequence[float],
    absorbs: Callable[[SixSOutput], bool],
    workers: int,
    stage: str,
    show: bool,
) -> _Screened:
    """Run ``make(wavelength, settings[-1])`` (the most absorbing setting) at every wavelength, then
    the other settings only at the wavelengths where ``absorbs`` says that run absorbed.
    """
    first = run_many([make(w, settings[-1]) for w in wavelengths_um], workers=workers,
                     progress=_Progress(stage + " (screening)", show))  # fmt: skip
    mask = np.array([absorbs(o) for o in first], dtype=bool)
    inputs = [make(w, x) for x in settings[:-1] for w in wavelengths_um[mask]]
    flat = run_many(inputs, workers=workers, progress=_Progress(stage, show))
    n = int(mask.sum())
    return _Screened(first, mask, [flat[i * n : (i + 1) * n] for i in range(len(settings) - 1)])


@dataclass(frozen=True)
class _DryRun:
    """Aerosol-free, water-free runs at the reference ozone (a picklable ``make`` for the pool)."""

    axes: LUTAxes
    profile: str

    def __call__(self, wavelength_um: float, solar_zenith: float) -> SixSInput:
        return SixSInput(
            wavelength_um=float(wavelength_um),
            profile=self.profile,
            water_scale=0.0,
            ozone_scale=self.axes.ozone_reference / get_profile(self.profile).ozone_column,
            aerosol="none",
            aot550=0.0,
            solar_zenith=float(solar_zenith),
            month=self.axes.month,
            day=self.axes.day,
        )


@dataclass(frozen=True)
class _WaterRun:
    """Aerosol-free runs over a white target at the reference zenith and ozone, for one water column."""

    axes: LUTAxes
    profile: str

    def __call__(self, wavelength_um: float, water_vapour: float) -> SixSInput:
        prof = get_profile(self.profile)
        return SixSInput(
            wavelength_um=float(wavelength_um),
            reflectance=1.0,
            profile=self.profile,
            water_scale=water_vapour / prof.water_column,
            ozone_scale=self.axes.ozone_reference / prof.ozone_column,
            aerosol="none",
            aot550=0.0,
            solar_zenith=self.axes.reference_zenith,
            month=self.axes.month,
            day=self.axes.day,
        )


_DRY_GASES = ("ozone", *FIXED_GASES)


def _absorbs_dry(out: SixSOutput) -> bool:
    return any(out.gas[g] < 1.0 for g in _DRY_GASES)


def _absorbs_water(out: SixSOutput) -> bool:
    return out.gas["water"] < 1.0


def _dry_gas_stage(axes: LUTAxes, workers: int, show: bool) -> tuple[dict[str, np.ndarray], int]:
    """Two-way transmittances of ozone and the fixed gases, shape (n_p, n_sza, n_wl6s).

    Screening runs at the largest zenith (longest path); the other zeniths only where a gas absorbs.
    """
    wl = axes.sixs_wavelengths_um
    result = {g: np.ones((len(axes.profiles), len(axes.solar_zenith), wl.size)) for g in _DRY_GASES}
    runs = 0
    for ip, profile in enumerate(axes.profiles):
        done = _screen_then_run(
            _DryRun(axes, profile), wl, axes.solar_zenith, _absorbs_dry, workers, f"dry gases, {profile}", show
        )
        runs += done.runs
        for g in _DRY_GASES:
            result[g][ip, -1] = [o.gas[g] for o in done.first]
            for isza, outs in enumerate(done.rest):
                result[g][ip, isza, done.mask] = [o.gas[g] for o in outs]
    return result, runs


def _water_stage(axes: LUTAxes, rayleigh: np.ndarray, workers: int, show: bool) -> tuple[np.ndarray, np.ndarray, int]:
    """Two-way H2O transmittance (n_p, n_wv, n_wl6s) at the reference zenith, and E0 at 1 AU.

    Screening runs at the largest column; the others only where it absorbs.

    :param rayleigh: gas-free Rayleigh (R, Td, Tu, S), shape (n_p, 4, n_wl6s) at the reference zenith.
    """
    wl = axes.sixs_wavelengths_um
    t_water = np.ones((len(axes.profiles), len(axes.water_vapour), wl.size))
    e0 = np.full(wl.size, np.nan)
    runs = 0
    for ip, profile in enumerate(axes.profiles):
        done = _screen_then_run(
            _WaterRun(axes, profile), wl, axes.water_vapour, _absorbs_water, workers, f"water, {profile}", show
        )
        runs += done.runs
        if ip == 0:
            e0[:] = [o.solar_irradiance / o.earth_sun_factor for o in done.first]
        t_water[ip, -1] = _water_transmittance(done.first, rayleigh[ip])
        for iwv, outs in enumerate(done.rest):
            if outs:
                t_water[ip, iwv, done.mask] = _water_transmittance(outs, rayleigh[ip][:, done.mask])
        t_water[ip] = np.minimum.accumulate(t_water[ip], axis=0)  # H2O transmittance falls with the column
    return t_water, e0, runs


def _water_transmittance(outputs: Sequence[SixSOutput], rayleigh: np.ndarray) -> np.ndarray:
    """H2O two-way transmittance from aerosol-free runs over a white target (rho = 1).

    rho_app(1) = R_R t_nw + t_gas Td Tu / (1 - S): the 7-decimal apparent reflectance gives t_gas
    far better than the 5-decimal printout where absorption is strong; t_nw is the printed product
    of the other gases.
    """
    rr, td, tu, s = rayleigh
    rho = np.array([o.apparent_reflectance for o in outputs])
    t_nw = np.array([math.prod(v for g, v in o.gas.items() if g not in ("water", "global")) for o in outputs])
    t_gas = (rho - rr * t_nw) * (1.0 - s) / (td * tu)
    printed = np.array([o.gas["water"] for o in outputs])
    with np.errstate(divide="ignore", invalid="ignore"):
        t_water = np.where(t_nw > 1e-3, t_gas / t_nw, printed)
    t_water = np.where(printed >= 1.0, 1.0, t_water)
    return np.clip(t_water, 1e-12, 1.0)


# ---------------------------------------------------------------- assembly


def _to_1nm(values: np.ndarray, wl6s_um: np.ndarray, wl_nm: np.ndarray) -> np.ndarray:
    """Linear interpolation along the last axis from 6S's 2.5 nm grid to 1 nm."""
    flat = values.reshape(-1, values.shape[-1])
    out = np.stack([np.interp(wl_nm, wl6s_um * 1000.0, row) for row in flat])
    return out.reshape(*values.shape[:-1], wl_nm.size)


def _provenance(axes: LUTAxes, report: BuildReport, command: str, workers: int, extra: dict) -> dict:
    return {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "s2cl_version": __version__,
        "sixs_version": SIXS_VERSION,
        "sixs": describe(),
        "builder_command": command,
        "settings": {
            **{k: list(v) if isinstance(v, tuple) else v for k, v in asdict(axes).items()},
            "aerosol_model": "continental (6S predefined)",
            "target": "Lambertian, sea level",
            "sensor": "satellite level, nadir view (view zenith 0 deg)",
            "atmospheric_profiles": "6S's mid-latitude summer/winter (McClatchey 1972) given as user profiles, "
            "H2O and O3 densities scaled to the requested columns (shape kept)",
            "date": f"{axes.month}/{axes.day}; E0 divided by 6S's Earth-Sun factor, i.e. at 1 AU",
        },
        "spectral_sampling": "6S computes gas absorption and the solar spectrum on its 2.5 nm grid (0.25 um + k "
        "2.5 nm); they are interpolated linearly in wavelength to the 1 nm grid. Scattering terms are "
        "evaluated at each 1 nm wavelength with 6S's own power law between its fixed wavelengths.",
        "formula": "L = Lp + G rho / (1 - S rho); Lp = mu_s E0 rho_path / pi; G = mu_s E0 t_gas Td Tu / pi; "
        "rho_path = R_R t_nw + (R - R_R) t_gas (6S: water vapour above the aerosol); t_gas = t_water t_nw; "
        "t_nw = t_ozone * product of fixed gases",
        "build": {
            "seconds": round(report.seconds, 1),
            "workers": workers,
            "sixs_runs": report.stage_runs,
            "stage_seconds": {k: round(v, 1) for k, v in report.stage_seconds.items()},
        },
        **extra,
    }


def build_lut(
    output: str | Path,
    axes: LUTAxes | None = None,
    *,
    workers: int = 2,
    progress: bool = True,
    command: str | None = None,
) -> BuildReport:
    """Build a LUT with 6S and write it atomically to ``output`` (``.npz``).

    :param output: file to write.
    :param axes: what to cover (default: the shipped LUT's axes).
    :param workers: 6S processes in parallel.
    :param progress: print progress to stderr.
    :param command: command line to record in the provenance (default: this process's argv).
    :raises DependencyError: when 6S is not installed.
    """
    axes = axes or LUTAxes()
    report = BuildReport(path=Path(output))
    t0 = time.perf_counter()

    t = time.perf_counter()
    scat_inputs = _scattering_inputs(axes)
    scat_out = run_many(scat_inputs, workers=workers, progress=_Progress("scattering", progress))
    log_nodes = _scattering_nodes(axes, scat_out)
    report.stage_seconds["scattering"] = time.perf_counter() - t
    report.stage_runs["scattering"] = len(scat_inputs)

    wl6s, wl_nm = axes.sixs_wavelengths_um, axes.wavelengths_nm
    iref = axes.solar_zenith.index(axes.reference_zenith)
    rayleigh6s = _scattering_at(log_nodes[:, iref, 0], wl6s)  # (n_p, 4, n_wl6s)

    t = time.perf_counter()
    dry, runs = _dry_gas_stage(axes, workers, progress)
    report.stage_seconds["dry gases"] = time.perf_counter() - t
    report.stage_runs["dry gases"] = runs

    t = time.perf_counter()
    t_water, e0, runs = _water_stage(axes, rayleigh6s, workers, progress)
    report.stage_seconds["water"] = time.perf_counter() - t
    report.stage_runs["water"] = runs

    scat = _scattering_at(log_nodes, wl_nm / 1000.0)  # (n_p, n_sza, n_aot, 4, n_wl)
    spread = float(np.max(np.abs(scat[:, :, :, 2:] - scat[:, iref : iref + 1, :, 2:])))
    arrays = {
        "wavelength_nm": wl_nm.astype(np.float32),
        "profiles": np.array(axes.profiles),
        "aot550": np.asarray(axes.aot550, dtype=np.float32),
        "solar_zenith": np.asarray(axes.solar_zenith, dtype=np.float32),
        "water_vapour": np.asarray(axes.water_vapour, dtype=np.float32),
        "reference": np.array([axes.reference_zenith, axes.ozone_reference, 0.0], dtype=np.float32),
        "ozone_range": np.asarray(axes.ozone_range, dtype=np.float32),
        "e0": _to_1nm(e0, wl6s, wl_nm).astype(np.float32),
        "path_reflectance_scattering": scat[:, :, :, 0].astype(np.float32),
        "t_down": scat[:, :, :, 1].astype(np.float32),
        "t_up": scat[:, iref, :, 2].astype(np.float32),
        "spherical_albedo": scat[:, iref, :, 3].astype(np.float32),
        "t_water": _to_1nm(t_water, wl6s, wl_nm).astype(np.float32),
        "t_ozone": _to_1nm(dry["ozone"][:, iref], wl6s, wl_nm).astype(np.float32),
    }
    for gas in FIXED_GASES:
        arrays[fixed_gas_key(gas)] = _to_1nm(dry[gas], wl6s, wl_nm).astype(np.float32)
    bad = [k for k, v in arrays.items() if v.dtype.kind == "f" and not np.all(np.isfinite(v))]
    if bad:
        raise InputError(f"6S produced non-finite values in {', '.join(bad)}", source=str(output))

    report.seconds = time.perf_counter() - t0
    command = command if command is not None else _command_line()
    extra = {"max_spread_over_zenith_of_t_up_and_spherical_albedo": spread}
    arrays["provenance"] = np.array(json.dumps(_provenance(axes, report, command, workers, extra), indent=1))
    write_npz_atomic(report.path, arrays)
    return report


# ---------------------------------------------------------------- command line


def _command_line() -> str:
    """This process's command line, with the module path of ``python -m`` runs shortened."""
    argv = list(sys.argv)
    if argv and Path(argv[0]).name in ("lut_build.py", "__main__.py"):
        argv = ["python", "-m", "s2cl.atmos.lut_build", *argv[1:]]
    elif argv:
        argv[0] = Path(argv[0]).name
    return " ".join(shlex.quote(a) for a in argv)


def _floats(text: str | None) -> tuple[float, ...] | None:
    if text is None:
        return None
    try:
        return tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError as err:
        raise click.BadParameter(f"expected comma-separated numbers, got {text!r}") from err


@click.command(name="build-lut")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, help="LUT file to write (.npz).")
@click.option("-j", "--workers", type=click.IntRange(1, 64), default=2, show_default=True, help="6S processes.")
@click.option("--profiles", default=",".join(PROFILES), show_default=True, help="Comma-separated profiles.")
@click.option("--aot", "aot", default=None, help="AOT550 nodes, comma-separated, first 0 [default: shipped].")
@click.option("--sza", "sza", default=None, help="Solar zenith nodes (deg), comma-separated [default: shipped].")
@click.option("--water-vapour", "wv", default=None, help="Water-vapour nodes (g/cm2) at the reference zenith.")
@click.option("--wavelengths", default="400,2500", show_default=True, help="First,last wavelength in nm (2.5 nm grid).")
@click.option("--quiet", is_flag=True, help="No progress output.")
def main(
    output: str,
    workers: int,
    profiles: str,
    aot: str | None,
    sza: str | None,
    wv: str | None,
    wavelengths: str,
    quiet: bool,
) -> None:
    """Build s2cl's atmosphere look-up table with 6S (needs `pip install "s2cl[sixs]"` and libgfortran5)."""
    kwargs: dict = {"profiles": tuple(p.strip() for p in profiles.split(",") if p.strip())}
    for key, text in (("aot550", aot), ("solar_zenith", sza), ("water_vapour", wv)):
        values = _floats(text)
        if values is not None:
            kwargs[key] = values
    lo_hi = _floats(wavelengths)
    if lo_hi is None or len(lo_hi) != 2:
        raise click.BadParameter("needs two numbers: first,last", param_hint="--wavelengths")
    kwargs["wavelength_range_nm"] = lo_hi
    axes = LUTAxes(**kwargs)
    report = build_lut(output, axes, workers=workers, progress=not quiet)
    stages = ", ".join(f"{k} {report.stage_runs[k]} runs in {v:.0f} s" for k, v in report.stage_seconds.items())
    click.echo(f"wrote {report.path}: {report.runs} 6S runs, {report.seconds:.0f} s ({stages})")


if __name__ == "__main__":
    main()
