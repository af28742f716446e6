"""What each instrument effect costs on an image: each [instrument] effect switched on alone at its specified
magnitude (the scene's own values, by default those of :data:`s2cl.scene.instrument_schema.SOURCES`), the
product compared with the ideal instrument's, and the time it takes.

Every run of one comparison uses the same seed, so the noise of a pixel is drawn from the same numbers in every
run and the difference to the ideal run is the effect's alone (``rms_vs_ideal``); ``rms_vs_truth`` compares with
the ideal instrument without noise (the noise floor in the ideal row). The compared product is the L2 band
reflectance when the scene corrects the atmosphere, else calibrated radiance, else band radiance. ``score``
plugs in a map-level figure: a function of the simulated dataset (e.g. a retrieval map's RMS against the scene's
truth map) whose numbers enter each row.
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
    """One row: the instrument (``ideal`` or one effect on), its seconds per run and its product's RMS
    difference per band to the ideal instrument and to the noise-free ideal one (units of the product)."""

    instrument: str
    source: str
    seconds: float
    rms_vs_ideal: dict[str, float]
    rms_vs_truth: dict[str, float]
    score: dict[str, float] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        def mean(d: dict[str, float]) -> float:
            return float(np.mean(list(d.values()))) if d else float("nan")

        return {"instrument": self.instrument, "source": self.source, "seconds": self.seconds,
                "rms_vs_ideal_mean": mean(self.rms_vs_ideal), "rms_vs_truth_mean": mean(self.rms_vs_truth),
                "rms_vs_ideal": self.rms_vs_ideal, "rms_vs_truth": self.rms_vs_truth, "score": self.score}


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


def band_rms(a: xr.Dataset, b: xr.Dataset, prefix: str, names: list[str]) -> dict[str, float]:
    """Per band, the RMS of ``a − b`` over pixels finite in both (float64)."""
    out = {}
    for n in names:
        x, y = a[f"{prefix}_{n}"].values.astype(np.float64), b[f"{prefix}_{n}"].values.astype(np.float64)
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
    base = scene.spec.instrument.model_dump()
    for name in EFFECTS:
        base[name] = False
    ideal_scene = with_instrument(scene, base)
    prepared = load_scene_cube(ideal_scene, cube, wavelengths_nm)
    prefix = product_variable(ideal_scene)
    names = ideal_scene.sensor.band_names
    truth_scene = with_instrument(scene, base, effects={"noise": False})
    truth = simulate_cube(rt, truth_scene, prepared)
    ideal, seconds = _timed(rt, ideal_scene, prepared, repeats)
    rows = [EffectCost("ideal", "no instrument effect (noise and quantisation only)", seconds,
                       band_rms(ideal, ideal, prefix, names), band_rms(ideal, truth, prefix, names),
                       score(ideal) if score else {})]
    for name in effects:
        variant = with_instrument(scene, {**base, name: True})
        ds, seconds = _timed(rt, variant, prepared, repeats)
        rows.append(EffectCost(name, SOURCES[name], seconds, band_rms(ds, ideal, prefix, names),
                               band_rms(ds, truth, prefix, names), score(ds) if score else {}))
    return rows
