"""``s2cl optimise`` of a scene with several applications (``[[application]]``): each application's own sweep over its
own sub-space, then the joint results table by lookup, ranked for the first application and reported with one
record per application.

The folder holds the joint sweep (``manifest.json``, ``chunks/``, ``results.parquet``, ``summary.json``, heatmaps)
and, under ``applications/<name>/``, each application's own sweep (its manifest, chunks and results): a killed run
resumes every part. :class:`PreparedApplications` is what the other parts of issue 35 use per application: its
single-application :class:`~s2cl.app.checks.Checked`, its :class:`~s2cl.sweep.engine.SweepJob` and
:meth:`PreparedApplication.configs_of` (joint configuration numbers → its own), so that the within-noise machinery
(:mod:`s2cl.sweep.within_noise`) runs per application.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import s2cl.sweep.joint as joint_table
from s2cl.app.applications import ApplicationPart, CheckedApplications, check_applications
from s2cl.app.checks import Checked
from s2cl.app.plan import OwnDesign, own_design, plan_sweep, reference_pixels, reference_row
from s2cl.app.sweep_budget import require_sweep_disk, sweep_resources
from s2cl.cl.runtime import get_runtime
from s2cl.io.budget import Budget, require_disk
from s2cl.sensor.names import safe_file_part
from s2cl.sweep.digest import TOP
from s2cl.sweep.engine import (
    SweepJob,
    check_folder,
    keep_together,
    kernel_evaluator,
    prepare_folder,
    results_disk_bytes,
    results_meta,
    resumable_chunk,
    run_sweep,
)
from s2cl.sweep.front_search import check_front_search
from s2cl.sweep.joint import APPLICATIONS, JointApplication, JointJob, indices_of, run_joint
from s2cl.sweep.metrics_kernel import metrics_on_device
from s2cl.sweep.report import Digest, heatmap, open_results, shapes, summarise
from s2cl.sweep.trade_off import trade_off
from s2cl.sweep.within_noise import mark_top, within_noise


@dataclass(frozen=True, eq=False)
class PreparedApplication:
    """One application of a prepared multi-application sweep: its checked part (:class:`ApplicationPart`: its
    single-application scene and :class:`~s2cl.app.checks.Checked`), its planned sweep ``job`` over its own
    sub-space, the ``folder`` of that sweep, and how the joint table reads it (``joint``)."""

    part: ApplicationPart
    job: SweepJob
    folder: Path
    joint: JointApplication
    #: the joint space's variants per band (for :meth:`configs_of`)
    joint_counts: tuple[int, ...]

    @property
    def name(self) -> str:
        return self.part.name

    @property
    def checked(self) -> Checked:
        """Its single-application scene, checked (the shared library, terms and sweep space's parts)."""
        return self.part.checked

    @property
    def column(self) -> str:
        """Its score column in the joint results (``<name>_<score column>``)."""
        return self.part.column

    def configs_of(self, joint_configs: np.ndarray) -> np.ndarray:
        """Its own configuration numbers (of :attr:`job`) of the joint configuration numbers ``joint_configs``."""
        return self.joint.configs_of(indices_of(self.joint_counts, joint_configs))


@dataclass(frozen=True, eq=False)
class PreparedApplications:
    """A multi-application sweep checked and planned: the checked scene, the applications in the order written,
    and the joint table's job."""

    checked: CheckedApplications
    apps: tuple[PreparedApplication, ...]
    joint: JointJob

    @property
    def first(self) -> PreparedApplication:
        """The application whose row the joint table carries (ranking, heatmaps, reference, within noise)."""
        return self.apps[0]


def prepare_applications(scene: Any, folder: Path, *, budget: Budget, chunk: int | None, device: str | None,
                         overwrite: bool, distributed: bool) -> PreparedApplications:
    """Check the scene's applications (:func:`s2cl.app.applications.check_applications`), then plan each
    application's sweep (memory, chunk, tables, kernel) and the joint table, and check every folder they will use
    and the disk they need: nothing is created here."""
    checked = check_applications(scene, budget=budget)
    check_front_search(scene.spec.sweep.search, scene.spec.sweep.search_start, checked.space.size,
                       source=scene.source)  # a search: at most search_start joint designs
    rt = get_runtime(device or scene.run.device)
    host_metrics = not metrics_on_device(rt, distributed=distributed)
    space = checked.space
    n_apps = len(checked.parts)
    # the joint chunks and results (the first application's columns, a score per application) and, while they are
    # written, the applications' columns mapped from disk (the first one's whole row, a score and a flag of others)
    lookups = sum(p.space.size * 8 * (len(p.metric.columns) + 2 if i == 0 else 2) for i, p in enumerate(checked.parts))
    require_disk(folder, results_disk_bytes(space.size, len(space.ranges) + n_apps + 8) + lookups,
                 what=f"the joint results of {space.size:,} designs ([sweep]: {len(space.ranges)} bands)",
                 key="sweep", source=scene.source)
    apps, joint_apps, together = [], [], []
    counts = tuple(int(n) for n in space.counts)
    for i, part in enumerate(checked.parts):
        sub = folder / APPLICATIONS / part.name
        require_sweep_disk(part.checked, sub)
        plan = sweep_resources(part.checked, chunk=chunk, budget=budget, resumed=resumable_chunk(sub, overwrite),
                               host_metrics=host_metrics, rt=rt)
        job = plan_sweep(part.scene, checked=part.checked, device=device, resources=plan)
        job = dataclasses.replace(job, scene_name=f"{scene.name}/{part.name}")  # what its manifest and progress say
        check_folder(job, sub, overwrite=overwrite)
        together.append(job.fingerprint())
        keep_together(together)  # each application's kernel serves its run and its designs' scores: built once
        if not distributed:
            kernel_evaluator(job, device)  # each kernel builds (and is checked) before the folder is made
        exclude = job.underdetermined != "keep"
        ja = JointApplication(part.name, part.column, part.metric.score_column, i == 0, part.slots,
                              tuple(int(n) for n in part.space.counts), exclude, job.fingerprint())
        joint_apps.append(ja)
        apps.append(PreparedApplication(part, job, sub, ja, counts))
    per_band = space.per_band
    joint = JointJob(tuple(r.band for r in space.ranges), counts, tuple(v[:, 0].copy() for v in per_band),
                     tuple(v[:, 1].copy() for v in per_band), tuple(joint_apps), scene.name, {},
                     chunk=joint_table.JOINT_CHUNK)
    records = [application_record(a) for a in apps]
    meta = {**results_meta(apps[0].job), b"scene": scene.name.encode(), b"fingerprint": joint.fingerprint().encode(),
            b"bands": json.dumps(list(joint.bands)).encode(), b"applications": json.dumps(records).encode()}
    joint = dataclasses.replace(joint, meta=meta)
    check_folder(joint, folder, overwrite=overwrite)  # a JointJob has a SweepJob's fingerprint(), chunk and chunks()
    return PreparedApplications(checked, tuple(apps), joint)


def application_record(a: PreparedApplication, reference: float | None = None) -> dict[str, Any]:
    """``summary.json``'s record of one application: name, kind, parameter, metric (its score column), units,
    column (in ``results.parquet``), target (in the metric's units, or None) and reference (the sensor's own
    bands' score, or None)."""
    analysis = a.part.app.analysis
    return {"name": a.name, "kind": analysis.kind, "parameter": analysis.parameter,
            "metric": a.part.metric.score_column, "units": a.part.metric.unit(analysis.parameter),
            "column": a.column, "target": a.part.target, "bands": list(a.part.bands),
            "reference": None if reference is None or not np.isfinite(reference) else float(reference)}


def run_applications(prepared: PreparedApplications, folder: Path, *, workers: int | None, scheduler: str | None,
                     overwrite: bool, device: str | None, progress: Callable[[int], None] | None = None,
                     on_start: Callable[[Any, int, int], None] | None = None) -> Path:
    """Run (or resume) each application's sweep, then write (or resume) the joint table into the (claimed)
    ``folder``; the path of the joint ``results.parquet``. The joint manifest is written first: ``overwrite``
    clears the folder, the applications' sweeps included, before any of them runs."""
    prepare_folder(prepared.joint, folder, overwrite=overwrite, manifest=prepared.joint.manifest())
    results = []
    for a in prepared.apps:
        started = (lambda todo, done, job=a.job: on_start(job, todo, done)) if on_start else None
        results.append(run_sweep(a.job, a.folder, progress=progress, on_start=started, workers=workers,
                                 scheduler=scheduler, overwrite=overwrite, device=device))
    return run_joint(prepared.joint, folder, results)


def rank_applications(prepared: PreparedApplications, results: Path, device: str | None
                      ) -> tuple[Digest, dict[str, Any]]:
    """Rank the joint results for the first application against the sensor's own bands, test its best designs
    within noise (as a single-application sweep does, on its own job), and add ``applications``: one record per
    application with the sensor's own bands' score for it."""
    first = prepared.first
    path, meta = open_results(results)
    owns: list[OwnDesign] = [own_design(a.checked, a.job) for a in prepared.apps]
    # each application's kernels kept beside the others', its own design's (a one-design job) too
    keep_together([j.fingerprint() for j in {id(j): j for a, own in zip(prepared.apps, owns, strict=True)
                                             for j in (a.job, own.job)}.values()])
    rows = [reference_row(a.checked, a.job, device, own) for a, own in zip(prepared.apps, owns, strict=True)]
    reference = _joint_reference(prepared, rows)
    candidates = first.checked.scene.spec.sweep.within_noise_top
    digest = Digest.of_file(path, meta, reference=reference, top_n=max(TOP, candidates))
    summary = summarise(digest, meta, reference)
    if candidates:
        tested = _within_noise(prepared, digest, candidates, device, owns[0])
        if tested is not None:
            summary["within_noise"] = tested
        mark_top(summary)
    summary["applications"] = [application_record(a, row.get(a.part.metric.score_column))
                               for a, row in zip(prepared.apps, rows, strict=True)]
    add_pareto(prepared, results, summary, device)
    return digest, summary


def add_pareto(prepared: PreparedApplications, results: Path, summary: dict[str, Any], device: str | None) -> None:
    """The trade-off (:func:`s2cl.sweep.trade_off.trade_off`): the Pareto front over the applications' columns of
    ``results`` (``summary["applications"][i]["column"]``), each application's noise margin measured on its own
    sweep's job, into ``summary["pareto"]``, the ``pareto`` column of ``results`` and, for two or more applications,
    :data:`~s2cl.sweep.trade_off.FIGURE` beside it."""
    record, _ = trade_off(results, summary["applications"], [a.job for a in prepared.apps],
                          [a.configs_of for a in prepared.apps], device=device)
    summary["pareto"] = record


def unread_by_first(summary: dict[str, Any], bands: list[str]) -> list[str]:
    """The ``bands`` the first application of a multi-application sweep's ``summary`` does not read (its ranking's
    metric does not depend on them); none for a single-application sweep."""
    apps = summary.get("applications") or []
    return [b for b in bands if apps and b not in apps[0].get("bands", bands)]


def application_heatmaps(digest: Digest, summary: dict[str, Any], folder: Path, bands: list[str]) -> list[Path]:
    """A heatmap of each of ``bands`` (bands the first application does not read) for the first application that
    reads it: its score column's best over the other bands at each centre × width (one more pass over the results
    per application drawn); the files written."""
    written, digests = [], {}
    for b in bands:
        app = next((a for a in summary["applications"] if b in a.get("bands", ())), None)
        if app is None or not isinstance(digest.source, Path):
            continue
        column = app["column"]
        if column not in digests:  # every design counts: the column is NaN where this application cannot fit it
            digests[column] = Digest.of_file(digest.source, {"underdetermined": "keep"}, metric_column=column)
        title = f"{b}: {column}\n(best over the other bands; red: best)"
        written.append(heatmap(digests[column], b, folder / f"heatmap_{safe_file_part(b)}.png", metric=column,
                               unit=app.get("units") or "", title=title))
    return written


def _joint_reference(prepared: PreparedApplications, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The reference row of the joint table: the first application's row of the sensor's own bands, the sensor's
    own centre and width of every joint band, each application's own-bands score in its column, and ``config``
    where the joint space holds the sensor's own design."""
    sensor, joint = prepared.checked.scene.sensor, prepared.joint
    ref = dict(rows[0])
    config = 0
    for k, b in enumerate(joint.bands):
        c, w = sensor.band(b).centre_nm, sensor.band(b).fwhm_nm
        ref[f"{b}_centre_nm"], ref[f"{b}_width_nm"] = c, w
        hit = np.flatnonzero((np.abs(joint.centre[k] - c) <= 1e-9) & (np.abs(joint.width[k] - w) <= 1e-9))
        config = None if config is None or hit.size == 0 else config * joint.counts[k] + int(hit[0])
    ref.pop("config", None)  # the first application's number; the joint one where the sweep holds the design
    if config is not None:
        ref["config"] = config
    for a, row in zip(prepared.apps, rows, strict=True):
        ref[a.column] = row.get(a.part.metric.score_column, float("nan"))
    return ref


def _within_noise(prepared: PreparedApplications, digest: Digest, candidates: int, device: str | None,
                  own: OwnDesign) -> dict[str, Any] | None:
    """The first application's within-noise test of the joint ranking's best designs: their configurations of its
    own job, scored per pixel there; the record names the joint configurations and bands."""
    first = prepared.first
    top = digest.top.head(candidates)
    if top is None or len(top) < 2:
        return None
    joint_configs = top["config"].to_numpy(np.int64)
    mine = top.copy()
    mine["config"] = first.configs_of(joint_configs)
    tables = first.job.tables
    for k, b in enumerate(tables.bands):  # a band the [sweep] does not move: the sensor's own, its one variant
        if f"{b}_centre_nm" not in mine.columns:
            mine[f"{b}_centre_nm"], mine[f"{b}_width_nm"] = float(tables.centre[k][0]), float(tables.width[k][0])
    tested = within_noise(first.job, mine, digest.metric, device=device,
                          reference=reference_pixels(first.checked, first.job, device, own), ranked=digest.ranked)
    if tested is None:
        return None
    for d, (_, row), jc in zip(tested["designs"], top.iterrows(), joint_configs, strict=True):
        d["application_config"], d["config"] = d["config"], int(jc)
        d["bands"] = shapes(row, list(prepared.joint.bands))
    tested["configs"] = [d["config"] for d in tested["designs"] if d["within"]]
    return tested
