"""LUT build time: separable builder against brute force (one 6S run per wavelength and state).

Measured in one process on the same machine:

1. correctness first: the shipped LUT against direct 6S runs at two wavelengths (must agree to 3e-4);
2. a separable build of a slice (one profile, SZA 40, two AOTs, four water columns, 400-2500 nm), timed;
3. brute force on a random sample of the slice's (wavelength, state) pairs: two runs each (rho = 0
   and 1 give path and ground terms; S and the transmittances are printed), timed per run for
   aerosol and aerosol-free states, then extrapolated to the whole slice and to the shipped LUT's
   axes (with ozone as a 5-node axis, 250-410 DU by 40 DU, which the separable LUT covers by
   Beer's law).

Writes ``bench/results/lut_build.json``. Usage: ``python -m bench.bench_lut_build [-j 2] [--sample 24]``.
"""

from __future__ import annotations

import argparse
import json
import random
import tempfile
import time
from pathlib import Path

from bench.common import RESULTS, check, load_average, load_note, machine_info, write_json
from s2cl.atmos.atmosphere import AtmosphereLUT
from s2cl.atmos.lut_axes import LUTAxes
from s2cl.atmos.lut_build import build_lut
from s2cl.atmos.lut_validate import sixs_input_for, validate
from s2cl.atmos.sixs import SixSInput, describe, run_many
from s2cl.atmos.state import PAPER_AOT550, AtmosphereState

RESULT = RESULTS / "lut_build.json"
BRUTE_OZONE_NODES = 5


def check_correctness(lut: AtmosphereLUT, workers: int) -> float:
    rows = validate(lut, AtmosphereState.paper_standard(), (550.0, 945.0), (0.3,), workers=workers)
    worst = max(abs(r.relative_error) for r in rows)
    check(worst <= 3e-4, f"shipped LUT disagrees with 6S by {worst:.2e}: not benchmarking")
    return worst


def time_separable(axes: LUTAxes, workers: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        report = build_lut(Path(tmp) / "slice.npz", axes, workers=workers, progress=False, command="bench")
        seconds = time.perf_counter() - t0
    return {"seconds": seconds, "sixs_runs": report.runs, "stage_runs": report.stage_runs}


def brute_inputs(lut: AtmosphereLUT, state: AtmosphereState, wavelength_nm: float) -> list[SixSInput]:
    return [sixs_input_for(state, wavelength_nm, rho, lut) for rho in (0.0, 1.0)]


def time_brute_force(lut: AtmosphereLUT, axes: LUTAxes, sample: int, workers: int) -> dict:
    """Wall seconds per 6S run (with ``workers`` in parallel), aerosol and aerosol-free states."""
    rng = random.Random(1)
    wavelengths = [float(w) * 1000.0 for w in axes.sixs_wavelengths_um]
    per_run = {}
    for label, aots in (("aerosol", [a for a in axes.aot550 if a > 0]), ("aerosol_free", [0.0])):
        inputs = []
        for _ in range(sample):
            state = AtmosphereState(
                profile=rng.choice(axes.profiles),
                water_vapour=rng.choice(axes.water_vapour),
                aot550=rng.choice(aots),
                solar_zenith=rng.choice(axes.solar_zenith),
            )
            inputs += brute_inputs(lut, state, rng.choice(wavelengths))
        t0 = time.perf_counter()
        run_many(inputs, workers=workers)
        per_run[label] = (time.perf_counter() - t0) / len(inputs)
    return per_run


def brute_force_seconds(n_wl: int, n_states_aerosol: int, n_states_clear: int, per_run: dict) -> float:
    runs_per_state = 2 * n_wl * BRUTE_OZONE_NODES
    return runs_per_state * (n_states_aerosol * per_run["aerosol"] + n_states_clear * per_run["aerosol_free"])


def states(profiles: int, sza: int, aot: list[float], wv: int) -> tuple[int, int]:
    """Number of (aerosol, aerosol-free) states of a node grid."""
    n_aerosol = sum(1 for a in aot if a > 0)
    base = profiles * sza * wv
    return base * n_aerosol, base * (len(aot) - n_aerosol)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-j", "--workers", type=int, default=2)
    parser.add_argument("--sample", type=int, default=24, help="brute-force (wavelength, state) pairs per kind")
    parser.add_argument("--output", type=Path, default=RESULT)
    args = parser.parse_args()

    lut = AtmosphereLUT.load()
    start = load_average()
    worst = check_correctness(lut, args.workers)
    slice_axes = LUTAxes(
        profiles=("midlatitude_summer",),
        aot550=(0.0, PAPER_AOT550),
        solar_zenith=(40.0,),
        water_vapour=(0.4, 1.0, 1.5, 3.0),
    )
    separable = time_separable(slice_axes, args.workers)
    per_run = time_brute_force(lut, slice_axes, args.sample, args.workers)

    n_wl = slice_axes.sixs_wavelengths_um.size
    slice_states = states(1, 1, list(slice_axes.aot550), len(slice_axes.water_vapour))
    brute_slice = brute_force_seconds(n_wl, *slice_states, per_run)
    ax = lut.axes
    full_states = states(len(ax.profiles), ax.solar_zenith.size, list(ax.aot550), ax.water_vapour.size)
    brute_full = brute_force_seconds(n_wl, *full_states, per_run)
    shipped = lut.provenance["build"]

    result = {
        "benchmark": "atmosphere LUT build: separable vs brute force",
        "machine": machine_info(),
        "sixs": describe(),
        "workers": args.workers,
        "correctness_max_rel_error_vs_6s": worst,
        "brute_force_definition": f"2 runs (rho=0, rho=1) per 2.5 nm wavelength ({n_wl}) and state node, "
        f"ozone as a {BRUTE_OZONE_NODES}-node axis; per-run wall time measured on {args.sample} random pairs "
        "per kind with the same worker count, then extrapolated",
        "brute_force_seconds_per_run": per_run,
        "slice": {
            "axes": "midlatitude_summer, SZA 40, AOT (0, 0.23472), WV (0.4, 1, 1.5, 3), 400-2500 nm",
            "separable_seconds": separable["seconds"],
            "separable_sixs_runs": separable["sixs_runs"],
            "brute_force_seconds_extrapolated": brute_slice,
            "ratio_brute_over_separable": brute_slice / separable["seconds"],
        },
        "shipped_lut": {
            "separable_seconds": shipped["seconds"],
            "separable_workers": shipped["workers"],
            "separable_sixs_runs": sum(shipped["sixs_runs"].values()),
            "brute_force_seconds_extrapolated": brute_full,
            "ratio_brute_over_separable": brute_full / shipped["seconds"],
        },
    }
    result["load_note"] = load_note(start, load_average())
    write_json(args.output.resolve(), result)
    print(json.dumps(result, indent=2))
    print(
        f"slice: separable {separable['seconds']:.0f} s vs brute force ~{brute_slice / 3600:.1f} h "
        f"({brute_slice / separable['seconds']:.0f}x); shipped LUT: {shipped['seconds'] / 60:.0f} min vs "
        f"~{brute_full / 86400:.0f} days ({brute_full / shipped['seconds']:.0f}x)"
    )


if __name__ == "__main__":
    main()
