"""Build the atmosphere look-up table with 6S (``s2cl lut build``), fast, by separating scattering from gas
absorption.

6S evaluates its scattering quantities (path reflectance, transmittances, spherical albedo) only
at 20 fixed wavelengths and interpolates them with a power law in between; gas absorption it
computes on its 2.5 nm grid, independently of aerosol. The builder uses both facts in three stages
of 6S runs (:mod:`s2cl.atmos.lut_runs`: ``scattering``, ``dry gases``, ``water``); this module puts
their results together on the LUT's 1 nm grid and writes the file with its provenance.

Recombined as 6S does (water vapour above the aerosol, Rayleigh path unabsorbed by it), the
tables reproduce 6S's apparent reflectance to print rounding (:func:`s2cl.atmos.lut_validate.validate`).
Brute force, one 6S run per wavelength and state, costs thousands of times more
(``bench/bench_lut_build.py``).
"""

from __future__ import annotations

import json
import shlex
import sys
import time
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from s2cl.atmos.lut_axes import LUTAxes
from s2cl.atmos.lut_format import FIXED_GASES, FORMAT_NAME, FORMAT_VERSION, fixed_gas_key
from s2cl.atmos.lut_runs import dry_gas_stage, scattering_at, scattering_stage, water_stage
from s2cl.atmos.sixs import SIXS_VERSION, describe
from s2cl.errors import InputError
from s2cl.io.cache import write_npz_atomic
from s2cl.version import __version__


@dataclass
class BuildReport:
    """What a build did: output path, seconds and 6S runs per stage, total seconds."""

    path: Path
    seconds: float = 0.0
    stage_seconds: dict[str, float] = field(default_factory=dict)
    stage_runs: dict[str, int] = field(default_factory=dict)

    @property
    def runs(self) -> int:
        """6S runs of all stages."""
        return sum(self.stage_runs.values())

    def record(self, stage: str, started: float, runs: int) -> None:
        """Note that ``stage`` made ``runs`` 6S runs since ``started`` (a ``time.perf_counter()`` value)."""
        self.stage_seconds[stage] = time.perf_counter() - started
        self.stage_runs[stage] = runs


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
    log_nodes, dry, t_water, e0 = _run_stages(axes, workers, progress, report)
    arrays, spread = _assemble(axes, log_nodes, dry, t_water, e0)
    bad = [k for k, v in arrays.items() if v.dtype.kind == "f" and not np.all(np.isfinite(v))]
    if bad:
        raise InputError(f"6S produced non-finite values in {', '.join(bad)}", source=str(output))
    report.seconds = time.perf_counter() - t0
    command = command if command is not None else _command_line()
    extra = {"max_spread_over_zenith_of_t_up_and_spherical_albedo": spread}
    arrays["provenance"] = np.array(json.dumps(_provenance(axes, report, command, workers, extra), indent=1))
    write_npz_atomic(report.path, arrays)
    return report


def _run_stages(
    axes: LUTAxes, workers: int, show: bool, report: BuildReport
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """The three stages of 6S runs, each recorded in ``report``.

    :returns: ln scattering node values (n_p, n_sza, n_aot, 4, n_nodes), dry-gas transmittances
        (gas -> (n_p, n_sza, n_wl6s)), H2O transmittance (n_p, n_wv, n_wl6s) and E0 (n_wl6s,), W m-2 um-1.
    """
    t = time.perf_counter()
    log_nodes, runs = scattering_stage(axes, workers, show)
    report.record("scattering", t, runs)
    iref = axes.solar_zenith.index(axes.reference_zenith)
    rayleigh6s = scattering_at(log_nodes[:, iref, 0], axes.sixs_wavelengths_um)  # (n_p, 4, n_wl6s)
    t = time.perf_counter()
    dry, runs = dry_gas_stage(axes, workers, show)
    report.record("dry gases", t, runs)
    t = time.perf_counter()
    t_water, e0, runs = water_stage(axes, rayleigh6s, workers, show)
    report.record("water", t, runs)
    return log_nodes, dry, t_water, e0


def _assemble(
    axes: LUTAxes, log_nodes: np.ndarray, dry: dict[str, np.ndarray], t_water: np.ndarray, e0: np.ndarray
) -> tuple[dict[str, np.ndarray], float]:
    """The LUT's arrays (float32, on the 1 nm grid; layout in :mod:`s2cl.atmos.lut_format`) and the largest
    change of Tu and S over the solar zenith (the table keeps them at the reference zenith only)."""
    wl6s, wl_nm = axes.sixs_wavelengths_um, axes.wavelengths_nm
    iref = axes.solar_zenith.index(axes.reference_zenith)
    scat = scattering_at(log_nodes, wl_nm / 1000.0)  # (n_p, n_sza, n_aot, 4, n_wl)
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
    return arrays, spread


def _to_1nm(values: np.ndarray, wl6s_um: np.ndarray, wl_nm: np.ndarray) -> np.ndarray:
    """Linear interpolation along the last axis from 6S's 2.5 nm grid to 1 nm."""
    flat = values.reshape(-1, values.shape[-1])
    out = np.stack([np.interp(wl_nm, wl6s_um * 1000.0, row) for row in flat])
    return out.reshape(*values.shape[:-1], wl_nm.size)


def _provenance(axes: LUTAxes, report: BuildReport, command: str, workers: int, extra: dict) -> dict:
    """The LUT's provenance record: format, versions, command, 6S settings, sampling, formula, build figures."""
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


def _command_line() -> str:
    """This process's command line without machine paths: the program's name only (``python -m s2cl``: ``s2cl``)."""
    argv = list(sys.argv)
    if argv and Path(argv[0]).name == "__main__.py" and Path(argv[0]).parent.name == "s2cl":
        argv[0] = "s2cl"
    elif argv:
        argv[0] = Path(argv[0]).name
    return " ".join(shlex.quote(a) for a in argv)
