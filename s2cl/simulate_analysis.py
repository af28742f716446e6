"""The scene's analysis on a simulation with the sensor's own bands (``s2cl simulate``): IGRM,
GVMI or SAM on the corrected band reflectances, scored with the same metrics as a sweep row."""

from __future__ import annotations

from typing import Any

import numpy as np

from .analysis import AnalysisSettings
from .errors import InputError
from .metrics import classification_metrics, regression_metrics
from .scene import Scene
from .simulate import LibrarySimulation

RED_EDGE = ["B4", "B5", "B6", "B7"]


def analysis_bands(scene: Scene) -> list[str]:
    a = scene.spec.analysis
    if a.bands:
        return a.bands
    if scene.spec.sweep is not None:
        return list(scene.spec.sweep.bands)
    if a.kind == "igrm":
        return RED_EDGE
    if a.kind == "gvmi":
        return [a.nir or "B8", a.swir or "B11"]
    return list(scene.sensor.band_names)


def analyse(scene: Scene, sim: LibrarySimulation) -> dict[str, Any]:
    """Metrics of the scene's [analysis] on ``sim`` (needs the correct effect)."""
    if sim.reflectance is None:
        raise InputError("the analysis needs band reflectance: set effects.atmosphere and effects.correct",
                         source=scene.source, key="effects.correct")
    bands = analysis_bands(scene)
    rows = [sim.sensor.band_names.index(scene.sensor.band(b).name) for b in bands]
    settings = AnalysisSettings.from_scene(scene, bands)
    refl = sim.reflectance[rows].reshape(len(rows), -1)
    lib = sim.library
    out: dict[str, Any] = {"kind": settings.kind, "bands": bands}
    if settings.kind == "sam":
        classes = scene.spec.analysis.classes or sorted(set(lib.groups))
        keep = np.isin(np.array(lib.groups), classes)
        truth = np.repeat([classes.index(g) if g in classes else -1 for g in lib.groups], sim.copies)
        pixels = np.repeat(keep, sim.copies)
        refs = _class_references(scene, lib, bands, classes)
        from .sam import SamClassifier

        threshold = settings.angle_threshold_deg
        result = SamClassifier(refs, threshold_rad=None if threshold is None else np.deg2rad(threshold)).classify(
            refl[:, pixels])
        m = classification_metrics(np.maximum(result.label, 0)[None], _sam_status(result)[None],
                                   truth[pixels], len(classes))
        out.update(classes=classes, confusion=m.pop("confusion")[0].tolist())
    else:
        target = np.repeat(np.asarray(lib.params[settings.parameter], dtype=np.float64), sim.copies)
        if settings.kind == "igrm":
            from .igrm import IgrmFitter, IgrmSettings

            centres = np.array([scene.sensor.band(b).centre_nm for b in bands])
            order = np.argsort(centres, kind="stable")
            fit = IgrmFitter(len(bands), IgrmSettings.from_mapping(dict(settings.igrm), source=scene.source))
            r = fit.fit(refl[order], centres[order])
            index, status, bounds = r.lp, r.status, r.bounds
        else:
            from .gvmi import GvmiKernel

            g = GvmiKernel()(refl, settings.nir_slot, settings.swir_slot)
            index, status, bounds = g.gvmi, g.status, np.zeros_like(g.status)
        m = regression_metrics(index[None], status[None], bounds[None], target)
        out["parameter"] = settings.parameter
    out.update({k: np.asarray(v)[0].item() for k, v in m.items()})
    return out


def _sam_status(result: Any) -> np.ndarray:
    """SAM statuses in the shared codes (0 classified, 2 unclassified, 3 invalid)."""
    return np.where(result.label >= 0, 0, np.where(result.status >= 2, 3, 2)).astype(np.uint8)


def _class_references(scene: Scene, lib: Any, bands: list[str], classes: list[str]) -> np.ndarray:
    """Mean noise-free band reflectance of each class's spectra (the references SAM compares to)."""
    groups = np.array(lib.groups)
    out = np.empty((len(classes), len(bands)))
    for k, b in enumerate(bands):
        w = scene.sensor.band(b).weights(scene.grid, scene.spec.sensor.support, scene.source)
        band_rho = lib.spectra[:, w.start : w.stop] @ w.weights
        out[:, k] = [band_rho[groups == c].mean() for c in classes]
    return out
