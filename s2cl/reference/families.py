"""float64 numpy twins of the analysis families' sweep code (:attr:`s2cl.retrieve.family.Family.twin` names them):
each takes the settings, the slots' band names, the corrected reflectance of each slot ``(n_configs, n_pixels)``,
the band centres ``(n_configs, n_slots)`` in nm and, for a classification, the unit-length class references
``(n_configs, n_classes, n_slots)``, and returns the per-pixel :class:`s2cl.retrieve.family.Outcome`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from s2cl.reference import stages
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.families.sam import cos_min
from s2cl.retrieve.family import Outcome
from s2cl.retrieve.indices import INDICES
from s2cl.retrieve.metrics import condition_code
from s2cl.status import Status


def normalised_difference(a: AnalysisSettings, bands: Sequence[str], rhos: Sequence[np.ndarray], centres: np.ndarray,
                          references: np.ndarray | None) -> Outcome:
    index, status = stages.normalised_difference(rhos[a.slots[0]], rhos[a.slots[1]], INDICES[a.kind].offsets)
    return Outcome(index, status, np.zeros_like(status), np.zeros_like(status))


def sam(a: AnalysisSettings, bands: Sequence[str], rhos: Sequence[np.ndarray], centres: np.ndarray,
        references: np.ndarray | None) -> Outcome:
    assert references is not None
    pixels = np.stack(rhos, axis=-1)  # (n_cfg, n_px, n_slots)
    best, _, _, status = stages.sam(pixels, references[:, None, :, :], cos_min(a))
    index = np.where(status == Status.OK, best, references.shape[1]).astype(np.float64)
    return Outcome(index, status, np.zeros_like(status), np.zeros_like(status))


def igrm(a: AnalysisSettings, bands: Sequence[str], rhos: Sequence[np.ndarray], centres: np.ndarray,
         references: np.ndarray | None) -> Outcome:
    return Outcome(*igrm_per_configuration(np.stack(rhos), centres, dict(a.igrm)))


def igrm_per_configuration(rhos: np.ndarray, centres: np.ndarray, settings: dict, dtype: type = np.float64
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """IGRM fits of ``rhos`` ``(n_slots, n_configs, n_pixels)`` with each configuration's band
    centres ``(n_configs, n_slots)``: the kernel's fit (variable projection or LM, as the settings
    say) in vectorised numpy, one configuration at a time, the bands sorted by centre (stable) as the kernel sorts
    them. Returns λp (nm), status, bound bits and condition codes, each ``(n_configs, n_pixels)``."""
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
