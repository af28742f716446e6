"""float64 numpy evaluation of sweep configurations: the oracle of the OpenCL sweep kernel and the
"same sweep written as vectorised numpy" baseline of the benchmarks (pass a :class:`NumpyEvaluator` to
:func:`s2cl.sweep.engine.run_sweep` to run a whole sweep this way).

Per configuration and pixel: gather noise-free band radiance and σ → add σ·z → quantise (ties
up) → calibrate → band-effective correction (a calibration error is folded into its terms) → the
analysis, through the stage twins of :mod:`s2cl.reference.stages` (the kernel's rules).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

import numpy as np

from s2cl.reference import stages
from s2cl.retrieve.analysis import AnalysisSettings
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
    """Evaluate configurations ``start … stop-1`` in float64: the analysis through its family's numpy twin
    (:attr:`s2cl.retrieve.family.Family.twin`)."""
    rhos, centres = band_reflectance(t, start, stop)
    references = None
    if t.references:
        idx = variant_indices(t, start, stop)
        refs = np.stack([t.references[k][idx[:, k]] for k in range(t.n_slots)], axis=-1)  # (n_cfg, n_cls, n_slots)
        norms = np.sqrt((refs * refs).sum(-1, keepdims=True))
        references = refs * np.where(norms > 0, 1.0 / np.where(norms > 0, norms, 1.0), 0.0)
    module, name = a.family.twin.split(":")
    r = getattr(importlib.import_module(module), name)(a, t.bands, rhos, centres, references)
    shape = rhos[0].shape
    condition = r.condition if r.condition is not None else np.zeros(shape, np.uint8)
    return RawChunk(start, stop, r.index, r.status, np.asarray(r.bounds, np.uint8), condition)


@dataclass(frozen=True)
class NumpyEvaluator:
    """A picklable chunk evaluator (for :func:`s2cl.sweep.engine.run_sweep`, Dask included) of
    :func:`evaluate` on ``tables`` and ``analysis``."""

    tables: SweepTables
    analysis: AnalysisSettings

    def __call__(self, start: int, stop: int) -> RawChunk:
        return evaluate(self.tables, self.analysis, start, stop)
