"""The host memory of ``s2cl simulate`` on a library (:func:`s2cl.app.simulate.simulate_to_netcdf`), from what it
allocates: the sense kernel's declared buffers (:func:`s2cl.forward.sense.sense_buffers`, its outputs' types from
the chain's stages) and the named host arrays each step keeps, with their types. Each is an
:class:`~s2cl.io.budget.Allocation` of fixed bytes for the planned sizes.

A run holds the library and its band radiance throughout, and, with an [analysis], the analysed bands' reflectance
of every pixel; its peak is then the larger of a chunk's arrays and the analysis' arrays (which run after the
chunks). A chunk holds its spectra's band radiance repeated over their copies and the stages' outputs, and on top of
them either one launch's arrays (the radiance made contiguous, the device's buffers where the device works in host
memory, one fetched output) or, after the launches, the summary's float64 work, the clipping counts' masks or the
analysed bands' gather, whichever is largest. ``tests/test_simulate_footprint.py`` measures a run (resident set and
numpy's allocations, in a child process) against this declaration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.app.checks import Checked
from s2cl.forward.sense import launch_pixels, sense_args, sense_buffers
from s2cl.forward.stages import chain
from s2cl.io.budget import BASELINE_BYTES, SIMULATE_CHUNK_PIXELS, Allocation
from s2cl.retrieve.metrics import ROW_BLOCK, block_work_bytes
from s2cl.scene.scene import Scene

#: bytes of the host's float64 work values (the band summary's, the library's reflectance, the regression target)
F64 = np.dtype(np.float64).itemsize
#: bytes of a boolean mask value and of the retrieval's status, bounds and condition codes (uint8)
BYTE = 1


def chunk_spectra(copies: int) -> int:
    """Spectra per chunk: about :data:`~s2cl.io.budget.SIMULATE_CHUNK_PIXELS` pixels, at least one spectrum."""
    return max(1, SIMULATE_CHUNK_PIXELS // copies)


def chunk_pixels(n_spectra: int, copies: int) -> int:
    """Pixels of the largest chunk: :func:`chunk_spectra` spectra, no more than the library has, × ``copies``."""
    return min(chunk_spectra(copies), n_spectra) * copies


@dataclass(frozen=True)
class SimulateFootprint:
    """``held`` through the run, the largest ``chunk``'s arrays at its peak, and the ``analysis``' arrays (empty
    without one), each a list of allocations (bytes)."""

    held: list[Allocation]
    chunk: list[Allocation]
    analysis: list[Allocation]

    @property
    def peak(self) -> float:
        """Bytes at the run's peak: what is held, and the larger of a chunk and the analysis."""
        return total(self.held) + max(total(self.chunk), total(self.analysis))


def total(allocations: list[Allocation]) -> float:
    """The bytes of ``allocations``."""
    return sum(a.fixed for a in allocations)


def simulate_footprint(checked: Checked, *, copies: int | None = None, device_memory: bool = True,
                       baseline: bool = True) -> SimulateFootprint:
    """The footprint of simulating ``checked``'s library (``copies``: another number of copies, for what would
    fit); ``device_memory``: the device's buffers are the host's (PoCL's CPU devices); ``baseline``: count
    :data:`~s2cl.io.budget.BASELINE_BYTES`, what every run holds before its own arrays."""
    scene, lib = checked.scene, checked.library
    assert lib is not None
    c = scene.run.copies if copies is None else copies
    ns, nb, grid = lib.size, scene.sensor.size, scene.grid.size
    real = np.dtype(scene.run.precision).itemsize
    n_ab = len(checked.analysis_bands) if checked.analysis is not None else 0
    held = [Allocation("baseline", BASELINE_BYTES if baseline else 0.0),
            Allocation("library (float64)", F64 * ns * grid),
            # the resampling pass, before the chunks (counted throughout: a bound, and small)
            Allocation("library in the working precision", real * ns * grid),
            Allocation("band radiance", real * nb * ns)]
    if n_ab:
        held.append(Allocation("analysed bands' reflectance", real * n_ab * ns * c))
    return SimulateFootprint(held, chunk_arrays(checked, chunk_pixels(ns, c), device_memory=device_memory),
                             analysis_arrays(checked, ns * c, device_memory=device_memory) if n_ab else [])


def chunk_arrays(checked: Checked, pixels: int, *, device_memory: bool) -> list[Allocation]:
    """A chunk of ``pixels`` of ``s2cl simulate`` at its peak (see the module's docstring)."""
    analysed = len(checked.analysis_bands) if checked.analysis is not None else 0
    return sense_chunk(checked.scene, pixels, device_memory=device_memory, summary=True, analysed=analysed)


def sense_chunk(scene: Scene, pixels: int, *, device_memory: bool, summary: bool,
                analysed: int = 0, bands: int | None = None) -> list[Allocation]:
    """A chunk of ``pixels`` through the sense kernel at its peak: the band radiance repeated and the stages' outputs
    (their declared types), and the larger of one launch's arrays and what follows the launches one after the other
    (with ``summary``, the band summary's float64 work; the clipping counts' masks; the gather of ``analysed``
    bands); ``bands``: the bands sensed (default the sensor's; an image's GSD group senses its own)."""
    nb, real = scene.sensor.size if bands is None else bands, np.dtype(scene.run.precision).itemsize
    stages = chain(scene.effects)
    names = {a.name for a in sense_args(stages) if a.kind == "out"}
    declared = sense_buffers(stages, nb, real)  # per pixel of a launch: the outputs' and the radiance's buffers
    held = [Allocation("band radiance repeated", real * nb * pixels),
            *[Allocation(b.name, b.per_unit * pixels) for b in declared if b.name in names]]
    launch = min(pixels, launch_pixels(nb))
    at_launch = [Allocation("launch radiance (contiguous)", real * nb * launch),
                 Allocation("fetched output", max(b.per_unit for b in declared if b.name in names) * launch
                            if names else 0.0)]
    if device_memory:
        at_launch += [Allocation(f"{b.name} (device)", b.bytes(launch)) for b in declared]
    after = []
    if summary and names & {"noisy", "calibrated"}:  # the summary: a float64 copy and its deviation from the mean
        after.append(Allocation("summary work (float64)", 2 * F64 * nb * pixels))
    if "flags" in names:  # the clipping counts: a masked copy, its test, and the low and high masks
        after.append(Allocation("clipping masks", 4 * BYTE * nb * pixels))
    if analysed and "reflectance" in names:
        after.append(Allocation("analysed bands' gather", real * analysed * pixels))
    after = [max(after, key=lambda a: a.fixed)] if after else []  # one after the other
    return [*held, *max([at_launch, after], key=total)]


def in_memory_footprint(scene: Scene, n_spectra: int, *, copies: int | None = None, device_memory: bool = True,
                        baseline: bool = True, dataset: bool = True) -> SimulateFootprint:
    """The footprint of ``s2cl.simulate`` (:meth:`s2cl.forward.simulate.Simulator.run_library`) of ``n_spectra``
    × ``copies`` (default the scene's): the library, its band radiance and every pixel's outputs held, a chunk as
    ``s2cl simulate``'s (no summary) or the clipping counts' masks over every pixel; with ``dataset``, then
    :meth:`~s2cl.forward.simulate.LibrarySimulation.to_dataset` (the outputs laid out again, one of them twice at
    once, and four int64 maps of the image's pixels)."""
    c = scene.run.copies if copies is None else copies
    nb, grid, n = scene.sensor.size, scene.grid.size, n_spectra * c
    real = np.dtype(scene.run.precision).itemsize
    stages = chain(scene.effects)
    names = {a.name for a in sense_args(stages) if a.kind == "out"}
    outs = [b for b in sense_buffers(stages, nb, real) if b.name in names]
    held = [Allocation("baseline", BASELINE_BYTES if baseline else 0.0),
            Allocation("library (float64)", F64 * n_spectra * grid),
            Allocation("library in the working precision", real * n_spectra * grid),
            Allocation("band radiance", real * nb * n_spectra),
            *[Allocation(f"{b.name} (every pixel)", b.per_unit * n) for b in outs]]
    phases = [sense_chunk(scene, chunk_pixels(n_spectra, c), device_memory=device_memory, summary=False)]
    if "flags" in names:
        phases.append([Allocation("clipping masks (every pixel)", 4 * BYTE * nb * n)])
    if dataset and outs:
        phases.append([*[Allocation(f"{b.name} (dataset)", b.per_unit * n) for b in outs],
                       Allocation("dataset's largest output again", max(b.per_unit for b in outs) * n),
                       Allocation("image maps (int64)", 4 * F64 * n)])
    return SimulateFootprint(held, max(phases, key=total), [])


def analysis_arrays(checked: Checked, pixels: int, *, device_memory: bool) -> list[Allocation]:
    """The analysis of ``pixels`` after the chunks: the analysed bands' reflectance taken again (in the bands'
    order and then in the retrieval's), the float64 target, the retrieval's index (float64) and status, bounds and
    condition codes, its device buffers where they are the host's (the reflectance and the outputs), the
    non-finite pixels' masks and the metrics' row."""
    scene = checked.scene
    real = np.dtype(scene.run.precision).itemsize
    n_ab = len(checked.analysis_bands)
    classifies = checked.analysis is not None and checked.analysis.family.metric.classifies
    out = [Allocation("analysed reflectance (copies)", 2 * real * n_ab * pixels),
           Allocation("target (float64)", F64 * pixels),
           Allocation("retrieval outputs", (F64 + 3 * BYTE) * pixels),
           Allocation("non-finite masks", BYTE * (n_ab + 1) * pixels),
           Allocation("metrics (one row)", block_work_bytes(pixels, classifies=classifies) / ROW_BLOCK)]
    if device_memory:
        out.append(Allocation("retrieval buffers (device)", (real * n_ab + F64 + 3 * BYTE) * pixels))
    return out

