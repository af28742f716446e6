"""Which designs are within noise of the best: a paired bootstrap over library spectra.

A sweep ranks designs by one score (:func:`s2cl.sweep.digest.metric_of`: RMS of the regression, or SAM's mean
omission error), computed on one draw of the simulation's noise over one library. Designs whose scores differ by
less than that draw can move are not told apart by the simulation. The test, per candidate design ``j`` (the
sweep's best :data:`DEFAULT_TOP` designs, re-evaluated with per-pixel results):

1. per library spectrum ``s``, sufficient statistics of the score over the spectrum's pixels (its noisy copies),
   for every candidate, as the ranking's :class:`~s2cl.retrieve.metric.Metric` sums them
   (:mod:`s2cl.retrieve.spectrum_stats`: the moments of the quadratic regression, or the correct and total pixel
   counts per class);
2. :data:`REPLICATES` bootstrap replicates resample the spectra with replacement (within each class for SAM),
   the same draw for every design, so all copies of a spectrum move together and the designs stay paired; a
   replicate's score is the score of the weighted statistics (the regression is refitted on each replicate);
3. the difference ``score_j − score_best`` per replicate; ``j`` is *within noise of #1* when the two-sided
   :data:`LEVEL` percentile interval of that difference reaches zero (is not all above it).

Everything is seeded (:data:`SEED`): the same sweep gives the same set.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from s2cl.retrieve.metric import Metric, metric_scored_by
from s2cl.sweep.designs import design_pixels
from s2cl.sweep.engine import last_one
from s2cl.sweep.raw import ChunkEvaluator

LEVEL = 0.95
REPLICATES = 2000
SEED = 20_120_000
#: best designs re-scored per pixel when the scene does not say (``sweep.within_noise_top``)
DEFAULT_TOP = 100
#: designs whose bootstrap replicates are held at once (bounds the memory: designs × replicates × statistics)
DESIGN_BLOCK = 64


# -- per-spectrum statistics --------------------------------------------------------------------------

def spectrum_stats(metric: Metric, raw: Any, job: Any) -> np.ndarray:
    """Per design and library spectrum, the statistics ``metric`` scores (:meth:`~s2cl.retrieve.metric.Metric.
    spectrum_stats`) of the per-pixel results ``raw`` (a :class:`~s2cl.sweep.raw.RawChunk`) of ``job``'s sweep."""
    t = job.tables
    return metric.spectrum_stats(raw.index, raw.status, t.target, t.copies, regress=job.analysis.regress,
                                 n_classes=len(t.class_names))


# -- the bootstrap ----------------------------------------------------------------------------------------

def resample_indices(n_spectra: int, replicates: int = REPLICATES, seed: int = SEED,
                     strata: np.ndarray | None = None) -> np.ndarray:
    """The spectra each bootstrap replicate draws, ``(replicates, n_spectra)``: with replacement, from all
    spectra, or (``strata``: a label per spectrum) within each stratum, keeping its size. Seeded: reproducible."""
    rng = np.random.default_rng(seed)
    if strata is None:
        return rng.integers(0, n_spectra, size=(replicates, n_spectra))
    strata = np.asarray(strata)
    out = np.empty((replicates, n_spectra), dtype=np.int64)
    for label in np.unique(strata):
        members = np.flatnonzero(strata == label)
        out[:, members] = members[rng.integers(0, members.size, size=(replicates, members.size))]
    return out


def replicate_weights(draws: np.ndarray, n_spectra: int) -> np.ndarray:
    """How often each spectrum is drawn per replicate, ``(replicates, n_spectra)`` float64."""
    r = draws.shape[0]
    flat = (np.arange(r)[:, None] * n_spectra + draws).ravel()
    return np.bincount(flat, minlength=r * n_spectra).reshape(r, n_spectra).astype(np.float64)


@dataclass(frozen=True)
class Bootstrap:
    """A paired bootstrap of candidate designs against one of them (``best``), per design: the full-sample
    ``score``, its ``difference`` to the best, the percentile interval (``low``, ``high``) of that difference
    at ``level``, the share of replicates in which the design scores at least as well as the best
    (``as_good``), and ``within`` (``low`` ≤ 0: not told apart from the best)."""

    score: np.ndarray
    difference: np.ndarray
    low: np.ndarray
    high: np.ndarray
    as_good: np.ndarray
    within: np.ndarray
    level: float
    replicates: int


def paired_bootstrap(stats: np.ndarray, score: Callable[[np.ndarray], np.ndarray], best: int = 0, *,
                     replicates: int = REPLICATES, seed: int = SEED, level: float = LEVEL,
                     strata: np.ndarray | None = None) -> Bootstrap:
    """Bootstrap the score difference of every design of ``stats`` ``(n_designs, n_spectra, m)`` to design
    ``best``, resampling spectra (:func:`resample_indices`; the same draws for all designs). ``score`` maps
    summed statistics ``(..., m)`` to the score (lower is better)."""
    stats = np.asarray(stats, dtype=np.float64)
    n_designs, n_spectra, m = stats.shape
    weights = replicate_weights(resample_indices(n_spectra, replicates, seed, strata), n_spectra)
    full = score(stats.sum(axis=1))
    best_b = score(weights @ stats[best])  # (replicates,)
    # a design with the best's very statistics (the sensor's own bands as #1, say) differs by 0, not by the rounding
    # of another matrix product
    alike = (stats == stats[best]).all(axis=(1, 2))
    alpha = (1.0 - level) / 2.0
    low, high, as_good = (np.empty(n_designs) for _ in range(3))
    for a in range(0, n_designs, DESIGN_BLOCK):
        block = stats[a:a + DESIGN_BLOCK]
        sums = (weights @ block.transpose(1, 0, 2).reshape(n_spectra, -1)).reshape(replicates, block.shape[0], m)
        diff = score(sums) - best_b[:, None]  # (replicates, designs)
        diff[:, alike[a:a + DESIGN_BLOCK]] = 0.0
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a design without any pixel: NaN, never within
            low[a:a + block.shape[0]], high[a:a + block.shape[0]] = np.nanquantile(diff, [alpha, 1.0 - alpha],
                                                                                   axis=0)
            as_good[a:a + block.shape[0]] = np.mean(diff <= 0.0, axis=0)
    difference = full - full[best]
    within = np.asarray(low <= 0.0)
    within[best] = True
    return Bootstrap(full, difference, low, high, as_good, within, level, replicates)


# -- a sweep's candidates ----------------------------------------------------------------------------------

#: per-spectrum statistics of the designs already scored per pixel, by (sweep job fingerprint, device, metric name)
#: → configuration → ``(1, n_spectra, m)``: one sweep's (or one multi-application sweep's, :func:`s2cl.sweep.engine.
#: keep_together`) at a time
_STATS: dict[tuple[str, str | None, str], dict[int, np.ndarray]] = {}


def design_stats(job: Any, configs: np.ndarray, metric: Metric, *, device: str | None = None,
                 evaluator_of: Callable[[Any], ChunkEvaluator] | None = None) -> np.ndarray:
    """Per-spectrum statistics ``(len(configs), n_spectra, m)`` of the configurations ``configs`` of ``job``, with
    per-pixel results on the sweep's pixels and noise deviates, so each design's as in the sweep
    (:func:`s2cl.sweep.designs.design_pixels`: batched, one kernel launch per batch)."""
    configs = np.asarray(configs, dtype=np.int64).ravel()
    # each distinct design once (a multi-application sweep's joint ranking holds one design of its first application
    # many times: designs that differ only in bands it does not read), and none scored before for the same sweep
    # (its within-noise set and its noise margin's designs overlap): a design's statistics do not depend on the
    # designs scored beside it, so the same numbers, bit for bit
    memo = {} if evaluator_of is not None else last_one(_STATS, (job.fingerprint(), device, metric.name), dict)
    _, first = np.unique(configs, return_index=True)
    todo = np.array([c for c in configs[np.sort(first)] if int(c) not in memo], dtype=np.int64)
    if todo.size:
        raw = design_pixels(job, todo, device=device, evaluator_of=evaluator_of)
        for i, c in enumerate(todo):
            memo[int(c)] = spectrum_stats(metric, raw.row(i), job)
    return np.concatenate([memo[int(c)] for c in configs])


def within_noise(job: Any, top: Any, metric: str, *, evaluator_of: Callable[[Any], ChunkEvaluator] | None = None,
                 device: str | None = None, reference: Any = None, ranked: int | None = None,
                 replicates: int = REPLICATES, seed: int = SEED, level: float = LEVEL) -> dict[str, Any] | None:
    """The designs of ``top`` (the sweep's best rows, best first: ``config``, band centres and widths,
    ``metric``) within noise of the first, as ``summary.json``'s ``within_noise``; None when fewer than two
    designs were ranked or ``metric`` is no :class:`~s2cl.retrieve.metric.Metric`'s score column.

    :param evaluator_of: the per-pixel evaluator of a batch of designs (default: the sweep kernel on ``device``;
        tests: the numpy twin).
    :param reference: per-pixel results (a :class:`~s2cl.sweep.raw.RawChunk` of one design on the same pixels)
        of the sensor's own bands, tested against #1 too (``within_noise["reference"]``), or None.
    :param ranked: how many designs the sweep ranked (all of them tested: the set is complete).
    """
    scored = metric_scored_by(metric)
    if scored is None or top is None or len(top) < 2:
        return None
    t0 = time.perf_counter()
    t = job.tables
    configs = top["config"].to_numpy(np.int64)
    stats = design_stats(job, configs, scored, device=device, evaluator_of=evaluator_of)
    if reference is not None:
        stats = np.concatenate([stats, spectrum_stats(scored, reference, job)])
    strata = np.asarray(t.target)[:: t.copies] if scored.stratified else None
    boot = paired_bootstrap(stats, scored.score, 0, replicates=replicates, seed=seed, level=level, strata=strata)
    n = len(configs)
    bands = list(t.bands)
    designs = []
    for i, (_, row) in enumerate(top.iterrows()):  # the candidates; the reference, if any, is design n
        designs.append({
            "rank": i + 1, "config": int(configs[i]),  # exact: iterrows gives floats
            "bands": {b: [float(row[f"{b}_centre_nm"]), float(row[f"{b}_width_nm"])] for b in bands},
            metric: _finite(row[metric]), "difference": _finite(boot.difference[i]),
            "interval": [_finite(boot.low[i]), _finite(boot.high[i])], "as_good": float(boot.as_good[i]),
            "within": bool(boot.within[i])})
    out = {"metric": metric, "level": level, "replicates": replicates, "seed": seed,
           "resampled": "library spectra" + (" within each class" if scored.stratified else ""),
           "spectra": t.n_spectra, "copies": t.copies, "candidates": n, "count": int(boot.within[:n].sum()),
           # False: the last candidate is still within noise, so designs ranked below it may be too
           "complete": not bool(boot.within[n - 1]) or n == ranked,
           "configs": [d["config"] for d in designs if d["within"]]}
    if reference is not None:
        out["reference"] = {"score": _finite(boot.score[n]), "difference": _finite(boot.difference[n]),
                            "interval": [_finite(boot.low[n]), _finite(boot.high[n])],
                            "as_good": float(boot.as_good[n]), "within": bool(boot.within[n])}
    return {**out, "seconds": time.perf_counter() - t0, "designs": designs}


def _finite(value: Any) -> float | None:
    v = float(value)
    return v if np.isfinite(v) else None


def mark_top(summary: dict[str, Any]) -> None:
    """Write each ``summary["top"]`` entry's and the reference's ``within_noise`` (True, False, or None when
    it was not tested) from ``summary["within_noise"]``."""
    wn = summary.get("within_noise")
    tested = {d["config"]: d["within"] for d in wn["designs"]} if wn else {}
    for entry in summary.get("top", []):
        entry["within_noise"] = tested.get(entry.get("config"))
    if isinstance(summary.get("reference"), dict):
        summary["reference"]["within_noise"] = (wn or {}).get("reference", {}).get("within")


def within_pairs(summary: dict[str, Any], band: str) -> list[tuple[float, float]]:
    """(centre, width) of ``band`` in each design within noise of #1 (the heatmap's hatched cells)."""
    wn = summary.get("within_noise") or {}
    return [tuple(d["bands"][band]) for d in wn.get("designs", []) if d["within"] and band in d["bands"]]


def within_column(summary: dict[str, Any], configs: np.ndarray) -> Any:
    """Per configuration of ``configs``, whether it is within noise of #1 (a pandas nullable boolean array:
    True or False where tested, missing elsewhere)."""
    import pandas as pd

    wn = summary.get("within_noise") or {}
    tested = {d["config"]: d["within"] for d in wn.get("designs", [])}
    return pd.Series(np.asarray(configs)).map(tested).astype("boolean").array


def kept_within_noise(summary: dict[str, Any], kept: dict[str, Any]) -> None:
    """Carry a previous ``summary.json``'s within-noise set into ``summary`` (a report ranked again from the
    results) when both rank the same design first; re-scoring it needs the sweep's tables, not only its results.
    Marks the ranking's entries (:func:`mark_top`)."""
    wn = kept.get("within_noise")
    best = summary.get("best") or {}
    if isinstance(wn, dict) and wn.get("designs") and wn["designs"][0].get("config") == best.get("config"):
        summary["within_noise"] = wn
    mark_top(summary)
