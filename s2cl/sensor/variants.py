"""The sensor-definition tool: band variants from ranges, and configurations as their product.

A band may move inside a window ``[left, right]`` (nm): its edges ``λc ± Δλ/2`` stay inside, its
width ``Δλ`` runs from ``min_width`` to ``max_width`` and centre and width lie on a ``step`` grid
(5 nm by default, as in Segl et al. 2012, Table 2). One more variant is admitted when a width
equals the window (``Δλ = right − left``): the band that fills its window, centred on it even
when that centre is off the grid (the paper's B8: 775–890 nm, 115 nm wide, centre 832.5 nm). A
band may also be fixed. Configurations are all combinations of one variant per band, numbered
in mixed radix with the last band fastest.

Counts for the paper's red-edge sets: 43,056 (B4 B5 B6 B7), 3,312 (B4 B5 B6 B8),
82,800 (B4 B5 B6 B8a).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from s2cl.errors import InputError

EPS = 1e-9
#: most widths, and centres per width, one band may take (a finer step is refused before anything is counted)
MAX_WIDTHS = 1_000_000
MAX_CENTRES = 1_000_000_000


@dataclass(frozen=True)
class BandRange:
    """Where one band may go (nm). ``fixed`` bands have ``left = right = centre`` semantics via
    :meth:`fixed`."""

    band: str
    left_nm: float
    right_nm: float
    min_width_nm: float
    max_width_nm: float
    step_nm: float = 5.0

    @classmethod
    def fixed(cls, band: str, centre_nm: float, width_nm: float) -> BandRange:
        """A band that does not move: one variant (centre, width)."""
        return cls(band, centre_nm - width_nm / 2, centre_nm + width_nm / 2, width_nm, width_nm, step_nm=0.0)

    def validate(self, source: str | None = None) -> None:
        key = f"sweep.ranges.{self.band}"
        values = (self.left_nm, self.right_nm, self.min_width_nm, self.max_width_nm, self.step_nm)
        if not all(math.isfinite(v) for v in values):
            raise InputError("all range values must be finite", source=source, key=key)
        if self.min_width_nm <= 0:
            raise InputError(f"min_width must be > 0 nm, got {self.min_width_nm}", source=source, key=key)
        if self.max_width_nm < self.min_width_nm:
            raise InputError(f"max_width ({self.max_width_nm}) < min_width ({self.min_width_nm})", source=source,
                             key=key)
        if self.right_nm <= self.left_nm:
            raise InputError(f"right ({self.right_nm}) must be > left ({self.left_nm})", source=source, key=key)
        if self.step_nm < 0:
            raise InputError(f"step must be >= 0 nm, got {self.step_nm}", source=source, key=key)
        if not self.is_fixed:
            widths = (self.max_width_nm - self.min_width_nm) / self.step_nm + 1
            centres = (self.right_nm - self.left_nm) / self.step_nm + 1
            if widths > MAX_WIDTHS or centres > MAX_CENTRES:
                raise InputError(f"a {self.step_nm:g} nm step gives {widths:,.0f} widths and {centres:,.0f} centres "
                                 f"for band {self.band} (at most {MAX_WIDTHS:,} and {MAX_CENTRES:,})",
                                 source=source, key="sweep.step_nm")
        if not self.count():
            raise InputError(
                f"admits no variant: no width in {self.min_width_nm:g}–{self.max_width_nm:g} nm on the "
                f"{self.step_nm:g} nm grid fits inside {self.left_nm:g}–{self.right_nm:g} nm",
                source=source, key=key,
            )

    @property
    def is_fixed(self) -> bool:
        return self.step_nm == 0.0

    def widths(self) -> np.ndarray:
        if self.is_fixed:
            return np.array([self.min_width_nm])
        n = math.floor((self.max_width_nm - self.min_width_nm) / self.step_nm + EPS)
        return self.min_width_nm + self.step_nm * np.arange(n + 1)

    def _centre_ranges(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per width: (width, first and last centre index k on the step grid, whether the width fills the
        window with no grid centre), computed as :meth:`variants` does, without enumerating centres."""
        w = self.widths()
        lo, hi = self.left_nm + w / 2, self.right_nm - w / 2
        k0, k1 = np.ceil(lo / self.step_nm - EPS), np.floor(hi / self.step_nm + EPS)
        fills = (np.abs(w - (self.right_nm - self.left_nm)) < EPS) & (k1 < k0)
        return w, k0, k1, fills

    def count(self) -> int:
        """Number of variants (what ``len(variants())`` would be), computed, not enumerated."""
        if self.is_fixed:
            return 1
        _, k0, k1, fills = self._centre_ranges()
        return int(np.maximum(k1 - k0 + 1, 0).sum() + fills.sum())

    def extent(self) -> tuple[float, float, float, float]:
        """(smallest centre, largest centre, smallest width, largest width) of the variants, nm."""
        if self.is_fixed:
            c = (self.left_nm + self.right_nm) / 2
            return c, c, self.min_width_nm, self.min_width_nm
        w, k0, k1, fills = self._centre_ranges()
        some = k1 >= k0
        fill_c = (self.left_nm + self.right_nm) / 2
        centres = [*(k0[some] * self.step_nm), *(k1[some] * self.step_nm), *([fill_c] if fills.any() else [])]
        widths = w[some | fills]
        return float(min(centres)), float(max(centres)), float(widths.min()), float(widths.max())

    def support_extent(self, support: float) -> tuple[float, float]:
        """(lowest, highest) wavelength, nm, that the model SRF of any variant reaches: centre ± support × width."""
        if self.is_fixed:
            c = (self.left_nm + self.right_nm) / 2
            return c - support * self.min_width_nm, c + support * self.min_width_nm
        w, k0, k1, fills = self._centre_ranges()
        some = k1 >= k0
        fill_c = (self.left_nm + self.right_nm) / 2
        lows = [*(k0[some] * self.step_nm - support * w[some]), *(fill_c - support * w[fills])]
        highs = [*(k1[some] * self.step_nm + support * w[some]), *(fill_c + support * w[fills])]
        return float(min(lows)), float(max(highs))

    def variants(self) -> np.ndarray:
        """All (centre, width) pairs, float64 ``(n, 2)``, sorted by width then centre."""
        if self.is_fixed:
            return np.array([[(self.left_nm + self.right_nm) / 2, self.min_width_nm]])
        out: list[tuple[float, float]] = []
        for w in self.widths():
            lo, hi = self.left_nm + w / 2, self.right_nm - w / 2
            k0, k1 = math.ceil(lo / self.step_nm - EPS), math.floor(hi / self.step_nm + EPS)
            centres = [k * self.step_nm for k in range(k0, k1 + 1)]
            fills = abs(w - (self.right_nm - self.left_nm)) < EPS
            if fills and not centres:
                centres = [(self.left_nm + self.right_nm) / 2]
            out += [(c, float(w)) for c in centres]
        return np.array(out, dtype=np.float64).reshape(-1, 2)


@dataclass(frozen=True)
class BandGrid:
    """A band whose variants are every (centre, width) of two lists (nm), as in the paper's
    Tables 4–6 (e.g. B4 centres 660–705 × widths 15–50)."""

    band: str
    centres: tuple[float, ...]
    widths: tuple[float, ...]

    def validate(self, source: str | None = None) -> None:
        key = f"sweep.ranges.{self.band}"
        values = self.centres + self.widths
        if not self.centres or not self.widths:
            raise InputError("needs at least one centre and one width", source=source, key=key)
        if not all(math.isfinite(v) for v in values):
            raise InputError("centres and widths must be finite", source=source, key=key)
        if min(self.widths) <= 0:
            raise InputError(f"widths must be > 0 nm, got {min(self.widths)}", source=source, key=key)
        for name, seq in (("centres", self.centres), ("widths", self.widths)):
            if len(set(seq)) != len(seq):
                raise InputError(f"{name} hold duplicates", source=source, key=key)

    @property
    def is_fixed(self) -> bool:
        return len(self.centres) == len(self.widths) == 1

    def count(self) -> int:
        return len(self.centres) * len(self.widths)

    def extent(self) -> tuple[float, float, float, float]:
        """(smallest centre, largest centre, smallest width, largest width), nm."""
        return min(self.centres), max(self.centres), min(self.widths), max(self.widths)

    def support_extent(self, support: float) -> tuple[float, float]:
        """(lowest, highest) wavelength, nm, that the model SRF of any variant reaches: centre ± support × width."""
        return min(self.centres) - support * max(self.widths), max(self.centres) + support * max(self.widths)

    def variants(self) -> np.ndarray:
        """All (centre, width) pairs, ``(n, 2)``, widths outer, centres inner."""
        return np.array([(c, w) for w in self.widths for c in self.centres], dtype=np.float64).reshape(-1, 2)


@dataclass(frozen=True)
class BandList:
    """A band whose variants are an explicit list of distinct (centre, width) pairs (nm), in that order: e.g.
    the nominal band, then its shifted and its widened copies (``s2cl study stability``)."""

    band: str
    shapes: tuple[tuple[float, float], ...]

    def validate(self, source: str | None = None) -> None:
        key = f"sweep.ranges.{self.band}"
        if not self.shapes:
            raise InputError("needs at least one (centre, width)", source=source, key=key)
        if not all(math.isfinite(v) for s in self.shapes for v in s):
            raise InputError("centres and widths must be finite", source=source, key=key)
        if min(w for _, w in self.shapes) <= 0:
            raise InputError(f"widths must be > 0 nm, got {min(w for _, w in self.shapes)}", source=source, key=key)
        if len(set(self.shapes)) != len(self.shapes):
            raise InputError("the (centre, width) pairs hold duplicates", source=source, key=key)

    @property
    def is_fixed(self) -> bool:
        return len(self.shapes) == 1

    def count(self) -> int:
        return len(self.shapes)

    def extent(self) -> tuple[float, float, float, float]:
        """(smallest centre, largest centre, smallest width, largest width), nm."""
        c, w = zip(*self.shapes, strict=True)
        return min(c), max(c), min(w), max(w)

    def support_extent(self, support: float) -> tuple[float, float]:
        """(lowest, highest) wavelength, nm, that the model SRF of any variant reaches: centre ± support × width."""
        return (min(c - support * w for c, w in self.shapes), max(c + support * w for c, w in self.shapes))

    def variants(self) -> np.ndarray:
        """The (centre, width) pairs as given, ``(n, 2)``."""
        return np.array(self.shapes, dtype=np.float64).reshape(-1, 2)


#: configurations a space may hold: each is numbered by a signed 64-bit integer (results.parquet's ``config``)
MAX_CONFIGS = 2**63 - 1


@dataclass(frozen=True)
class SweepSpace:
    """The product of the band ranges: ``size`` configurations of one variant per band."""

    ranges: tuple[BandRange | BandGrid | BandList, ...]

    def validate(self, source: str | None = None) -> SweepSpace:
        if not self.ranges:
            raise InputError("a sweep needs at least one band", source=source, key="sweep.bands")
        names = [r.band for r in self.ranges]
        if len(set(names)) != len(names):
            raise InputError(f"a band appears twice: {names}", source=source, key="sweep.bands")
        for r in self.ranges:
            r.validate(source)
        return self

    def check_numbered(self, source: str | None = None) -> None:
        """Refuse (one line) a space whose configurations cannot be numbered by a signed 64-bit integer: it can be
        counted (``s2cl sweep count``), not run or searched."""
        if self.size > MAX_CONFIGS:
            raise InputError(f"{self.size:,} configurations: configuration numbers are 64-bit, at most "
                             f"{MAX_CONFIGS:,}; narrow the bands' ranges or take a coarser sweep.step_nm",
                             source=source, key="sweep.ranges")

    @property
    def bands(self) -> list[str]:
        return [r.band for r in self.ranges]

    @cached_property
    def per_band(self) -> tuple[np.ndarray, ...]:
        """Variants of each band, ``(n_k, 2)`` arrays of (centre, width) in nm."""
        return tuple(r.variants() for r in self.ranges)

    @property
    def counts(self) -> list[int]:
        """Variants per band, computed without enumerating them."""
        return [r.count() for r in self.ranges]

    @property
    def size(self) -> int:
        return math.prod(self.counts)

    def indices(self, start: int, stop: int) -> np.ndarray:
        """Variant index of each band for configurations ``start … stop-1``: ``(n, n_bands)`` int32."""
        if not 0 <= start <= stop <= self.size:
            raise InputError(f"configurations {start}–{stop} outside 0–{self.size}")
        flat = np.arange(start, stop, dtype=np.int64)
        out = np.empty((flat.size, len(self.ranges)), dtype=np.int32)
        for k in range(len(self.ranges) - 1, -1, -1):
            flat, out[:, k] = np.divmod(flat, self.counts[k])
        return out

    def index_of(self, variant_indices: list[int]) -> int:
        """The configuration number of one variant index per band."""
        index = 0
        for k, v in enumerate(variant_indices):
            if not 0 <= v < self.counts[k]:
                raise InputError(f"variant {v} of band {self.ranges[k].band} outside 0–{self.counts[k] - 1}")
            index = index * self.counts[k] + v
        return index

    def find(self, shapes: list[tuple[float, float]]) -> int | None:
        """Configuration whose bands have these (centre, width) pairs, or None."""
        idx = []
        for variants, (c, w) in zip(self.per_band, shapes, strict=True):
            hit = np.flatnonzero((np.abs(variants[:, 0] - c) < 1e-6) & (np.abs(variants[:, 1] - w) < 1e-6))
            if not hit.size:
                return None
            idx.append(int(hit[0]))
        return self.index_of(idx)

    def shapes(self, start: int, stop: int) -> np.ndarray:
        """(centre, width) of every band for configurations ``start … stop-1``: ``(n, n_bands, 2)``."""
        idx = self.indices(start, stop)
        return np.stack([self.per_band[k][idx[:, k]] for k in range(len(self.ranges))], axis=1)


# The paper's Table 2 (nm): band -> (left, right, min width, max width)
TABLE2 = {
    "B4": (630, 690, 30, 50),
    "B5": (700, 740, 15, 40),
    "B6": (720, 750, 15, 30),
    "B7": (770, 810, 20, 40),
    "B8": (775, 890, 115, 115),
    "B8a": (840, 890, 20, 50),
}


def table2_space(bands: list[str], step_nm: float = 5.0) -> SweepSpace:
    """A sweep over the paper's Table 2 ranges for ``bands``."""
    return SweepSpace(tuple(BandRange(b, *map(float, TABLE2[b]), step_nm=step_nm) for b in bands)).validate()
