"""The search of a scene with several applications (``[sweep] search = "halving"`` with ``[[application]]``):
successive halving over the joint designs that keeps, at every rung, each design that could still be on the
Pareto front, not the best by one number.

A joint design's score vector on ``k`` noise copies is each application's score of its projection (its own
configuration of the application's own sweep, :meth:`~s2cl.app.multi_optimise.PreparedApplication.configs_of`) on
the first ``min(k, copies)`` copies of that application's library, computed with the application's own job
(:class:`s2cl.sweep.search.Scorer`: the same tables, kernel and noise deviates as its exhaustive sweep, each
projection scored once per fidelity however many joint designs share it). Every joint design starts on one copy;
a rung keeps whole non-dominated layers (the Pareto front of the rung's scores, then the front of the rest, …)
until at least ``search_keep`` of its designs (and at least ``search_finalists``) are kept, every design of the
first layer always; the next rung scores them on ``1 / search_keep`` times more copies, up to every copy. It runs
in three steps: the joint designs with strict layers; each application's own sub-space by the single-application
halving (:class:`s2cl.sweep.search.Halving`), for the :data:`~s2cl.sweep.pareto.MARGIN_TOP` best designs its
noise margin is measured on (:func:`s2cl.sweep.pareto.noise_margin`, as the exhaustive run's trade-off measures
it; each also reaches every copy in a joint design, so the trade-off of the results finds the same margins); then
the joint designs again with layers sorted within those margins, scaled by ``sqrt(copies / k)`` on ``k`` copies.
The front is then :func:`s2cl.sweep.pareto.front` of the full-fidelity scores (:mod:`s2cl.sweep.trade_off`), so a
design that reaches the last rung has exactly the exhaustive run's scores.

Spaces of more than ``search_start`` joint designs (the coarse-to-fine refinement of the single-application
search) are refused in one line (:func:`check_front_search`).

Each application's batches are chunk files of its own folder (``applications/<name>/chunks/``, as a single-
application search writes them): the search is deterministic, so a killed search started again replays its
decisions from them. ``results.parquet`` holds every joint design evaluated, at the most copies it reached
(``copies``: the rung's; ``pixels``: its pixel-evaluations summed over the applications), with the first
application's row, one score column per application and ``full_fidelity`` marking those scored on every copy of
every application: only they are ranked (:func:`s2cl.sweep.digest.rankable_rows`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError
from s2cl.sweep.engine import SweepJob, prepare_folder
from s2cl.sweep.folder import chunk_path, merge_chunks, write_chunk
from s2cl.sweep.joint import indices_of
from s2cl.sweep.lattice import Lattice
from s2cl.sweep.pareto import MARGIN_TOP, front, noise_margin
from s2cl.sweep.raw import ChunkEvaluator
from s2cl.sweep.search import Halving, Scorer, SearchSettings, _local, prepare_search_folder


def check_front_search(search: str, search_start: int, joint_designs: int, source: str | None = None) -> None:
    """Refuse, in one line, a multi-application search (``search``, the [sweep] key) over more than
    ``search_start`` joint designs (the coarse-to-fine start of the single-application search is not there yet for
    several applications); ``source``: the scene file named in the message."""
    if search == "exhaustive" or joint_designs <= search_start:
        return
    raise InputError(f"search = {search!r} on a scene with several applications covers at most search_start = "
                     f"{search_start:,} joint designs; this [sweep] has {joint_designs:,}: raise search_start, "
                     "narrow the ranges or use search = 'exhaustive'", source=source, key="sweep.search_start")


def layers_kept(scores: np.ndarray, keep: int, margins: np.ndarray | None = None) -> np.ndarray:
    """``bool[n]``: the designs of ``scores`` ``(n, applications)`` (lower is better, +inf: cannot be scored) in
    whole non-dominated layers (:func:`s2cl.sweep.pareto.front` under ``margins``, default 0), from the first,
    until at least ``keep`` are kept; the first layer always, whole. Designs that cannot be scored for some
    application join only when every scored design is kept."""
    n = len(scores)
    kept = np.zeros(n, dtype=bool)
    finite = np.isfinite(scores).all(axis=1)
    rest = np.flatnonzero(finite)
    while rest.size and (not kept.any() or kept.sum() < keep):
        layer = front(scores[rest], margins)
        kept[rest[layer]] = True
        rest = rest[~layer]
    if kept.sum() < keep:  # fewer scored designs than asked: the unscored ones, in configuration order
        kept[np.flatnonzero(~finite)[:keep - int(kept.sum())]] = True
    return kept


@dataclass
class FrontHalving:
    """Successive halving of the joint designs on their score vectors (one :class:`Scorer` per application)."""

    settings: SearchSettings
    scorers: list[Scorer]
    #: each application's map of joint configuration numbers onto its own
    to_own: list[Callable[[np.ndarray], np.ndarray]]
    copies: list[int]
    #: per rung: copies, joint designs scored, pixel-evaluations it took and designs kept
    rungs: list[dict[str, Any]] = field(default_factory=list)
    #: the rung (copies on the longest schedule) each joint design reached
    reached: dict[int, int] = field(default_factory=dict)

    def vectors(self, configs: np.ndarray, k: int) -> np.ndarray:
        """Score vectors ``(len(configs), applications)`` of joint ``configs`` on ``k`` copies (each application
        on ``min(k, its copies)``; +inf where its ranking leaves a design out)."""
        out = np.empty((len(configs), len(self.scorers)))
        for i, (scorer, own, c) in enumerate(zip(self.scorers, self.to_own, self.copies, strict=True)):
            mine = own(configs)
            unique, back = np.unique(mine, return_inverse=True)
            designs = indices_of(tuple(int(x) for x in scorer.lattice.counts), unique)
            out[:, i] = scorer.score(designs, min(k, c))[back]
        return out

    def run(self, n_joint: int, margins: np.ndarray | None = None) -> np.ndarray:
        """The joint configurations scored on every copy (the last rung's designs). ``margins``: each application's
        noise margin on every copy; a rung on ``k`` copies sorts its layers with them scaled by
        ``sqrt(copies / k)`` (the noise of a mean over fewer copies), none by default."""
        s, most = self.settings, max(self.copies)
        alive = np.arange(n_joint, dtype=np.int64)
        for k in s.schedule(most):
            if k < most and len(alive) <= s.finalists:
                continue
            before = [sc.pixel_evaluations for sc in self.scorers]
            scores = self.vectors(alive, k)
            for c in alive.tolist():
                self.reached[c] = max(k, self.reached.get(c, 0))
            rung: dict[str, Any] = {"copies": k, "designs": len(alive),
                                    "pixel_evaluations": sum(sc.pixel_evaluations for sc in self.scorers) - sum(before)}
            self.rungs.append(rung)
            if k == most:
                return alive
            scaled = None if margins is None else margins * np.sqrt(
                np.array(self.copies) / np.minimum(k, np.array(self.copies)))
            if scaled is not None:
                rung["margins"] = [float(x) for x in scaled]
            kept = layers_kept(scores, max(s.finalists, math.ceil(len(alive) * s.keep)), scaled)
            rung["kept"] = int(kept.sum())
            alive = alive[kept]
        raise AssertionError("the schedule ends on every copy")


def run_front_search(prepared: Any, folder: str | Path, *, overwrite: bool = False, device: str | None = None,
                     evaluator_of: Callable[[SweepJob], ChunkEvaluator] | None = None) -> tuple[Path, dict[str, Any]]:
    """Run (or resume) the search of the multi-application sweep ``prepared``
    (:class:`~s2cl.app.multi_optimise.PreparedApplications`, its jobs carrying the [sweep] search settings) into
    ``folder``: the joint ``results.parquet`` and the search's record (settings, evaluations, pixel-evaluations
    against the exhaustive multi-application sweep's, time, rungs)."""
    out = Path(folder)
    first = prepared.first.job
    if first.search is None:
        raise InputError("the sweep is exhaustive ([sweep] search)", key="sweep.search")
    joint = prepared.joint
    settings = SearchSettings(**first.search)
    check_front_search(settings.strategy, settings.start, joint.n_configs)
    prepare_folder(joint, out, overwrite=overwrite, manifest={**joint.manifest(), "search": first.search})
    t0 = time.perf_counter()
    scorers = []
    for a in prepared.apps:
        prepare_search_folder(a.job, a.folder, overwrite=overwrite)
        scorers.append(Scorer(a.job, a.folder, _local(device, evaluator_of), Lattice(a.job)))
    halving = FrontHalving(settings, scorers, [a.configs_of for a in prepared.apps],
                           [a.job.tables.copies for a in prepared.apps])
    strict = halving.run(joint.n_configs)
    passes = [{"stage": "pass 1, every joint design, whole strict Pareto layers kept", "rungs": halving.rungs}]
    margins = []
    for a, scorer in zip(prepared.apps, scorers, strict=True):  # each application's margin, as the exhaustive run's
        best = own_best(a, scorer, settings, passes)
        margins.append(noise_margin(a.job, best, a.joint.score, device=device, evaluator_of=evaluator_of)["margin"])
        carriers = carrying(joint.counts, a.joint.slots, int(strict[0]), indices_of(tuple(a.joint.counts), best))
        halving.vectors(carriers, max(halving.copies))  # its best designs on every copy, in joint designs
        for c in carriers.tolist():
            halving.reached[c] = max(halving.copies)
    margins = np.asarray(margins)
    halving.rungs = []
    halving.run(joint.n_configs, margins)
    passes.append({"stage": "pass 2, every joint design again, whole Pareto layers within the noise margins "
                            "(scaled for the copies) kept", "margins": [float(x) for x in margins],
                   "rungs": halving.rungs})
    path = merge_front_search(prepared, out, scorers, halving.reached)
    exhaustive = sum(a.job.n_configs * a.job.tables.n_pixels for a in prepared.apps)
    used = sum(sc.pixel_evaluations for sc in scorers)
    record = {**settings.record(), "applications": [a.name for a in prepared.apps],
              "evaluations": sum(sc.evaluations for sc in scorers), "pixel_evaluations": used,
              "joint_configurations": joint.n_configs,
              # what the exhaustive run evaluates: each application's own sub-space
              "exhaustive_configurations": sum(a.job.n_configs for a in prepared.apps),
              "exhaustive_application_configurations": [a.job.n_configs for a in prepared.apps],
              "exhaustive_pixel_evaluations": exhaustive, "pixel_evaluation_fraction": used / exhaustive,
              "full_fidelity_designs": sum(1 for k in halving.reached.values() if k == max(halving.copies)),
              "seconds": time.perf_counter() - t0, "stages": passes}
    return path, record


def own_best(app: Any, scorer: Scorer, settings: SearchSettings, passes: list[dict[str, Any]]) -> np.ndarray:
    """The :data:`~s2cl.sweep.pareto.MARGIN_TOP` best of ``app``'s own designs on every copy (best first, ties by
    configuration number, those its ranking leaves out never), by the single-application halving over its whole
    sub-space: the designs its noise margin is measured on, as the exhaustive run measures it; the stage joins
    ``passes``."""
    lattice = scorer.lattice
    every = indices_of(tuple(int(n) for n in lattice.counts), np.arange(app.job.n_configs, dtype=np.int64))
    single = Halving(dataclasses.replace(settings, finalists=max(settings.finalists, MARGIN_TOP)), scorer,
                     app.job.tables.copies)
    designs, scores = single.halve(every, f"{app.name}: its own designs, its best {MARGIN_TOP} for its margin")
    passes.extend(single.stages)
    return lattice.configs(designs)[np.isfinite(scores)][:MARGIN_TOP]


def carrying(counts: tuple[int, ...], slots: tuple[int | None, ...], base: int, own: np.ndarray) -> np.ndarray:
    """Joint configuration numbers of the joint design ``base`` with an application's bands (its ``slots`` in the
    joint space) set to each of its own designs ``own`` (variant indices per own slot)."""
    idx = np.repeat(indices_of(counts, np.array([base])), len(own), axis=0)
    for k, slot in enumerate(slots):
        if slot is not None:
            idx[:, slot] = own[:, k]
    strides = np.array([int(np.prod(counts[k + 1:])) for k in range(len(counts))], dtype=np.int64)
    return idx @ strides


def merge_front_search(prepared: Any, out: Path, scorers: list[Scorer], reached: dict[int, int]) -> Path:
    """``results.parquet`` of a multi-application search: each joint design evaluated, once, at the rung it
    reached, in configuration order: ``config``, the band shapes, the first application's row, each application's
    score column (NaN where its ranking leaves the design out, as :class:`~s2cl.sweep.joint.JointJob` writes it),
    ``copies``, ``pixels`` and ``full_fidelity``; the joint table's metadata."""
    import pandas as pd

    joint = prepared.joint
    configs = np.array(sorted(reached), dtype=np.int64)
    k = np.array([reached[c] for c in configs.tolist()], dtype=np.int64)
    idx = indices_of(joint.counts, configs)
    rows: dict[str, Any] = {"config": configs}
    for b, band in enumerate(joint.bands):
        rows[f"{band}_centre_nm"] = joint.centre[b][idx[:, b]]
        rows[f"{band}_width_nm"] = joint.width[b][idx[:, b]]
    pixels = np.zeros(len(configs), dtype=np.int64)
    for i, (a, scorer) in enumerate(zip(prepared.apps, scorers, strict=True)):
        mine = pd.concat([pd.read_parquet(chunk_path(a.folder, s)) for s in scorer.starts], ignore_index=True)
        mine = mine.drop_duplicates(["config", "copies"], keep="last").set_index(["config", "copies"])
        copies = np.minimum(k, a.job.tables.copies)
        at = mine.loc[list(zip(a.configs_of(configs).tolist(), copies.tolist(), strict=True))]
        if i == 0:
            for c in at.columns:
                if c != "pixels" and not c.endswith(("_centre_nm", "_width_nm")):
                    rows[c] = at[c].to_numpy()
        score = at[a.joint.score].to_numpy(dtype=np.float64)
        if a.joint.exclude:
            score = np.where(at["underdetermined"].to_numpy(dtype=bool), np.nan, score)
        rows[a.column] = score
        pixels += at["pixels"].to_numpy(dtype=np.int64)
    rows["copies"], rows["pixels"] = k, pixels
    rows["full_fidelity"] = k == max(a.job.tables.copies for a in prepared.apps)
    write_chunk(out, 0, rows)  # the joint folder's one chunk, then results.parquet with the joint metadata
    return merge_chunks(out, [0], joint.meta)


__all__ = ["FrontHalving", "check_front_search", "layers_kept", "merge_front_search", "run_front_search"]
