"""What each instrument effect costs on an image: each [instrument] effect switched on alone at its specified
magnitude (the scene's own values, by default those of :data:`s2cl.scene.instrument_schema.SOURCES`), compared
with the ideal instrument, and the time it takes.

Each instrument runs twice: as the scene asks (noise, quantisation, calibration, correction: the product a user
gets, timed) and clean (no noise, no quantisation: the effect alone). ``rms_effect`` is the clean product's RMS
difference to the clean ideal one — the effect's own size, free of noise and of the re-rounding to DN that any
sub-DN change brings; ``rms_vs_truth`` is the product's RMS difference to the clean ideal one (for the ideal row:
the noise and quantisation floor). The compared product is the L2 band reflectance when the scene corrects the
atmosphere, else band radiance (calibrated in the product). ``score`` plugs in map-level figures: a function of
the scene, the simulated product (its image store) and the cube, whose numbers enter each row;
:func:`analysis_score` is the scene's [analysis] retrieval map against the cube's truth (its RMS, bias and R²).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xarray as xr

from s2cl.app.checks import check_simulate
from s2cl.app.image_analysis import analyse_image
from s2cl.app.image_simulation import scene_cube, simulate_image
from s2cl.cl.runtime import Runtime
from s2cl.forward.cube import SceneCube
from s2cl.forward.stages import STAGES, outputs
from s2cl.io.image_store import MemoryStore
from s2cl.scene.instrument_schema import IMAGE_EFFECTS, SOURCES, magnitudes
from s2cl.scene.scene import Scene

#: the image effects of [effects], each costed alone
EFFECTS = tuple(IMAGE_EFFECTS)
#: a map-level score: (scene, the simulated product's store, the cube) → named figures
Score = Callable[[Scene, MemoryStore, SceneCube], dict[str, float]]


@dataclass
class EffectCost:
    """One row: the instrument (``ideal`` or one effect on), its seconds per product run, and per band the RMS
    differences described in the module docstring (units of the product)."""

    instrument: str
    source: str
    seconds: float
    rms_effect: dict[str, float]
    rms_vs_truth: dict[str, float]
    score: dict[str, float] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        def mean(d: dict[str, float]) -> float:
            return float(np.mean(list(d.values()))) if d else float("nan")

        return {"instrument": self.instrument, "source": self.source, "seconds": self.seconds,
                "rms_effect_mean": mean(self.rms_effect), "rms_vs_truth_mean": mean(self.rms_vs_truth),
                "rms_effect": self.rms_effect, "rms_vs_truth": self.rms_vs_truth, "score": self.score}


def with_effects(scene: Scene, effects: dict[str, Any]) -> Scene:
    """``scene`` with those [effects] keys replaced."""
    data = scene.spec.model_dump(exclude_none=True)
    data["effects"] = {**data["effects"], **effects}
    if "output" in data:
        data["output"].pop("precision", None)
    return Scene.from_dict(data, path=scene.path, base_dir=scene.base_dir)


def effect_settings(scene: Scene, on: str | None = None) -> dict[str, Any]:
    """Each image effect's settings in ``scene`` (its table, else the defaults), every one off but ``on``."""
    out = {}
    for name in EFFECTS:
        settings = magnitudes(getattr(scene.spec.effects, name), IMAGE_EFFECTS[name])
        out[name] = {**settings.model_dump(exclude_none=True), "on": name == on}
    return out


def product_variable(scene: Scene) -> str:
    """The compared product's variable prefix: L2 reflectance, calibrated radiance or band radiance."""
    real = [o.name for o in outputs(scene.effects) if o.dtype is None]
    return real[-1] if real else "radiance"


#: the clean run: every stage that degrades the signal off (noise, quantisation, calibration, ...)
CLEAN = {s.name: False for s in STAGES if s.per_pixel and s.degrades}


def band_rms(a: xr.Dataset, b: xr.Dataset, names: list[str], prefix_a: str, prefix_b: str) -> dict[str, float]:
    """Per band, the RMS of ``a − b`` over pixels finite in both (float64)."""
    out = {}
    for n in names:
        x, y = a[f"{prefix_a}_{n}"].values.astype(np.float64), b[f"{prefix_b}_{n}"].values.astype(np.float64)
        ok = np.isfinite(x) & np.isfinite(y)
        out[n] = float(np.sqrt(np.mean((x[ok] - y[ok]) ** 2))) if ok.any() else float("nan")
    return out


def _timed(rt: Runtime, scene: Scene, cube: SceneCube, repeats: int) -> tuple[MemoryStore, float]:
    """The product's store and the best wall time of ``repeats`` runs after one warm-up (kernel builds
    excluded)."""
    best, store = float("inf"), MemoryStore()
    simulate_image(rt, scene, cube, store=store)
    for _ in range(repeats):
        store = MemoryStore()
        t0 = time.perf_counter()
        simulate_image(rt, scene, cube, store=store)
        best = min(best, time.perf_counter() - t0)
    return store, best


def analysis_score(rt: Runtime) -> Score:
    """The scene's [analysis] on the product (:func:`s2cl.app.image_analysis.analyse_image`): the parameter map's
    RMS, bias and R² against the cube's truth, where the cube knows it (else the fitted fraction alone)."""
    def score(scene: Scene, store: MemoryStore, cube: SceneCube) -> dict[str, float]:
        checked = check_simulate(scene)
        if checked.analysis is None:
            return {}
        out = analyse_image(rt, scene, store, cube, list(checked.analysis_bands), checked.analysis)
        figures = {"fitted_fraction": out["fitted_pixels"] / out["pixels"]}
        if "rms" in out:
            name = out["parameter"]
            figures.update({f"{name}_map_rms": out["rms"], f"{name}_map_bias": out["bias"],
                            f"{name}_map_r2": out["r2"]})
        return figures
    return score


def effect_costs(rt: Runtime, scene: Scene, cube: np.ndarray | SceneCube | None = None,
                 wavelengths_nm: np.ndarray | None = None,
                 *, effects: tuple[str, ...] = EFFECTS, score: Score | None = None,
                 repeats: int = 1) -> list[EffectCost]:
    """The ideal instrument and each of ``effects`` alone, on ``scene``'s cube (or ``cube`` in memory, or already
    made ready by :func:`s2cl.app.image_simulation.scene_cube`): one
    :class:`EffectCost` per instrument, the ideal first. The scene's own [effects] settings set each effect's
    magnitude (its on/off switches are ignored)."""
    base = effect_settings(scene)
    ideal_scene = with_effects(scene, base)
    prepared = cube if isinstance(cube, SceneCube) else scene_cube(ideal_scene, cube, wavelengths_nm)
    names = ideal_scene.sensor.band_names
    product = product_variable(ideal_scene)
    clean = "reflectance" if ideal_scene.effects.correct else "radiance"
    truth = simulate_image(rt, with_effects(scene, {**base, **CLEAN}), prepared)
    rows = []
    for name in ("ideal", *effects):
        spec = base if name == "ideal" else effect_settings(scene, name)
        variant = with_effects(scene, spec)
        store, seconds = _timed(rt, variant, prepared, repeats)
        figures = score(variant, store, prepared) if score else {}
        own = truth if name == "ideal" else simulate_image(rt, with_effects(scene, {**spec, **CLEAN}), prepared)
        source = "no instrument effect (noise and quantisation only)" if name == "ideal" else SOURCES[name]
        rows.append(EffectCost(name, source, seconds, band_rms(own, truth, names, clean, clean),
                               band_rms(store.dataset(), truth, names, product, clean), figures))
    return rows
