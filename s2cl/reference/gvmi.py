"""float64 oracle of the GVMI kernel (``kernels/gvmi.cl.mako``)."""

from __future__ import annotations

import numpy as np


def gvmi(nir: np.ndarray, swir: np.ndarray, max_abs: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """GVMI (paper eq. 3) and status (0 valid, 3 invalid) in float64."""
    nir = np.asarray(nir, dtype=np.float64)
    swir = np.asarray(swir, dtype=np.float64)
    a, b = nir + 0.1, swir + 0.02
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = (np.abs(nir) <= max_abs) & (np.abs(swir) <= max_abs) & (a + b > 1e-6)
        value = np.where(ok, (a - b) / (a + b), 0.0)
    return value, np.where(ok, 0, 3).astype(np.uint8)
