"""The one validation of the fused sweep kernel, run by every benchmark before it times the kernel.

Criterion (:func:`validate_sweep`): on :data:`CONFIGS` configurations spread over the sweep (the
first and the last included), the kernel and the float64 numpy evaluator
(:func:`s2cl.reference.sweep.evaluate`: the same tables, the same noise draws) give

- the same status class on at least :data:`SAME_STATUS_MIN` of the pixels (fitted: converged, stalled or
  iteration limit; degenerate; invalid: the float32 verdict may call a fit stalled that float64 carries
  to convergence, a precision difference the sweep reports honestly, so the exact status is recorded
  beside it, not checked), and
- each configuration's regression RMS (the number a sweep ranks designs by, computed as the sweep
  computes it) within :data:`RMS_REL_MAX` relative of the float64 one.

Otherwise :class:`bench.common.BenchValidationError` is raised and nothing is timed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from bench.common import check, max_rel_error

CONFIGS = 6
SAME_STATUS_MIN = 0.99
RMS_REL_MAX = 1e-3
CRITERION = (f"on {CONFIGS} configurations spread over the sweep: the same status class (fitted / degenerate / "
             f"invalid) on >= {SAME_STATUS_MIN:.0%} of "
             f"the pixels and each configuration's RMS within {RMS_REL_MAX:g} relative of the float64 numpy "
             "evaluator's, same noise draws")


def spread(n_configs: int, k: int) -> list[int]:
    """``k`` configuration numbers spread over ``n_configs`` (the ends included)."""
    return sorted({int(x) for x in np.rint(np.linspace(0, n_configs - 1, k))})


def _rms(job: Any, raw: Any) -> float:
    """The configuration's RMS as the sweep reports it (its regression statuses and condition codes)."""
    from s2cl.retrieve.metrics import regression_metrics

    a = job.analysis
    return float(regression_metrics(raw.index, raw.status, raw.bounds, job.tables.target, regress=a.regress,
                                    condition=raw.condition if a.family.has_condition else None)["rms"][0])


def _quantiles(d: np.ndarray) -> dict[str, float]:
    """Median, 99th percentile and max of ``d`` (NaN where it is empty)."""
    if not d.size:
        return {"p50": float("nan"), "p99": float("nan"), "max": float("nan")}
    return {"p50": float(np.median(d)), "p99": float(np.percentile(d, 99)), "max": float(d.max())}


def _status_class(status: np.ndarray) -> np.ndarray:
    """Fitted statuses (converged, stalled, iteration limit) as one class; the others as they are."""
    from s2cl.status import Status

    fitted = (status == Status.OK) | (status == Status.STALLED) | (status == Status.ITERATION_LIMIT)
    return np.where(fitted, Status.OK, status)


def _one(job: Any, run: Callable[[int, int], Any], c: int) -> tuple[float, float, np.ndarray, float, float]:
    """Configuration ``c`` by ``run`` and by the float64 evaluator: the share of equal status classes and
    of equal statuses, the index differences where both are OK, the kernel's RMS and the float64 RMS."""
    from s2cl.reference.sweep import evaluate
    from s2cl.status import Status

    ref, got = evaluate(job.tables, job.analysis, c, c + 1), run(c, c + 1)
    same = got.status == ref.status
    same_class = _status_class(got.status) == _status_class(ref.status)
    diff = np.abs(got.index - ref.index)[same & (ref.status == Status.OK)]
    return float(same_class.mean()), float(same.mean()), diff, _rms(job, got), _rms(job, ref)


def validate_sweep(job: Any, kernel: Callable[[int, int], Any] | None = None) -> dict[str, Any]:
    """Check ``kernel`` (``kernel(start, stop)`` → raw chunk; default: the job's own evaluator, as
    :func:`s2cl.sweep.engine.evaluate_chunk` runs it) against the float64 numpy evaluator on a few
    configurations of the regression sweep ``job`` (see the module's criterion). Returns what was
    measured (JSON), or raises :class:`bench.common.BenchValidationError`."""
    from s2cl.sweep.engine import kernel_evaluator as evaluator

    if not job.analysis.regression:
        raise ValueError("validate_sweep compares RMS: it needs a regression sweep (igrm, gvmi, formula)")
    run, configs = kernel or evaluator(job), spread(job.n_configs, CONFIGS)
    same_class, same, diff, rms_got, rms_ref = zip(*(_one(job, run, c) for c in configs), strict=True)
    out = {"configurations": configs, "same_status_class_fraction": float(np.mean(same_class)),
           "same_status_fraction": float(np.mean(same)),
           "index_abs_diff": _quantiles(np.concatenate(diff)), "rms_rel_diff_max": max_rel_error(rms_got, rms_ref),
           "criterion": CRITERION}
    check(out["same_status_class_fraction"] >= SAME_STATUS_MIN and out["rms_rel_diff_max"] <= RMS_REL_MAX,
          f"the sweep kernel disagrees with the float64 numpy evaluator ({CRITERION}): {out}")
    return out
