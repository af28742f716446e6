"""Which band designs a retrieval can fit at all: one rule, used by every command and API.

``s2cl simulate`` (a fixed band set), ``s2cl optimise`` / ``sweep run`` (every configuration),
``s2cl sweep count`` and the direct APIs (:class:`s2cl.retrieve.igrm.IgrmFitter`) all call these functions, so
a sweep never ranks a design that the direct API refuses.

- **IGRM** fits four parameters (rmax, rmin, l0, s) with the band centres as abscissae: it needs at
  least four *distinct* centres. Two bands on one centre (different widths or not) give one
  abscissa, and the fit has no unique solution (the minimum cost is reached along a whole curve
  of parameters: scipy finds lp anywhere in a 2 nm range from different starts).
- **A normalised-difference index** (GVMI, ...: :mod:`s2cl.retrieve.indices`) needs its two bands to
  differ (one band in both roles gives a constant index).
- **SAM** needs at least two distinct bands (with one direction every pixel has the same angle
  to every class).
- **A formula** (:mod:`s2cl.retrieve.formula`) needs the two bands of each difference (``B6 - B5``) or ratio
  (``B7 / B5``) it takes to differ: one band in both places makes the difference vanish (S2REP's denominator) or
  the ratio 1 (CIred-edge).

Band order is not part of validity: the IGRM kernels sort a design's bands by centre.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from s2cl.errors import InputError
from s2cl.retrieve.indices import INDICES
from s2cl.sensor.variants import SweepSpace

IGRM_PARAMETERS = 4
#: centres (and widths) closer than this (nm) count as one abscissa (one band)
SAME_CENTRE_NM = 1e-6


def same_band(c1: Any, w1: Any, c2: Any, w2: Any) -> Any:
    """Whether bands (centre, width in nm) are one band: centres and widths each within
    :data:`SAME_CENTRE_NM` (elementwise on arrays)."""
    return (np.abs(np.subtract(c1, c2)) <= SAME_CENTRE_NM) & (np.abs(np.subtract(w1, w2)) <= SAME_CENTRE_NM)


def design_problem(kind: str, names: Sequence[str], centres: Sequence[float], widths: Sequence[float], *,
                   slots: tuple[int, ...] = (0, 1), pairs: tuple[tuple[int, int], ...] = ()) -> str | None:
    """Why the retrieval ``kind`` cannot fit the design ``names`` (centres and widths in nm), or None. ``pairs``:
    a formula's slot pairs that must differ (:meth:`s2cl.retrieve.analysis.AnalysisSettings.pairs`)."""
    c = np.asarray(centres, dtype=np.float64)
    w = np.asarray(widths, dtype=np.float64)
    if kind == "igrm":
        distinct = _distinct(c)
        if distinct < IGRM_PARAMETERS:
            shared = _coincident(names, c)
            return (f"underdetermined: the IGRM fits {IGRM_PARAMETERS} parameters but the bands give only "
                    f"{distinct} distinct centres ({shared}); move the bands apart")
        return None
    if kind in INDICES:
        a, b = slots
        if same_band(c[a], w[a], c[b], w[b]):
            role_a, role_b = INDICES[kind].roles
            return (f"underdetermined: the {kind.upper()}'s {role_a} band {names[a]} and {role_b} band {names[b]} "
                    f"are the same band ({c[a]:g}/{w[a]:g} nm)")
        return None
    if kind == "sam":
        if bool(np.all(same_band(c, w, c[0], w[0]))):
            return "underdetermined: SAM needs at least two distinct bands; every band here is the same"
        return None
    if kind == "formula":
        for x, y in pairs:
            if same_band(c[x], w[x], c[y], w[y]):
                return (f"underdetermined: the formula compares {names[x]} with {names[y]} (a difference or a ratio, "
                        f"0 or 1 for one band), and they are the same band ({c[x]:g}/{w[x]:g} nm)")
        return None
    raise InputError(f"unknown analysis kind {kind!r}", key="analysis.kind")


def check_design(kind: str, names: Sequence[str], centres: Sequence[float], widths: Sequence[float], *,
                 source: str | None = None, key: str = "analysis.bands", slots: tuple[int, ...] = (0, 1),
                 pairs: tuple[tuple[int, int], ...] = ()) -> None:
    """:class:`InputError` (one line, naming file and key) when :func:`design_problem` finds one."""
    problem = design_problem(kind, names, centres, widths, slots=slots, pairs=pairs)
    if problem:
        raise InputError(problem, source=source, key=key)


def underdetermined(kind: str, centres: np.ndarray, widths: np.ndarray, *,
                    slots: tuple[int, ...] = (0, 1), pairs: tuple[tuple[int, int], ...] = ()) -> np.ndarray:
    """:func:`design_problem` for many configurations at once: ``centres``, ``widths`` ``(n_configs,
    n_slots)`` in nm; True where the design cannot be fitted."""
    c = np.asarray(centres, dtype=np.float64)
    w = np.asarray(widths, dtype=np.float64)
    if kind == "igrm":
        s = np.sort(c, axis=1)
        distinct = 1 + np.count_nonzero(np.diff(s, axis=1) > SAME_CENTRE_NM, axis=1)
        return distinct < IGRM_PARAMETERS
    if kind in INDICES:
        a, b = slots
        return same_band(c[:, a], w[:, a], c[:, b], w[:, b])
    if kind == "sam":
        same = same_band(c, w, c[:, :1], w[:, :1])
        return same.all(axis=1)
    if kind == "formula":
        bad = np.zeros(c.shape[0], dtype=bool)
        for x, y in pairs:
            bad |= same_band(c[:, x], w[:, x], c[:, y], w[:, y])
        return bad
    raise InputError(f"unknown analysis kind {kind!r}", key="analysis.kind")


#: a band with more variants than this is not listed to count the underdetermined configurations
MAX_LISTED_VARIANTS = 1_000_000


def count_underdetermined(kind: str, space: SweepSpace, *, slots: tuple[int, ...] = (0, 1),
                          pairs: tuple[tuple[int, int], ...] = (), limit: int = 10_000_000) -> int | None:
    """How many configurations of ``space`` cannot be fitted, without enumerating the configurations;
    None when a band has more than :data:`MAX_LISTED_VARIANTS` variants (its counts are computed, so
    nothing is listed) or the distinct values that decide it exceed ``limit``.

    Validity depends on centres only (and, for indices and SAM, widths of the bands involved), so it is
    evaluated once per combination of distinct values and weighted by how many variants share them.
    """
    if max(space.counts) > MAX_LISTED_VARIANTS:
        return None
    keys = [_value_counts(v, with_width=kind != "igrm") for v in space.per_band]
    combos = math.prod(len(k[0]) for k in keys)
    if combos > limit:
        return None
    total, block = 0, 1 << 16
    grids = [k[0] for k in keys]
    weights = [k[1] for k in keys]
    for start in range(0, combos, block):
        idx = np.unravel_index(np.arange(start, min(start + block, combos)), [len(g) for g in grids])
        values = np.stack([grids[k][i] for k, i in enumerate(idx)], axis=1)  # (n, n_slots, 2)
        bad = underdetermined(kind, values[..., 0], values[..., 1], slots=slots, pairs=pairs)
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


def _distinct(c: np.ndarray) -> int:
    s = np.sort(c)
    return int(1 + np.count_nonzero(np.diff(s) > SAME_CENTRE_NM)) if s.size else 0


def _coincident(names: Sequence[str], c: np.ndarray) -> str:
    """"B5 and B6 at 730 nm"-style text for the bands that share a centre."""
    groups: dict[float, list[str]] = {}
    for name, centre in zip(names, c, strict=True):
        groups.setdefault(round(float(centre), 6), []).append(name)
    shared = [f"{' and '.join(g)} at {k:g} nm" for k, g in groups.items() if len(g) > 1]
    return "; ".join(shared) if shared else f"{len(c)} bands"
