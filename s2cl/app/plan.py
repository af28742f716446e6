"""From a scene to a sweep: tables, analysis, chunking, and the scene's own band set as reference."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from s2cl.app.checks import Checked, check_sweep
from s2cl.app.sweep_budget import Budget, SweepPlan, sweep_resources
from s2cl.cl.runtime import get_runtime
from s2cl.libraries.library import SpectralLibrary
from s2cl.retrieve.analysis import AnalysisSettings, analysis_targets
from s2cl.retrieve.design import count_underdetermined
from s2cl.scene.library import scene_library
from s2cl.scene.scene import Scene
from s2cl.scene.terms import correction_terms, scene_terms
from s2cl.sensor.variants import BandRange, SweepSpace
from s2cl.sweep.addition import base_reference, check_base_score, meta_of
from s2cl.sweep.designs import design_pixels, score_designs
from s2cl.sweep.engine import SweepJob
from s2cl.sweep.raw import RawChunk
from s2cl.sweep.search import SearchSettings
from s2cl.sweep.space import addition_scene
from s2cl.sweep.tables import SweepTables, build_tables, sweep_space


def _tables(scene: Scene, space: SweepSpace, analysis: AnalysisSettings,
            library: SpectralLibrary | None = None) -> SweepTables:
    lib, target, classes = analysis_targets(scene, library or scene_library(scene), analysis)
    return build_tables(scene, space, lib, scene_terms(scene), correction_terms(scene), target=target,
                        class_names=classes)


def plan_sweep(scene: Scene, *, chunk: int | None = None, checked: Checked | None = None,
               budget: Budget | None = None, host_metrics: bool = True, device: str | None = None,
               resources: SweepPlan | None = None) -> SweepJob:
    """The sweep a scene describes, ready for :func:`s2cl.sweep.engine.run_sweep`: checked (:mod:`s2cl.app.checks`),
    its memory estimated against ``budget`` and the memory of ``device`` before the tables are built
    (``host_metrics``: see :func:`s2cl.app.sweep_budget.sweep_resources`), the chunk chosen to fit both. A
    band-addition sweep's base set is scored here, on ``device`` (:func:`fixed_row`), and the job carries it (each
    row's ``gain``). ``resources``: the estimate the caller already made (its chunk is used; nothing is estimated
    twice)."""
    checked = checked or check_sweep(scene)
    plan = resources or sweep_resources(checked, chunk=chunk, budget=budget, host_metrics=host_metrics,
                                        rt=get_runtime(device or scene.run.device))
    assert checked.space is not None and checked.analysis is not None
    tables_scene = addition_scene(scene)  # with [sweep.add]: the added band in the sensor
    tables = _tables(tables_scene, checked.space, checked.analysis, checked.library)
    text = scene.path.read_text(encoding="utf-8") if scene.path else ""
    run = scene.run
    search = SearchSettings.of_spec(scene.spec.sweep)
    job = SweepJob(tables, checked.analysis, chunk=plan.chunk, precision=run.precision, lanes=run.lanes,
                   device=run.device, scene_name=scene.name, scene_text=text,
                   underdetermined=scene.spec.sweep.underdetermined, search=search.record() if search else None)
    base = checked.base
    if base is None:
        return job
    row = fixed_row(tables_scene, job, base.space, base.analysis, checked.library, device)
    score = check_base_score(scene, row, base.analysis)
    return replace(job, base_row=row, addition=meta_of(base, score))


def underdetermined_count(space: SweepSpace, analysis: AnalysisSettings) -> int | None:
    """Configurations of ``space`` the analysis cannot fit (:mod:`s2cl.retrieve.design`), counted without
    enumerating them; None when there are too many distinct centres to count."""
    return count_underdetermined(analysis, space)


def reference_row(scene: Scene, job: SweepJob, device: str | None = None,
                  library: SpectralLibrary | None = None) -> dict[str, Any]:
    """Metrics of the sensor's own band set (e.g. ESA's) with the same library, atmosphere and noise; for a
    band-addition sweep, the base set's row (:func:`s2cl.sweep.addition.base_reference`). ``library``: the sweep's,
    as the checks loaded it (default: loaded again from the scene) where the design needs tables of its own."""
    if job.base_row is not None:
        return base_reference(job.base_row, job.addition["band"])
    shapes = _own_shapes(scene, job)
    config = configuration_of(job.tables, shapes)
    if config is not None:  # the sensor's own design is one of the sweep's: its tables serve
        return _first(score_designs(job, np.array([config]), device=device))
    return fixed_row(scene, job, _own_bands(scene, job), job.analysis, library, device)


def _first(rows: dict[str, Any]) -> dict[str, Any]:
    """The first row of ``rows`` (column → array) as plain values."""
    return {k: (v[0].item() if isinstance(v, np.ndarray) else v) for k, v in rows.items()}


def configuration_of(tables: SweepTables, shapes: list[tuple[float, float]]) -> int | None:
    """The configuration number of the design whose slot ``k`` has centre and width ``shapes[k]`` (nm), or None
    when a slot has no such variant (within 1e-9 nm): the mixed radix of :mod:`s2cl.sweep.raw`."""
    config = 0
    for k, (c, w) in enumerate(shapes):
        hit = np.flatnonzero((np.abs(tables.centre[k] - c) <= 1e-9) & (np.abs(tables.width[k] - w) <= 1e-9))
        if hit.size == 0:
            return None
        config = config * tables.counts[k] + int(hit[0])
    return config


def reference_pixels(scene: Scene, job: SweepJob, device: str | None = None,
                     library: SpectralLibrary | None = None) -> RawChunk | None:
    """Per-pixel results of the sensor's own band set (:func:`reference_row`'s design) on the sweep's pixels and
    noise deviates, by the sweep kernel on ``device``; None for a band-addition sweep (its base set is another
    analysis). ``library``: as for :func:`reference_row`."""
    if job.base_row is not None:
        return None
    config = configuration_of(job.tables, _own_shapes(scene, job))
    if config is not None:
        return design_pixels(job, np.array([config]), device=device)
    return design_pixels(_one_job(scene, job, _own_bands(scene, job), job.analysis, library), np.array([0]),
                         device=device)


def _own_shapes(scene: Scene, job: SweepJob) -> list[tuple[float, float]]:
    """(centre, width) in nm of the sensor's own band in each of the sweep's slots."""
    return [(scene.sensor.band(b).centre_nm, scene.sensor.band(b).fwhm_nm) for b in job.tables.bands]


def _own_bands(scene: Scene, job: SweepJob) -> SweepSpace:
    """The sweep's bands fixed at the sensor's own shapes."""
    return SweepSpace(tuple(BandRange.fixed(b, c, w) for b, (c, w) in zip(job.tables.bands, _own_shapes(scene, job),
                                                                          strict=True))).validate(scene.source)


def _one_job(scene: Scene, job: SweepJob, space: SweepSpace, analysis: AnalysisSettings,
             library: SpectralLibrary | None = None) -> SweepJob:
    """``job`` over the one configuration of ``space`` (fixed bands) scored by ``analysis``."""
    tables = _tables(scene, space, analysis, library)
    return replace(job, tables=tables, analysis=analysis, chunk=1, base_row=None, addition=None, search=None)


def fixed_row(scene: Scene, job: SweepJob, space: SweepSpace, analysis: AnalysisSettings,
              library: SpectralLibrary | None = None, device: str | None = None) -> dict[str, Any]:
    """Metrics of the one configuration of ``space`` (fixed bands) scored by ``analysis``, with ``job``'s library,
    atmosphere, noise deviates (keyed by each band's index in ``scene``'s sensor), precision and device."""
    return _first(score_designs(_one_job(scene, job, space, analysis, library), np.array([0]), device=device))


def count_table(scene: Scene) -> list[dict[str, Any]]:
    """Variants per band (count and extremes) for ``s2cl sweep count``."""
    space = sweep_space(scene)
    rows = []
    for r, n in zip(space.ranges, space.counts, strict=True):
        c0, c1, w0, w1 = r.extent()
        rows.append({"band": r.band, "variants": n, "centres_nm": f"{c0:g}–{c1:g}", "widths_nm": f"{w0:g}–{w1:g}"})
    return rows
