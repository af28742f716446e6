"""A sweep's memory, from the checked scene, before its tables are built; the chunk chosen to fit.

The host's part is what the sweep allocates, listed by its engines (:mod:`s2cl.sweep.host_footprint`, each an
:class:`~s2cl.io.budget.Allocation` of fixed bytes and bytes per configuration of a chunk):

- held through the run: what every run holds (:data:`~s2cl.io.budget.BASELINE_BYTES`), the library, the tables
  (a float64 copy of each table the sweep kernel's argument declarations say it reads, the widths and the target)
  and, on a device that works in host memory (PoCL's CPU devices), the device's buffers;
- while the tables are built: the TOA radiance, the variants' lists and SRF weights and the deviates' draws;
- per configuration of a chunk: where the metrics run on the device, the chunk's device buffers (in host memory
  on a CPU device) and its metric rows; else the kernel's outputs fetched, and the numpy metrics' row block
  (fixed); and the chunk's rows of results, twice (the rows and the chunk file's Arrow table);
- the report (:mod:`s2cl.sweep.digest`, which streams ``results.parquet``): per band variant the best value of
  each (centre, width) pair (:data:`~s2cl.sweep.digest.BYTES_PER_VARIANT`), one batch of rows, and the heatmap
  figure (at most 60 × 40 cells: :data:`HEATMAP_BYTES`). No step holds all configurations.

The run needs the held part plus the largest of the build, a chunk and the report. The largest part decides the key
an error names: ``surface.copies`` (pixels), ``sweep.step_nm`` (variants) or ``sweep.chunk`` / ``--chunk``.
``tests/test_host_footprint.py`` measures the declared parts against a chunk's resident set and numpy's allocations.

The device's memory bounds the chunk too (:mod:`s2cl.sweep.device_footprint`, from the kernels' argument
declarations): the sweep's buffers together within 80 % of the device's global memory, each within its largest
allocation (:class:`s2cl.cl.device_memory.DeviceMemory`); a sweep whose tables or single configuration do not fit
the device is refused in one line naming the device.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from s2cl.app.checks import Checked
from s2cl.cl.device_memory import POOL_ROUNDING, DeviceBuffer
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.forward.stages import Stage, chain
from s2cl.io.budget import BASELINE_BYTES, Allocation, Budget, gb, largest_fitting, most_fitting, require_disk
from s2cl.retrieve.metric import Metric
from s2cl.sweep.device_footprint import SweepSizes, sweep_device_buffers
from s2cl.sweep.digest import BATCH_BYTES_PER_COLUMN, BYTES_PER_VARIANT
from s2cl.sweep.engine import results_disk_bytes
from s2cl.sweep.host_footprint import (
    build_arrays,
    chunk_arrays,
    held_bytes,
    library_arrays,
    per_unit_bytes,
    table_arrays,
)
from s2cl.sweep.metrics_kernel import MetricsKernel

#: a chunk's work arrays (host and device) at most (auto chunk): larger chunks run faster (the time per
#: configuration against the chunk: bench/results/sweep-chunks-*.json, python -m bench.bench_sweep --skip-dask
#: --chunks A,B,C)
AUTO_CHUNK_BYTES = 1e9
MAX_AUTO_CHUNK = 16384
#: a heatmap figure of at most 60 × 40 cells while matplotlib draws and writes it (measured about 150 MB)
HEATMAP_BYTES = 200e6
#: columns of a results row besides each band's centre and width (config, metrics, fit accounting)
RESULT_COLUMNS = 24

__all__ = ["Budget", "SweepPlan", "require_sweep_disk", "sweep_resources"]


@dataclass(frozen=True)
class SweepPlan:
    """The chunk a sweep will run with, the host memory it is expected to take and the device memory of its
    buffers (bytes)."""

    chunk: int
    memory_bytes: float
    configurations: int
    device_bytes: float = 0.0


@dataclass(frozen=True)
class HostFootprint:
    """A sweep's host memory (:mod:`s2cl.sweep.host_footprint`): ``held`` through the run, ``build`` while the
    tables are built, ``chunk`` per configuration of a chunk (and its fixed row block), ``report`` at the end."""

    held: list[Allocation]
    build: list[Allocation]
    chunk: list[Allocation]
    report: float

    def need(self, n: int) -> float:
        """Bytes at the peak of a run in chunks of ``n`` configurations."""
        chunk = sum(a.bytes(n) for a in self.chunk)
        return held_bytes(self.held) + max(held_bytes(self.build), chunk, self.report)

    @property
    def tables(self) -> float:
        """The part that grows with the band variants: the tables and their device copies."""
        return sum(a.fixed for a in self.held if a.name not in ("baseline", "library", "z", "target"))


def host_footprint(checked: Checked, *, host_metrics: bool, device_memory: bool, device_metrics: bool,
                   copies: int | None = None) -> HostFootprint:
    """The sweep's host memory from its engines' declarations: ``host_metrics``: the numpy metrics run on the host;
    ``device_memory``: the device works in host memory (its buffers count here, ``device_metrics``: with the
    metrics kernel's); ``copies``: instead of the scene's (the largest number of copies that fits)."""
    scene, space = checked.scene, checked.space
    assert space is not None
    sizes, stages, metric, real_bytes = _sizes(checked)
    if copies is not None:
        sizes = replace(sizes, copies=copies)
    device = sweep_device_buffers(stages, sizes, real_bytes=real_bytes, device_metrics=device_metrics,
                                  metric=metric) if device_memory else []
    widest = max(2.0 * scene.run.support * r.extent()[3] / scene.grid.step_nm + 2 for r in space.ranges)
    build = build_arrays(sizes, scene.grid.size, widest)
    held = [Allocation("baseline", BASELINE_BYTES), *library_arrays(sizes, scene.grid.size),
            *table_arrays(stages, sizes, metric), *(Allocation(d.name, d.fixed) for d in device if d.fixed)]
    columns = 2 * sizes.slots + RESULT_COLUMNS
    chunk = chunk_arrays(sizes, metric, real_bytes=real_bytes, device_metrics=not host_metrics, columns=columns)
    # a launch's buffers come from the memory pool, which rounds each up to its bin
    chunk += [Allocation(d.name, 0.0, d.per_unit * (1 + POOL_ROUNDING)) for d in device if d.per_unit]
    report = BYTES_PER_VARIANT * sizes.variants + BATCH_BYTES_PER_COLUMN * columns + HEATMAP_BYTES
    return HostFootprint(held, build, chunk, report)


def sweep_resources(checked: Checked, *, chunk: int | None = None, budget: Budget | None = None,
                    resumed: int | None = None, host_metrics: bool = True,
                    rt: Runtime | None = None) -> SweepPlan:
    """Estimate the sweep's memory; choose the chunk (``chunk``, else ``resumed``: the chunk of the unfinished
    sweep in the output folder, whose chunk files are keyed by it, else ``sweep.chunk``, else the largest
    that keeps a chunk's work arrays within 1 GB and the whole within ``budget``). ``host_metrics``: whether the
    per-configuration metrics run in numpy on the host (default, the larger estimate) or on the device.
    ``rt``: the runtime of the device the chunks run on (default: the scene's ``compute.device``); the chunk is at most
    what its buffers leave room for there (:func:`device_buffers`; with the metrics kernel's where it has float64),
    and its buffers count in the host's memory where the device works in it (:func:`host_footprint`).
    The chunk of a Dask worker's device is sized from this one.

    :raises ResourceError: even one configuration per chunk does not fit, or the chunk asked for does not.
    """
    scene, space = checked.scene, checked.space
    assert space is not None and checked.library is not None
    budget = budget or Budget.of()
    rt = rt or get_runtime(scene.run.device)
    copies, n_configs, variants = scene.run.copies, space.size, sum(space.counts)
    pixels = checked.library.size * copies

    def footprint(n_copies: int | None = None) -> HostFootprint:
        return host_footprint(checked, host_metrics=host_metrics, device_memory=rt.host_memory,
                              device_metrics=not host_metrics, copies=n_copies)

    host = footprint()
    need = host.need
    what = f"a sweep of {n_configs:,} configurations × {pixels:,} pixels"
    if need(1) > budget.memory_bytes:
        if footprint(0).need(1) > budget.memory_bytes:  # not even without copies: too many band variants' tables
            budget.require(need(1), what=what + f" ({variants:,} band variants)", key="sweep.step_nm",
                           source=scene.source, fits=f"the variant tables alone take {gb(host.tables)}")
        # not a straight line in the copies: past some count the chunk's part outgrows the report's
        most = most_fitting(lambda c: footprint(c).need(1) <= budget.memory_bytes, copies)
        budget.require(need(1), what=what, key="surface.copies", source=scene.source,
                       fits=f"at most {most:,} copies fit" if most else "")
    space.check_numbered(scene.source)  # after the memory: a space too large to hold is told so first
    device = rt.memory
    buffers = device_buffers(checked, device_metrics=MetricsKernel.available(rt))
    on_device = device.units_fitting(buffers)
    if not on_device:  # the tables, or one configuration's outputs, do not fit the device
        tables_part = sum(b.fixed for b in buffers if b.name not in ("z", "target"))
        key = "sweep.step_nm" if tables_part > sum(b.per_unit for b in buffers) else "surface.copies"
        device.require(buffers, 1, what=what, key=key, source=scene.source,
                       fits="choose a device with more memory (compute.device, --device)")
    per_config = per_unit_bytes(host.chunk)
    room = min(largest_fitting(budget.memory_bytes, need(0), per_config), on_device)
    if resumed and not chunk:
        budget.require(need(resumed), what=what + f" resumed in the chunks of {resumed:,} it started with",
                       key="--max-memory", source=scene.source, fits=f"at most {room:,} configurations per chunk "
                       "fit: raise --max-memory, or pass --overwrite to start afresh")
        device.require(buffers, resumed, what=what + f" resumed in the chunks of {resumed:,} it started with",
                       key="--overwrite", source=scene.source, fits=f"at most {on_device:,} configurations per "
                       "chunk fit this device: pass --overwrite to start afresh, or choose another (--device)")
        return _plan(resumed, need, n_configs, buffers)
    asked = chunk or scene.spec.sweep.chunk
    if asked:
        key = "--chunk" if chunk else "sweep.chunk"
        budget.require(need(asked), what=what + f" in chunks of {asked:,}", key=key, source=scene.source,
                       fits=f"at most {room:,} configurations per chunk fit")
        device.require(buffers, asked, what=what + f" in chunks of {asked:,}", key=key, source=scene.source,
                       fits=f"at most {on_device:,} configurations per chunk fit this device")
        size = asked
    else:
        # a chunk's work arrays: its host arrays and its device buffers (counted once where they are the host's)
        work = per_config + (0.0 if rt.host_memory else sum(b.per_unit for b in buffers))
        size = max(1, min(n_configs, int(AUTO_CHUNK_BYTES // work), MAX_AUTO_CHUNK, room))
    return _plan(size, need, n_configs, buffers)


def _plan(size: int, need: Callable[[int], float], n_configs: int, buffers: list[DeviceBuffer]) -> SweepPlan:
    return SweepPlan(chunk=int(size), memory_bytes=need(size), configurations=n_configs,
                     device_bytes=sum(b.bytes(size) for b in buffers))


def _sizes(checked: Checked) -> tuple[SweepSizes, list[Stage], Metric, int]:
    """The sizes a sweep's buffers and arrays scale with, the chain's stages, the metric and the kernel's bytes per
    real, from the checked scene before its tables are built."""
    scene, space, library = checked.scene, checked.space, checked.library
    assert space is not None and library is not None and checked.analysis is not None
    metric = checked.analysis.family.metric
    classes = len(set(library.groups)) if metric.classifies else 0
    sizes = SweepSizes(variants=sum(space.counts), spectra=library.size, copies=scene.run.copies,
                       slots=len(space.ranges), classes=classes)
    return sizes, chain(scene.effects), metric, 8 if scene.run.precision == "float64" else 4


def device_buffers(checked: Checked, *, device_metrics: bool) -> list[DeviceBuffer]:
    """The sweep's device buffers (:func:`s2cl.sweep.device_footprint.sweep_device_buffers`), from the checked scene
    before its tables are built: fixed bytes and bytes per configuration of a chunk; ``device_metrics``: with the
    metrics kernel's (:class:`s2cl.sweep.metrics_kernel.MetricsKernel`, on devices with float64)."""
    sizes, stages, metric, real_bytes = _sizes(checked)
    return sweep_device_buffers(stages, sizes, real_bytes=real_bytes, device_metrics=device_metrics, metric=metric)


def require_sweep_disk(checked: Checked, out: str | Path) -> None:
    """Refuse a sweep whose results would not fit on the disk of ``out`` (before the tables are built)."""
    space = checked.space
    assert space is not None
    require_disk(out, results_disk_bytes(space.size, len(space.ranges)),
                 what=f"the results of {space.size:,} configurations", key="sweep", source=checked.scene.source)
