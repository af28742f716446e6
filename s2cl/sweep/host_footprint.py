"""A sweep's host memory, from what it allocates: the tables' arrays (float64 copies of what the sweep kernel's
argument declarations say it reads, :func:`s2cl.sweep.kernel.kernel_args`), the chunk's fetched outputs (the
kernel's declared outputs, :data:`s2cl.sweep.kernel.OUTPUTS`), the numpy metrics' row block
(:func:`s2cl.retrieve.metrics.block_work_bytes`) or the device metrics' rows, the rows of results, and, on a device
that works in host memory (PoCL's CPU devices), the device buffers themselves
(:func:`s2cl.sweep.device_footprint.sweep_device_buffers`). Each is an :class:`~s2cl.io.budget.Allocation`: fixed
bytes plus bytes per configuration of a chunk. ``tests/test_host_footprint.py`` measures them (resident set and
numpy's allocations of a chunk run in a child process) against these declarations."""

from __future__ import annotations

import numpy as np

from s2cl.cl.kernel_args import buffers
from s2cl.forward.noise import sensor_noise_bytes
from s2cl.forward.stages import Stage
from s2cl.io.budget import Allocation
from s2cl.retrieve.metric import Metric
from s2cl.retrieve.metrics import ROW_BLOCK, block_work_bytes
from s2cl.sweep.device_footprint import UNIT, SweepSizes
from s2cl.sweep.kernel import OUTPUTS, kernel_args

#: bytes of each value the host keeps in the tables and its rows of results (float64; int64 configuration numbers)
HOST_ITEM = np.dtype(np.float64).itemsize


def table_arrays(stages: list[Stage], sizes: SweepSizes, metric: Metric) -> list[Allocation]:
    """The sweep tables' host arrays (:class:`s2cl.sweep.tables.SweepTables`), held through the run: a float64 copy
    of each table the kernel reads (its declaration's shape, the deviates over the pixels rather than the padded
    pitch), the variants' widths and the per-pixel target."""
    named = {**sizes.named(metric), "pitch": sizes.pixels}
    read = [a for a in kernel_args(stages) if a.kind == "in"]
    return [*buffers(read, named, HOST_ITEM, UNIT), Allocation("width", HOST_ITEM * sizes.variants),
            Allocation("target", HOST_ITEM * sizes.pixels)]


def library_arrays(sizes: SweepSizes, grid: int) -> list[Allocation]:
    """The library's reflectance (float64, spectra × grid), held through the run."""
    return [Allocation("library", HOST_ITEM * sizes.spectra * grid)]


def build_arrays(sizes: SweepSizes, grid: int, widest_samples: float) -> list[Allocation]:
    """What building the tables holds besides them, once: the library's TOA radiance with the expression's
    temporary (``2`` float64 arrays of spectra × grid), per variant and spectrum the band radiance and surface
    reflectance lists before they are stacked (``2`` float64 values), each variant's SRF weights (float64 samples of
    the widest variant) and the Philox draws of the deviates (:func:`s2cl.forward.noise.sensor_noise_bytes`)."""
    return [Allocation("TOA radiance", 2.0 * HOST_ITEM * sizes.spectra * grid),
            Allocation("variant lists", 2.0 * HOST_ITEM * sizes.variants * sizes.spectra),
            Allocation("SRF weights", HOST_ITEM * sizes.variants * widest_samples),
            Allocation("deviate draws", float(sensor_noise_bytes(sizes.pixels, sizes.slots)))]


def chunk_arrays(sizes: SweepSizes, metric: Metric, *, real_bytes: int, device_metrics: bool,
                 columns: int) -> list[Allocation]:
    """A chunk's host arrays per configuration: with ``device_metrics`` the metrics kernel's rows (its ``columns``
    as float64, fetched and copied out per column) and, once, the rows the kernel marks for the host (a few: a row
    block's outputs and the numpy metrics' work; a chunk whose rows were all marked would take the host path's
    memory); else the kernel's outputs fetched (their declared types over the padded pixels) and the numpy metrics'
    row block (fixed); and the chunk's ``columns`` of results as float64, twice (its rows and their Arrow table when
    the chunk file is written)."""
    named = sizes.named(metric)
    rows = Allocation("results", 0.0, 2.0 * HOST_ITEM * columns)
    fetched = [Allocation(f"{b.name} (fetched)", b.fixed, b.per_unit)
               for b in buffers(OUTPUTS, named, real_bytes, UNIT)]
    work = Allocation("metrics row block", float(block_work_bytes(sizes.pixels, classifies=metric.classifies)))
    if device_metrics:  # rows the kernel marks are recomputed on the host: a row block's outputs and work (few)
        marked = Allocation("marked rows", ROW_BLOCK * per_unit_bytes(fetched) + work.fixed)
        return [Allocation("metric rows", 0.0, 2.0 * HOST_ITEM * len(metric.columns)), marked, rows]
    return [*fetched, work, rows]


def held_bytes(allocations: list[Allocation]) -> float:
    """The fixed bytes of ``allocations``."""
    return sum(a.fixed for a in allocations)


def per_unit_bytes(allocations: list[Allocation]) -> float:
    """The bytes per configuration of ``allocations``."""
    return sum(a.per_unit for a in allocations)
