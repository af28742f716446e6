"""Search instead of sweep: the best design of a space from a fraction of its pixel-evaluations.

Successive halving on noise copies (``[sweep] search = "halving"``): every design of the start set is scored
on one noise copy of every spectrum, the best ``keep`` of them on ``1 / keep`` times more copies, and so on
until at most :attr:`SearchSettings.finalists` remain; those are scored on every copy, which is exactly the
exhaustive sweep's score of each (:mod:`s2cl.sweep.design_tables`: the same tables, kernel and noise
deviates). A rung ranks by the sweep's metric (:func:`s2cl.sweep.digest.metric_of`), ties by configuration
number; designs the ranking leaves out (``sweep.underdetermined``) and NaN scores rank last.

A space of more than :attr:`SearchSettings.start` designs starts from a coarse sub-grid of each band's centres
and widths (every ``s``-th, from an offset drawn from the seed), then refines: around the eight best finalists, all
bands at once move by ``± s/2`` lattice steps (halved to 1), each set of candidates halved as above. It does so from
:attr:`SearchSettings.restarts` sub-grids (the offsets moved by ``s / restarts`` steps each); the starts' best
designs are then crossed band by band (every design taking each band from one of them), halved and refined
``± 1`` step. Then, at the space's own step and on every pixel, each band alone over ``± radius`` steps of centre
and width and all bands together over ``± 1`` step, from the best design, until no design there scores better;
and from that local optimum each band alone over its whole range (halved, refined ``± 1``), back to the local
stage wherever that finds a better design. Where moving every centre and width at once gives more than
:data:`~s2cl.sweep.lattice.MAX_JOINT` designs (six bands and more), the refinement moves each band alone over
``± s/2`` steps, and it and the local step move all centres together, all widths together and every two bands in
centre and width at once (:meth:`~s2cl.sweep.lattice.Lattice.joint_moves`).

Each batch of designs is one chunk file (``chunks/part-E.parquet``, ``E`` the search's running count of
design evaluations, written atomically): the search is deterministic, so a killed search started again replays
its decisions from the files it finds and computes only the rest. ``results.parquet`` holds every design
evaluated, once, at the most copies it was scored on (``copies``, ``pixels``), ``full_fidelity`` marking those
scored on every pixel: only they are ranked (:func:`s2cl.sweep.report.rankable`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError
from s2cl.io.output import atomic_path, write_json
from s2cl.sweep.cluster import DASK_SCRATCH, dask_client
from s2cl.sweep.designs import DesignKernels, batch_job
from s2cl.sweep.digest import metric_of
from s2cl.sweep.engine import (
    MANIFEST,
    SweepJob,
    _manifest,
    _remove_sweep_files,
    check_folder,
    evaluate_chunk,
    results_meta,
)
from s2cl.sweep.folder import CHUNKS, RESULTS, chunk_done, chunk_path, write_chunk
from s2cl.sweep.lattice import MAX_JOINT, Lattice, unique_designs
from s2cl.sweep.raw import ChunkEvaluator

STRATEGIES = ("exhaustive", "halving")
#: configuration-pixel evaluations per batch at low fidelity (kernel launches and table gathers amortised)
BATCH_EVALUATIONS = 2_000_000
MAX_BATCH = 8192
#: finalists a refinement stage moves around (each basin among them keeps its chance)
REFINE_AROUND = 8


@dataclass(frozen=True)
class SearchSettings:
    """How a search runs (the [sweep] ``search*`` keys)."""

    strategy: str = "halving"
    keep: float = 0.25
    finalists: int = 16
    start: int = 100_000
    radius: int = 5
    seed: int = 0
    restarts: int = 4

    @classmethod
    def of_spec(cls, spec: Any) -> SearchSettings | None:
        """The settings of a scene's [sweep] section; None for the exhaustive sweep."""
        if spec is None or spec.search == "exhaustive":
            return None
        return cls(spec.search, spec.search_keep, spec.search_finalists, spec.search_start, spec.search_radius,
                   spec.search_seed, spec.search_restarts)

    def record(self) -> dict[str, Any]:
        return asdict(self)

    def schedule(self, copies: int) -> list[int]:
        """Noise copies of each rung: 1, 1/keep, 1/keep², … and finally ``copies``."""
        out, k, step = [], 1.0, 1.0 / self.keep
        while round(k) < copies:
            if not out or round(k) > out[-1]:
                out.append(round(k))
            k *= step
        return [*out, copies]


# -- scoring designs, resumably ------------------------------------------------------------------------

Evaluate = Callable[[Iterable[SweepJob]], Iterator[tuple[int, dict[str, np.ndarray]]]]


@dataclass
class Scorer:
    """Scores designs at a number of noise copies, each (design, copies) once; every batch a chunk file."""

    job: SweepJob
    out: Path
    evaluate: Evaluate
    lattice: Lattice
    memo: dict[int, dict[int, float]] = field(default_factory=dict)
    evaluations: int = 0
    pixel_evaluations: int = 0
    starts: list[int] = field(default_factory=list)

    def batch_rows(self, copies: int) -> int:
        """Designs per batch at ``copies``: about :data:`BATCH_EVALUATIONS`, at most the sweep's chunk scaled to
        the pixels, a power of two (one kernel build per fidelity)."""
        t = self.job.tables
        pixels = t.n_spectra * copies
        most = min(MAX_BATCH, max(1, self.job.chunk * t.n_pixels // pixels), max(1, BATCH_EVALUATIONS // pixels))
        return 1 << max(0, math.floor(math.log2(most)))

    def score(self, designs: np.ndarray, copies: int) -> np.ndarray:
        """The metric of ``designs`` on ``copies`` copies (+inf where the ranking leaves a design out)."""
        known = self.memo.setdefault(copies, {})
        configs = self.lattice.configs(designs)
        todo = np.flatnonzero([c not in known for c in configs.tolist()])
        if todo.size:
            _, first = np.unique(configs[todo], return_index=True)
            self._compute(designs[todo[np.sort(first)]], copies)
        return np.array([known[c] for c in configs.tolist()])

    def _compute(self, designs: np.ndarray, copies: int) -> None:
        rows = self.batch_rows(copies)
        batches, jobs = [], []
        for lo in range(0, len(designs), rows):
            part = designs[lo: lo + rows]
            start = self.evaluations
            self.evaluations += len(part)
            self.pixel_evaluations += len(part) * self.job.tables.n_spectra * copies
            self.starts.append(start)
            batches.append((start, part))
            if not self._resumed(start, part, copies):
                jobs.append((start, part))
        pending = {start: part for start, part in jobs}
        subjobs = (batch_job(self.job, part, copies, rows)
                   for _, part in jobs)  # gathered one at a time where they run one at a time
        for i, raw in self.evaluate(subjobs):
            start = jobs[i][0]
            self._store(start, self._rows(raw, pending[start], copies), copies)
        for start, part in batches:
            assert all(c in self.memo[copies] for c in self.lattice.configs(part).tolist()), start

    def _rows(self, raw: dict[str, np.ndarray], part: np.ndarray, copies: int) -> dict[str, np.ndarray]:
        n = len(part)
        rows = {k: np.asarray(v)[:n] for k, v in raw.items()}
        rows["config"] = self.lattice.configs(part)
        rows["copies"] = np.full(n, copies, dtype=np.int64)
        rows["pixels"] = np.full(n, self.job.tables.n_spectra * copies, dtype=np.int64)
        return rows

    def _store(self, start: int, rows: dict[str, np.ndarray], copies: int) -> None:
        write_chunk(self.out, start, rows)
        self._remember(rows, copies)

    def _remember(self, rows: dict[str, np.ndarray], copies: int) -> None:
        values = np.asarray(rows[metric_of(list(rows))], dtype=np.float64).copy()
        if self.job.underdetermined == "exclude":
            values[np.asarray(rows["underdetermined"], dtype=bool)] = np.inf
        values[np.isnan(values)] = np.inf
        self.memo[copies].update(zip(np.asarray(rows["config"]).tolist(), values.tolist(), strict=True))

    def _resumed(self, start: int, part: np.ndarray, copies: int) -> bool:
        """Whether batch ``start`` is on disk from an earlier run of this search (read into the memo)."""
        if not chunk_done(self.out, start, start + len(part)):
            return False
        import pyarrow.parquet as pq

        table = pq.read_table(chunk_path(self.out, start)).to_pydict()
        rows = {k: np.asarray(v) for k, v in table.items()}
        if not np.array_equal(rows["config"], self.lattice.configs(part)) or int(rows["copies"][0]) != copies:
            return False  # not this search's batch: recomputed and replaced
        self._remember(rows, copies)
        return True


# -- the strategy ----------------------------------------------------------------------------------------

@dataclass
class Halving:
    """Successive halving on noise copies, with coarse-to-fine refinement for spaces above ``start`` designs."""

    settings: SearchSettings
    scorer: Scorer
    copies: int
    stages: list[dict[str, Any]] = field(default_factory=list)

    def halve(self, pool: np.ndarray, stage: str) -> tuple[np.ndarray, np.ndarray]:
        """Finalists of ``pool`` scored on every copy, best first, and their scores."""
        s, lattice = self.settings, self.scorer.lattice
        alive = unique_designs(pool, lattice)
        rungs = []
        for k in self.settings.schedule(self.copies):
            if k < self.copies and len(alive) <= s.finalists:
                continue
            scores = self.scorer.score(alive, k)
            order = np.lexsort((lattice.configs(alive), scores))
            rungs.append({"copies": k, "designs": len(alive)})
            if k == self.copies:
                self.stages.append({"stage": stage, "rungs": rungs, "best": _finite(scores[order[0]])})
                return alive[order], scores[order]
            alive = alive[order[:max(s.finalists, math.ceil(len(alive) * s.keep))]]
        raise AssertionError("the schedule ends on every copy")

    def full(self, pool: np.ndarray, stage: str) -> tuple[np.ndarray, np.ndarray]:
        """``pool`` scored on every copy, best first."""
        lattice = self.scorer.lattice
        alive = unique_designs(pool, lattice)
        scores = self.scorer.score(alive, self.copies)
        order = np.lexsort((lattice.configs(alive), scores))
        self.stages.append({"stage": stage, "rungs": [{"copies": self.copies, "designs": len(alive)}],
                            "best": _finite(scores[order[0]])})
        return alive[order], scores[order]

    def run(self) -> np.ndarray:
        """The search; returns the best design (variant index per slot)."""
        s, lattice = self.settings, self.scorer.lattice
        pool, stride, offsets = lattice.coarse_offsets(s.start, np.random.default_rng(s.seed))
        if stride == 1:
            best, _ = self.halve(pool, "start: every design")
            return best[0]
        finals = []
        for r in range(s.restarts):
            if r:
                pool = lattice.sub_grid(stride, lattice.shifted(offsets, stride, r * stride // s.restarts))
            tag = f"start {r + 1} of {s.restarts}: " if s.restarts > 1 else "start: "
            best, _ = self.halve(pool, tag + f"sub-grid every {stride} steps")
            finals.append(self.refine(best, stride))
        best = self.recombine(finals) if len(finals) > 1 else finals[0]
        while True:
            incumbent = self.local(best)
            best = self.lines(incumbent)
            if not self.better(best[0], incumbent):
                return incumbent

    def refine(self, best: np.ndarray, stride: int) -> np.ndarray:
        """Finalists refined from ``stride`` steps down to 1: around the :data:`REFINE_AROUND` best, every band moved
        by ± half the step before, each set halved with the finalists before it."""
        lattice = self.scorer.lattice
        step = stride
        while step > 1:
            step = max(1, step // 2)
            top = best[:REFINE_AROUND]
            joint = [lattice.joint(d, step) for d in top] if 3 ** (2 * len(lattice.slots)) <= MAX_JOINT else \
                [np.concatenate([*(lattice.band_box(d, k, step) for k in range(len(lattice.slots))),
                                 lattice.joint_moves(d, step)]) for d in top]
            best, _ = self.halve(np.concatenate([best, *joint]), f"refine ± {step} steps")
        return best

    def recombine(self, finals: list[np.ndarray]) -> np.ndarray:
        """The starts' finalists crossed band by band: every design taking each band from one of the starts' best
        designs (:meth:`~s2cl.sweep.lattice.Lattice.crossed`), halved with all the finalists and refined ± 1 step."""
        lattice = self.scorer.lattice
        elite = unique_designs(np.stack([f[0] for f in finals]), lattice)
        best, _ = self.halve(np.concatenate([*finals, lattice.crossed(elite)]),
                             f"recombine the best of {len(finals)} starts band by band")
        return self.refine(best, 2)

    def better(self, design: np.ndarray, than: np.ndarray) -> bool:
        """Whether ``design`` scores better than ``than`` on every pixel (both scored there already); ties by
        configuration number, as a rung ranks."""
        pair = np.stack([design, than])
        (a, b), (sa, sb) = self.scorer.lattice.configs(pair).tolist(), self.scorer.score(pair, self.copies).tolist()
        return (sa, a) < (sb, b)

    def lines(self, incumbent: np.ndarray) -> np.ndarray:
        """The incumbent with each band alone moved over its whole range (halved), refined ± 1 step: a move between
        one band's basins that no local step makes."""
        best, _ = self.halve(np.concatenate([incumbent[None, :], self.scorer.lattice.lines(incumbent)]),
                             "each band alone over its whole range")
        return self.refine(best, 2)

    def local(self, best: np.ndarray) -> np.ndarray:
        """At the space's own step, on every pixel: the incumbent's neighbourhood until nothing there is better."""
        s, lattice = self.settings, self.scorer.lattice
        while True:
            incumbent = best[0]
            best, _ = self.full(np.concatenate([best[:1], lattice.neighbourhood(incumbent, s.radius)]),
                                f"local ± {s.radius} / ± 1 steps, every pixel")
            if np.array_equal(best[0], incumbent):
                return incumbent


def _finite(value: float) -> float | None:
    """A stage's best score for the record (None where no design has one)."""
    return float(value) if np.isfinite(value) else None


# -- running ------------------------------------------------------------------------------------------------

def prepare_search_folder(job: SweepJob, out: Path, *, overwrite: bool = False) -> None:
    """The output folder as :func:`s2cl.sweep.engine.prepare_folder` makes it (manifest with the search's
    settings in the fingerprint; another sweep or search refused unless ``overwrite``), without listing chunks."""
    old = check_folder(job, out, overwrite=overwrite)
    if overwrite or old is None or old.get("fingerprint") != job.fingerprint():
        if overwrite or old is not None:
            _remove_sweep_files(out)
        write_json(out / MANIFEST, {**_manifest(job), "search": job.search})
    (out / CHUNKS).mkdir(parents=True, exist_ok=True)


def _local(device: str | None, evaluator_of: Callable[[SweepJob], ChunkEvaluator] | None) -> Evaluate:
    """Batches in this process (:class:`s2cl.sweep.designs.DesignKernels`: one sweep kernel per fidelity, loaded
    with each batch's tables in turn), one launch each."""
    kernels = DesignKernels(device, evaluator_of)

    def evaluate(jobs: Iterable[SweepJob]) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        for i, j in enumerate(jobs):
            yield i, kernels.rows(j)
    return evaluate


def _on_dask(client: Any, device: str | None,
             evaluator_of: Callable[[SweepJob], ChunkEvaluator] | None) -> Evaluate:
    def evaluate(jobs: Iterable[SweepJob]) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        from dask.distributed import as_completed

        futures = {client.submit(evaluate_chunk, j, 0, j.n_configs, device,
                                 evaluator_of(j) if evaluator_of else None, pure=False): i
                   for i, j in enumerate(jobs)}
        for future in as_completed(futures):
            yield futures[future], future.result()
    return evaluate


def run_search(job: SweepJob, out: str | Path, *, workers: int | None = None, scheduler: str | None = None,
               overwrite: bool = False, device: str | None = None,
               evaluator_of: Callable[[SweepJob], ChunkEvaluator] | None = None) -> tuple[Path, dict[str, Any]]:
    """Run (or resume) the search ``job.search`` into folder ``out``: ``results.parquet`` and the search's
    record (strategy, settings, evaluations, pixel-evaluations, the exhaustive count, time, stages, best).

    :param evaluator_of: the chunk evaluator of a batch's job instead of the kernel (tests: the numpy twin).
    """
    if job.search is None:
        raise InputError("the sweep is exhaustive ([sweep] search)", key="sweep.search")
    settings = SearchSettings(**job.search)
    out = Path(out)
    prepare_search_folder(job, out, overwrite=overwrite)
    t0 = time.perf_counter()
    lattice = Lattice(job)

    def search(evaluate: Evaluate) -> tuple[Scorer, Halving, np.ndarray]:
        scorer = Scorer(job, out, evaluate, lattice)
        halving = Halving(settings, scorer, job.tables.copies)
        return scorer, halving, halving.run()

    if workers or scheduler:
        with dask_client(workers, scheduler, out / DASK_SCRATCH) as client:
            scorer, halving, best = search(_on_dask(client, device, evaluator_of))
    else:
        scorer, halving, best = search(_local(device, evaluator_of))
    path = merge_search(job, out, scorer.starts)
    t = job.tables
    record = {**settings.record(), "evaluations": scorer.evaluations,
              "pixel_evaluations": scorer.pixel_evaluations, "exhaustive_configurations": job.n_configs,
              "exhaustive_pixel_evaluations": job.n_configs * t.n_pixels,
              "pixel_evaluation_fraction": scorer.pixel_evaluations / (job.n_configs * t.n_pixels),
              "best_config": int(lattice.configs(best[None, :])[0]), "seconds": time.perf_counter() - t0,
              "stages": halving.stages}
    return path, record


def merge_search(job: SweepJob, out: Path, starts: list[int]) -> Path:
    """``results.parquet`` of a search: each design evaluated once, at the most copies it was scored on, in
    configuration order, ``full_fidelity`` marking those scored on every copy; the sweep's metadata."""
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    frames = [pd.read_parquet(chunk_path(out, s)) for s in starts]
    df = pd.concat(frames, ignore_index=True).sort_values(["config", "copies"], kind="stable")
    df = df.drop_duplicates("config", keep="last").reset_index(drop=True)
    df["full_fidelity"] = df["copies"].to_numpy() == job.tables.copies
    table = pa.Table.from_pandas(df, preserve_index=False)
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **results_meta(job)})
    path = out / RESULTS
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)
    return path
