"""Per-configuration metrics from per-pixel results.

Regression (IGRM λp → chlorophyll, GVMI → leaf water): a second-order polynomial of the
parameter in the index over all valid pixels, numerically conditioned (the index is centred on
its mean and scaled by its standard deviation before the 3 × 3 normal equations are solved in
float64). Reported: RMS of the residuals (the paper's number), R², a robust error
(1.4826 × median |residual|, which equals the RMS for Gaussian residuals and is not inflated by
a few large residuals), ``rms_unbounded`` (the same regression refitted without the pixels
whose fit sits on a bound: a runaway fit far outside the index range bends the quadratic
itself, which the median cannot undo), and the fractions of pixels whose fit failed
(degenerate or invalid), hit the iteration limit, or sits on a bound. A constant index gives the
RMS of the parameter about its mean, R² = 0 and ``constant_index = True`` instead of a singular
solve.

Classification (SAM): confusion matrix per configuration, mean omission error over classes
(1 − producer's accuracy, in %), overall accuracy and the unclassified fraction.
"""

from __future__ import annotations

import numpy as np

from .analysis import DEGENERATE, INVALID, ITERATION_LIMIT

MAD_TO_SIGMA = 1.482602218505602  # 1 / Φ⁻¹(3/4)
ROW_BLOCK = 32  # configurations per pass: keeps the float64 temporaries in cache


def regression_metrics(index: np.ndarray, status: np.ndarray, bounds: np.ndarray,
                       target: np.ndarray) -> dict[str, np.ndarray]:
    """Metrics per row of ``index`` ``(n_configs, n_pixels)`` against ``target`` ``(n_pixels,)``."""
    x = np.asarray(index)
    valid = (status != DEGENERATE) & (status != INVALID) & np.isfinite(x)
    parts = []
    for a in range(0, max(x.shape[0], 1), ROW_BLOCK):
        b = min(a + ROW_BLOCK, x.shape[0])
        xb, vb = x[a:b].astype(np.float64), valid[a:b]
        part = _poly2(xb, vb, target)
        part["rms_unbounded"] = part["rms"].copy()
        bounded = np.flatnonzero((bounds[a:b] != 0).any(axis=1))
        if bounded.size:
            refit = _poly2(xb[bounded], vb[bounded] & (bounds[a:b][bounded] == 0), target, robust=False)
            part["rms_unbounded"][bounded] = refit["rms"]
        parts.append(part)
    out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    out["failed_fraction"] = 1.0 - out["n_valid"] / x.shape[1]
    out["iteration_limit_fraction"] = (status == ITERATION_LIMIT).mean(axis=1)
    out["bound_fraction"] = (bounds != 0).mean(axis=1)
    return out


def _poly2(x: np.ndarray, valid: np.ndarray, target: np.ndarray, robust: bool = True) -> dict[str, np.ndarray]:
    """Conditioned second-order polynomial regression of ``target`` on the valid ``x`` of each row.

    Moments are row reductions and matrix–vector products with the target (no 3-D temporaries):
    this runs once per sweep chunk over (configurations × pixels) arrays.
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
    u /= np.where(constant, 1.0, xs)[:, None]
    u2 = u * u
    m = np.empty((x.shape[0], 3, 3))
    m[:, 0, 0] = n
    m[:, 0, 1] = m[:, 1, 0] = u.sum(axis=1)
    m[:, 0, 2] = m[:, 2, 0] = m[:, 1, 1] = u2.sum(axis=1)
    m[:, 1, 2] = m[:, 2, 1] = (u2 * u).sum(axis=1)
    m[:, 2, 2] = (u2 * u2).sum(axis=1)
    b = np.stack([w @ y, u @ y, u2 @ y], axis=1)
    m[constant, 1:, :] = 0.0
    m[constant, :, 1:] = 0.0
    m[constant, 1, 1] = m[constant, 2, 2] = 1.0
    b[constant, 1:] = 0.0
    coef = np.linalg.solve(m + np.eye(3) * (n[:, None, None] == 0), b[..., None])[..., 0]
    residual = y[None, :] - coef[:, :1] - coef[:, 1:2] * u - coef[:, 2:3] * u2
    if not every:
        residual *= w
    ss_res = np.einsum("ij,ij->i", residual, residual)
    y_mean = (w @ y) / safe_n
    ss_tot = w @ (y * y) - n * y_mean**2
    with np.errstate(invalid="ignore", divide="ignore"):
        r2 = np.where(ss_tot > 0, 1.0 - ss_res / ss_tot, 0.0)
    rms = np.sqrt(ss_res / safe_n)
    return {
        "rms": np.where(n > 0, rms, np.nan),
        "r2": np.where(n > 0, r2, np.nan),
        "robust_rms": _robust(np.abs(residual, out=residual), valid, n) if robust else np.full(n.size, np.nan),
        "n_valid": n.astype(np.int64),
        "constant_index": constant & (n > 0),
    }


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
    pred = np.where(status == 0, np.asarray(predicted, dtype=np.int64), n_classes)
    truth = np.asarray(truth, dtype=np.int64)
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
        "failed_fraction": (status == INVALID).mean(axis=1),
        "confusion": confusion,
    }
