"""Resource estimates: the memory and disk a run will need, computed from the scene before anything
is allocated or written, against what the run may use.

A run may use at most ``--max-memory`` (or ``$S2CL_MAX_MEMORY``; default 4 GB) and never more
than 90 % of the memory available now (``psutil``). An estimate above that is a one-line
:class:`~s2cl.errors.ResourceError` naming the scene key to lower and the largest value that fits.
Engines declare what they allocate as :class:`Allocation` lists (the sweep's
:mod:`s2cl.sweep.host_footprint`, a library simulation's :mod:`s2cl.app.simulate_footprint`), from their
kernels' argument declarations and their named host arrays; the tests measure them.
"""

from __future__ import annotations

import math
import os
import re
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from s2cl.errors import InputError, ResourceError, token

DEFAULT_MAX_MEMORY = 4_000_000_000
MAX_MEMORY_ENV = "S2CL_MAX_MEMORY"
#: what every run holds before its own arrays: Python, numpy, pyopencl + PoCL, the LUT (bytes)
BASELINE_BYTES = 350e6
#: pixels per simulate chunk (all copies of whole spectra; at least one spectrum)
SIMULATE_CHUNK_PIXELS = 1 << 20

_SIZE = re.compile(r"^\s*([0-9]*\.?[0-9]+)\s*([kmgt]?)(i?b?)\s*$", re.IGNORECASE)


def parse_size(text: str, *, key: str = "--max-memory") -> int:
    """Bytes from ``'4G'`` / ``'4GB'`` (10⁹), ``'1.5GiB'`` (2³⁰), ``'512M'`` or a plain number of bytes."""
    m = _SIZE.match(str(text))
    if not m:
        raise InputError(f"must be a size such as 4G, 512M or 1.5GiB, got {token(text)}", key=key)
    base = 1024 if "i" in m.group(3).lower() else 1000
    value = float(m.group(1)) * base ** "_kmgt".index((m.group(2) or "_").lower())
    if not 0 < value < 2**62:
        raise InputError(f"must be > 0, got {text!r}", key=key)
    return int(value)


def available_memory() -> int:
    """Memory that can be allocated now without swapping (bytes)."""
    import psutil

    return int(psutil.virtual_memory().available)


@dataclass(frozen=True)
class Budget:
    """What a run may use: ``memory_bytes`` and where that limit comes from."""

    memory_bytes: int
    why: str

    @classmethod
    def of(cls, max_memory: str | None = None) -> Budget:
        """From ``--max-memory`` (else ``$S2CL_MAX_MEMORY``, else 4 GB), capped at 90 % of the
        memory available now."""
        text = max_memory or os.environ.get(MAX_MEMORY_ENV) or None
        key = "--max-memory" if max_memory else MAX_MEMORY_ENV
        limit = parse_size(text, key=key) if text else DEFAULT_MAX_MEMORY
        why = f"{key} {text}" if text else "the default limit; --max-memory raises it"
        free = int(0.9 * available_memory())
        if free < limit:
            return cls(free, f"90 % of the memory available now ({gb(available_memory())})")
        return cls(limit, why)

    def require(self, need: float, *, what: str, key: str | None, source: str | None, fits: str = "") -> None:
        """Raise :class:`ResourceError` when ``need`` bytes exceed the budget.

        :param what: the thing that needs the memory ("simulating 120 spectra × 10⁶ copies").
        :param key: the scene key (or option) to lower.
        :param fits: what would fit, e.g. "at most 310,000 copies fit".
        """
        if need <= self.memory_bytes:
            return
        tail = f"; {fits}" if fits else ""
        raise ResourceError(f"{what} needs about {gb(need)} of memory, more than {gb(self.memory_bytes)} "
                            f"({self.why}){tail}", source=source, key=key)


@dataclass(frozen=True)
class Allocation:
    """Memory an engine allocates for ``n`` units of work (the configurations of a sweep chunk, say): ``fixed +
    per_unit · n`` bytes, named for the messages; engines list theirs from the arrays and buffers they make."""

    name: str
    fixed: float
    per_unit: float = 0.0

    def bytes(self, units: int) -> float:
        return self.fixed + self.per_unit * units


def gb(nbytes: float) -> str:
    """'1.2 GB' / '350 MB' (decimal units, as users read them)."""
    return f"{nbytes / 1e9:.1f} GB" if nbytes >= 1e9 else f"{nbytes / 1e6:,.0f} MB"


def largest_fitting(budget_bytes: float, fixed: float, per_unit: float) -> int:
    """The largest count ``n`` with ``fixed + n · per_unit <= budget_bytes`` (0 if none)."""
    if per_unit <= 0:
        return 0
    return max(0, math.floor((budget_bytes - fixed) / per_unit))


def most_fitting(fits: Callable[[int], bool], upper: int) -> int:
    """The largest count ``n`` in ``0 … upper`` with ``fits(n)`` (0 if none), by bisection: for footprints that grow
    with the count but not in a straight line (a larger part taking over past some count)."""
    lo, hi = 0, upper
    while lo < hi:
        mid = (lo + hi + 1) // 2
        lo, hi = (mid, hi) if fits(mid) else (lo, mid - 1)
    return lo


def require_disk(folder: str | Path, need: float, *, what: str, key: str, source: str | None = None) -> None:
    """Raise :class:`ResourceError` when the filesystem of ``folder`` has less than ``need`` bytes free
    (a full disk mid-write is what crashes HDF5: it is refused before the run instead)."""
    p = Path(os.path.abspath(folder))
    while not p.exists() and p != p.parent:
        p = p.parent
    free = shutil.disk_usage(p).free
    if need > free:
        raise ResourceError(f"{what} needs about {gb(need)} of disk in {folder}, {gb(free)} are free",
                            source=source, key=key)
