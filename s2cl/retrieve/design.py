"""Which band designs a retrieval can fit at all: one rule, used by every command and API.

``s2cl simulate`` (a fixed band set), ``s2cl optimise`` / ``sweep run`` (every configuration),
``s2cl sweep count`` and the direct APIs (:class:`s2cl.retrieve.igrm.IgrmFitter`) all call these functions, so
a sweep never ranks a design that the direct API refuses.

Each analysis family states its rule (:meth:`s2cl.retrieve.family.Family.problem`, in
:mod:`s2cl.retrieve.families`): IGRM needs four distinct centres, an index two different bands, SAM two distinct
bands, a formula the two bands of each difference or ratio it takes to differ.

Band order is not part of validity: the IGRM kernels sort a design's bands by centre.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from s2cl.errors import InputError
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.sensor.variants import SweepSpace

if TYPE_CHECKING:
    from s2cl.retrieve.analysis import AnalysisSettings

#: centres (and widths) closer than this (nm) count as one abscissa (one band)
SAME_CENTRE_NM = 1e-6


def same_band(c1: Any, w1: Any, c2: Any, w2: Any) -> Any:
    """Whether bands (centre, width in nm) are one band: centres and widths each within
    :data:`SAME_CENTRE_NM` (elementwise on arrays)."""
    return (np.abs(np.subtract(c1, c2)) <= SAME_CENTRE_NM) & (np.abs(np.subtract(w1, w2)) <= SAME_CENTRE_NM)


def design_problem(settings: AnalysisSettings | str, names: Sequence[str], centres: Sequence[float],
                   widths: Sequence[float]) -> str | None:
    """Why the analysis ``settings`` cannot fit the design ``names`` (centres and widths in nm), or None: its
    family's rule (:meth:`s2cl.retrieve.family.Family.problem`)."""
    settings = _settings(settings)
    return settings.family.problem(settings, names, np.asarray(centres, dtype=np.float64),
                                   np.asarray(widths, dtype=np.float64))


def check_design(settings: AnalysisSettings | str, names: Sequence[str], centres: Sequence[float],
                 widths: Sequence[float], *, source: str | None = None, key: str = "analysis.bands") -> None:
    """:class:`InputError` (one line, naming file and key) when :func:`design_problem` finds one."""
    problem = design_problem(settings, names, centres, widths)
    if problem:
        raise InputError(problem, source=source, key=key)


def underdetermined(settings: AnalysisSettings | str, centres: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """:func:`design_problem` for many configurations at once: ``centres``, ``widths`` ``(n_configs,
    n_slots)`` in nm; True where the design cannot be fitted."""
    settings = _settings(settings)
    return settings.family.underdetermined(settings, np.asarray(centres, dtype=np.float64),
                                           np.asarray(widths, dtype=np.float64))


#: a band with more variants than this is not listed to count the underdetermined configurations
MAX_LISTED_VARIANTS = 1_000_000


def count_underdetermined(settings: AnalysisSettings | str, space: SweepSpace, *,
                          limit: int = 10_000_000) -> int | None:
    """How many configurations of ``space`` cannot be fitted, without enumerating the configurations;
    None when a band has more than :data:`MAX_LISTED_VARIANTS` variants (its counts are computed, so
    nothing is listed) or the distinct values that decide it exceed ``limit``.

    Validity depends on centres only (and, for indices and SAM, widths of the bands involved), so it is
    evaluated once per combination of distinct values and weighted by how many variants share them.
    """
    if max(space.counts) > MAX_LISTED_VARIANTS:
        return None
    settings = _settings(settings)
    keys = [_value_counts(v, with_width=settings.family.width_matters) for v in space.per_band]
    combos = math.prod(len(k[0]) for k in keys)
    if combos > limit:
        return None
    total, block = 0, 1 << 16
    grids = [k[0] for k in keys]
    weights = [k[1] for k in keys]
    for start in range(0, combos, block):
        idx = np.unravel_index(np.arange(start, min(start + block, combos)), [len(g) for g in grids])
        values = np.stack([grids[k][i] for k, i in enumerate(idx)], axis=1)  # (n, n_slots, 2)
        bad = underdetermined(settings, values[..., 0], values[..., 1])
        mult = np.prod(np.stack([weights[k][i] for k, i in enumerate(idx)], axis=1), axis=1)
        total += int(mult[bad].sum())
    return total


def _value_counts(variants: np.ndarray, with_width: bool) -> tuple[np.ndarray, np.ndarray]:
    """Distinct (centre, width) pairs of a band's variants (width dropped when it does not matter)
    and how many variants each stands for."""
    v = np.asarray(variants, dtype=np.float64).reshape(-1, 2)
    key = v if with_width else np.stack([v[:, 0], np.zeros(len(v))], axis=1)
    uniq, counts = np.unique(key, axis=0, return_counts=True)
    return uniq, counts.astype(np.int64)


def _settings(settings: AnalysisSettings | str) -> AnalysisSettings:
    """``settings``, or a kind's default settings (an index on slots 0 and 1)."""
    if isinstance(settings, str):
        return AnalysisSettings(settings)
    return settings
