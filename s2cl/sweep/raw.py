"""Per-pixel results of a chunk of sweep configurations, and the configuration numbering.

Configurations are numbered in mixed radix over the band slots, last slot fastest: configuration
``c`` takes variant ``(c // strides[k]) % counts[k]`` of slot ``k`` (the kernel decodes the same); in
tables of a design list (``diagonal``) configuration ``c`` takes variant ``c`` of every slot.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass
class RawChunk:
    """Per (configuration, pixel) results of configurations ``start … stop-1``.

    ``index``: λp (nm) for igrm, GVMI for gvmi, class index for sam (float64); ``status``
    (:class:`s2cl.status.Status`), ``bounds`` (IGRM active-bound bits) and ``condition`` (IGRM:
    round(20 log10 of the fit's condition estimate), 240 = capped) are uint8; all ``(n_configs, n_pixels)``.
    """

    start: int
    stop: int
    index: np.ndarray
    status: np.ndarray
    bounds: np.ndarray
    condition: np.ndarray | None = None

    def row(self, i: int) -> RawChunk:
        """Configuration ``start + i`` alone (arrays ``(1, n_pixels)``, views)."""
        cut = slice(i, i + 1)
        return RawChunk(self.start + i, self.start + i + 1, self.index[cut], self.status[cut], self.bounds[cut],
                        None if self.condition is None else self.condition[cut])


#: evaluates configurations ``start … stop-1`` of one sweep: the fused kernel, or a float64 numpy twin
ChunkEvaluator = Callable[[int, int], RawChunk]


class _Counted(Protocol):
    counts: tuple[int, ...]

    @property
    def n_slots(self) -> int: ...


def variant_indices(t: _Counted, start: int, stop: int) -> np.ndarray:
    """Variant index per slot, ``(n_configs, n_slots)``, last slot fastest (diagonal tables: ``c`` in every slot)."""
    flat = np.arange(start, stop, dtype=np.int64)
    if getattr(t, "diagonal", False):
        return np.repeat(flat[:, None], t.n_slots, axis=1)
    out = np.empty((flat.size, t.n_slots), dtype=np.int64)
    for k in range(t.n_slots - 1, -1, -1):
        flat, out[:, k] = np.divmod(flat, t.counts[k])
    return out
