"""A sweep space as a lattice: each band's variants on the grid of its distinct centres × widths, designs as a
variant index per band, numbered as the exhaustive sweep numbers them; the coarse sub-grids and neighbourhoods a
search (:mod:`s2cl.sweep.search`) moves through."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from s2cl.sweep.engine import SweepJob

#: the joint neighbourhood (3 ** (2 · bands) designs) above this many designs moves centres and widths apart
MAX_JOINT = 60_000


@dataclass(frozen=True)
class SlotLattice:
    """One band slot's variants on the grid of its distinct centres × widths (``lookup[i, j]``: the variant at
    centre ``i`` and width ``j``, -1 where the range holds none)."""

    ci: np.ndarray
    wi: np.ndarray
    lookup: np.ndarray

    @classmethod
    def of(cls, centre: np.ndarray, width: np.ndarray) -> SlotLattice:
        cs, ci = np.unique(np.round(centre, 6), return_inverse=True)
        ws, wi = np.unique(np.round(width, 6), return_inverse=True)
        lookup = np.full((cs.size, ws.size), -1, dtype=np.int64)
        lookup[ci, wi] = np.arange(centre.size)
        return cls(ci.astype(np.int64), wi.astype(np.int64), lookup)

    def moved(self, variant: np.ndarray, dc: np.ndarray, dw: np.ndarray) -> np.ndarray:
        """Variant of ``variant`` moved by ``dc`` centre and ``dw`` width steps (-1 outside the range)."""
        i, j = self.ci[variant] + dc, self.wi[variant] + dw
        ok = (i >= 0) & (i < self.lookup.shape[0]) & (j >= 0) & (j < self.lookup.shape[1])
        out = np.full(np.broadcast(i, j).shape, -1, dtype=np.int64)
        out[ok] = self.lookup[i[ok], j[ok]]
        return out

    def coarse(self, stride: int, offset: tuple[int, int]) -> np.ndarray:
        """Variants on every ``stride``-th centre and width from ``offset``."""
        sub = self.lookup[offset[0]::stride, offset[1]::stride]
        return sub[sub >= 0]


class Lattice:
    """The space's designs as variant indices per slot, numbered as the exhaustive sweep numbers them."""

    def __init__(self, job: SweepJob):
        t = job.tables
        self.slots = [SlotLattice.of(c, w) for c, w in zip(t.centre, t.width, strict=True)]
        self.counts = np.array(t.counts, dtype=np.int64)
        self.strides = np.array([int(np.prod(t.counts[k + 1:])) for k in range(t.n_slots)], dtype=np.int64)

    def configs(self, designs: np.ndarray) -> np.ndarray:
        return designs @ self.strides

    def coarse(self, start: int, rng: np.random.Generator) -> tuple[np.ndarray, int]:
        """The sub-grid of every ``s``-th centre and width of every band (``s`` the smallest that keeps at most
        ``start`` designs; offsets drawn from ``rng``), and ``s``."""
        grid, s, _ = self.coarse_offsets(start, rng)
        return grid, s

    def coarse_offsets(self, start: int, rng: np.random.Generator) -> tuple[np.ndarray, int, list[tuple[int, int]]]:
        """:meth:`coarse`, with the sub-grid's (centre, width) offset of each band."""
        s = 1
        while True:
            offsets = [(int(rng.integers(min(s, sl.lookup.shape[0]))), int(rng.integers(min(s, sl.lookup.shape[1]))))
                       for sl in self.slots] if s > 1 else [(0, 0)] * len(self.slots)
            size = math.prod(sl.coarse(s, o).size for sl, o in zip(self.slots, offsets, strict=True))
            if size <= start or all(sl.lookup.size <= 1 for sl in self.slots):
                return self.sub_grid(s, offsets), s, offsets
            s += 1

    def sub_grid(self, stride: int, offsets: list[tuple[int, int]]) -> np.ndarray:
        """Every design on every ``stride``-th centre and width of each band from its (centre, width) offset."""
        per = [sl.coarse(stride, o) for sl, o in zip(self.slots, offsets, strict=True)]
        if math.prod(p.size for p in per) == 0:
            return np.zeros((0, len(self.slots)), dtype=np.int64)
        return np.array(list(itertools.product(*per)), dtype=np.int64).reshape(-1, len(self.slots))

    def shifted(self, offsets: list[tuple[int, int]], stride: int, shift: int) -> list[tuple[int, int]]:
        """``offsets`` moved by ``shift`` steps in every centre and width, modulo the stride (or the band's size)."""
        return [((c + shift) % min(stride, sl.lookup.shape[0]), (w + shift) % min(stride, sl.lookup.shape[1]))
                for sl, (c, w) in zip(self.slots, offsets, strict=True)]

    def crossed(self, designs: np.ndarray) -> np.ndarray:
        """Every design that takes each band's variant from one of ``designs`` (band by band: the product of each
        band's distinct variants among them)."""
        per = [np.unique(designs[:, k]) for k in range(designs.shape[1])]
        return np.array(list(itertools.product(*per)), dtype=np.int64).reshape(-1, designs.shape[1])

    def joint(self, design: np.ndarray, step: int, what: str = "both") -> np.ndarray:
        """Every band moved by -step, 0 or +step at once (inside the space): centre and width (``"both"``,
        3 ** (2 · bands) moves), or only the centres or only the widths (``"centres"``, ``"widths"``: 3 ** bands)."""
        n = len(self.slots)
        moves = np.array(list(itertools.product((-step, 0, step), repeat=n if what != "both" else 2 * n)),
                         dtype=np.int64)
        zero = np.zeros((len(moves), n), dtype=np.int64)
        dc, dw = {"both": (moves[:, 0::2], moves[:, 1::2]), "centres": (moves, zero), "widths": (zero, moves)}[what]
        out = np.stack([sl.moved(np.full(len(moves), design[k]), dc[:, k], dw[:, k])
                        for k, sl in enumerate(self.slots)], axis=1)
        return out[(out >= 0).all(axis=1)]

    def joint_moves(self, design: np.ndarray, step: int) -> np.ndarray:
        """All bands moved together by ± ``step``: centres and widths at once when that is at most
        :data:`MAX_JOINT` designs, else the centres together, the widths together (2 · 3 ** bands) and every two
        bands in centre and width at once (:meth:`pairs`)."""
        if 3 ** (2 * len(self.slots)) <= MAX_JOINT:
            return self.joint(design, step)
        return np.concatenate([self.joint(design, step, "centres"), self.joint(design, step, "widths"),
                               self.pairs(design, step)])

    def pairs(self, design: np.ndarray, step: int) -> np.ndarray:
        """Every two bands moved together by -step, 0 or +step in centre and width (3⁴ moves per pair)."""
        moves = np.array(list(itertools.product((-step, 0, step), repeat=4)), dtype=np.int64)
        out = []
        for k, m in itertools.combinations(range(len(self.slots)), 2):
            d = np.repeat(design[None, :], len(moves), axis=0)
            d[:, k] = self.slots[k].moved(d[:, k], moves[:, 0], moves[:, 1])
            d[:, m] = self.slots[m].moved(d[:, m], moves[:, 2], moves[:, 3])
            out.append(d[(d >= 0).all(axis=1)])
        return np.concatenate(out)

    def band_box(self, design: np.ndarray, k: int, radius: int) -> np.ndarray:
        """Band ``k`` over ± ``radius`` steps of centre and width, the others as in ``design``."""
        d = np.arange(-radius, radius + 1)
        dc, dw = (a.ravel() for a in np.meshgrid(d, d, indexing="ij"))
        v = self.slots[k].moved(np.full(dc.size, design[k]), dc, dw)
        out = np.repeat(design[None, :], int((v >= 0).sum()), axis=0)
        out[:, k] = v[v >= 0]
        return out

    def lines(self, design: np.ndarray) -> np.ndarray:
        """Each band alone over every variant of its range, the others as in ``design``."""
        out = []
        for k, sl in enumerate(self.slots):
            d = np.repeat(design[None, :], sl.ci.size, axis=0)
            d[:, k] = np.arange(sl.ci.size)
            out.append(d)
        return np.concatenate(out)

    def neighbourhood(self, design: np.ndarray, radius: int) -> np.ndarray:
        """The local check's designs: each band alone over ± ``radius``, all bands together over ± 1
        (:meth:`joint_moves`)."""
        parts = [self.band_box(design, k, radius) for k in range(len(self.slots))]
        return np.concatenate([*parts, self.joint_moves(design, 1)])


def unique_designs(designs: np.ndarray, lattice: Lattice) -> np.ndarray:
    """``designs`` without repeats, in configuration order."""
    _, first = np.unique(lattice.configs(designs), return_index=True)
    return designs[np.sort(first)]
