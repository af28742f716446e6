"""The 6S runs of a LUT build, stage by stage, and what each stage makes of their printouts.

1. **Scattering** (:func:`scattering_stage`): per profile, solar zenith and AOT, 19 runs on a gas-free
   copy of the profile, one at a 2.5 nm grid point inside each interval between 6S's fixed
   wavelengths (a point where the fixed gases absorb < 1 %, their printed transmittance divided
   out). The power law is linear in log-log, so the 19 runs give 6S's node values exactly (to
   print rounding) and with them the scattering terms at every wavelength (:func:`scattering_at`).
2. **Fixed gases and ozone** (:func:`dry_gas_stage`): aerosol-free runs on the 2.5 nm grid per profile
   and solar zenith, water removed; their printed two-way transmittances.
3. **Water vapour** (:func:`water_stage`): aerosol-free runs on the 2.5 nm grid per profile and water
   column at the reference zenith with a black-then-white target; the two-way gas transmittance
   comes from the apparent reflectance (7 decimals) and the Rayleigh terms of stage 1. 6S's H2O
   transmittance depends on the slant column only (checked: identical printouts for equal
   column x airmass), so one zenith suffices. Wavelengths where the largest column shows no
   absorption (or where no fixed gas absorbs at the largest zenith) are not run again.

Wavelengths in um (6S's unit) unless a name says nm; transmittances and reflectances unitless.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from s2cl.atmos.lut_axes import LUTAxes
from s2cl.atmos.lut_format import FIXED_GASES
from s2cl.atmos.sixs import SixSError, SixSInput, SixSOutput, run_many
from s2cl.atmos.sixs_profiles import get_profile

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

_MIN_SAMPLE_GAS_TRANSMITTANCE = 0.98


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


def scattering_stage(axes: LUTAxes, workers: int, show: bool) -> tuple[np.ndarray, int]:
    """Stage 1: the ln of 6S's scattering node values (R, Td, Tu, S), shape (n_p, n_sza, n_aot, 4, n_nodes),
    and the number of 6S runs."""
    inputs = _scattering_inputs(axes)
    outputs = run_many(inputs, workers=workers, progress=_Progress("scattering", show))
    return _scattering_nodes(axes, outputs), len(inputs)


def _scattering_inputs(axes: LUTAxes) -> list[SixSInput]:
    """One gas-free run per profile, solar zenith, AOT and sample wavelength (Rayleigh only at AOT 0)."""
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


def scattering_at(log_nodes: np.ndarray, wavelengths_um: np.ndarray) -> np.ndarray:
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
        """6S runs of the stage."""
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
    """Whether ozone or a fixed gas absorbs in this run."""
    return any(out.gas[g] < 1.0 for g in _DRY_GASES)


def _absorbs_water(out: SixSOutput) -> bool:
    """Whether water vapour absorbs in this run."""
    return out.gas["water"] < 1.0


def dry_gas_stage(axes: LUTAxes, workers: int, show: bool) -> tuple[dict[str, np.ndarray], int]:
    """Stage 2: two-way transmittances of ozone and the fixed gases, shape (n_p, n_sza, n_wl6s), and the runs.

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


def water_stage(axes: LUTAxes, rayleigh: np.ndarray, workers: int, show: bool) -> tuple[np.ndarray, np.ndarray, int]:
    """Stage 3: two-way H2O transmittance (n_p, n_wv, n_wl6s) at the reference zenith, E0 at 1 AU
    (W m-2 um-1, (n_wl6s,)) and the runs.

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
