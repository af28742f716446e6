"""float64 oracle of the SAM kernel (``kernels/sam.cl.mako``): plain numpy, first index on ties."""

from __future__ import annotations

import numpy as np


def spectral_angles(refl: np.ndarray, references: np.ndarray) -> np.ndarray:
    """Angles (radians) between every pixel of ``refl`` (n_bands, n) and every reference
    (n_refs, n_bands): shape (n_refs, n); NaN where a pixel has zero norm."""
    p = np.asarray(refl, dtype=np.float64)
    r = np.asarray(references, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = (r @ p) / (np.linalg.norm(r, axis=1)[:, None] * np.linalg.norm(p, axis=0)[None, :])
    return np.arccos(np.clip(cos, -1.0, 1.0))


def classify(refl: np.ndarray, references: np.ndarray, threshold_rad: float | None = None,
             max_abs: float = 10.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(best reference or -1, angle, status) with the kernel's status rules."""
    p = np.asarray(refl, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        valid = np.all(np.abs(p) <= max_abs, axis=0)
    nonzero = (p * p).sum(axis=0) > 1e-30
    ang = spectral_angles(np.where(valid & nonzero, p, 1.0), references)
    best = np.argmin(ang, axis=0)
    angle = ang[best, np.arange(p.shape[1])]
    inside = np.ones_like(valid) if threshold_rad is None else angle <= threshold_rad
    status = np.where(~valid, 3, np.where(~nonzero, 2, np.where(inside, 0, 1))).astype(np.uint8)
    angle = np.where(valid & nonzero, angle, 0.0)
    return np.where(status == 0, best, -1).astype(np.int32), angle, status
