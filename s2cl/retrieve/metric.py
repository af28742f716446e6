"""What a retrieval's designs are scored by, as one object beside its family (:attr:`Family.metric
<s2cl.retrieve.family.Family.metric>`): a regression of a library parameter on the index (:data:`REGRESSION`: RMS,
R², ...) or a classification against the library's classes (:data:`CLASSIFICATION`: mean omission error, ...).

A metric says what the sweep ranks on (:attr:`Metric.score_column`), what its metrics kernel writes
(:attr:`Metric.columns`), what the ranking prints beside the score, how the within-noise bootstrap scores a design
(:meth:`Metric.spectrum_stats`, :meth:`Metric.score`, :attr:`Metric.stratified`), the numpy metrics of per-pixel
results (:meth:`Metric.metrics`), its words and units. The application, the sweep, the studies and the CLI ask it
instead of choosing between regression and classification; a new metric is a new instance here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from s2cl.libraries.params import PARAMETER_UNITS
from s2cl.retrieve.metrics import classification_metrics, regression_metrics
from s2cl.retrieve.spectrum_stats import (
    classification_score,
    classification_stats,
    regression_score,
    regression_stats,
)


@dataclass(frozen=True)
class Metric:
    """How designs are scored (lower is better).

    :param name: ``"regression"`` or ``"classification"``: the metrics kernel's template kind and its entry point
        ``<name>_metrics``.
    :param score_column: the results column a design is ranked on (and a band addition's gain taken on).
    :param columns: the metrics kernel's output columns, in order (``"host"``: the row is recomputed on the host).
    :param ranking_columns: what the CLI's ranking prints after the score: (column, heading, format spec); a
        row without the column prints an empty cell.
    :param regressed: the index is regressed on a library parameter (``analysis.parameter`` is required); else the
        truth is each spectrum's class among the library's groups (class references needed).
    :param stratified: the within-noise bootstrap resamples spectra within their class.
    :param pixel_scratch: the metrics kernel needs ``n_configs × n_pixels`` doubles of scratch (its medians).
    """

    name: str
    score_column: str
    columns: tuple[str, ...]
    ranking_columns: tuple[tuple[str, str, str], ...]
    regressed: bool
    stratified: bool
    pixel_scratch: bool

    @property
    def classifies(self) -> bool:
        """The truth is a class per spectrum (class references from the library are needed)."""
        return not self.regressed

    @property
    def kernel_name(self) -> str:
        """The metrics kernel's entry point (``kernels/metrics.cl.mako``)."""
        return f"{self.name}_metrics"

    def score_label(self, parameter: str | None) -> str:
        """What the score is, in words (``RMS of cab`` for the ``parameter`` regressed, ``omission error``)."""
        raise NotImplementedError

    def unit(self, parameter: str | None) -> str:
        """The score's unit (``µg/cm²`` for cab, ``%``; empty when unknown)."""
        raise NotImplementedError

    def gain_unit(self, parameter: str | None) -> str:
        """The unit of a difference of two scores, in words (a band addition's gain)."""
        raise NotImplementedError

    def summary_line(self, result: dict[str, Any]) -> str:
        """One line of a simulation's analysis result (:func:`s2cl.app.analysis.analyse`)."""
        raise NotImplementedError

    def labels(self, parameter: str | None, classes: Sequence[str] | None) -> dict[str, Any]:
        """What a simulation's analysis result names besides its metrics (the ``parameter`` regressed, or the
        ``classes``)."""
        raise NotImplementedError

    def metrics(self, index: np.ndarray, status: np.ndarray, bounds: np.ndarray, target: np.ndarray, *,
                regress: Sequence[int], n_classes: int, condition: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Per-configuration metrics (numpy, float64) of per-pixel results ``(n_configs, n_pixels)`` against the
        per-pixel ``target`` (a parameter's value, or a class index); a classification adds ``confusion``."""
        raise NotImplementedError

    def spectrum_stats(self, index: np.ndarray, status: np.ndarray, target: np.ndarray, copies: int, *,
                       regress: Sequence[int], n_classes: int) -> np.ndarray:
        """Per design and library spectrum, the sums :meth:`score` needs ``(n_designs, n_spectra, m)`` (each
        spectrum's ``copies`` consecutive pixels summed): the within-noise bootstrap resamples them."""
        raise NotImplementedError

    def score(self, sums: np.ndarray) -> np.ndarray:
        """The score of summed :meth:`spectrum_stats` ``(..., m)``."""
        raise NotImplementedError


@dataclass(frozen=True)
class _Regression(Metric):
    def score_label(self, parameter: str | None) -> str:
        return f"RMS of {parameter}"

    def unit(self, parameter: str | None) -> str:
        return PARAMETER_UNITS.get(str(parameter), "")

    def gain_unit(self, parameter: str | None) -> str:
        return PARAMETER_UNITS.get(str(parameter), "parameter units")

    def summary_line(self, result: dict[str, Any]) -> str:
        r, bands = result, " ".join(result["bands"])
        return (f"{r['kind'].upper()} on {bands} -> {r['parameter']}: RMS {r['rms']:.3g}, R² {r['r2']:.3f}, "
                f"robust {r['robust_rms']:.3g}, without fits on a bound {r['rms_unbounded']:.3g}; "
                f"failed {r['failed_fraction']:.2%}, on a bound {r['bound_fraction']:.2%}")

    def labels(self, parameter: str | None, classes: Sequence[str] | None) -> dict[str, Any]:
        return {"parameter": parameter}

    def metrics(self, index: np.ndarray, status: np.ndarray, bounds: np.ndarray, target: np.ndarray, *,
                regress: Sequence[int], n_classes: int, condition: np.ndarray | None = None) -> dict[str, np.ndarray]:
        return regression_metrics(index, status, bounds, target, regress=regress, condition=condition)

    def spectrum_stats(self, index: np.ndarray, status: np.ndarray, target: np.ndarray, copies: int, *,
                       regress: Sequence[int], n_classes: int) -> np.ndarray:
        return regression_stats(index, status, target, copies, tuple(int(r) for r in regress))

    def score(self, sums: np.ndarray) -> np.ndarray:
        return regression_score(sums)


@dataclass(frozen=True)
class _Classification(Metric):
    def score_label(self, parameter: str | None) -> str:
        return "omission error"

    def unit(self, parameter: str | None) -> str:
        return "%"

    def gain_unit(self, parameter: str | None) -> str:
        return "percentage points"

    def summary_line(self, result: dict[str, Any]) -> str:
        r, bands = result, " ".join(result["bands"])
        return (f"{r['kind'].upper()} on {bands}: mean omission error {r['omission_error_pct']:.1f} %, overall "
                f"accuracy {r['overall_accuracy_pct']:.1f} %, unclassified {r['unclassified_fraction']:.1%}")

    def labels(self, parameter: str | None, classes: Sequence[str] | None) -> dict[str, Any]:
        return {"classes": classes}

    def metrics(self, index: np.ndarray, status: np.ndarray, bounds: np.ndarray, target: np.ndarray, *,
                regress: Sequence[int], n_classes: int, condition: np.ndarray | None = None) -> dict[str, np.ndarray]:
        return classification_metrics(index, status,  # int64 class numbers, a row block at a time
                                      np.asarray(target).astype(np.int64), n_classes)

    def spectrum_stats(self, index: np.ndarray, status: np.ndarray, target: np.ndarray, copies: int, *,
                       regress: Sequence[int], n_classes: int) -> np.ndarray:
        return classification_stats(index, status, target, copies, n_classes)

    def score(self, sums: np.ndarray) -> np.ndarray:
        return classification_score(sums)


#: RMS of a quadratic regression of the parameter on the index (the paper's number), R², a robust error and the
#: fit accounting (:func:`s2cl.retrieve.metrics.regression_metrics`)
REGRESSION: Metric = _Regression(
    name="regression", score_column="rms",
    columns=("rms", "r2", "robust_rms", "n_valid", "constant_index", "rms_unbounded", "converged_fraction",
             "stalled_fraction", "iteration_limit_fraction", "degenerate_fraction", "invalid_fraction",
             "failed_fraction", "bound_fraction", "excluded_fraction", "log10_condition_median", "host"),
    ranking_columns=(("robust_rms", "robust_rms", ".3g"), ("failed_fraction", "failed_fraction", ".2%"),
                     ("bound_fraction", "bound_fraction", ".2%"), ("converged_fraction", "converged", ".2%")),
    regressed=True, stratified=False, pixel_scratch=True)

#: mean omission error over the classes (the paper's SAM number), overall accuracy and the unclassified share
#: (:func:`s2cl.retrieve.metrics.classification_metrics`)
CLASSIFICATION: Metric = _Classification(
    name="classification", score_column="omission_error_pct",
    columns=("omission_error_pct", "overall_accuracy_pct", "unclassified_fraction", "failed_fraction", "host"),
    ranking_columns=(("overall_accuracy_pct", "overall_accuracy_pct", ".3g"),
                     ("failed_fraction", "failed_fraction", ".2%")),
    regressed=False, stratified=True, pixel_scratch=False)

#: every metric, in the order a results table's columns are matched (:func:`metric_in`)
METRICS: tuple[Metric, ...] = (CLASSIFICATION, REGRESSION)


def metric_in(columns: Sequence[str]) -> Metric:
    """The metric whose score column ``columns`` (a results table's) holds; a regression when none."""
    return next((m for m in METRICS if m.score_column in columns), REGRESSION)


def metric_scored_by(column: str) -> Metric | None:
    """The metric ranked on ``column`` (``rms``, ``omission_error_pct``), or None."""
    return next((m for m in METRICS if m.score_column == column), None)
