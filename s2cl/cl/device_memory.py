"""A device's memory as s2cl plans with it: its global memory and its largest single buffer, as the driver
reports them (``CL_DEVICE_GLOBAL_MEM_SIZE``, ``CL_DEVICE_MAX_MEM_ALLOC_SIZE``), and how many units of work (the
configurations of a sweep chunk) a set of device buffers leaves room for.

The seam for tests: ``$S2CL_DEVICE_GLOBAL_MEM`` and ``$S2CL_DEVICE_MAX_ALLOC`` (sizes such as ``512M``, ``2G`` or a
number of bytes) lower what the device is taken to have, never raise it: a PoCL CPU device, which reports
host-sized numbers, then plans as a small GPU would. :attr:`s2cl.cl.runtime.Runtime.memory` applies them.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from s2cl.errors import ResourceError
from s2cl.io.budget import Allocation, gb, largest_fitting, parse_size

GLOBAL_ENV = "S2CL_DEVICE_GLOBAL_MEM"
MAX_ALLOC_ENV = "S2CL_DEVICE_MAX_ALLOC"
#: the share of the device's global memory s2cl's live buffers may take: the driver, other programs on the device
#: and the memory pool's rounding (pyopencl rounds a buffer up by at most 1/16) take the rest
GLOBAL_FRACTION = 0.8
#: what pyopencl's memory pool (:attr:`s2cl.cl.runtime.Runtime.pool`, the buffers of each launch) adds to a buffer at
#: most: it rounds the size up to its bin
POOL_ROUNDING = 1 / 16


#: a device buffer whose size (bytes) is ``fixed + per_unit · n`` for ``n`` units of work
DeviceBuffer = Allocation


@dataclass(frozen=True)
class DeviceMemory:
    """What one device offers (bytes): ``global_bytes`` in all, at most ``max_alloc_bytes`` in one buffer;
    ``why``: where a lowered number comes from ("" when the driver's)."""

    name: str
    global_bytes: int
    max_alloc_bytes: int
    why: str = ""

    @classmethod
    def of(cls, name: str, global_bytes: int, max_alloc_bytes: int,
           environ: Mapping[str, str] | None = None) -> DeviceMemory:
        """The driver's numbers, each lowered by its environment variable where set (:data:`GLOBAL_ENV`,
        :data:`MAX_ALLOC_ENV`; a malformed size is a one-line :class:`~s2cl.errors.InputError` naming it)."""
        env = os.environ if environ is None else environ
        why, sizes = [], []
        for key, reported in ((GLOBAL_ENV, int(global_bytes)), (MAX_ALLOC_ENV, int(max_alloc_bytes))):
            text = env.get(key, "").strip()
            size = parse_size(text, key=f"${key}") if text else reported
            if size < reported:
                why.append(f"${key} {text}")
            sizes.append(min(size, reported))
        return cls(name, sizes[0], min(sizes), ", ".join(why))

    @property
    def usable_bytes(self) -> int:
        """What s2cl's live buffers may take together: :data:`GLOBAL_FRACTION` of the global memory."""
        return int(GLOBAL_FRACTION * self.global_bytes)

    def units_fitting(self, buffers: Sequence[DeviceBuffer], most: int = 2**62) -> int:
        """The largest ``n <= most`` for which every buffer fits in one allocation and all of them together in
        :attr:`usable_bytes` (0: not even one unit fits)."""
        n = most
        fixed = sum(b.fixed for b in buffers)
        per_unit = sum(b.per_unit for b in buffers)
        limits = [(self.usable_bytes, fixed, per_unit)] + [(self.max_alloc_bytes, b.fixed, b.per_unit) for b in buffers]
        for limit, a, b in limits:
            if a + b > limit:
                return 0
            if b > 0:
                n = min(n, largest_fitting(limit, a, b))
        return max(0, int(n))

    def require(self, buffers: Sequence[DeviceBuffer], units: int, *, what: str, key: str | None,
                source: str | None, fits: str = "") -> None:
        """Raise a one-line :class:`ResourceError` naming this device, the bytes needed and available and ``key``
        when ``buffers`` for ``units`` units do not fit (:meth:`units_fitting`)."""
        if units <= self.units_fitting(buffers, units):
            return
        total = sum(b.bytes(units) for b in buffers)
        largest = max(buffers, key=lambda b: b.bytes(units))
        whence = f" ({self.why})" if self.why else ""
        tail = f"; {fits}" if fits else ""
        raise ResourceError(f"{what} needs about {_size(total)} of device memory, its largest buffer ({largest.name}) "
                            f"{_size(largest.bytes(units))}; {self.name} offers {_size(self.usable_bytes)} "
                            f"({GLOBAL_FRACTION:.0%} of {_size(self.global_bytes)}) and {_size(self.max_alloc_bytes)} "
                            f"per buffer{whence}{tail}", source=source, key=key)


def _size(nbytes: float) -> str:
    """:func:`s2cl.io.budget.gb`, in kB below 1 MB (a device made small for a test)."""
    return gb(nbytes) if nbytes >= 1e6 else f"{nbytes / 1e3:,.0f} kB"
