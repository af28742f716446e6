"""The analysis that scores a band design: IGRM red-edge index, a normalised-difference index (GVMI, ...:
:mod:`s2cl.retrieve.indices`), or SAM classes.

Per-pixel statuses are the shared codes of :mod:`s2cl.status` (``kernels/common/s2_status.clh``);
which designs can be analysed at all is :mod:`s2cl.retrieve.design`'s rule.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from s2cl.errors import InputError, token
from s2cl.libraries.library import SpectralLibrary
from s2cl.retrieve.indices import INDICES
from s2cl.status import REGRESS_NAMES, Status

if TYPE_CHECKING:
    from s2cl.retrieve.formula import Formula


@dataclass(frozen=True)
class AnalysisSettings:
    """What to compute from the band reflectances of each pixel.

    :param kind: ``"igrm"`` (index: inflection wavelength λp in nm), a key of
        :data:`s2cl.retrieve.indices.INDICES` (index: e.g. GVMI) or ``"sam"`` (class of each pixel).
    :param parameter: library parameter regressed on the index (``cab``, ``ewt``); igrm and indices.
    :param slots: indices: band slots of band a and band b (GVMI: NIR, SWIR); formula: the slot of each band the
        expression names, in the order it names them.
    :param angle_threshold_deg: sam: pixels whose smallest angle exceeds it are unclassified.
    :param igrm: IGRM fit settings (keys of ``s2cl.retrieve.igrm.IgrmSettings``).
    :param regress: IGRM statuses (:class:`s2cl.status.Status` values) whose index enters the regression.
    :param expression: formula: the expression (:class:`s2cl.retrieve.formula.Formula`).
    :param pairs: formula: slot pairs the design rule requires to differ, the bands of each difference or ratio
        the expression takes (:func:`s2cl.retrieve.design.design_problem`).
    """

    kind: str
    parameter: str | None = None
    slots: tuple[int, ...] = (0, 1)
    angle_threshold_deg: float | None = None
    igrm: tuple[tuple[str, Any], ...] = field(default_factory=tuple)
    regress: tuple[int, ...] = (Status.OK, Status.STALLED, Status.ITERATION_LIMIT)
    expression: str | None = None
    pairs: tuple[tuple[int, int], ...] = ()

    @property
    def regression(self) -> bool:
        return self.kind in ("igrm", "formula") or self.kind in INDICES

    def formula(self, bands: Sequence[str]) -> Formula:
        """The formula of a ``formula`` analysis whose slots hold ``bands``."""
        from s2cl.retrieve.formula import Formula

        assert self.expression is not None
        return Formula.parse(self.expression, bands)

    @classmethod
    def from_scene(cls, scene: Any, bands: list[str]) -> AnalysisSettings:
        """From the scene's [analysis] section; ``bands`` are the band slots in order."""
        a = scene.spec.analysis
        if a is None:
            raise InputError("the scene has no [analysis] section", source=scene.source, key="analysis")
        lower = [b.lower() for b in bands]

        def slot(name: str, key: str) -> int:
            if name.lower() not in lower:
                raise InputError(f"band {name!r} is not among the bands {', '.join(bands)}", source=scene.source,
                                 key=f"analysis.{key}")
            return lower.index(name.lower())

        if (a.kind in ("igrm", "formula") or a.kind in INDICES) and not a.parameter:
            example = INDICES[a.kind].parameter if a.kind in INDICES else "cab"
            raise InputError(f"{a.kind} needs the library parameter to regress (e.g. {example!r})",
                             source=scene.source, key="analysis.parameter")
        if a.kind == "igrm" and len(bands) < 4:
            raise InputError(f"IGRM needs at least 4 bands, got {len(bands)}", source=scene.source, key="analysis")
        own = INDICES[a.kind].roles if a.kind in INDICES else ()
        stray = [r for r in a.roles if r not in own]
        if stray:
            raise InputError(f"not a band role of {a.kind}" + (f" (its roles: {', '.join(own)})" if own else ""),
                             source=scene.source, key=f"analysis.{stray[0]}")
        if (a.kind == "formula") != (a.expression is not None):
            raise InputError("an expression is the formula kind's, and it needs one" if a.kind == "formula" else
                             f"only kind = 'formula' takes an expression, not {a.kind}", source=scene.source,
                             key="analysis.expression")
        if a.kind == "formula":
            from s2cl.retrieve.formula import Formula

            try:
                formula = Formula.parse(a.expression, bands)
            except InputError as err:
                raise InputError(err.detail, source=scene.source, key="analysis.expression") from None
            slots = {b: slot(b, "expression") for b in formula.bands}
            return cls("formula", a.parameter, slots=tuple(slots.values()), expression=a.expression,
                       pairs=tuple(dict.fromkeys((slots[x], slots[y]) for x, y in
                                                 formula.subtracted_pairs() + formula.divided_pairs())))
        if a.kind in INDICES:
            return cls(a.kind, a.parameter, slots=index_slots(a.kind, a.roles, slot))
        if a.kind == "sam":
            return cls("sam", angle_threshold_deg=a.angle_threshold_deg)
        regress = tuple(sorted(int(REGRESS_NAMES[name]) for name in set(a.regress)))
        return cls("igrm", a.parameter, igrm=tuple(sorted(a.igrm.items())), regress=regress)


def index_bands(kind: str, roles: dict[str, str]) -> list[str]:
    """The bands of index ``kind`` (band a, band b): the scene's role keys, else the registry's defaults."""
    nd = INDICES[kind]
    return [roles.get(role, default) for role, default in zip(nd.roles, nd.default_bands, strict=True)]


def index_slots(kind: str, roles: dict[str, str], slot: Any) -> tuple[int, int]:
    """Slots of index ``kind``'s two bands; ``slot(band name, role)`` finds one among the analysed bands."""
    a, b = (slot(name, role) for name, role in zip(index_bands(kind, roles), INDICES[kind].roles, strict=True))
    return a, b


def analysis_targets(scene: Any, lib: SpectralLibrary, analysis: AnalysisSettings
                     ) -> tuple[SpectralLibrary, np.ndarray, tuple[str, ...]]:
    """The library (restricted to the SAM classes), the per-spectrum target and the class names."""
    if analysis.kind == "sam":
        wanted = scene.spec.analysis.classes or sorted(set(lib.groups))
        twice = sorted({c for c in wanted if wanted.count(c) > 1})
        if twice:
            raise InputError(f"lists class(es) {', '.join(map(token, twice))} more than once; SAM needs at least two "
                             "different classes", source=scene.source, key="analysis.classes")
        missing = [c for c in wanted if c not in lib.groups]
        if missing:
            raise InputError(f"no spectra of class(es) {', '.join(map(token, missing))}; library groups: "
                             f"{', '.join(sorted(set(lib.groups)))}", source=scene.source, key="analysis.classes")
        if len(wanted) < 2:
            raise InputError("SAM needs at least two classes", source=scene.source, key="analysis.classes")
        keep = [i for i, g in enumerate(lib.groups) if g in wanted]
        lib = lib.subset(keep)
        return lib, np.array([wanted.index(g) for g in lib.groups], dtype=np.float64), tuple(wanted)
    param = analysis.parameter
    if param not in lib.params:
        raise InputError(f"library has no parameter {token(param)}; it has {', '.join(sorted(lib.params)) or 'none'}",
                         source=scene.source, key="analysis.parameter")
    return lib, np.asarray(lib.params[param], dtype=np.float64), ()
