"""What each instrument effect costs on an image: each [instrument] effect switched on alone at its specified
magnitude (the scene's own values, by default those of :data:`s2cl.scene.instrument_schema.SOURCES`), compared
with the ideal instrument, and the time it takes.

Each instrument runs twice: as the scene asks (noise, quantisation, calibration, correction: the product a user
gets, timed) and clean (no noise, no quantisation: the effect alone). ``rms_effect`` is the clean product's RMS
difference to the clean ideal one — the effect's own size, free of noise and of the re-rounding to DN that any
sub-DN change brings; ``rms_vs_truth`` is the product's RMS difference to the clean ideal one (for the ideal row:
the noise and quantisation floor). The compared product is the L2 band reflectance when the scene corrects the
atmosphere, else band radiance (calibrated in the product). ``score`` plugs in a map-level figure: a function of
the simulated product dataset (e.g. a retrieval map's RMS against the scene's truth map) whose numbers enter each
row.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xarray as xr

from s2cl.cl.runtime import Runtime
from s2cl.forward.cube import SceneCube, load_scene_cube, simulate_cube
from s2cl.scene.instrument_schema import SOURCES
from s2cl.scene.scene import Scene

EFFECTS = ("mtf", "coregistration", "smile", "nonuniformity")
Score = Callable[[xr.Dataset], dict[str, float]]


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


def with_instrument(scene: Scene, instrument: dict[str, Any], effects: dict[str, Any] | None = None) -> Scene:
    """``scene`` with its [instrument] section replaced by ``instrument`` (and [effects] keys updated)."""
    data = scene.spec.model_dump(exclude_none=True)
    data["instrument"] = instrument
    if effects:
        data["effects"] = {**data["effects"], **effects}
    if "output" in data:
        data["output"].pop("precision", None)
    return Scene.from_dict(data, path=scene.path, base_dir=scene.base_dir)


def product_variable(scene: Scene) -> str:
    """The compared product's variable prefix: L2 reflectance, calibrated radiance or band radiance."""
    e = scene.effects
    return "reflectance" if e.correct else "calibrated" if e.calibrate else "noisy" if e.noise else "radiance"


#: the clean run: no noise, no quantisation (so no calibration either)
CLEAN = {"noise": False, "quantise": False, "calibrate": False}


def band_rms(a: xr.Dataset, b: xr.Dataset, names: list[str], prefix_a: str, prefix_b: str) -> dict[str, float]:
    """Per band, the RMS of ``a − b`` over pixels finite in both (float64)."""
    out = {}
    for n in names:
        x, y = a[f"{prefix_a}_{n}"].values.astype(np.float64), b[f"{prefix_b}_{n}"].values.astype(np.float64)
        ok = np.isfinite(x) & np.isfinite(y)
        out[n] = float(np.sqrt(np.mean((x[ok] - y[ok]) ** 2))) if ok.any() else float("nan")
    return out


def _timed(rt: Runtime, scene: Scene, cube: SceneCube, repeats: int) -> tuple[xr.Dataset, float]:
    """The dataset and the best wall time of ``repeats`` runs after one warm-up (kernel builds excluded)."""
    ds = simulate_cube(rt, scene, cube)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        ds = simulate_cube(rt, scene, cube)
        best = min(best, time.perf_counter() - t0)
    return ds, best


def effect_costs(rt: Runtime, scene: Scene, cube: np.ndarray | None = None, wavelengths_nm: np.ndarray | None = None,
                 *, effects: tuple[str, ...] = EFFECTS, score: Score | None = None,
                 repeats: int = 1) -> list[EffectCost]:
    """The ideal instrument and each of ``effects`` alone, on ``scene``'s cube (or ``cube`` in memory): one
    :class:`EffectCost` per instrument, the ideal first. The scene's own [instrument] values set each effect's
    magnitude (its on/off switches are ignored)."""
    base = {**scene.spec.instrument.model_dump(), **dict.fromkeys(EFFECTS, False)}
    ideal_scene = with_instrument(scene, base)
    prepared = load_scene_cube(ideal_scene, cube, wavelengths_nm)
    names = ideal_scene.sensor.band_names
    product = product_variable(ideal_scene)
    clean = "reflectance" if ideal_scene.effects.correct else "radiance"
    truth = simulate_cube(rt, with_instrument(scene, base, effects=CLEAN), prepared)
    rows = []
    for name in ("ideal", *effects):
        spec = base if name == "ideal" else {**base, name: True}
        ds, seconds = _timed(rt, with_instrument(scene, spec), prepared, repeats)
        own = truth if name == "ideal" else simulate_cube(rt, with_instrument(scene, spec, effects=CLEAN), prepared)
        source = "no instrument effect (noise and quantisation only)" if name == "ideal" else SOURCES[name]
        rows.append(EffectCost(name, source, seconds, band_rms(own, truth, names, clean, clean),
                               band_rms(ds, truth, names, product, clean), score(ds) if score else {}))
    return rows
