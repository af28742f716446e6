"""A sweep's memory, from the checked scene, before its tables are built; the chunk chosen to fit.

What a sweep holds (bytes; ``P`` pixels = spectra × copies, ``S`` band slots, ``V`` band variants
over all slots, ``G`` grid wavelengths, ``C`` configurations per chunk):

- the library and its TOA radiance: ``3 · 8 · spectra · G``;
- per variant and spectrum: band radiance, noise σ and surface reflectance, float64, with their lists while
  they are stacked and the kernel's float32 copies (:data:`TABLE_BYTES_PER_VARIANT_SPECTRUM`, measured
  about 49); per variant its SRF weights while its slot is tabulated (``16`` bytes per grid sample of the
  widest variant's support, plus :data:`TABLE_BYTES_PER_VARIANT`);
- the common random numbers ``z`` (float64 on the host, float32 on the device) and the target:
  ``(12 · S + 16) · P``, plus the Philox work arrays of one slot while they are drawn (``160 · P``);
- per configuration-pixel of a chunk: the kernel's outputs with their host copies (``28``), and the metrics'
  work arrays: float64 scratch on the device (:data:`METRICS_SCRATCH_BYTES`) when the metrics run there (a
  device with float64, one process), else the numpy metrics' float64 work arrays on the host
  (:data:`s2cl.sweep.engine.HOST_BYTES_PER_EVALUATION`; Dask workers and devices without float64);
  per configuration of a chunk, its row of results twice (the chunk file and the merge into
  ``results.parquet``);
- the report (:mod:`s2cl.sweep.digest`, which streams ``results.parquet``): per band variant the best value of
  each (centre, width) pair (:data:`~s2cl.sweep.digest.BYTES_PER_VARIANT`), one batch of rows, and the
  heatmap figure (at most 60 × 40 cells: :data:`HEATMAP_BYTES`). No step holds all configurations.

The largest part decides the key an error names: ``surface.copies`` (pixels), ``sweep.step_nm``
(variants) or ``sweep.chunk`` / ``--chunk``.

The device's memory bounds the chunk too (:mod:`s2cl.sweep.device_footprint`, from the kernels' argument
declarations): the sweep's buffers together within 80 % of the device's global memory, each within its largest
allocation (:class:`s2cl.cl.device_memory.DeviceMemory`); a sweep whose tables or single configuration do not fit
the device is refused in one line naming the device.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from s2cl.app.checks import Checked
from s2cl.cl.device_memory import DeviceBuffer
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.forward.stages import chain
from s2cl.io.budget import BASELINE_BYTES, Budget, gb, largest_fitting, require_disk
from s2cl.scene.scene import Scene
from s2cl.sensor.variants import BandGrid, BandRange
from s2cl.sweep.device_footprint import SweepSizes, sweep_device_buffers
from s2cl.sweep.digest import BATCH_BYTES_PER_COLUMN, BYTES_PER_VARIANT
from s2cl.sweep.engine import HOST_BYTES_PER_EVALUATION, results_disk_bytes
from s2cl.sweep.metrics_kernel import MetricsKernel

KERNEL_BYTES_PER_EVALUATION = 28
PHILOX_BYTES_PER_PIXEL = 160
PER_PIXEL_SLOT = 12
PER_PIXEL = 16
#: float64 scratch per configuration-pixel of the metrics kernel (kernels/metrics.cl.mako: the median's copy)
METRICS_SCRATCH_BYTES = 8
#: a chunk's work arrays at most (auto chunk): larger chunks run faster (the time per configuration against the
#: chunk: bench/results/sweep-chunks-*.json, python -m bench.bench_sweep --skip-dask --chunks A,B,C)
AUTO_CHUNK_BYTES = 1e9
MAX_AUTO_CHUNK = 16384
#: a heatmap figure of at most 60 × 40 cells while matplotlib draws and writes it (measured about 150 MB)
HEATMAP_BYTES = 200e6
TABLE_BYTES_PER_VARIANT_SPECTRUM = 56
TABLE_BYTES_PER_VARIANT = 256
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


def sweep_resources(checked: Checked, *, chunk: int | None = None, budget: Budget | None = None,
                    resumed: int | None = None, host_metrics: bool = True,
                    rt: Runtime | None = None) -> SweepPlan:
    """Estimate the sweep's memory; choose the chunk (``chunk``, else ``resumed``: the chunk of the unfinished
    sweep in the output folder, whose chunk files are keyed by it, else ``sweep.chunk``, else the largest
    that keeps a chunk's work arrays within 1 GB and the whole within ``budget``). ``host_metrics``: whether the
    per-configuration metrics run in numpy on the host (default, the larger estimate) or on the device.
    ``rt``: the runtime of the device the chunks run on (default: the scene's ``compute.device``); the chunk is at most
    what its buffers leave room for there (:func:`device_buffers`; with the metrics kernel's where it has float64).
    The chunk of a Dask worker's device is sized from this one.

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
    columns = 2 * slots + RESULT_COLUMNS
    report = BYTES_PER_VARIANT * variants + BATCH_BYTES_PER_COLUMN * columns + HEATMAP_BYTES
    tables = sum(n * (TABLE_BYTES_PER_VARIANT_SPECTRUM * spectra + _weights_bytes(r, scene) + BYTES_PER_VARIANT)
                 for r, n in zip(space.ranges, space.counts, strict=True))
    fixed = BASELINE_BYTES + 24.0 * spectra * scene.grid.size + tables
    held = fixed + copies * per_copy  # through the whole run; then the chunks' arrays, then the report
    metrics = HOST_BYTES_PER_EVALUATION if host_metrics else METRICS_SCRATCH_BYTES
    per_evaluation = KERNEL_BYTES_PER_EVALUATION + metrics
    per_config = pixels * per_evaluation + 16.0 * columns

    def need(n: int) -> float:
        return held + max(n * per_config, report)

    what = f"a sweep of {n_configs:,} configurations × {pixels:,} pixels"
    if need(1) > budget.memory_bytes:
        if tables > copies * per_copy:
            budget.require(need(1), what=what + f" ({variants:,} band variants)", key="sweep.step_nm",
                           source=scene.source, fits=f"the variant tables alone take {gb(tables)}")
        most = largest_fitting(budget.memory_bytes, fixed + report, per_copy + spectra * per_config / pixels)
        budget.require(need(1), what=what, key="surface.copies", source=scene.source,
                       fits=f"at most {most:,} copies fit" if most else "")
    space.check_numbered(scene.source)  # after the memory: a space too large to hold is told so first
    rt = rt or get_runtime(scene.run.device)
    device = rt.memory
    buffers = device_buffers(checked, device_metrics=MetricsKernel.available(rt))
    on_device = device.units_fitting(buffers)
    if not on_device:  # the tables, or one configuration's outputs, do not fit the device
        tables_part = sum(b.fixed for b in buffers if b.name not in ("z", "target"))
        key = "sweep.step_nm" if tables_part > sum(b.per_unit for b in buffers) else "surface.copies"
        device.require(buffers, 1, what=what, key=key, source=scene.source,
                       fits="choose a device with more memory (compute.device, --device)")
    room = min(largest_fitting(budget.memory_bytes, held, per_config), on_device)
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
        size = max(1, min(n_configs, int(AUTO_CHUNK_BYTES // (pixels * per_evaluation)), MAX_AUTO_CHUNK,
                          room))
    return _plan(size, need, n_configs, buffers)


def _plan(size: int, need: Callable[[int], float], n_configs: int, buffers: list[DeviceBuffer]) -> SweepPlan:
    return SweepPlan(chunk=int(size), memory_bytes=need(size), configurations=n_configs,
                     device_bytes=sum(b.bytes(size) for b in buffers))


def device_buffers(checked: Checked, *, device_metrics: bool) -> list[DeviceBuffer]:
    """The sweep's device buffers (:func:`s2cl.sweep.device_footprint.sweep_device_buffers`), from the checked scene
    before its tables are built: fixed bytes and bytes per configuration of a chunk; ``device_metrics``: with the
    metrics kernel's (:class:`s2cl.sweep.metrics_kernel.MetricsKernel`, on devices with float64)."""
    scene, space, library = checked.scene, checked.space, checked.library
    assert space is not None and library is not None and checked.analysis is not None
    metric = checked.analysis.family.metric
    classes = len(set(library.groups)) if metric.classifies else 0
    sizes = SweepSizes(variants=sum(space.counts), spectra=library.size, copies=scene.run.copies,
                       slots=len(space.ranges), classes=classes)
    real_bytes = 8 if scene.run.precision == "float64" else 4
    return sweep_device_buffers(chain(scene.effects), sizes, real_bytes=real_bytes, device_metrics=device_metrics,
                                metric=metric)


def _weights_bytes(r: BandRange | BandGrid, scene: Scene) -> float:
    """One variant's SRF weights (float64 samples over ± ``sensor.support`` FWHM of the widest variant, with
    their indices) and its bookkeeping, while its slot is tabulated."""
    samples = 2.0 * scene.run.support * r.extent()[3] / scene.grid.step_nm + 2
    return TABLE_BYTES_PER_VARIANT + 16.0 * samples


def require_sweep_disk(checked: Checked, out: str | Path) -> None:
    """Refuse a sweep whose results would not fit on the disk of ``out`` (before the tables are built)."""
    space = checked.space
    assert space is not None
    require_disk(out, results_disk_bytes(space.size, len(space.ranges)),
                 what=f"the results of {space.size:,} configurations", key="sweep", source=checked.scene.source)
