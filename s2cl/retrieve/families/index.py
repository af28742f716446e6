"""The normalised-difference indices (GVMI, NDVI, ...: :data:`s2cl.retrieve.indices.INDICES`) as analysis families:
``[analysis] kind = "gvmi"`` with its band roles as keys (``nir = "B8"``, ``swir = "B11"``), regressed on
``parameter``. Its two bands must differ: one band in both roles gives a constant index."""

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
from s2cl.retrieve.index_kernel import IndexKernel
from s2cl.retrieve.indices import INDICES, NormalisedDifference


class IndexFamily(Family):
    """One normalised-difference index ``nd``."""

    keys = ()
    twin = "s2cl.reference.families:normalised_difference"

    def __init__(self, nd: NormalisedDifference):
        self.nd = nd
        self.kind = nd.kind  # type: ignore[misc]  # one instance per index
        self.example_parameter = nd.parameter  # type: ignore[misc]

    def roles(self, spec: Any) -> tuple[str, ...]:
        return self.nd.roles

    def default_bands(self, spec: Any, band_names: Sequence[str]) -> list[str]:
        return index_bands(self.nd, spec.roles)

    def settings(self, spec: Any, bands: list[str], slot: Any, source: str | None) -> AnalysisSettings:
        a, b = (slot(name, role) for name, role in zip(index_bands(self.nd, spec.roles), self.nd.roles, strict=True))
        return AnalysisSettings(self.kind, spec.parameter, slots=(a, b))

    def problem(self, settings: AnalysisSettings, names: Sequence[str], c: np.ndarray, w: np.ndarray) -> str | None:
        a, b = settings.slots
        if same_band(c[a], w[a], c[b], w[b]):
            role_a, role_b = self.nd.roles
            return (f"underdetermined: the {self.kind.upper()}'s {role_a} band {names[a]} and {role_b} band "
                    f"{names[b]} are the same band ({c[a]:g}/{w[a]:g} nm)")
        return None

    def underdetermined(self, settings: AnalysisSettings, c: np.ndarray, w: np.ndarray) -> np.ndarray:
        a, b = settings.slots
        return same_band(c[:, a], w[:, a], c[:, b], w[:, b])

    def sweep_code(self, settings: AnalysisSettings, T: VecTypes, ctx: SweepContext) -> tuple[str, str]:
        a, b = settings.slots
        body = (f"    {T.M} st;\n    const {T.V} value = s2_{self.kind}_{T.suffix}(rho[{a}], rho[{b}], &st);\n"
                f"    const {T.M} bd = ({T.M})(0), code = ({T.M})(0);")
        return render_def("common/stages.mako", "normalised_difference", T=T, nd=self.nd, max_abs=ctx.max_abs), body

    def run(self, rt: Runtime, settings: AnalysisSettings, bands: Sequence[str], refl: np.ndarray,
            centres: np.ndarray, *, real_t: str, lanes: int | None, references: np.ndarray | None = None) -> Outcome:
        g = IndexKernel(rt, self.kind, real_t=real_t, lanes=lanes)(refl, *settings.slots)
        return Outcome(g.index, g.status, np.zeros_like(g.status))


def index_bands(nd: NormalisedDifference, roles: dict[str, str]) -> list[str]:
    """The bands of index ``nd`` (band a, band b): the scene's role keys, else the registry's defaults."""
    return [roles.get(role, default) for role, default in zip(nd.roles, nd.default_bands, strict=True)]


FAMILIES = tuple(IndexFamily(nd) for nd in INDICES.values())
