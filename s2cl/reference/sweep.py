"""float64 numpy evaluation of sweep configurations: the oracle of the OpenCL sweep kernel and the
"same sweep written as vectorised numpy" baseline of the benchmarks (pass a :class:`NumpyEvaluator` to
:func:`s2cl.sweep.engine.run_sweep` to run a whole sweep this way).

Per configuration and pixel: gather noise-free band radiance and σ → add σ·z → quantise (ties
up) → calibrate → band-effective correction (a calibration error is folded into its terms) → the
analysis, through the stage twins of :mod:`s2cl.reference.stages` (the kernel's rules).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.reference import stages
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.indices import INDICES
from s2cl.retrieve.metrics import condition_code
from s2cl.status import Status
from s2cl.sweep.raw import RawChunk, variant_indices
from s2cl.sweep.tables import SweepTables


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
            dn, flags = stages.quantise(L, t.lmin[k], t.lmax[k], t.maxdn)
            L = stages.calibrate(dn, flags, t.lmin[k], (t.lmax[k] - t.lmin[k]) / t.maxdn)
        rhos.append(stages.correct(L, t.lp[k][v][:, None], t.g[k][v][:, None], t.s[k][v][:, None]))
        centres[:, k] = t.centre[k][v]
    return rhos, centres


def evaluate(t: SweepTables, a: AnalysisSettings, start: int, stop: int) -> RawChunk:
    """Evaluate configurations ``start … stop-1`` in float64."""
    rhos, centres = band_reflectance(t, start, stop)
    shape = rhos[0].shape
    bounds = np.zeros(shape, np.uint8)
    condition = np.zeros(shape, np.uint8)
    if a.kind in INDICES:
        index, status = stages.normalised_difference(rhos[a.slots[0]], rhos[a.slots[1]], INDICES[a.kind].offsets)
    elif a.kind == "formula":
        formula = a.formula(t.bands)
        index, status = formula.evaluate({b: rhos[s] for b, s in zip(formula.bands, a.slots, strict=True)})
    elif a.kind == "sam":
        idx = variant_indices(t, start, stop)
        refs = np.stack([t.references[k][idx[:, k]] for k in range(t.n_slots)], axis=-1)  # (n_cfg, n_cls, n_slots)
        norms = np.sqrt((refs * refs).sum(-1, keepdims=True))
        unit = refs * np.where(norms > 0, 1.0 / np.where(norms > 0, norms, 1.0), 0.0)
        pixels = np.stack(rhos, axis=-1)  # (n_cfg, n_px, n_slots)
        theta = a.angle_threshold_deg
        best, _, _, status = stages.sam(pixels, unit[:, None, :, :], -2.0 if theta is None else
                                        float(np.cos(np.deg2rad(theta))))
        index = np.where(status == Status.OK, best, len(t.class_names)).astype(np.float64)
    else:
        index, status, bounds, condition = igrm_per_configuration(np.stack(rhos), centres, dict(a.igrm))
    return RawChunk(start, stop, index, status, bounds, condition)


def igrm_per_configuration(rhos: np.ndarray, centres: np.ndarray, settings: dict, dtype: type = np.float64
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """IGRM fits of ``rhos`` ``(n_slots, n_configs, n_pixels)`` with each configuration's band
    centres ``(n_configs, n_slots)``: the kernel's fit (variable projection or LM, as the settings
    say) in vectorised numpy, one configuration at a
    time, the bands sorted by centre (stable) as the kernel sorts them. Returns λp (nm), status,
    bound bits and condition codes, each ``(n_configs, n_pixels)``."""
    from s2cl.reference.igrm import fit_numpy_lm
    from s2cl.reference.igrm_varpro import fit_numpy_varpro
    from s2cl.retrieve.igrm import IgrmSettings

    s = IgrmSettings.from_mapping(settings)
    fit = fit_numpy_varpro if s.resolved_solver() == "varpro" else fit_numpy_lm
    n_cfg, n_px = rhos.shape[1:]
    index, status = np.empty((n_cfg, n_px)), np.empty((n_cfg, n_px), np.uint8)
    bounds, condition = np.empty((n_cfg, n_px), np.uint8), np.empty((n_cfg, n_px), np.uint8)
    for i in range(n_cfg):
        order = np.argsort(centres[i], kind="stable")
        r = fit(rhos[order, i, :], centres[i][order], s, dtype=dtype)
        index[i], status[i], bounds[i] = r.lp, r.status, r.bounds
        condition[i] = condition_code(r.log10_condition)
    return index, status, bounds, condition


@dataclass(frozen=True)
class NumpyEvaluator:
    """A picklable chunk evaluator (for :func:`s2cl.sweep.engine.run_sweep`, Dask included) of
    :func:`evaluate` on ``tables`` and ``analysis``."""

    tables: SweepTables
    analysis: AnalysisSettings

    def __call__(self, start: int, stop: int) -> RawChunk:
        return evaluate(self.tables, self.analysis, start, stop)
