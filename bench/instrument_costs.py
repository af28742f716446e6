"""What each instrument effect costs: the ideal instrument and each [instrument] effect alone at its specified
magnitude (:data:`s2cl.scene.instrument_schema.SOURCES`) on a parcel image, the L2 reflectance's RMS difference
to the ideal instrument's, an NDVI map's RMS against the true NDVI, and the time per run
(:func:`s2cl.app.instrument_costs.effect_costs`). Also the time of the spatial step (the per-band FFT of MTF and
shift) against the whole run, which says whether that step is worth a device kernel.

The image: ``--size`` × ``--size`` pixels at 5 m of PROSAIL canopies (builtin:lib1 and lib2, Cab and LAI known)
and iron-bearing backgrounds, in square parcels of 20 pixels with sharp edges, drawn from ``--seed``; the standard
atmosphere forward and corrected (L2 reflectance). The truth NDVI is each pixel's true surface reflectance through
the nominal B4 and B8 SRFs, box-averaged to 10 m (float64).

Writes ``bench/results/instrument_costs.json`` atomically. Usage: ``python -m bench.instrument_costs`` (a minute
or two on 2 cores).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
import xarray as xr

from bench.common import RESULTS, load_average, load_note, machine_info, write_json
from s2cl.app.instrument_costs import EFFECTS, effect_costs, product_variable
from s2cl.cl.runtime import get_runtime
from s2cl.forward.cube import aggregate
from s2cl.forward.instrument import Instrument
from s2cl.grid import DEFAULT_GRID
from s2cl.libraries.registry import load_library
from s2cl.scene.instrument_schema import SOURCES
from s2cl.scene.scene import Scene

RESULT = RESULTS / "instrument_costs.json"
GSD_M = 5.0
PARCEL = 20
COMMAND = "python -m bench.instrument_costs"


def parcel_cube(size: int, seed: int) -> np.ndarray:
    """Reflectance cube ``(size, size, grid)`` (float32) of square parcels, each one library spectrum."""
    rng = np.random.default_rng(seed)
    libs = [load_library(f"builtin:{n}", DEFAULT_GRID) for n in ("lib1", "lib2", "iron-backgrounds")]
    spectra = np.concatenate([lib.spectra for lib in libs])
    n = -(-size // PARCEL)
    pick = rng.integers(0, spectra.shape[0], (n, n))
    idx = np.repeat(np.repeat(pick, PARCEL, axis=0), PARCEL, axis=1)[:size, :size]
    return spectra[idx].astype(np.float32)


def scene(seed: int) -> Scene:
    """The bench's scene: a reflectance cube at 5 m, atmosphere on and corrected, default [instrument] values."""
    return Scene.from_dict({"scene": {"name": "instrument-costs"},
                            "surface": {"cube": "in-memory.nc", "gsd_m": GSD_M, "quantity": "reflectance"},
                            "effects": {"atmosphere": True, "correct": True, "seed": seed}})


def true_ndvi(s: Scene, cube: np.ndarray) -> np.ndarray:
    """NDVI at 10 m of the true surface reflectance through the nominal B4 and B8 SRFs (float64)."""
    factor = round(10.0 / GSD_M)
    flat = cube.reshape(-1, cube.shape[2])
    red, nir = (aggregate(s.sensor.band(b).weights(s.grid).apply(flat).reshape(cube.shape[:2]), factor)
                for b in ("B4", "B8"))
    return (nir - red) / (nir + red)


def ndvi_score(truth: np.ndarray):
    """A map-level score as :func:`effect_costs` takes it: RMS of the product's NDVI against ``truth``."""
    def score(ds: xr.Dataset) -> dict[str, float]:
        red, nir = (ds[f"reflectance_{b}"].values.astype(np.float64) for b in ("B4", "B8"))
        ndvi = (nir - red) / (nir + red)
        ok = np.isfinite(ndvi)
        return {"ndvi_rms": float(np.sqrt(np.mean((ndvi[ok] - truth[ok]) ** 2)))}
    return score


def spatial_seconds(s: Scene, size: int, effect: str) -> float:
    """Seconds of the spatial step alone (every band's FFT at the input grid) for ``effect`` on."""
    from s2cl.app.instrument_costs import with_instrument

    base = {**s.spec.instrument.model_dump(), **dict.fromkeys(EFFECTS, False), effect: True}
    inst = Instrument.of(with_instrument(s, base))
    image = np.random.default_rng(0).random((size, size)).astype(np.float32)
    t0 = time.perf_counter()
    for k, band in enumerate(s.sensor.bands):
        inst.spatial(image, k, round(band.gsd_m / GSD_M))
    return time.perf_counter() - t0


def measure(size: int = 240, seed: int = 1, repeats: int = 2) -> dict[str, Any]:
    rt = get_runtime(None)
    s = scene(seed)
    cube = parcel_cube(size, seed)
    before = load_average()
    rows = effect_costs(rt, s, cube, DEFAULT_GRID.wavelengths, score=ndvi_score(true_ndvi(s, cube)),
                        repeats=repeats)
    spatial = {e: spatial_seconds(s, size, e) for e in ("mtf", "coregistration")}
    after = load_average()
    return {"benchmark": "instrument_costs", "command": COMMAND, "machine": machine_info(rt),
            "load": load_note(before, after), "scene": "parcels of builtin:lib1, lib2 and iron-backgrounds spectra",
            "pixels": size * size, "input_gsd_m": GSD_M, "parcel_pixels": PARCEL, "seed": seed,
            "product": product_variable(s), "bands": s.sensor.band_names, "sources": SOURCES,
            "rows": [r.as_dict() for r in rows], "spatial_step_seconds": spatial}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog=COMMAND, description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=240, help="image side, pixels at 5 m (a multiple of 12)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=2, help="timed runs per instrument (the best counts)")
    args = ap.parse_args(argv)
    result = measure(args.size, args.seed, args.repeats)
    for r in result["rows"]:
        print(f"{r['instrument']:>15}  {r['seconds']:.2f} s  effect {r['rms_effect_mean']:.2e}  "
              f"vs truth {r['rms_vs_truth_mean']:.2e}  {r['score']}")
    print("wrote", write_json(RESULT, result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
