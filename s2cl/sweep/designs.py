"""Scoring given designs of a sweep: the one engine call for any set of configuration numbers (the reference row,
the within-noise set, designs numbered past the kernel's 32-bit configuration numbers) and the batches of a
search's rungs.

Designs are gathered into tables of their own (:func:`s2cl.sweep.design_tables.design_tables`: each design's rows of
the sweep's tables, its noise deviates, so the same scores as in the exhaustive sweep, bit for bit), ``rows``
designs per batch, and each batch is one launch of the sweep kernel. The kernel is built once per batch shape (noise
copies, rows) and loaded with each batch's tables in turn (:meth:`s2cl.sweep.kernel.SweepKernel.load`). A batch
numbers its designs ``0 … rows-1``, so a design numbered past the kernel's 32-bit configuration numbers is no special
case.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from s2cl.cl.runtime import get_runtime
from s2cl.sweep.design_tables import config_tables, design_tables
from s2cl.sweep.engine import SweepJob, evaluate_chunk, last_one
from s2cl.sweep.kernel import SweepKernel
from s2cl.sweep.raw import ChunkEvaluator, RawChunk

#: designs per launch at most when scoring given configurations (the sweep's chunk, sized to the memory budget,
#: bounds it too): the within-noise set's default 100 candidates and the reference row take one launch each, on
#: one kernel build
DESIGN_BATCH = 128


@dataclass
class DesignKernels:
    """The evaluators of batches of designs of one sweep on ``device``: a sweep kernel per batch shape (noise copies,
    rows), built on first use and loaded with each later batch's tables; or (``evaluator_of``) an evaluator made
    per batch (tests: the float64 numpy twin)."""

    device: str | None = None
    evaluator_of: Callable[[SweepJob], ChunkEvaluator] | None = None
    kernels: dict[tuple[int, int], ChunkEvaluator] = field(default_factory=dict)

    def evaluator(self, job: SweepJob) -> ChunkEvaluator:
        """The evaluator of ``job``, a batch of designs (:func:`batch_job`)."""
        if self.evaluator_of is not None:
            return self.evaluator_of(job)
        key = (job.tables.copies, job.n_configs)
        kernel = self.kernels.get(key)
        if kernel is None:
            kernel = self.kernels[key] = SweepKernel(job.tables, job.analysis, get_runtime(self.device or job.device),
                                                     precision=job.precision, lanes=job.lanes)
        else:
            kernel.load(job.tables)  # type: ignore[attr-defined]
        return kernel

    def rows(self, job: SweepJob, n: int | None = None) -> dict[str, np.ndarray]:
        """Rows (:func:`s2cl.sweep.engine.evaluate_chunk`: centres, widths, metrics) of the first ``n`` designs of
        batch ``job`` (default: all of its rows), in one launch."""
        return evaluate_chunk(job, 0, job.n_configs if n is None else n, evaluator=self.evaluator(job))

    def pixels(self, job: SweepJob, n: int) -> RawChunk:
        """Per-pixel results of the first ``n`` designs of batch ``job``, in one launch."""
        return self.evaluator(job)(0, n)


#: the kernels of the sweep last scored here: (job fingerprint, device) → its kernels (one sweep at a time)
_KERNELS: dict[tuple[str, str | None], DesignKernels] = {}


def design_kernels(job: SweepJob, device: str | None = None,
                   evaluator_of: Callable[[SweepJob], ChunkEvaluator] | None = None) -> DesignKernels:
    """The kernels that score designs of ``job`` on ``device``, kept between calls (the reference row, its pixels and
    the within-noise set share one build); with ``evaluator_of``, that evaluator per batch instead (not kept)."""
    if evaluator_of is not None:
        return DesignKernels(device, evaluator_of)
    return last_one(_KERNELS, (job.fingerprint(), device), lambda: DesignKernels(device))


def batch_job(job: SweepJob, designs: np.ndarray, copies: int, rows: int) -> SweepJob:
    """``job`` over the designs ``designs`` (variant index per slot) on ``copies`` noise copies, as tables of
    ``rows`` rows (the last design repeats)."""
    return replace(job, tables=design_tables(job.tables, designs, copies, rows), chunk=rows)


def batch_rows(job: SweepJob) -> int:
    """Designs per launch when scoring given configurations of ``job``: :data:`DESIGN_BATCH`, at most its chunk."""
    return max(1, min(job.chunk, DESIGN_BATCH))


def _batches(job: SweepJob, configs: np.ndarray) -> Iterator[tuple[SweepJob, int]]:
    """(batch job, designs in it) of configurations ``configs`` of ``job`` on every copy, :func:`batch_rows` each."""
    if configs.size == 0:
        raise ValueError("no configuration to score")
    rows = batch_rows(job)
    for lo in range(0, configs.size, rows):
        part = configs[lo: lo + rows]
        yield replace(job, tables=config_tables(job.tables, part, rows), chunk=rows), part.size


def score_designs(job: SweepJob, configs: np.ndarray, *, device: str | None = None,
                  evaluator_of: Callable[[SweepJob], ChunkEvaluator] | None = None) -> dict[str, np.ndarray]:
    """Rows of configurations ``configs`` of ``job`` (any numbers, any order), as the exhaustive sweep gives them
    (:func:`s2cl.sweep.engine.evaluate_chunk`: ``config``, centres, widths, metrics), row ``i`` for ``configs[i]``;
    one kernel launch per :func:`batch_rows` designs. ``evaluator_of``: an evaluator per batch instead of the kernel
    (tests: the numpy twin)."""
    configs = np.asarray(configs, dtype=np.int64).ravel()
    kernels = design_kernels(job, device, evaluator_of)
    parts = [kernels.rows(batch, n) for batch, n in _batches(job, configs)]
    rows = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    rows["config"] = configs
    return rows


def design_pixels(job: SweepJob, configs: np.ndarray, *, device: str | None = None,
                  evaluator_of: Callable[[SweepJob], ChunkEvaluator] | None = None) -> RawChunk:
    """Per-pixel results of configurations ``configs`` of ``job`` on every copy (row ``i`` for ``configs[i]``; the
    sweep's pixels and noise deviates), one kernel launch per :func:`batch_rows` designs."""
    configs = np.asarray(configs, dtype=np.int64).ravel()
    kernels = design_kernels(job, device, evaluator_of)
    parts = [kernels.pixels(batch, n) for batch, n in _batches(job, configs)]
    condition = None if any(p.condition is None for p in parts) else np.concatenate([p.condition for p in parts])
    return RawChunk(0, configs.size, np.concatenate([p.index for p in parts]),
                    np.concatenate([p.status for p in parts]), np.concatenate([p.bounds for p in parts]), condition)
