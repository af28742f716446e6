"""An analysis family as one object: what ``[analysis] kind = "..."`` selects.

A family holds everything the commands ask about a retrieval: its scene keys (:meth:`Family.settings`), its
design rule (:meth:`Family.problem`, :meth:`Family.underdetermined`), its device code for the sweep kernel
(:meth:`Family.sweep_code`), its standalone engine (:meth:`Family.run`), its float64 numpy twin (:attr:`Family.twin`,
named, so that the product never imports the twins), its metric (:attr:`Family.metric`, a
:class:`~s2cl.retrieve.metric.Metric`: what a design is scored by) and its one-line description. The sweep
kernel, the design rule, ``simulate``, the metrics, band additions and the studies ask the family (and its
metric) instead of branching on the kind.

The families are the modules of :mod:`s2cl.retrieve.families`: each that defines ``FAMILY`` (or ``FAMILIES``) is
registered when the registry is first asked; adding a family is adding a module there (and its kernel).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cache
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from s2cl.errors import InputError
from s2cl.retrieve.metric import REGRESSION, Metric
from s2cl.status import Status

if TYPE_CHECKING:
    from s2cl.cl.runtime import Runtime
    from s2cl.cl.vectypes import VecTypes


@dataclass
class Outcome:
    """Per-pixel outcome of a retrieval, in the sweep kernel's terms: ``index`` (its value: λp nm, an index, a
    formula's value, or a SAM class with ``n_classes`` for none), ``status`` (:class:`s2cl.status.Status`),
    ``bounds`` (IGRM active-bound bits, else 0) and ``condition`` (IGRM condition codes, else None)."""

    index: np.ndarray
    status: np.ndarray
    bounds: np.ndarray
    condition: np.ndarray | None = None


@dataclass(frozen=True)
class SweepContext:
    """What a family's sweep code may use of the sweep kernel (``kernels/sweep.cl.mako``): the band names of the
    slots, the mixed-radix decoding of a configuration (``counts``, ``strides``, ``var0``), the SAM class count,
    and |ρ| above which a pixel is invalid."""

    bands: tuple[str, ...]
    counts: tuple[int, ...]
    strides: tuple[int, ...]
    var0: tuple[int, ...]
    n_classes: int
    max_abs: float


class Family:
    """The base of every analysis family; a family overrides what differs.

    :cvar kind: the ``[analysis] kind`` that selects it (:meth:`kinds`: every kind it answers).
    :cvar metric: what a design is scored by (:mod:`s2cl.retrieve.metric`): :data:`~s2cl.retrieve.metric.REGRESSION`
        (the index is regressed on a library parameter) or :data:`~s2cl.retrieve.metric.CLASSIFICATION`.
    :cvar keys: the family's own ``[analysis]`` keys (besides kind, bands, parameter); any other family's key set
        in a scene is refused.
    :cvar uses_every_band: whether it reads every analysed band (a band addition can only score such families).
    :cvar has_condition: whether the outcome carries condition codes.
    :cvar iterative: whether its sweep body sets ``it``, the fit's iterations (the sweep profile's
        ``iterations`` switch reads it).
    :cvar width_matters: whether the design rule depends on band widths.
    :cvar twin: ``"module:function"`` of its numpy twin on a sweep chunk (:mod:`s2cl.reference.families`).
    """

    kind: ClassVar[str]
    metric: ClassVar[Metric] = REGRESSION
    keys: ClassVar[tuple[str, ...]] = ()
    uses_every_band: ClassVar[bool] = False
    has_condition: ClassVar[bool] = False
    iterative: ClassVar[bool] = False
    width_matters: ClassVar[bool] = True
    twin: ClassVar[str]
    #: a library parameter it is usually regressed on (examples in messages)
    example_parameter: ClassVar[str] = "cab"

    def kinds(self) -> tuple[str, ...]:
        return (self.kind,)

    @property
    def score_column(self) -> str:
        """The results column a design is ranked (and a band addition's gain taken) on."""
        return self.metric.score_column

    def score_label(self, settings: AnalysisSettings) -> str:
        """What the score is, in words (``RMS of cab``)."""
        return self.metric.score_label(settings.parameter)

    def summary_line(self, result: dict[str, Any]) -> str:
        """One line of a simulation's analysis result (the metrics of :func:`s2cl.app.analysis.analyse`)."""
        return self.metric.summary_line(result)

    def default_bands(self, spec: Any, band_names: Sequence[str]) -> list[str]:
        """The bands ``s2cl simulate`` analyses when the scene names none (``spec``: its [analysis] section)."""
        return list(band_names)

    def roles(self, spec: Any) -> tuple[str, ...]:
        """The band-role keys the family reads (an index's ``nir``, ``swir``); none by default."""
        return ()

    def settings(self, spec: Any, bands: list[str], slot: Any, source: str | None) -> AnalysisSettings:
        """The settings of ``spec`` (the scene's [analysis]) on the band slots ``bands``; ``slot(name, key)`` finds
        a band's slot (refusing, key ``analysis.KEY``, one that is not analysed)."""
        raise NotImplementedError

    def problem(self, settings: AnalysisSettings, names: Sequence[str], c: np.ndarray, w: np.ndarray) -> str | None:
        """Why the design (centres ``c``, widths ``w`` in nm) cannot be fitted, or None."""
        raise NotImplementedError

    def underdetermined(self, settings: AnalysisSettings, c: np.ndarray, w: np.ndarray) -> np.ndarray:
        """:meth:`problem` for ``(n_configs, n_slots)`` centres and widths: True where it finds one."""
        raise NotImplementedError

    def sweep_code(self, settings: AnalysisSettings, T: VecTypes, ctx: SweepContext) -> tuple[str, str]:
        """OpenCL C of the family in the sweep kernel: (device functions, body). The body reads ``rho[k]``
        (corrected reflectance of slot k, vector of T) and ``x[k]`` (centre, nm), may use ``cfg``, and sets
        ``value`` (T.V), ``st``, ``bd`` and ``code`` (T.M: status, bound bits, condition code)."""
        raise NotImplementedError

    def run(self, rt: Runtime, settings: AnalysisSettings, bands: Sequence[str], refl: np.ndarray,
            centres: np.ndarray, *, real_t: str, lanes: int | None, references: np.ndarray | None = None) -> Outcome:
        """The standalone engine on ``refl`` (bands × pixels, corrected reflectance), ``centres`` (nm) the bands'
        centres; ``references`` (classes × bands) for a classification."""
        raise NotImplementedError


@dataclass(frozen=True)
class AnalysisSettings:
    """What to compute from the band reflectances of each pixel.

    :param kind: the ``[analysis] kind``, which names its family (:func:`s2cl.retrieve.family.family_of`): ``"igrm"``
        (index: inflection wavelength λp in nm), a key of :data:`s2cl.retrieve.indices.INDICES` (e.g. GVMI),
        ``"formula"`` or ``"sam"`` (class of each pixel).
    :param parameter: library parameter regressed on the index (``cab``, ``ewt``); igrm and indices.
    :param slots: indices: band slots of band a and band b (GVMI: NIR, SWIR); formula: the slot of each band the
        expression names, in the order it names them.
    :param angle_threshold_deg: sam: pixels whose smallest angle exceeds it are unclassified.
    :param igrm: IGRM fit settings (keys of ``s2cl.retrieve.igrm.IgrmSettings``).
    :param regress: IGRM statuses (:class:`s2cl.status.Status` values) whose index enters the regression.
    :param options: a family's own settings, as (key, value) pairs (formula: its ``expression``).
    :param pairs: slot pairs the design rule requires to differ (formula: the bands of each difference or ratio
        the expression takes).
    """

    kind: str
    parameter: str | None = None
    slots: tuple[int, ...] = (0, 1)
    angle_threshold_deg: float | None = None
    igrm: tuple[tuple[str, Any], ...] = field(default_factory=tuple)
    regress: tuple[int, ...] = (Status.OK, Status.STALLED, Status.ITERATION_LIMIT)
    options: tuple[tuple[str, Any], ...] = ()
    pairs: tuple[tuple[int, int], ...] = ()

    @property
    def family(self) -> Family:
        """The registered family of :attr:`kind` (:mod:`s2cl.retrieve.family`)."""
        return family_of(self.kind)

    @property
    def regression(self) -> bool:
        return self.family.metric.regressed

    @classmethod
    def from_spec(cls, a: Any, bands: list[str]) -> AnalysisSettings:
        """From the scene's [analysis] section ``a`` (None: refused); ``bands`` are the band slots in order. The checks
        every family shares are here; the family reads its own keys (:meth:`s2cl.retrieve.family.Family.settings`).
        Errors name the key ``analysis.*`` (the caller adds the scene's file: :func:`s2cl.errors.errors_in`)."""
        if a is None:
            raise InputError("the scene has no [analysis] section", key="analysis")
        family = family_of(a.kind)
        lower = [b.lower() for b in bands]

        def slot(name: str, key: str) -> int:
            if name.lower() not in lower:
                raise InputError(f"band {name!r} is not among the bands {', '.join(bands)}", key=f"analysis.{key}")
            return lower.index(name.lower())

        if family.metric.regressed and not a.parameter:
            raise InputError(f"{a.kind} needs the library parameter to regress (e.g. {family.example_parameter!r})",
                             key="analysis.parameter")
        own = family.roles(a)
        stray = [r for r in a.roles if r not in own]
        if stray:
            raise InputError(f"not a band role of {a.kind} " + (f"(its roles: {', '.join(own)})" if own else
                                                                 "(it has none), nor a key of [analysis]"),
                             key=f"analysis.{stray[0]}")
        foreign = sorted(k for k in family_keys() - set(family.keys) if k in a.model_fields_set)
        if foreign:
            owners = [f.kind for f in dict.fromkeys(registry().values()) if foreign[0] in f.keys]
            raise InputError(f"only kind = {' or '.join(map(repr, owners))} reads this key, not {a.kind}",
                             key=f"analysis.{foreign[0]}")
        return family.settings(a, bands, slot, None)


def _load() -> dict[str, Family]:
    from s2cl.retrieve import families

    found: dict[str, Family] = {}
    for info in sorted(pkgutil.iter_modules(families.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{families.__name__}.{info.name}")
        for family in getattr(module, "FAMILIES", ()) or ((module.FAMILY,) if hasattr(module, "FAMILY") else ()):
            for kind in family.kinds():
                if kind in found:
                    raise RuntimeError(f"analysis kind {kind!r} registered twice")
                found[kind] = family
    return found


@cache
def registry() -> dict[str, Family]:
    """Every registered family, by kind (an index family answers several kinds)."""
    return _load()


def family_of(kind: str, source: str | None = None) -> Family:
    """The family of ``[analysis] kind``; one-line :class:`InputError` listing the known kinds otherwise."""
    try:
        return registry()[kind]
    except KeyError:
        raise InputError(f"unknown analysis kind {kind!r}; known: {', '.join(registry())}", source=source,
                         key="analysis.kind") from None


def family_keys() -> set[str]:
    """Every family's own [analysis] keys."""
    return {k for family in registry().values() for k in family.keys}
