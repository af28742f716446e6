"""float64 numpy evaluation of sweep configurations: the oracle of the OpenCL sweep kernel and the
"same sweep written as vectorised numpy" baseline of the benchmarks.

Per configuration and pixel: gather noise-free band radiance and σ → add σ·z → quantise (ties
up) → calibrate → band-effective correction (a calibration error is folded into its terms) → the
analysis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..analysis import AnalysisSettings, gvmi, sam_classify
from ..correction import MIN_DENOMINATOR
from ..sweep_tables import SweepTables


@dataclass
class RawChunk:
    """Per (configuration, pixel) results of configurations ``start … stop-1``.

    ``index``: λp (nm) for igrm, GVMI for gvmi, class index for sam (float64); ``status`` and
    ``bounds`` (IGRM active-bound bits) are uint8; all ``(n_configs, n_pixels)``.
    """

    start: int
    stop: int
    index: np.ndarray
    status: np.ndarray
    bounds: np.ndarray


def variant_indices(t: SweepTables, start: int, stop: int) -> np.ndarray:
    """Variant index per slot, ``(n_configs, n_slots)``, last slot fastest (as SweepSpace.indices)."""
    flat = np.arange(start, stop, dtype=np.int64)
    out = np.empty((flat.size, t.n_slots), dtype=np.int64)
    for k in range(t.n_slots - 1, -1, -1):
        flat, out[:, k] = np.divmod(flat, t.counts[k])
    return out


def quantise(L: np.ndarray, lmin: float, lmax: float, maxdn: int) -> np.ndarray:
    """DN (as float64) with s2cl's rule: ties round up, clipped into [0, maxdn], NaN → 0."""
    x = (L - lmin) * (maxdn / (lmax - lmin))
    safe = np.where(np.isfinite(x), x, 0.0)
    f = np.floor(safe)
    q = np.where(safe - f >= 0.5, f + 1.0, f)
    return np.clip(np.where(x > 0, q, 0.0), 0, maxdn)


def band_reflectance(t: SweepTables, start: int, stop: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Corrected band reflectance per slot ``(n_configs, n_pixels)`` and band centres ``(n_configs, n_slots)``."""
    idx = variant_indices(t, start, stop)
    spectrum = np.arange(t.n_pixels) // t.copies
    rhos, centres = [], np.empty((stop - start, t.n_slots))
    for k in range(t.n_slots):
        v = idx[:, k]
        L = t.radiance[k][v][:, spectrum]
        if t.noise:
            L = L + t.sigma[k][v][:, spectrum] * t.z[k][None, :]
        if t.quantise:
            gain = (t.lmax[k] - t.lmin[k]) / t.maxdn
            L = t.lmin[k] + quantise(L, t.lmin[k], t.lmax[k], t.maxdn) * gain
        y = (L - t.lp[k][v][:, None]) / t.g[k][v][:, None]
        rhos.append(y / np.maximum(1.0 + t.s[k][v][:, None] * y, MIN_DENOMINATOR))
        centres[:, k] = t.centre[k][v]
    return rhos, centres


def evaluate(t: SweepTables, a: AnalysisSettings, start: int, stop: int) -> RawChunk:
    """Evaluate configurations ``start … stop-1`` in float64."""
    rhos, centres = band_reflectance(t, start, stop)
    shape = rhos[0].shape
    bounds = np.zeros(shape, np.uint8)
    if a.kind == "gvmi":
        index, status = gvmi(rhos[a.nir_slot], rhos[a.swir_slot])
    elif a.kind == "sam":
        idx = variant_indices(t, start, stop)
        refs = np.stack([t.references[k][idx[:, k]] for k in range(t.n_slots)], axis=-1)  # (n_cfg, n_cls, n_slots)
        pixels = np.stack(rhos, axis=-1)  # (n_cfg, n_px, n_slots)
        cls, _, status = sam_classify(pixels, refs[:, None, :, :], a.angle_threshold_deg)
        index = cls.astype(np.float64)
    else:
        index, status, bounds = igrm_per_configuration(np.stack(rhos), centres, dict(a.igrm))
    return RawChunk(start, stop, index, status, bounds)


def igrm_per_configuration(rhos: np.ndarray, centres: np.ndarray, settings: dict,
                           dtype: type = np.float64) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IGRM fits of ``rhos`` ``(n_slots, n_configs, n_pixels)`` with each configuration's band
    centres ``(n_configs, n_slots)``: the kernel's LM in vectorised numpy, one configuration at a
    time. Returns λp (nm), status and bound bits, each ``(n_configs, n_pixels)``."""
    from ..igrm import IgrmSettings
    from .igrm import fit_numpy_lm

    s = IgrmSettings.from_mapping(settings)
    n_cfg, n_px = rhos.shape[1:]
    index, status, bounds = np.empty((n_cfg, n_px)), np.empty((n_cfg, n_px), np.uint8), np.empty((n_cfg, n_px),
                                                                                                   np.uint8)
    for i in range(n_cfg):
        r = fit_numpy_lm(rhos[:, i, :], centres[i], s, dtype=dtype)
        index[i], status[i], bounds[i] = r.lp, r.status, r.bounds
    return index, status, bounds
