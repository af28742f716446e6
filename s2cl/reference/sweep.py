"""float64 numpy evaluation of sweep configurations: the oracle of the OpenCL sweep kernel and the
"same sweep written as vectorised numpy" baseline of the benchmarks (pass a :class:`NumpyEvaluator` to
:func:`s2cl.sweep.engine.run_sweep` to run a whole sweep this way).

Per configuration and pixel: gather noise-free band radiance → the twins of the chain's per-pixel stages that are
on (:mod:`s2cl.reference.stages`, in the chain's order: the kernel's rules) → the analysis.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from s2cl.forward.stages import stage
from s2cl.reference.forward import run_steps
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.sweep.raw import RawChunk, variant_indices
from s2cl.sweep.tables import SweepTables


def band_reflectance(t: SweepTables, start: int, stop: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Corrected band reflectance per slot ``(n_configs, n_pixels)`` and band centres ``(n_configs, n_slots)``."""
    idx = variant_indices(t, start, stop)
    spectrum = np.arange(t.n_pixels) // t.copies
    slots = range(t.n_slots)
    L = np.stack([t.radiance[k][idx[:, k]][:, spectrum] for k in slots])  # (n_slots, n_configs, n_pixels)
    v: dict[str, Any] = {}
    for val in t.inputs():
        x = t.values[val.name]
        if val.varies == "band":
            v[val.name] = np.asarray(x, dtype=np.float64).reshape(-1, 1, 1)
        elif val.varies == "variant":
            v[val.name] = np.stack([x[k][idx[:, k]] for k in slots])[:, :, None]
        elif val.varies == "pixel":
            v[val.name] = np.stack([x[k][idx[:, k]][:, spectrum] for k in slots])
        else:
            v[val.name] = x
    v["z"] = np.asarray(t.z)[:, None, :]
    L, _ = run_steps([stage(n) for n in t.stages], L, v)
    centres = np.stack([t.centre[k][idx[:, k]] for k in slots], axis=1)
    return list(L), centres


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
