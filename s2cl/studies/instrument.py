"""What each instrument effect costs on an image (``s2cl study instrument``): the ideal instrument and each
[instrument] effect alone at the scene's magnitudes (by default those of
:data:`s2cl.scene.instrument_schema.SOURCES`), through :func:`s2cl.app.instrument_costs.effect_costs`.

The image: ``image_px`` × ``image_px`` input pixels at the scene's ``surface.gsd_m`` of square parcels
(``parcel_px`` on a side, sharp edges), each one spectrum drawn (with the scene's seed) from the [study]
``targets`` libraries. Where the sensor has B4 and B8, the map-level score is the NDVI map's RMS against the true
NDVI: each pixel's true surface reflectance through the nominal B4 and B8 SRFs, box-averaged to 10 m (float64).
Also timed: the spatial step alone (every band's PSF and shift, :meth:`s2cl.forward.instrument.Instrument.spatial`) with
``mtf`` and with ``coregistration`` on, against the whole run, which says whether that step is worth a device
kernel.
"""

from __future__ import annotations

import datetime as _dt
import os
import time
from typing import Any

import numpy as np
import xarray as xr

from s2cl.app.instrument_costs import EFFECTS, Score, effect_costs, product_variable, with_instrument
from s2cl.cl.runtime import get_runtime
from s2cl.errors import InputError
from s2cl.forward.cube import aggregate
from s2cl.forward.instrument import Instrument
from s2cl.scene.scene import Scene
from s2cl.studies.common import StudyResult, StudySetup

#: what the study needs: bands in [sweep], non-empty [study] lists (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = (), ("targets",)


def parcel_cube(spectra: np.ndarray, size: int, parcel: int, seed: int) -> np.ndarray:
    """Reflectance cube ``(size, size, n_wavelengths)`` (float32) of square parcels of ``parcel`` pixels, each one
    row of ``spectra`` drawn with ``seed``."""
    rng = np.random.default_rng(seed)
    n = -(-size // parcel)
    pick = rng.integers(0, spectra.shape[0], (n, n))
    idx = np.repeat(np.repeat(pick, parcel, axis=0), parcel, axis=1)[:size, :size]
    return np.asarray(spectra, dtype=np.float32)[idx]


def cube_scene(scene: Scene) -> Scene:
    """The study scene as an image-cube scene (surface reflectance at ``surface.gsd_m``; the cube is given in
    memory) without its [study]."""
    data = scene.spec.model_dump(exclude_none=True)
    gsd = scene.spec.surface.gsd_m
    if gsd is None:
        raise InputError("the instrument study needs surface.gsd_m (the parcel image's pixel size)",
                         source=scene.source, key="surface.gsd_m")
    data["surface"] = {"cube": "parcels (in memory)", "gsd_m": gsd, "quantity": "reflectance"}
    data.pop("study", None)
    data.get("output", {}).pop("precision", None)
    return Scene.from_dict(data, path=scene.path, base_dir=scene.base_dir)


def true_ndvi(scene: Scene, cube: np.ndarray) -> np.ndarray:
    """NDVI at 10 m of the true surface reflectance through the nominal B4 and B8 SRFs (float64)."""
    factor = round(10.0 / float(scene.spec.surface.gsd_m or 10.0))
    flat = cube.reshape(-1, cube.shape[2])
    red, nir = (aggregate(scene.sensor.band(b).weights(scene.grid).apply(flat).reshape(cube.shape[:2]), factor)
                for b in ("B4", "B8"))
    return (nir - red) / (nir + red)


def ndvi_score(truth: np.ndarray) -> Score:
    """A map-level score as :func:`effect_costs` takes it: RMS of the product's NDVI against ``truth``."""
    def score(ds: xr.Dataset) -> dict[str, float]:
        red, nir = (ds[f"reflectance_{b}"].values.astype(np.float64) for b in ("B4", "B8"))
        ndvi = (nir - red) / (nir + red)
        ok = np.isfinite(ndvi) & np.isfinite(truth)
        return {"ndvi_rms": float(np.sqrt(np.mean((ndvi[ok] - truth[ok]) ** 2)))}
    return score


def spatial_seconds(scene: Scene, size: int, effect: str) -> float:
    """Seconds of the spatial step alone (every band's PSF and shift on the input grid) with ``effect`` on."""
    spec = {**scene.spec.instrument.model_dump(), **dict.fromkeys(EFFECTS, False), effect: True}
    inst = Instrument.of(with_instrument(scene, spec))
    gsd = float(scene.spec.surface.gsd_m or 10.0)
    image = np.random.default_rng(0).random((size, size)).astype(np.float32)
    t0 = time.perf_counter()
    for k, band in enumerate(scene.sensor.bands):
        inst.spatial(image, k, round(band.gsd_m / gsd))
    return time.perf_counter() - t0


def run(setup: StudySetup) -> StudyResult:
    study = setup.study
    scene = cube_scene(setup.scene)
    spectra = np.concatenate([lib.spectra for lib in setup.targets().values()])
    cube = parcel_cube(spectra, study.image_px, study.parcel_px, scene.run.seed)
    rt = get_runtime(scene.run.device)
    names = scene.sensor.band_names
    score = ndvi_score(true_ndvi(scene, cube)) if {"B4", "B8"} <= set(names) and scene.effects.correct else None
    load_before = os.getloadavg()[0] if hasattr(os, "getloadavg") else 0.0
    rows = effect_costs(rt, scene, cube, scene.grid.wavelengths, score=score, repeats=2)
    spatial = {e: spatial_seconds(scene, study.image_px, e) for e in ("mtf", "coregistration")}
    load_after = os.getloadavg()[0] if hasattr(os, "getloadavg") else 0.0
    ideal = rows[0].seconds
    table = [[r.instrument, f"{r.as_dict()['rms_effect_mean']:.3g}", f"{r.as_dict()['rms_vs_truth_mean']:.3g}",
              f"{r.score['ndvi_rms']:.3g}" if "ndvi_rms" in r.score else "–", f"{r.seconds:.3g}",
              f"{r.seconds / ideal:.2f}"] for r in rows]
    data: dict[str, Any] = {
        "rows": [r.as_dict() for r in rows], "bands": names, "product": product_variable(scene),
        "pixels": study.image_px**2, "input_gsd_m": scene.spec.surface.gsd_m, "parcel_pixels": study.parcel_px,
        "targets": dict(study.targets), "seed": scene.run.seed, "spatial_step_seconds": spatial,
        "machine": {"device": rt.name, "cores": os.cpu_count(), "date": _dt.date.today().isoformat(),
                    "load_average_1min": [load_before, load_after]}}
    notes = [f"{r.instrument}: {r.source}" for r in rows[1:]]
    notes.append("rms_effect: the effect alone (no noise, no quantisation) against the ideal instrument; "
                 "vs truth: the product against the noise-free ideal one (ideal row: the noise and quantisation "
                 "floor); mean over bands, units of the product")
    return StudyResult(title=f"Instrument effects alone at their specified magnitudes ({study.image_px}² pixels)",
                       columns=["instrument", f"RMS effect ({data['product']})", "RMS vs truth", "NDVI map RMS",
                                "s per run", "× ideal"],
                       rows=table, key_figures=[], data=data, notes=notes)
