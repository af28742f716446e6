"""SAM classification as an analysis family: ``[analysis] kind = "sam"``, the library groups as classes
(``classes``), pixels beyond ``angle_threshold_deg`` unclassified; scored by omission error. It needs at least two
distinct bands (with one direction every pixel has the same angle to every class)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from s2cl.cl.runtime import Runtime
from s2cl.cl.templates import render_def
from s2cl.cl.vectypes import VecTypes
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.design import same_band
from s2cl.retrieve.family import Family, Outcome, SweepContext
from s2cl.retrieve.metric import CLASSIFICATION
from s2cl.retrieve.sam import SamClassifier

TEMPLATE = "common/analysis_sam.mako"


class SamFamily(Family):
    kind = "sam"
    metric = CLASSIFICATION
    keys = ("classes", "angle_threshold_deg")
    uses_every_band = True
    twin = "s2cl.reference.families:sam"

    def settings(self, spec: Any, bands: list[str], slot: Any, source: str | None) -> AnalysisSettings:
        return AnalysisSettings("sam", angle_threshold_deg=spec.angle_threshold_deg)

    def problem(self, settings: AnalysisSettings, names: Sequence[str], c: np.ndarray, w: np.ndarray) -> str | None:
        if bool(np.all(same_band(c, w, c[0], w[0]))):
            return "underdetermined: SAM needs at least two distinct bands; every band here is the same"
        return None

    def underdetermined(self, settings: AnalysisSettings, c: np.ndarray, w: np.ndarray) -> np.ndarray:
        return same_band(c, w, c[:, :1], w[:, :1]).all(axis=1)

    def sweep_code(self, settings: AnalysisSettings, T: VecTypes, ctx: SweepContext) -> tuple[str, str]:
        return (render_def(TEMPLATE, "functions", T=T, n_slots=len(ctx.counts), n_classes=ctx.n_classes,
                           max_abs=ctx.max_abs),
                render_def(TEMPLATE, "body", T=T, ctx=ctx, n_classes=ctx.n_classes, cos_min=cos_min(settings)))

    def run(self, rt: Runtime, settings: AnalysisSettings, bands: Sequence[str], refl: np.ndarray,
            centres: np.ndarray, *, real_t: str, lanes: int | None, references: np.ndarray | None = None) -> Outcome:
        assert references is not None
        theta = settings.angle_threshold_deg
        r = SamClassifier(rt, references, real_t=real_t, lanes=lanes,
                          threshold_rad=None if theta is None else np.deg2rad(theta)).classify(refl)
        index = np.where(r.label >= 0, r.label, len(references)).astype(np.float64)
        return Outcome(index, r.status, np.zeros_like(r.status))


def cos_min(settings: AnalysisSettings) -> float:
    """cos of the angle threshold; -2 (below -1) for none."""
    a = settings.angle_threshold_deg
    return -2.0 if a is None else float(np.cos(np.deg2rad(a)))


FAMILY = SamFamily()
