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


def regression_metrics(index: np.ndarray, status: np.ndarray, bounds: np.ndarray,
                       target: np.ndarray) -> dict[str, np.ndarray]:
    """Metrics per row of ``index`` ``(n_configs, n_pixels)`` against ``target`` ``(n_pixels,)``."""
    x = np.asarray(index, dtype=np.float64)
    valid = (status != DEGENERATE) & (status != INVALID) & np.isfinite(x)
    out = _poly2(x, valid, target)
    unbounded = _poly2(x, valid & (bounds == 0), target)
    out["rms_unbounded"] = unbounded["rms"]
    out["failed_fraction"] = 1.0 - out["n_valid"] / x.shape[1]
    out["iteration_limit_fraction"] = (status == ITERATION_LIMIT).mean(axis=1)
    out["bound_fraction"] = (bounds != 0).mean(axis=1)
    return out


def _poly2(x: np.ndarray, valid: np.ndarray, target: np.ndarray) -> dict[str, np.ndarray]:
    """Conditioned second-order polynomial regression of ``target`` on the valid ``x`` of each row."""
    y = np.broadcast_to(np.asarray(target, dtype=np.float64), x.shape)
    x = np.where(valid, x, 0.0)
    n = valid.sum(axis=1)
    w = valid.astype(np.float64)
    safe_n = np.maximum(n, 1)
    x0 = (x * w).sum(axis=1) / safe_n
    xs = np.sqrt((((x - x0[:, None]) * w) ** 2).sum(axis=1) / safe_n)
    constant = xs <= 1e-12 * np.maximum(np.abs(x0), 1.0)
    u = np.where(valid, (x - x0[:, None]) / np.where(constant, 1.0, xs)[:, None], 0.0)
    basis = np.stack([w, u * w, u * u * w], axis=-1)  # (n_cfg, n_px, 3), zero rows for invalid pixels
    m = np.einsum("cpi,cpj->cij", basis, basis)
    b = np.einsum("cpi,cp->ci", basis, y * w)
    m[constant, 1:, :] = 0.0
    m[constant, :, 1:] = 0.0
    m[constant, 1, 1] = m[constant, 2, 2] = 1.0
    b[constant, 1:] = 0.0
    coef = np.linalg.solve(m + np.eye(3) * (n[:, None, None] == 0), b[..., None])[..., 0]
    fitted = coef[:, :1] + coef[:, 1:2] * u + coef[:, 2:3] * u * u
    residual = np.where(valid, y - fitted, 0.0)
    ss_res = (residual**2).sum(axis=1)
    y_mean = (y * w).sum(axis=1) / safe_n
    ss_tot = (((y - y_mean[:, None]) * w) ** 2).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        r2 = np.where(ss_tot > 0, 1.0 - ss_res / ss_tot, 0.0)
    rms = np.sqrt(ss_res / safe_n)
    return {
        "rms": np.where(n > 0, rms, np.nan),
        "r2": np.where(n > 0, r2, np.nan),
        "robust_rms": _robust(np.abs(residual), valid, n),
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
