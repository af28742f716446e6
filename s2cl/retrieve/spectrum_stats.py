"""Per-spectrum sufficient statistics of a design's score, and the score of their sums: what the within-noise
bootstrap (:mod:`s2cl.sweep.within_noise`) resamples. A regression sums the moments of the quadratic regression
(:func:`regression_stats`, scored by :func:`regression_score`: the RMS, target units); a classification the correct
and total pixel counts per class (:func:`classification_stats`, :func:`classification_score`: the mean omission
error, %). Each :class:`~s2cl.retrieve.metric.Metric` names its pair."""

from __future__ import annotations

import warnings

import numpy as np

from s2cl.status import Status


def _per_spectrum(values: np.ndarray, copies: int) -> np.ndarray:
    """``(n_designs, n_pixels, m)`` summed over each spectrum's ``copies`` consecutive pixels."""
    d, p, m = values.shape
    return values.reshape(d, p // copies, copies, m).sum(axis=2)


def regression_stats(index: np.ndarray, status: np.ndarray, target: np.ndarray, copies: int,
                     regress: tuple[int, ...]) -> np.ndarray:
    """Per design and spectrum, the sums the RMS of the quadratic regression of ``target`` on ``index`` needs:
    ``n, Σu, Σu², Σu³, Σu⁴, Σy, Σuy, Σu²y, Σy²`` over the pixels that enter it (status in ``regress``, finite
    index). ``u``: the index centred and scaled over all of the design's regression pixels (a constant index: 0);
    ``y``: the target minus its mean. Pixel ``p`` is a copy of spectrum ``p // copies``.

    :param index: ``(n_designs, n_pixels)``, any unit; :param target: ``(n_pixels,)``.
    :returns: ``(n_designs, n_spectra, 9)`` float64.
    """
    x = np.atleast_2d(np.asarray(index, dtype=np.float64))
    status = np.atleast_2d(status)
    valid = np.isin(status, np.asarray(regress, dtype=status.dtype)) & np.isfinite(x)
    n = valid.sum(axis=1)
    safe = np.maximum(n, 1)
    x0 = np.where(valid, x, 0.0).sum(axis=1) / safe
    u = np.where(valid, x - x0[:, None], 0.0)
    scale = np.sqrt((u * u).sum(axis=1) / safe)
    constant = scale <= 1e-12 * np.maximum(np.abs(x0), 1.0)
    u = u / np.where(constant, 1.0, scale)[:, None]
    u[constant] = 0.0
    y = np.asarray(target, dtype=np.float64)
    y = np.broadcast_to(y - y.mean(), x.shape)
    w = valid.astype(np.float64)
    u2 = u * u
    terms = np.stack([w, u, u2, u2 * u, u2 * u2, w * y, u * y, u2 * y, w * y * y], axis=-1)
    return _per_spectrum(terms, copies)


def regression_score(sums: np.ndarray) -> np.ndarray:
    """RMS of the least-squares quadratic from :func:`regression_stats` sums ``(..., 9)`` (target units; NaN
    without a pixel). A singular fit (fewer than three distinct index values, a constant index) takes the
    minimum-norm solution, as :func:`s2cl.retrieve.metrics.regression_metrics` does."""
    s = np.asarray(sums, dtype=np.float64)
    n, su, su2, su3, su4, sy, suy, su2y, syy = np.moveaxis(s, -1, 0)
    m = np.stack([np.stack([n, su, su2], -1), np.stack([su, su2, su3], -1), np.stack([su2, su3, su4], -1)], -2)
    b = np.stack([sy, suy, su2y], -1)
    coef = _solve3(m.reshape(-1, 3, 3), b.reshape(-1, 3)).reshape(b.shape)
    ss_res = np.maximum(syy - (coef * b).sum(-1), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sqrt(ss_res / np.where(n > 0, n, 1.0)), np.nan)


def _solve3(m: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched 3 × 3 solves; rows whose matrix is singular (relative to its scale) by the pseudo-inverse."""
    out = np.empty_like(b)
    scale = np.maximum(np.abs(m).max(axis=(1, 2)), 1e-300)
    det = np.linalg.det(m / scale[:, None, None])
    good = np.abs(det) > 1e-12
    if good.any():
        out[good] = np.linalg.solve(m[good], b[good][..., None])[..., 0]
    if (~good).any():
        out[~good] = np.einsum("rij,rj->ri", np.linalg.pinv(m[~good]), b[~good])
    return out


def classification_stats(index: np.ndarray, status: np.ndarray, target: np.ndarray, copies: int,
                         n_classes: int) -> np.ndarray:
    """Per design and spectrum, the correctly classified pixels and all pixels, each in the column of the
    spectrum's class: ``(n_designs, n_spectra, 2 n_classes)`` (correct counts, then pixel counts). A pixel is
    correct when its status is OK and its class index equals the truth ``target`` (class index per pixel)."""
    pred = np.atleast_2d(np.asarray(index))
    status = np.atleast_2d(status)
    truth = np.asarray(target).astype(np.int64)
    correct = (status == Status.OK) & (np.rint(pred).astype(np.int64) == truth[None, :])
    onehot = np.eye(n_classes)[truth]  # (n_pixels, n_classes)
    terms = np.concatenate([correct[..., None] * onehot[None], np.broadcast_to(onehot, (*correct.shape,
                                                                                       n_classes))], axis=-1)
    return _per_spectrum(terms.astype(np.float64), copies)


def classification_score(sums: np.ndarray) -> np.ndarray:
    """Mean omission error over the classes present (%), from :func:`classification_stats` sums ``(..., 2C)``."""
    s = np.asarray(sums, dtype=np.float64)
    c = s.shape[-1] // 2
    correct, total = s[..., :c], s[..., c:]
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # no class present: NaN
        omission = np.where(total > 0, 1.0 - correct / np.where(total > 0, total, 1.0), np.nan)
        return 100.0 * np.nanmean(omission, axis=-1)
