"""The trade-off across a scene's applications: the designs no other design beats by more than the noise
(the Pareto front), the designs that meet every requirement, and a ranking by the sum of each score relative to
the sensor's own bands' score.

Every score is lower-is-better (an RMS, an omission error). Design ``a`` *dominates* design ``b`` when

* ``a`` scores no worse than ``b`` on every application (``a_k ≤ b_k``), and
* ``a`` scores better than ``b`` by more than that application's noise margin on at least one
  (``b_k − a_k > margin_k``),

so a design within noise of another on every application is not dominated by it: both stay on the front. With
every margin 0 this is the usual Pareto dominance. The relation is transitive (``a`` dominates ``b`` and ``b``
dominates ``c`` give ``a_k ≤ c_k`` everywhere and ``c_k − a_k ≥ c_k − b_k > margin_k`` somewhere), so the front is
well defined and every design off it is dominated by a design on it.

A design that cannot be scored for an application (NaN, or not finite) is worse than any number: it is never on
the front while some design can be scored for that application. An application no design can be scored for
does not take part.

The margins (:func:`noise_margin`) come from the paired bootstrap of :mod:`s2cl.sweep.within_noise`, run on the
application's own single-application sweep.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.io.output import atomic_path
from s2cl.retrieve.metric import metric_scored_by
from s2cl.sweep.digest import bands_of, rankable_rows
from s2cl.sweep.report import open_results, shapes
from s2cl.sweep.within_noise import LEVEL, REPLICATES, SEED, design_stats, paired_bootstrap

#: the results column that marks the front's designs
PARETO = "pareto"
#: designs checked against the front at once (memory: FRONT_BLOCK × BLOCK × applications booleans)
BLOCK = 1024
FRONT_BLOCK = 256
#: the best-by-sum designs whose front screens every design first (most designs fall to one of them)
SCREEN = 4096
#: the application's best designs whose bootstrap sets its margin (the best and its nearest competitors)
MARGIN_TOP = 20
#: what the rule is, in words (summary.json and the docs)
RULE = ("design a dominates design b when a scores no worse than b on every application and better by more than "
        "that application's noise margin on at least one; lower is better; a design that cannot be scored for an "
        "application some design can be scored for is not on the front")
RELATIVE_SUM = ("the sum over the applications of the design's score divided by the sensor's own bands' score for "
                "that application (the sensor's own bands: the number of applications; lower is better)")


# -- the front -----------------------------------------------------------------------------------------------------

def front(scores: np.ndarray, margins: np.ndarray | Sequence[float] | None = None) -> np.ndarray:
    """Which designs are on the Pareto front, ``bool[n]``, of ``scores`` ``(n designs, k applications)`` (lower is
    better; NaN: cannot be scored) under noise ``margins`` ``(k,)`` (≥ 0, in each application's units; default 0):
    the rule of this module's docstring.

    Sort-based and block-wise: designs in order of their summed normalised scores (a dominating design comes
    first), screened by the front of the :data:`SCREEN` first ones, then the rest checked :data:`BLOCK` at a time
    against the front found so far; memory stays ``O(n k)``."""
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim == 1:
        s = s[:, None]
    if s.ndim != 2:
        raise ValueError(f"scores: need (designs, applications), got shape {s.shape}")
    n, k = s.shape
    m = np.zeros(k) if margins is None else np.asarray(margins, dtype=np.float64).reshape(-1)
    if m.shape != (k,) or not (np.isfinite(m) & (m >= 0)).all():
        raise ValueError(f"margins: need {k} finite values ≥ 0, got {m.tolist()}")
    finite = np.isfinite(s)
    scored = finite.any(axis=0)  # applications some design can be scored for
    eligible = np.flatnonzero(finite[:, scored].all(axis=1))
    out = np.zeros(n, dtype=bool)
    if eligible.size == 0:
        return out
    x, m = s[np.ix_(eligible, np.flatnonzero(scored))], m[scored]
    lo, hi = x.min(axis=0), x.max(axis=0)
    order = np.argsort(((x - lo) / np.where(hi > lo, hi - lo, 1.0)).sum(axis=1), kind="stable")
    xs = x[order]
    screen = xs[_front_of(xs[:SCREEN], m)]
    alive = np.arange(len(xs))
    for point in screen:  # each screening design removes what it dominates from the rest
        if alive.size == 0:
            break
        alive = alive[~_dominated_by_one(point, xs[alive], m)]
    out[eligible[order[alive[_front_of(xs[alive], m)]]]] = True
    return out


def _dominated_by_one(a: np.ndarray, b: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``bool[len(b)]``: design ``a`` dominates the row of ``b``."""
    return (a <= b).all(axis=1) & ((b - a) > m).any(axis=1)


def dominated_by(a: np.ndarray, b: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``bool[len(b)]``: some row of ``a`` dominates the row of ``b`` (``a`` in blocks of :data:`FRONT_BLOCK`; the
    rows of ``b`` found dominated leave the next blocks' work)."""
    out = np.zeros(len(b), dtype=bool)
    left = np.arange(len(b))
    for i in range(0, len(a), FRONT_BLOCK):
        if left.size == 0:
            break
        ai, bl = a[i:i + FRONT_BLOCK, None, :], b[left][None, :, :]
        hit = ((ai <= bl).all(axis=2) & ((bl - ai) > m).any(axis=2)).any(axis=0)
        out[left[hit]] = True
        left = left[~hit]
    return out


def _front_of(x: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Row numbers of ``x``'s front (finite scores), :data:`BLOCK` rows at a time: each block's rows not dominated
    by the front so far nor by another of the block join it, and front rows they dominate leave it (so the answer
    does not depend on the order, only the work does)."""
    k = x.shape[1]
    f, fi = np.empty((0, k)), np.empty(0, dtype=np.int64)
    for lo in range(0, len(x), BLOCK):
        block, bi = x[lo:lo + BLOCK], np.arange(lo, min(lo + BLOCK, len(x)))
        keep = ~dominated_by(f, block, m)
        block, bi = block[keep], bi[keep]
        keep = ~dominated_by(block, block, m)
        block, bi = block[keep], bi[keep]
        if len(block):
            stay = ~dominated_by(block, f, m)
            f, fi = np.vstack([f[stay], block]), np.concatenate([fi[stay], bi])
    return np.sort(fi)


# -- requirements and the relative sum ------------------------------------------------------------------------------

def meets(scores: np.ndarray, targets: Sequence[float | None]) -> np.ndarray:
    """``bool[n]``: the design meets every requirement: its score is at most the application's target (in the
    metric's units) wherever a target is given (NaN never meets one); an application without target is always met."""
    s = _table(scores)
    ok = np.ones(len(s), dtype=bool)
    for k, target in enumerate(targets):
        if target is not None:
            with np.errstate(invalid="ignore"):
                ok &= s[:, k] <= float(target)
    return ok


def relative_sum(scores: np.ndarray, reference: Sequence[float]) -> np.ndarray:
    """``float[n]``: the sum over the applications of each score divided by the sensor's own bands' score for it
    (``reference``, finite and > 0); NaN where a score is NaN. The sensor's own bands give the number of
    applications; lower is better."""
    ref = np.asarray(reference, dtype=np.float64)
    if not (np.isfinite(ref) & (ref > 0)).all():
        raise ValueError(f"reference: need a finite score > 0 per application, got {ref.tolist()}")
    return (_table(scores) / ref).sum(axis=1)


def _table(scores: np.ndarray) -> np.ndarray:
    """``scores`` as float64 ``(designs, applications)`` (one application: a column)."""
    s = np.asarray(scores, dtype=np.float64)
    return s[:, None] if s.ndim == 1 else s


# -- the margins ----------------------------------------------------------------------------------------------------

def best_configs(configs: np.ndarray, scores: np.ndarray, top: int = MARGIN_TOP) -> np.ndarray:
    """The ``top`` best distinct configurations of ``configs`` by ``scores`` (best first, NaN never): the candidates
    :func:`noise_margin` tests. ``configs`` may repeat (several joint designs are one design of an application that
    reads only some of their bands)."""
    configs, scores = np.asarray(configs, dtype=np.int64), np.asarray(scores, dtype=np.float64)
    ok = np.isfinite(scores)
    ranked = configs[ok][np.lexsort((configs[ok], scores[ok]))]
    _, first = np.unique(ranked, return_index=True)
    return ranked[np.sort(first)][:top]


def noise_margin(job: Any, configs: np.ndarray, metric: str, *,
                 evaluator_of: Callable[[Any], Any] | None = None, device: str | None = None,
                 replicates: int = REPLICATES, seed: int = SEED, level: float = LEVEL) -> dict[str, Any]:
    """One application's noise margin, in its metric's units, and how it was found (``"margin"`` and the record).

    ``job`` is the application's single-application :class:`~s2cl.sweep.engine.SweepJob`, ``configs`` its best
    designs there, best first (:func:`best_configs`), ``metric`` its score column. The designs are re-scored per
    pixel and the paired bootstrap of :func:`s2cl.sweep.within_noise.paired_bootstrap` (same spectra, replicates,
    seed and level as ``within_noise``) gives, per competitor ``j`` of the best, the observed difference ``d_j`` and
    the lower end ``low_j`` of its percentile interval. ``j`` is within noise of the best when ``low_j ≤ 0``, that is
    when ``d_j ≤ d_j − low_j``: ``d_j − low_j`` is the difference the bootstrap cannot tell from zero near the best.
    The margin is its median over the competitors (clipped at 0; a competitor with the best's very statistics,
    interval [0, 0], left out). Margin 0 (said so) when the metric has no
    bootstrap or fewer than two designs are given."""
    scored = metric_scored_by(metric)
    configs = np.asarray(configs, dtype=np.int64)
    record: dict[str, Any] = {"metric": metric, "candidates": int(configs.size), "level": level,
                              "replicates": replicates, "seed": seed}
    if scored is None or configs.size < 2:
        why = "no bootstrap for this metric" if scored is None else "fewer than two designs to compare"
        return {"margin": 0.0, **record, "method": f"none ({why})"}
    t = job.tables
    stats = design_stats(job, configs, scored, device=device, evaluator_of=evaluator_of)
    strata = np.asarray(t.target)[:: t.copies] if scored.stratified else None
    boot = paired_bootstrap(stats, scored.score, 0, replicates=replicates, seed=seed, level=level, strata=strata)
    alike = (boot.low == 0.0) & (boot.high == 0.0)  # the best's very statistics: they say nothing of the noise
    reach = (boot.difference - boot.low)[1:][~alike[1:]]
    reach = np.clip(reach[np.isfinite(reach)], 0.0, None)
    if reach.size == 0:
        return {"margin": 0.0, **record, "method": "none (no competitor could be scored)"}
    return {"margin": float(np.median(reach)), **record,
            "method": "median over the best design's nearest competitors of the difference to it minus the lower "
                      "end of its paired-bootstrap percentile interval",
            "resampled": "library spectra" + (" within each class" if scored.stratified else ""),
            "spectra": int(t.n_spectra), "copies": int(t.copies),
            "reach": [float(reach.min()), float(reach.max())]}


def noise_margins(df: Any, applications: Sequence[dict[str, Any]], jobs: Sequence[Any],
                  to_application: Sequence[Callable[[np.ndarray], np.ndarray] | None], *, top: int = MARGIN_TOP,
                  device: str | None = None, evaluator_of: Callable[[Any], Any] | None = None,
                  replicates: int = REPLICATES) -> tuple[np.ndarray, list[dict[str, Any]]]:
    """Every application's :func:`noise_margin` and its record: application ``k`` (``applications[k]``: its
    ``column`` and ``metric``) is measured on its own sweep ``jobs[k]``, on the ``top`` best of its designs among
    ``df``'s rows, each joint ``config`` mapped to the application's configuration number by
    ``to_application[k]`` (None: the same numbers, a single-application sweep)."""
    joint = df["config"].to_numpy(dtype=np.int64)
    margins, records = [], []
    for app, job, mapping in zip(applications, jobs, to_application, strict=True):
        own = joint if mapping is None else np.asarray(mapping(joint), dtype=np.int64)
        configs = best_configs(own, df[app["column"]].to_numpy(dtype=np.float64), top)
        rec = noise_margin(job, configs, app["metric"], device=device, evaluator_of=evaluator_of,
                           replicates=replicates)
        margins.append(rec["margin"])
        records.append(rec)
    return np.asarray(margins, dtype=np.float64), records


# -- summary.json's record ------------------------------------------------------------------------------------------

def application_columns(applications: Sequence[dict[str, Any]]) -> list[str]:
    """The results columns of ``summary["applications"]``' records, in order."""
    return [a["column"] for a in applications]


def pareto_record(df: Any, applications: Sequence[dict[str, Any]], margins: Sequence[float] | np.ndarray, *,
                  margin_records: Sequence[dict[str, Any]] | None = None, meta: dict[str, str] | None = None,
                  listed: int = 50, best: int = 5, top: int = 10) -> dict[str, Any]:
    """``summary.json``'s ``pareto`` record of results ``df`` (``config``, the band columns and each application's
    ``column``; ``meta``: the results' metadata, to rank only the rows a ranking may use,
    :func:`s2cl.sweep.digest.rankable_rows`): the rule, the margins (and ``margin_records``: how each was found),
    the front (every configuration in ``configs``; up to ``listed`` designs in ``designs``, by relative sum where
    every reference is known, else by the first application's score), the designs meeting every requirement
    (count and the ``best`` first) and the ranking by relative sum (``top``).

    Each listed design has its bands, each application's score, whether it is within noise of the front's best
    design on that application (its score exceeds the front's best by at most the margin), whether it meets every
    requirement and its relative sum."""
    if meta is not None:
        df = rankable_rows(df, meta)
    names = [a["name"] for a in applications]
    scores = df[application_columns(applications)].to_numpy(dtype=np.float64)
    m = np.asarray(margins, dtype=np.float64)
    on = front(scores, m)
    targets = [a.get("target") for a in applications]
    ok = meets(scores, targets)
    refs = [a.get("reference") for a in applications]
    ranked = all(r is not None and np.isfinite(r) and r > 0 for r in refs)
    rel = relative_sum(scores, refs) if ranked else np.full(len(df), np.nan)
    front_best = np.where(on[:, None], scores, np.inf).min(axis=0, initial=np.inf)  # inf: no front
    configs = df["config"].to_numpy(dtype=np.int64)
    bands = bands_of(df.columns)

    def entry(i: int) -> dict[str, Any]:
        row = df.iloc[i]
        e: dict[str, Any] = {"config": int(configs[i]),
                             "bands": shapes(row, bands),
                             "scores": {n: _finite(scores[i, k]) for k, n in enumerate(names)},
                             "within_noise": {n: bool(scores[i, k] - front_best[k] <= m[k])
                                              for k, n in enumerate(names)},
                             "meets": bool(ok[i])}
        if ranked:
            e["relative_sum"] = _finite(rel[i])
        return e

    key = rel if ranked else scores[:, 0]
    order = lambda rows: rows[np.lexsort((configs[rows], key[rows]))]  # noqa: E731
    on_rows, ok_rows = order(np.flatnonzero(on)), order(np.flatnonzero(ok))
    out: dict[str, Any] = {
        "rule": RULE, "applications": names, "columns": application_columns(applications),
        "margins": {n: {**(dict(margin_records[k]) if margin_records else {}), "margin": float(m[k])}
                    for k, n in enumerate(names)},
        "designs": len(df),
        "front": {"count": int(on.sum()), "configs": configs[on_rows].tolist(),
                  "order": "relative sum" if ranked else f"{names[0]} score",
                  "designs": [entry(i) for i in on_rows[:listed]]},
        "meeting": {"targets": dict(zip(names, targets, strict=True)), "count": int(ok.sum()),
                    "best": [entry(i) for i in ok_rows[:best]]},
        "reference": dict(zip(names, refs, strict=True))}
    if ranked:
        fin = np.flatnonzero(np.isfinite(rel))
        out["relative_sum"] = {"meaning": RELATIVE_SUM, "top": [entry(i) for i in order(fin)[:top]]}
    else:
        out["relative_sum"] = {"meaning": RELATIVE_SUM, "top": [],
                               "missing": [n for n, r in zip(names, refs, strict=True) if r is None]}
    return out


def _finite(value: float) -> float | None:
    v = float(value)
    return v if np.isfinite(v) else None


# -- the results file -----------------------------------------------------------------------------------------------

def add_pareto_column(results_path: str | Path, front_configs: Sequence[int] | np.ndarray) -> Path:
    """Rewrite ``results.parquet`` with a boolean :data:`PARETO` column (True for the configurations of
    ``front_configs``; replaced where the file has one), every other column, the row groups and the schema's
    metadata as they were. One row group at a time (memory: one row group, :data:`s2cl.sweep.folder.ROW_GROUP_ROWS`
    rows in a sweep's file) into a temporary file beside it, renamed onto it."""
    from pyarrow import array, bool_, field, parquet

    path = Path(results_path)
    wanted = np.unique(np.asarray(front_configs, dtype=np.int64))
    with atomic_path(path) as tmp:
        with parquet.ParquetFile(path, pre_buffer=False) as f:
            schema = f.schema_arrow
            meta = schema.metadata
            if PARETO in schema.names:
                schema = schema.remove(schema.get_field_index(PARETO))
            schema = schema.append(field(PARETO, bool_())).with_metadata(meta)
            with parquet.ParquetWriter(tmp, schema) as writer:
                for group in range(f.metadata.num_row_groups):
                    table = f.read_row_group(group)
                    if PARETO in table.column_names:
                        table = table.drop_columns([PARETO])
                    flag = np.isin(table.column("config").to_numpy(), wanted)
                    table = table.append_column(PARETO, array(flag, type=bool_()))
                    writer.write_table(table.replace_schema_metadata(meta), row_group_size=max(table.num_rows, 1))
    return path


def read_scores(results_path: str | Path, applications: Sequence[dict[str, Any]]) -> Any:
    """The columns :func:`pareto_record` needs from ``results.parquet`` (``config``, the band columns, the
    ranking's flags and each application's column) as a DataFrame, and the file's metadata."""
    from pyarrow import parquet

    path, meta = open_results(results_path)
    names = parquet.read_schema(path).names
    wanted = ["config", *(c for c in names if c.endswith(("_centre_nm", "_width_nm"))),
              *(c for c in ("full_fidelity", "underdetermined") if c in names), *application_columns(applications)]
    return parquet.read_table(path, columns=wanted).to_pandas(), meta
