"""Per-configuration metrics from per-pixel results.

Regression (IGRM λp → chlorophyll, GVMI → leaf water): a second-order polynomial of the
parameter in the index over the pixels that enter the regression (by default every fitted IGRM
status: converged, stalled, iteration limit; GVMI: valid; ``analysis.regress`` chooses), numerically
conditioned (the index is centred on its mean and scaled by its standard deviation before the
3 × 3 normal equations are solved in float64). Reported: RMS of the residuals (the paper's
number), R², a robust error (1.4826 × median |residual|, which equals the RMS for Gaussian
residuals and is not inflated by a few large residuals), ``rms_unbounded`` (the same regression
refitted without the pixels whose fit sits on a bound: a runaway fit far outside the index range
bends the quadratic itself, which the median cannot undo), and the fit accounting: the fractions
of pixels per status (:mod:`s2cl.status`: converged, stalled, iteration limit, degenerate,
invalid), on a bound, left out of the regression (``excluded_fraction``), and the median log10
condition estimate of the fits (``log10_condition_median``; large when the bands cannot pin the
four IGRM parameters). A constant index gives the RMS of the parameter about its mean, R² = 0
and ``constant_index = True`` instead of a singular solve.

Classification (SAM): confusion matrix per configuration, mean omission error over classes
(1 − producer's accuracy, in %), overall accuracy, the unclassified fraction (above the angle
threshold or without a valid pixel) and the failed fraction (invalid input or zero vector).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.status import Status

MAD_TO_SIGMA = 1.482602218505602  # 1 / Φ⁻¹(3/4)
ROW_BLOCK = 32  # configurations per pass: keeps the float64 temporaries in cache
#: arrays of a row block × the pixels a regression holds at once at most: float64 (:func:`_poly2`: the index, its
#: weights, u, u², the residual and the expressions' temporaries); a classification's int64 (the classes, their
#: masked copy, the confusion keys and their temporary); tests/test_host_footprint.py measures them
REGRESSION_BLOCK_ARRAYS, CLASSIFICATION_BLOCK_ARRAYS = 8, 4


def block_work_bytes(n_pixels: int, *, classifies: bool) -> int:
    """Bytes the numpy metrics hold at once for one row block (:func:`row_blocks`) of ``n_pixels`` pixels: the same
    for any number of configurations (8-byte values)."""
    arrays = CLASSIFICATION_BLOCK_ARRAYS if classifies else REGRESSION_BLOCK_ARRAYS
    return 8 * ROW_BLOCK * n_pixels * arrays


def regression_metrics(index: np.ndarray, status: np.ndarray, bounds: np.ndarray, target: np.ndarray, *,
                       condition: np.ndarray | None = None,
                       regress: tuple[int, ...] = (Status.OK, Status.STALLED, Status.ITERATION_LIMIT)
                       ) -> dict[str, np.ndarray]:
    """Metrics per row of ``index`` ``(n_configs, n_pixels)`` against ``target`` ``(n_pixels,)``.

    :param index: float32 or float64; the regression runs in float64 whatever it is.
    :param condition: IGRM condition codes (uint8, round(20 log10 cond)) of the same shape, or None.
    :param regress: the statuses whose index enters the regression (OK only for GVMI in effect).
    """
    x = np.asarray(index)
    status = np.asarray(status)
    bounds = np.asarray(bounds)
    parts, medians = [], []
    for a, b in row_blocks(x.shape[0]):
        # C order: each row's reductions run over contiguous memory, in the same order in any block
        xb = np.ascontiguousarray(x[a:b], dtype=np.float64)
        vb = _any_of(status[a:b], regress)
        vb &= np.isfinite(xb)
        part = _poly2(xb, vb, target)
        part["rms_unbounded"] = part["rms"].copy()
        bounded_px = bounds[a:b] != 0
        bounded = np.flatnonzero(bounded_px.any(axis=1))
        if bounded.size:
            refit = _poly2(xb[bounded], vb[bounded] & ~bounded_px[bounded], target, robust=False)
            part["rms_unbounded"][bounded] = refit["rms"]
        del xb, vb, bounded_px
        part.update(fit_accounting(status[a:b], bounds[a:b]))
        if condition is not None:
            fitted = _any_of(status[a:b], (Status.OK, Status.STALLED, Status.ITERATION_LIMIT))
            medians.append(median_code(np.asarray(condition)[a:b], fitted) / CONDITION_CODES_PER_DECADE)
        parts.append(part)
    out = _joined(parts)
    out["excluded_fraction"] = 1.0 - out["n_valid"] / x.shape[1]
    if condition is not None:
        out["log10_condition_median"] = np.concatenate(medians)
    return out


def row_blocks(n_rows: int) -> list[tuple[int, int]]:
    """The (start, stop) row ranges of :data:`ROW_BLOCK` configurations the numpy metrics take one at a time (one
    empty block for no rows): their work arrays are a block's, whatever the chunk (:func:`block_work_bytes`); every
    metric is a per-row reduction, so a row's value does not depend on its block."""
    return [(a, min(a + ROW_BLOCK, n_rows)) for a in range(0, max(n_rows, 1), ROW_BLOCK)]


def _joined(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _any_of(codes: np.ndarray, values: tuple[int, ...]) -> np.ndarray:
    """``codes`` equal to any of ``values``: one vectorised comparison each (faster than a table lookup
    or np.isin for the few status codes)."""
    out = codes == values[0]
    for v in values[1:]:
        out |= codes == v
    return out


#: condition codes are round(20 log10 cond): 0.05 decades each
CONDITION_CODES_PER_DECADE = 20.0


def condition_code(log10_condition: np.ndarray) -> np.ndarray:
    """IGRM condition estimates (log10, capped at 12) as the sweep kernel's uint8 codes, round(20 log10 cond)."""
    return np.floor(np.asarray(log10_condition, dtype=np.float64) * CONDITION_CODES_PER_DECADE + 0.5).astype(np.uint8)


def fit_accounting(status: np.ndarray, bounds: np.ndarray) -> dict[str, np.ndarray]:
    """Per row: the fraction of pixels in each status, ``failed_fraction`` (degenerate or invalid:
    no index at all) and ``bound_fraction`` (a fit on a bound)."""
    status = np.asarray(status)
    n_rows, n_px = status.shape
    # one histogram of (row, status) pairs: linear in the pixels, one pass
    counts = np.bincount((np.arange(n_rows, dtype=np.int64)[:, None] * 256 + status).ravel(),
                         minlength=n_rows * 256).reshape(n_rows, 256)
    out = {f"{name}_fraction": counts[:, code] / n_px for name, code in
           (("converged", Status.OK), ("stalled", Status.STALLED), ("iteration_limit", Status.ITERATION_LIMIT),
            ("degenerate", Status.DEGENERATE), ("invalid", Status.INVALID))}
    out["failed_fraction"] = out["degenerate_fraction"] + out["invalid_fraction"]
    out["bound_fraction"] = np.count_nonzero(np.asarray(bounds), axis=1) / n_px
    return out


def median_code(codes: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Per row, the (lower) median of the uint8 ``codes`` where ``mask``; NaN for rows without any.
    A histogram per row: linear in the pixels, no sort."""
    n_rows = codes.shape[0]
    rows = np.broadcast_to(np.arange(n_rows)[:, None], codes.shape)
    hist = np.bincount((rows[mask] * 256 + codes[mask].astype(np.int64)), minlength=n_rows * 256)
    hist = hist.reshape(n_rows, 256)
    count = hist.sum(axis=1)
    cum = np.cumsum(hist, axis=1)
    median = np.argmax(cum >= ((count + 1) // 2)[:, None], axis=1).astype(np.float64)
    return np.where(count > 0, median, np.nan)


@dataclass(frozen=True)
class Poly2:
    """The conditioned second-order polynomial :func:`regression_metrics` fits: ``target ≈ c0 + c1 u + c2 u²`` with
    ``u = (index − x0) / xs``."""

    x0: float
    xs: float
    coef: tuple[float, float, float]

    def __call__(self, index: np.ndarray) -> np.ndarray:
        """The parameter of each ``index`` (float64; NaN where the index is)."""
        u = (np.asarray(index, dtype=np.float64) - self.x0) / self.xs
        c0, c1, c2 = self.coef
        return c0 + c1 * u + c2 * u * u


def poly2_fit(index: np.ndarray, valid: np.ndarray, target: np.ndarray) -> Poly2:
    """The polynomial of ``target`` in ``index`` (both ``(n_pixels,)``) over the ``valid`` pixels, fitted exactly
    as :func:`regression_metrics` fits it (its RMS is that of this polynomial's residuals)."""
    x = np.where(valid, np.asarray(index, dtype=np.float64), 0.0)[None]
    part = _poly2(x, np.asarray(valid, dtype=bool)[None], np.where(valid, target, 0.0), robust=False,
                  coefficients=True)
    return Poly2(float(part["x0"][0]), float(part["xs"][0]), tuple(float(c) for c in part["coef"][0]))


def _poly2(x: np.ndarray, valid: np.ndarray, target: np.ndarray, robust: bool = True,
           coefficients: bool = False) -> dict[str, np.ndarray]:
    """Conditioned second-order polynomial regression of ``target`` on the valid ``x`` of each row.

    Moments are row reductions (no 3-D temporaries): this runs once per sweep chunk over (configurations ×
    pixels) arrays. Every reduction runs along a row on its own (numpy's pairwise sum, no BLAS
    matrix-vector product, whose rounding depends on how many rows it is given), so a configuration's
    metrics are bit-identical whatever chunk it is computed in.
    """
    y = np.asarray(target, dtype=np.float64)
    w = valid.astype(np.float64)
    n = valid.sum(axis=1)
    safe_n = np.maximum(n, 1)
    every = bool(valid.all())
    x0 = (x if every else np.where(valid, x, 0.0)).sum(axis=1) / safe_n
    u = x - x0[:, None]
    if not every:
        u[~valid] = 0.0
    xs = np.sqrt((u * u).sum(axis=1) / safe_n)
    constant = xs <= 1e-12 * np.maximum(np.abs(x0), 1.0)
    xs = np.where(constant, 1.0, xs)
    u /= xs[:, None]
    u2 = u * u
    m = np.empty((x.shape[0], 3, 3))
    m[:, 0, 0] = n
    m[:, 0, 1] = m[:, 1, 0] = u.sum(axis=1)
    m[:, 0, 2] = m[:, 2, 0] = m[:, 1, 1] = u2.sum(axis=1)
    m[:, 1, 2] = m[:, 2, 1] = (u2 * u).sum(axis=1)
    m[:, 2, 2] = (u2 * u2).sum(axis=1)
    wy = (w * y).sum(axis=1)
    b = np.stack([wy, (u * y).sum(axis=1), (u2 * y).sum(axis=1)], axis=1)
    m[constant, 1:, :] = 0.0
    m[constant, :, 1:] = 0.0
    m[constant, 1, 1] = m[constant, 2, 2] = 1.0
    b[constant, 1:] = 0.0
    coef = _solve3(m + np.eye(3) * (n[:, None, None] == 0), b)
    residual = y[None, :] - coef[:, :1] - coef[:, 1:2] * u - coef[:, 2:3] * u2
    if not every:
        residual *= w
    ss_res = np.einsum("ij,ij->i", residual, residual)
    y_mean = wy / safe_n
    ss_tot = (w * (y * y)).sum(axis=1) - n * y_mean**2
    with np.errstate(invalid="ignore", divide="ignore"):
        r2 = np.where(ss_tot > 0, 1.0 - ss_res / ss_tot, 0.0)
    rms = np.sqrt(ss_res / safe_n)
    fitted = {"x0": x0, "xs": xs, "coef": coef} if coefficients else {}
    return {**fitted,
        "rms": np.where(n > 0, rms, np.nan),
        "r2": np.where(n > 0, r2, np.nan),
        "robust_rms": _robust(np.abs(residual, out=residual), valid, n) if robust else np.full(n.size, np.nan),
        "n_valid": n.astype(np.int64),
        "constant_index": constant & (n > 0),
    }


def _solve3(m: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched 3 × 3 normal equations; a singular system (fewer than three distinct index values in the
    regression, e.g. when ``analysis.regress`` leaves two pixels) is solved by the pseudo-inverse instead:
    the minimum-norm polynomial, finite, never a LinAlgError. Each row is solved on its own terms, so its
    result does not depend on the other rows of the block."""
    try:
        return np.linalg.solve(m, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        out = np.empty_like(b)
        for i in range(m.shape[0]):
            try:
                out[i] = np.linalg.solve(m[i : i + 1], b[i : i + 1, :, None])[0, :, 0]
            except np.linalg.LinAlgError:
                out[i] = np.einsum("rij,rj->ri", np.linalg.pinv(m[i : i + 1]), b[i : i + 1])[0]
        return out


def _robust(abs_res: np.ndarray, valid: np.ndarray, n: np.ndarray) -> np.ndarray:
    """1.4826 × median |residual| over valid pixels of each row."""
    out = np.full(abs_res.shape[0], np.nan)
    full = n == abs_res.shape[1]
    if full.any():
        out[full] = MAD_TO_SIGMA * np.median(abs_res[full], axis=1)
    for i in np.flatnonzero(~full & (n > 0)):
        out[i] = MAD_TO_SIGMA * np.median(abs_res[i][valid[i]])
    return out


def classification_metrics(predicted: np.ndarray, status: np.ndarray, truth: np.ndarray,
                           n_classes: int) -> dict[str, np.ndarray]:
    """Confusion matrices ``(n_configs, n_classes, n_classes + 1)`` (last column: unclassified) and
    the mean omission error (%) per configuration."""
    truth = np.asarray(truth, dtype=np.int64)
    return _joined([_classification_block(np.asarray(predicted[a:b], dtype=np.int64), np.asarray(status[a:b]),
                                          truth, n_classes) for a, b in row_blocks(len(predicted))])


def _classification_block(predicted: np.ndarray, status: np.ndarray, truth: np.ndarray,
                          n_classes: int) -> dict[str, np.ndarray]:
    pred = np.where(status == 0, predicted, n_classes)
    n_cfg = pred.shape[0]
    flat = (np.arange(n_cfg)[:, None] * n_classes + truth[None, :]) * (n_classes + 1) + pred
    confusion = np.bincount(flat.ravel(), minlength=n_cfg * n_classes * (n_classes + 1)).reshape(
        n_cfg, n_classes, n_classes + 1)
    per_class = confusion.sum(axis=2)
    correct = confusion[:, np.arange(n_classes), np.arange(n_classes)]
    with np.errstate(invalid="ignore", divide="ignore"):
        omission = np.where(per_class > 0, 1.0 - correct / per_class, np.nan)
    return {
        "omission_error_pct": 100.0 * np.nanmean(omission, axis=1),
        "overall_accuracy_pct": 100.0 * correct.sum(axis=1) / np.maximum(per_class.sum(axis=1), 1),
        "unclassified_fraction": (pred == n_classes).mean(axis=1),
        "failed_fraction": np.isin(status, (Status.INVALID, Status.DEGENERATE)).mean(axis=1),
        "confusion": confusion,
    }
