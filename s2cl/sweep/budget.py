"""A sweep's memory, from the checked scene, before its tables are built; the chunk chosen to fit.

What a sweep holds (bytes; ``P`` pixels = spectra × copies, ``S`` band slots, ``V`` band variants
over all slots, ``G`` grid wavelengths, ``C`` configurations per chunk):

- the library and its TOA radiance: ``3 · 8 · spectra · G``;
- per variant and spectrum: band radiance, noise σ and surface reflectance, float64: ``24 · V · spectra``;
- the common random numbers ``z`` (float64 on the host, float32 on the device) and the target:
  ``(12 · S + 16) · P``, plus the Philox work arrays of one slot while they are drawn (``160 · P``);
- per configuration-pixel of a chunk: the metrics' float64 work arrays
  (:data:`s2cl.sweep.engine.HOST_BYTES_PER_EVALUATION`) and the kernel's outputs with their host copies (``28``).

The largest part decides the key an error names: ``surface.copies`` (pixels), ``sweep.step_nm``
(variants) or ``sweep.chunk`` / ``--chunk``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from s2cl.io.budget import BASELINE_BYTES, Budget, gb, largest_fitting, require_disk
from s2cl.scene.validate import Checked
from s2cl.sweep.engine import HOST_BYTES_PER_EVALUATION, results_disk_bytes

KERNEL_BYTES_PER_EVALUATION = 28
PHILOX_BYTES_PER_PIXEL = 160
PER_PIXEL_SLOT = 12
PER_PIXEL = 16
AUTO_CHUNK_BYTES = 512e6
MAX_AUTO_CHUNK = 16384

__all__ = ["Budget", "SweepPlan", "require_sweep_disk", "sweep_resources"]


@dataclass(frozen=True)
class SweepPlan:
    """The chunk a sweep will run with and the memory it is expected to take (bytes)."""

    chunk: int
    memory_bytes: float
    configurations: int


def sweep_resources(checked: Checked, *, chunk: int | None = None, budget: Budget | None = None) -> SweepPlan:
    """Estimate the sweep's memory; choose the chunk (``chunk``, else ``sweep.chunk``, else the largest
    that keeps a chunk's work arrays within 512 MB and the whole within ``budget``).

    :raises ResourceError: even one configuration per chunk does not fit, or the chunk asked for does not.
    """
    scene, space = checked.scene, checked.space
    assert space is not None and checked.library is not None
    budget = budget or Budget.of()
    spectra, copies, slots = checked.library.size, scene.run.copies, len(space.ranges)
    pixels = spectra * copies
    n_configs = space.size
    variants = sum(space.counts)
    per_copy = spectra * (PER_PIXEL_SLOT * slots + PER_PIXEL + PHILOX_BYTES_PER_PIXEL)
    fixed = BASELINE_BYTES + 24.0 * spectra * scene.grid.size + 24.0 * variants * spectra
    per_config = pixels * (HOST_BYTES_PER_EVALUATION + KERNEL_BYTES_PER_EVALUATION)
    need_one = fixed + copies * per_copy + per_config
    what = f"a sweep of {n_configs:,} configurations × {pixels:,} pixels"
    if need_one > budget.memory_bytes:
        tables = 24.0 * variants * spectra
        if tables > copies * per_copy:
            budget.require(need_one, what=what + f" ({variants:,} band variants)", key="sweep.step_nm",
                           source=scene.source, fits=f"the variant tables alone take {gb(tables)}")
        most = largest_fitting(budget.memory_bytes, fixed, per_copy + spectra * per_config / pixels)
        budget.require(need_one, what=what, key="surface.copies", source=scene.source,
                       fits=f"at most {most:,} copies fit" if most else "")
    room = largest_fitting(budget.memory_bytes, fixed + copies * per_copy, per_config)
    asked = chunk or scene.spec.sweep.chunk
    if asked:
        key = "--chunk" if chunk else "sweep.chunk"
        budget.require(fixed + copies * per_copy + asked * per_config, what=what + f" in chunks of {asked:,}",
                       key=key, source=scene.source, fits=f"at most {room:,} configurations per chunk fit")
        size = asked
    else:
        size = max(1, min(n_configs, int(AUTO_CHUNK_BYTES // (pixels * HOST_BYTES_PER_EVALUATION)), MAX_AUTO_CHUNK,
                          room))
    return SweepPlan(chunk=int(size), memory_bytes=fixed + copies * per_copy + size * per_config,
                     configurations=n_configs)


def require_sweep_disk(checked: Checked, out: str | Path) -> None:
    """Refuse a sweep whose results would not fit on the disk of ``out`` (before the tables are built)."""
    space = checked.space
    assert space is not None
    require_disk(out, results_disk_bytes(space.size, len(space.ranges)),
                 what=f"the results of {space.size:,} configurations", key="sweep", source=checked.scene.source)
