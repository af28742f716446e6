"""What each instrument effect costs on an image (``s2cl study instrument``): the ideal instrument and each
[instrument] effect alone at the scene's magnitudes (by default those of
:data:`s2cl.scene.instrument_schema.SOURCES`), through :func:`s2cl.studies.instrument_costs.effect_costs`, on the
scene's own image cube — any cube scene with a [study] of kind ``instrument``; the built-in one is
``builtin:fields`` (PROSAIL parcels with known Cab and LAI, soil and mineral patches), whose side [study]
``image_px`` sets. With an [analysis], each row also carries the retrieval map's RMS, bias and R² against the
cube's truth (:func:`s2cl.studies.instrument_costs.analysis_score`).

Also timed: the spatial step alone (every band's PSF and shift, :meth:`s2cl.forward.instrument.Instrument.spatial`)
with ``psf`` and with ``coregistration`` on, against the whole run, which says whether that step is worth a
device kernel.
"""

from __future__ import annotations

import datetime as _dt
import os
import time
from typing import Any

import numpy as np

from s2cl.app.chain_parts import scene_instrument, scene_simulator
from s2cl.app.image_simulation import scene_cube
from s2cl.cl.runtime import get_runtime
from s2cl.errors import InputError
from s2cl.libraries.fields import is_builtin_cube
from s2cl.scene.scene import Scene
from s2cl.scene.terms import scene_atmosphere
from s2cl.studies.common import StudyResult, StudySetup
from s2cl.studies.instrument_costs import analysis_score, effect_costs, effect_settings, product_variable, with_effects

#: what the study needs: bands in [sweep], non-empty [study] lists (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = (), ()


def cube_scene(scene: Scene, image_px: int = 0) -> Scene:
    """The study scene without its [study]; a ``builtin:fields`` cube resized to ``image_px`` square (0: as
    given)."""
    cube = scene.spec.surface.cube
    if cube is None:
        raise InputError("the instrument study runs on an image cube: give surface.cube (e.g. 'builtin:fields')",
                         source=scene.source, key="surface.cube")
    data = scene.spec.model_dump(exclude_none=True)
    if image_px:
        if not is_builtin_cube(cube):
            raise InputError("study.image_px resizes a builtin:fields cube; this scene's cube is a file",
                             source=scene.source, key="study.image_px")
        data["surface"]["cube"] = f"builtin:fields:{image_px}x{image_px}"
    data.pop("study", None)
    data.get("output", {}).pop("precision", None)
    return Scene.from_dict(data, path=scene.path, base_dir=scene.base_dir)


def spatial_seconds(scene: Scene, size: tuple[int, int], effect: str) -> float:
    """Seconds of the spatial step alone (every band's PSF and shift on the input grid) with ``effect`` on, on
    an input image of ``size``."""
    inst = scene_instrument(with_effects(scene, effect_settings(scene, effect)))
    gsd = float(scene.spec.surface.gsd_m or 10.0)
    image = np.random.default_rng(0).random(size).astype(np.float32)
    t0 = time.perf_counter()
    for k, band in enumerate(scene.sensor.bands):
        inst.spatial(image, k, round(band.gsd_m / gsd))
    return time.perf_counter() - t0


def resample_seconds(rt: Any, scene: Scene, cube: Any, sample: int = 8192) -> float:
    """Seconds the resampling kernel would take over every pixel of the image, as for a cube read from a file
    (a generated cube resamples its distinct spectra only): timed on ``sample`` pixels' spectra, scaled."""
    sim = scene_simulator(rt, scene, atmosphere=scene_atmosphere(scene), interpolation=cube.interpolation)
    pixels = cube.rows * cube.cols
    take = np.arange(min(sample, pixels))
    spectra = (cube.spectra[cube.labels[take]] if cube.labels is not None
               else cube.block(0, -(-take.size // cube.cols))[0][: take.size])
    spectra = np.ascontiguousarray(spectra, dtype=np.float32 if scene.run.precision == "float32" else np.float64)
    sim.band_radiance(spectra)  # warm-up
    t0 = time.perf_counter()
    sim.band_radiance(spectra)
    return (time.perf_counter() - t0) * pixels / take.size


def _load() -> float:
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else 0.0


def run(setup: StudySetup) -> StudyResult:
    study = setup.study
    scene = cube_scene(setup.scene, study.image_px)
    rt = get_runtime(scene.run.device)
    names = scene.sensor.band_names
    cube = scene_cube(scene)
    load_before = _load()
    rows = effect_costs(rt, scene, cube, score=analysis_score(rt), repeats=2)
    spatial = {e: spatial_seconds(scene, (cube.rows, cube.cols), e) for e in ("psf", "coregistration")}
    every_pixel = resample_seconds(rt, scene, cube)
    load_after = _load()
    ideal = rows[0].seconds
    map_key = next((k for k in rows[0].score if k.endswith("_map_rms")), None)
    table = [[r.instrument, f"{r.as_dict()['rms_effect_mean']:.3g}", f"{r.as_dict()['rms_vs_truth_mean']:.3g}",
              f"{r.score[map_key]:.3g}" if map_key and map_key in r.score else "–", f"{r.seconds:.3g}",
              f"{r.seconds / ideal:.2f}"] for r in rows]
    data: dict[str, Any] = {
        "rows": [r.as_dict() for r in rows], "bands": names, "product": product_variable(scene),
        "cube": scene.spec.surface.cube, "pixels": cube.rows * cube.cols, "input_gsd_m": scene.spec.surface.gsd_m,
        "analysis": None if scene.spec.analysis is None else {
            "kind": scene.spec.analysis.kind, "parameter": scene.spec.analysis.parameter,
            "bands": scene.spec.analysis.bands, "score": map_key},
        "seed": scene.run.seed, "spatial_step_seconds": spatial, "resample_every_pixel_seconds": every_pixel,
        "machine": {"device": rt.name, "cores": os.cpu_count(), "date": _dt.date.today().isoformat(),
                    "load_average_1min": [load_before, load_after]}}
    notes = [f"{r.instrument}: {r.source}" for r in rows[1:]]
    notes.append("RMS effect: the effect alone (no noise, no quantisation) against the ideal instrument; vs truth: "
                 "the product against the noise-free ideal one (ideal row: the noise and quantisation floor); mean "
                 "over bands, units of the product")
    map_column = f"{map_key.removesuffix('_rms').replace('_', ' ')} RMS vs truth" if map_key else "map RMS vs truth"
    return StudyResult(title=f"Instrument effects alone at their specified magnitudes ({scene.spec.surface.cube})",
                       columns=["instrument", f"RMS effect ({data['product']})", "RMS vs truth", map_column,
                                "s per run", "× ideal"],
                       rows=table, key_figures=[], data=data, notes=notes)
