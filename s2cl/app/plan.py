"""From a checked scene to a sweep: tables, analysis, chunking, and the scene's own band set as reference.

Everything here starts from :class:`s2cl.app.checks.Checked` (the scene resolved once): the tables are built from
its library, atmosphere terms and sensor, never from the scene again; the engines' errors get the scene's file here
(:func:`s2cl.errors.errors_in`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from s2cl.app.checks import Checked, check_sweep
from s2cl.app.sweep_budget import Budget, SweepPlan, sweep_resources
from s2cl.cl.runtime import get_runtime
from s2cl.errors import errors_in
from s2cl.retrieve.analysis import AnalysisSettings, analysis_targets
from s2cl.retrieve.design import count_underdetermined
from s2cl.scene.scene import Scene
from s2cl.sensor.variants import BandRange, SweepSpace
from s2cl.sweep.addition import base_reference, check_base_score, meta_of
from s2cl.sweep.designs import design_pixels, score_designs
from s2cl.sweep.engine import SweepJob
from s2cl.sweep.raw import RawChunk
from s2cl.sweep.search import SearchSettings
from s2cl.sweep.tables import SweepTables, build_tables


def sweep_tables(checked: Checked, space: SweepSpace, analysis: AnalysisSettings) -> SweepTables:
    """Tables of ``space`` scored by ``analysis``, from the checked scene's library, atmosphere terms and sensor (and
    the band tables it shares with the other applications of its scene, ``checked.shared_tables``)."""
    scene = checked.scene
    assert checked.library is not None and checked.truth is not None and checked.assumed is not None
    assert checked.sensor is not None and scene.spec.analysis is not None
    with errors_in(scene.source):
        lib, target, classes = analysis_targets(checked.library, analysis, scene.spec.analysis.classes)
        return build_tables(space, lib, checked.truth, checked.assumed, checked.sensor, scene.grid, scene.run,
                            scene.spec.effects, target=target, class_names=classes, shared=checked.shared_tables)


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
    assert checked.space is not None and checked.analysis is not None and scene.spec.sweep is not None
    tables = sweep_tables(checked, checked.space, checked.analysis)  # with [sweep.add]: the added band's too
    text = scene.path.read_text(encoding="utf-8") if scene.path else ""
    run = scene.run
    search = SearchSettings.of_spec(scene.spec.sweep)
    job = SweepJob(tables, checked.analysis, chunk=plan.chunk, precision=run.precision, lanes=run.lanes,
                   device=run.device, scene_name=scene.name, scene_text=text,
                   underdetermined=scene.spec.sweep.underdetermined, search=search.record() if search else None)
    base = checked.base
    if base is None:
        return job
    row = fixed_row(checked, job, base.space, base.analysis, device)
    with errors_in(scene.source):
        score = check_base_score(row, base.analysis)
    return replace(job, base_row=row, addition=meta_of(base, score))


def underdetermined_count(space: SweepSpace, analysis: AnalysisSettings) -> int | None:
    """Configurations of ``space`` the analysis cannot fit (:mod:`s2cl.retrieve.design`), counted without
    enumerating them; None when there are too many distinct centres to count."""
    return count_underdetermined(analysis, space)


@dataclass(frozen=True)
class OwnDesign:
    """The sensor's own band set (e.g. ESA's) as a design of a sweep: configuration ``config`` of ``job``, the sweep's
    own job when the design is one of its configurations, else a one-configuration job with tables of its own (built
    once, for both :func:`reference_row` and :func:`reference_pixels`)."""

    job: SweepJob
    config: int


def own_design(checked: Checked, job: SweepJob) -> OwnDesign:
    """The sensor's own design of ``job``'s sweep (:class:`OwnDesign`): its configuration when the sweep has it, else
    its own tables from the checked scene's library, atmosphere terms and noise deviates."""
    shapes = _own_shapes(checked, job)
    config = configuration_of(job.tables, shapes)
    if config is not None:  # the sensor's own design is one of the sweep's: its tables serve
        return OwnDesign(job, config)
    bands = SweepSpace(tuple(BandRange.fixed(b, c, w) for b, (c, w) in zip(job.tables.bands, shapes, strict=True)))
    with errors_in(checked.source):
        bands.validate()
    return OwnDesign(_one_job(checked, job, bands, job.analysis), 0)


def reference_row(checked: Checked, job: SweepJob, device: str | None = None,
                  own: OwnDesign | None = None) -> dict[str, Any]:
    """Metrics of the sensor's own band set (e.g. ESA's) with the same library, atmosphere and noise; for a
    band-addition sweep, the base set's row (:func:`s2cl.sweep.addition.base_reference`). ``own``: the design as
    :func:`own_design` gives it (default: found here; pass it to score it and its pixels on one set of tables)."""
    if job.base_row is not None:
        return base_reference(job.base_row, job.addition["band"])
    own = own or own_design(checked, job)
    return _first(score_designs(own.job, np.array([own.config]), device=device))


def reference_pixels(checked: Checked, job: SweepJob, device: str | None = None,
                     own: OwnDesign | None = None) -> RawChunk | None:
    """Per-pixel results of the sensor's own band set (:func:`reference_row`'s design) on the sweep's pixels and
    noise deviates, by the sweep kernel on ``device``; None for a band-addition sweep (its base set is another
    analysis). ``own``: as for :func:`reference_row`."""
    if job.base_row is not None:
        return None
    own = own or own_design(checked, job)
    return design_pixels(own.job, np.array([own.config]), device=device)


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


def _own_shapes(checked: Checked, job: SweepJob) -> list[tuple[float, float]]:
    """(centre, width) in nm of the sensor's own band in each of the sweep's slots."""
    sensor = checked.scene.sensor
    return [(sensor.band(b).centre_nm, sensor.band(b).fwhm_nm) for b in job.tables.bands]


def _one_job(checked: Checked, job: SweepJob, space: SweepSpace, analysis: AnalysisSettings) -> SweepJob:
    """``job`` over the one configuration of ``space`` (fixed bands) scored by ``analysis``."""
    tables = sweep_tables(checked, space, analysis)
    return replace(job, tables=tables, analysis=analysis, chunk=1, base_row=None, addition=None, search=None)


def fixed_row(checked: Checked, job: SweepJob, space: SweepSpace, analysis: AnalysisSettings,
              device: str | None = None) -> dict[str, Any]:
    """Metrics of the one configuration of ``space`` (fixed bands) scored by ``analysis``, with ``job``'s library,
    atmosphere, noise deviates (keyed by each band's index in the checked sensor), precision and device."""
    return _first(score_designs(_one_job(checked, job, space, analysis), np.array([0]), device=device))


def count_table(checked: Checked | SweepSpace) -> list[dict[str, Any]]:
    """Variants per band (count and extremes) of the checked sweep (or of a sweep space), for ``s2cl sweep
    count``."""
    space = checked if isinstance(checked, SweepSpace) else checked.space
    assert space is not None
    rows = []
    for r, n in zip(space.ranges, space.counts, strict=True):
        c0, c1, w0, w1 = r.extent()
        rows.append({"band": r.band, "variants": n, "centres_nm": f"{c0:g}–{c1:g}", "widths_nm": f"{w0:g}–{w1:g}"})
    return rows
