"""The scene's analysis on a simulation with the sensor's own bands (``s2cl simulate``): IGRM, a
normalised-difference index (GVMI, ...), a formula or SAM on the corrected band reflectances, scored with the same
metrics as a sweep row."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from s2cl.cl.runtime import Runtime
from s2cl.errors import InputError, errors_in
from s2cl.forward.simulate import LibrarySimulation
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.design import check_design
from s2cl.retrieve.family import family_of
from s2cl.scene.scene import Scene
from s2cl.status import Status


def analysis_bands(scene: Scene) -> list[str]:
    """The bands ``s2cl simulate`` analyses: the scene's ``analysis.bands``, else the swept bands, else its
    family's default (:meth:`s2cl.retrieve.family.Family.default_bands`)."""
    a = scene.spec.analysis
    if a.bands:
        return a.bands
    if scene.spec.sweep is not None:
        return list(scene.spec.sweep.bands)
    try:
        return family_of(a.kind, scene.source).default_bands(a, scene.sensor.band_names)
    except InputError as err:
        raise InputError(err.detail, source=scene.source, key=err.key) from None


def analysis_design(scene: Scene, bands: list[str] | None = None,
                    settings: AnalysisSettings | None = None) -> tuple[list[str], AnalysisSettings]:
    """The bands and settings of the scene's [analysis] (``bands``, ``settings``: as the caller already has them),
    refused in one line (file and key) when the retrieval cannot fit that design (:mod:`s2cl.retrieve.design`, the
    rule sweeps apply): call it before work."""
    bands = bands if bands is not None else analysis_bands(scene)
    if settings is None:
        with errors_in(scene.source):
            settings = AnalysisSettings.from_spec(scene.spec.analysis, bands)
    shapes = [scene.sensor.band(b) for b in bands]
    check_design(settings, bands, [b.centre_nm for b in shapes], [b.fwhm_nm for b in shapes],
                 source=scene.source, key="analysis.bands")
    return bands, settings


@dataclass
class PixelResults:
    """Per-pixel outcome of the scene's analysis on a simulation, in the sweep kernel's terms
    (:class:`s2cl.sweep.raw.RawChunk`): ``index`` (λp nm, the index, or SAM class with
    ``len(classes)`` for none), ``status`` (:class:`s2cl.status.Status`), ``bounds``, ``condition``
    (IGRM codes, else None), and the regression ``target`` or the SAM ``truth`` (empty for an image without
    one); ``pixels`` selects the simulated pixels analysed (SAM: those of the chosen classes)."""

    settings: AnalysisSettings
    bands: list[str]
    index: np.ndarray
    status: np.ndarray
    bounds: np.ndarray
    condition: np.ndarray | None
    target: np.ndarray
    pixels: np.ndarray
    classes: list[str] | None = None


def check_image_analysis(scene: Scene, settings: AnalysisSettings) -> None:
    """Refuse, in one line, an [analysis] an image cube cannot carry: a classification needs class references
    from a library, which an image does not have."""
    if not settings.regression:
        raise InputError(f"{settings.kind} on an image cube needs class references from a spectral library; an "
                         "image's analysis maps a retrieval (igrm, an index or a formula)", source=scene.source,
                         key="analysis.kind")


def retrieve_pixels(rt: Runtime, scene: Scene, bands: list[str], settings: AnalysisSettings, refl: np.ndarray, *,
                    target: np.ndarray | None = None, references: np.ndarray | None = None,
                    classes: list[str] | None = None) -> PixelResults:
    """The scene's retrieval on band reflectance ``refl`` ``(len(bands), pixels)`` (a library's copies or an
    image's pixels), on ``rt``, in the scene's precision, with the same stage functions the sweep kernel runs
    (so one design gets one verdict). A pixel with a non-finite reflectance in any band is INVALID (index NaN).
    SAM needs the ``references`` ``(len(classes), len(bands))`` of its ``classes``."""
    real_t, lanes = scene.run.precision, scene.run.lanes
    refl = np.asarray(refl)
    target = np.empty(0) if target is None else target
    family = settings.family
    if family.metric.classifies and (references is None or classes is None):
        raise InputError(f"{settings.kind} needs class references from a spectral library", source=scene.source,
                         key="analysis.kind")
    centres = np.array([scene.sensor.band(b).centre_nm for b in bands])
    r = family.run(rt, settings, bands, refl, centres, real_t=real_t, lanes=lanes, references=references)
    out = PixelResults(settings, bands, r.index, r.status, r.bounds, r.condition, target,
                       np.ones(refl.shape[1], dtype=bool), classes)
    return _invalid_where_not_finite(out, refl)


def _invalid_where_not_finite(r: PixelResults, refl: np.ndarray) -> PixelResults:
    """Pixels with a non-finite reflectance in any band: status INVALID, index NaN, no bound."""
    bad = ~np.isfinite(refl).all(axis=0)
    if bad.any():
        r.index = np.where(bad, np.nan, r.index)
        r.status = np.where(bad, np.uint8(Status.INVALID), r.status).astype(r.status.dtype)
        r.bounds = np.where(bad, 0, r.bounds).astype(r.bounds.dtype)
    return r


def pixel_results(rt: Runtime, scene: Scene, sim: LibrarySimulation) -> PixelResults:
    """Run the scene's [analysis] on ``sim``'s corrected band reflectance (:func:`retrieve_pixels`)."""
    if sim.reflectance is None:
        raise InputError("the analysis needs band reflectance: set effects.atmosphere and effects.correct",
                         source=scene.source, key="effects.correct")
    bands, settings = analysis_design(scene)
    rows = [sim.sensor.band_names.index(scene.sensor.band(b).name) for b in bands]
    refl = sim.reflectance[rows].reshape(len(rows), -1)
    lib = sim.library
    if settings.family.metric.classifies:
        classes = scene.spec.analysis.classes or sorted(set(lib.groups))
        pixels = np.repeat(np.isin(np.array(lib.groups), classes), sim.copies)
        truth = np.repeat([classes.index(g) if g in classes else -1 for g in lib.groups], sim.copies)
        r = retrieve_pixels(rt, scene, bands, settings, refl[:, pixels], target=truth[pixels],
                            references=_class_references(scene, lib, bands, classes), classes=classes)
        r.pixels = pixels
        return r
    target = np.repeat(np.asarray(lib.params[settings.parameter], dtype=np.float64), sim.copies)
    return retrieve_pixels(rt, scene, bands, settings, refl, target=target)


def analyse(rt: Runtime, scene: Scene, sim: LibrarySimulation) -> dict[str, Any]:
    """Metrics of the scene's [analysis] on ``sim``, run on ``rt`` (the simulation's device): the same
    columns a sweep row has."""
    r = pixel_results(rt, scene, sim)
    out: dict[str, Any] = {"kind": r.settings.kind, "bands": r.bands}
    metric = r.settings.family.metric
    m = metric.metrics(r.index[None], r.status[None], r.bounds[None], r.target, regress=r.settings.regress,
                       n_classes=len(r.classes or ()), condition=None if r.condition is None else r.condition[None])
    out.update(metric.labels(r.settings.parameter, r.classes))
    if "confusion" in m:  # a classification's confusion matrix: a list, not a per-configuration metric
        out["confusion"] = m.pop("confusion")[0].tolist()
    out.update({k: np.asarray(v)[0].item() for k, v in m.items()})
    out["summary"] = r.settings.family.summary_line(out)
    return out


def _class_references(scene: Scene, lib: Any, bands: list[str], classes: list[str]) -> np.ndarray:
    """Mean noise-free band reflectance of each class's spectra (the references SAM compares to)."""
    groups = np.array(lib.groups)
    out = np.empty((len(classes), len(bands)))
    for k, b in enumerate(bands):
        w = scene.sensor.band(b).weights(scene.grid, scene.run.support, scene.source)
        band_rho = lib.spectra[:, w.start : w.stop] @ w.weights
        out[:, k] = [band_rho[groups == c].mean() for c in classes]
    return out
