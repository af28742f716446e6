"""The inverted-Gaussian red-edge model (IGRM) as an analysis family: ``[analysis] kind = "igrm"``, the fit's
inflection wavelength λp (nm) regressed on ``parameter`` (e.g. cab); fit settings in ``[analysis.igrm]``, the fit
statuses that enter the regression in ``regress``.

Design rule: the fit has four parameters (rmax, rmin, l0, s) with the band centres as abscissae, so it needs at
least four *distinct* centres. Two bands on one centre (different widths or not) give one abscissa, and the fit has
no unique solution (the minimum cost lies along a whole curve of parameters: scipy finds λp anywhere in a 2 nm
range from different starts). Band order is not part of validity: the kernels sort a design's bands by centre.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from s2cl.cl.runtime import Runtime
from s2cl.cl.templates import render_def
from s2cl.cl.vecmath import EXP_DEGREE, exp_template_vars
from s2cl.cl.vectypes import VecTypes
from s2cl.errors import InputError, key_token
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.design import SAME_CENTRE_NM
from s2cl.retrieve.family import Family, Outcome, SweepContext
from s2cl.retrieve.igrm import IgrmFitter
from s2cl.retrieve.igrm_settings import IgrmSettings, kernel_config
from s2cl.retrieve.metrics import condition_code
from s2cl.status import REGRESS_NAMES

TEMPLATE = "common/analysis_igrm.mako"
IGRM_PARAMETERS = 4
#: the bands analysed when a scene names none
RED_EDGE = ("B4", "B5", "B6", "B7")


class IgrmFamily(Family):
    kind = "igrm"
    keys = ("igrm", "regress")
    uses_every_band = True
    has_condition = True
    iterative = True
    width_matters = False
    twin = "s2cl.reference.families:igrm"

    def default_bands(self, spec: Any, band_names: Sequence[str]) -> list[str]:
        return list(RED_EDGE)

    def settings(self, spec: Any, bands: list[str], slot: Any, source: str | None) -> AnalysisSettings:
        if len(bands) < IGRM_PARAMETERS:
            raise InputError(f"IGRM needs at least {IGRM_PARAMETERS} bands, got {len(bands)}", source=source,
                             key="analysis")
        fit_settings(spec.igrm, source)
        regress = tuple(sorted(int(REGRESS_NAMES[name]) for name in set(spec.regress)))
        return AnalysisSettings("igrm", spec.parameter, igrm=tuple(sorted(spec.igrm.items())), regress=regress)

    def problem(self, settings: AnalysisSettings, names: Sequence[str], c: np.ndarray, w: np.ndarray) -> str | None:
        s = np.sort(c)
        distinct = int(1 + np.count_nonzero(np.diff(s) > SAME_CENTRE_NM)) if s.size else 0
        if distinct < IGRM_PARAMETERS:
            return (f"underdetermined: the IGRM fits {IGRM_PARAMETERS} parameters but the bands give only "
                    f"{distinct} distinct centres ({_coincident(names, c)}); move the bands apart")
        return None

    def underdetermined(self, settings: AnalysisSettings, c: np.ndarray, w: np.ndarray) -> np.ndarray:
        s = np.sort(c, axis=1)
        return 1 + np.count_nonzero(np.diff(s, axis=1) > SAME_CENTRE_NM, axis=1) < IGRM_PARAMETERS

    def sweep_code(self, settings: AnalysisSettings, T: VecTypes, ctx: SweepContext) -> tuple[str, str]:
        precision = "float64" if T.double else "float32"
        c = kernel_config(IgrmSettings.from_mapping(dict(settings.igrm)), len(ctx.counts), precision, "poly")
        exp = exp_template_vars(precision, EXP_DEGREE[precision])
        return (render_def(TEMPLATE, "functions", T=T, T1=VecTypes(precision, 1), c=c, **exp),
                render_def(TEMPLATE, "body", T=T, n_slots=len(ctx.counts)))

    def run(self, rt: Runtime, settings: AnalysisSettings, bands: Sequence[str], refl: np.ndarray,
            centres: np.ndarray, *, real_t: str, lanes: int | None, references: np.ndarray | None = None) -> Outcome:
        order = np.argsort(centres, kind="stable")
        fit = IgrmFitter(rt, len(bands), IgrmSettings.from_mapping(dict(settings.igrm)), real_t=real_t, lanes=lanes)
        r = fit.fit(refl[order], np.asarray(centres)[order])
        return Outcome(r.lp, r.status, r.bounds, condition_code(r.log10_condition))


def fit_settings(values: dict[str, Any], source: str | None) -> Any:
    """The scene's ``analysis.igrm`` table as IGRM fit settings; errors name ``analysis.igrm.KEY``."""
    known = [f.name for f in dataclasses.fields(IgrmSettings)]
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise InputError(f"unknown key; allowed keys here: {', '.join(known)}", source=source,
                         key=f"analysis.igrm.{key_token(unknown[0])}")
    try:
        return IgrmSettings(**values)
    except InputError as err:
        raise InputError(err.detail, source=source, key=f"analysis.{err.key or 'igrm'}") from None
    except (TypeError, ValueError) as err:
        raise InputError(f"invalid settings ({type(err).__name__})", source=source, key="analysis.igrm") from None


def _coincident(names: Sequence[str], c: np.ndarray) -> str:
    """"B5 and B6 at 730 nm"-style text for the bands that share a centre."""
    groups: dict[float, list[str]] = {}
    for name, centre in zip(names, c, strict=True):
        groups.setdefault(round(float(centre), 6), []).append(name)
    shared = [f"{' and '.join(g)} at {k:g} nm" for k, g in groups.items() if len(g) > 1]
    return "; ".join(shared) if shared else f"{len(c)} bands"


FAMILY = IgrmFamily()
