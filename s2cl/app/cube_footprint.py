"""The host memory of ``s2cl simulate`` on an image cube (:func:`s2cl.app.simulate_scene.cube_block_rows`), from
what it allocates: each array's dtype itemsize times the shape it has, and the resampling and sense kernels' declared
buffers (:func:`s2cl.forward.resample.resample_buffers`, :func:`s2cl.forward.sense.sense_buffers`; on PoCL's CPU
devices they are the host's arrays, written in place). Each is an :class:`~s2cl.io.budget.Allocation` of fixed bytes.

A run holds ``whole`` throughout: a generated cube's labels and parcel ids (int32), the library it draws from
(float64) and its band values, and the analysis' map, status, bounds and flags on its common grid. On top of it, the
largest of

- a block of rows (:meth:`CubeFootprint.block`), per input pixel read (the block and its halo): a file's samples as
  read (the mapped pages and their float copy), their non-finite test, the spectra put on the grid (float64) unless
  they are its samples or the resampling kernel interpolates them, the resampling launch's buffers, the band values
  (the smile's node bands and their combination) and the NODATA mask; then the largest GSD group's arrays
  (:meth:`CubeFootprint.group`), with the analysis bands' rows the analysis keeps until every band holds them;
- a generated cube's opening (its library's pieces concatenated), or the analysis' finish over its common grid
  (the calibration's float64 pieces and their concatenation, its masks);
- the quicklook (:func:`quicklook_arrays`): panels of at most ``MAX_SIDE²`` pixels.

``tests/test_cube_footprint.py`` measures runs (resident set and numpy's allocations, in a child process) against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.app.image_quicklook import MAX_SIDE
from s2cl.app.simulate_footprint import sense_chunk, total
from s2cl.forward import grid_interpolation
from s2cl.forward.instrument import Instrument, Smile
from s2cl.forward.parts import ResolvedCube
from s2cl.forward.reach import band_groups
from s2cl.forward.resample import resample_buffers
from s2cl.forward.sense import sense_args, sense_buffers
from s2cl.forward.stages import chain
from s2cl.io.budget import Allocation, most_fitting
from s2cl.libraries.fields import fields_library
from s2cl.retrieve.metrics import ROW_BLOCK, block_work_bytes
from s2cl.scene.scene import Scene

#: bytes of a float64 value (a file's samples as read, spectra on the grid, the PSF's work, the calibration)
F64 = np.dtype(np.float64).itemsize
#: bytes of an int32 value (a generated cube's labels and parcel ids: :func:`s2cl.libraries.fields.fields_image`)
I32 = np.dtype(np.int32).itemsize
#: bytes of a bool or uint8 value (masks, flags, the analysis' status and bounds)
BYTE = np.dtype(np.uint8).itemsize
#: bytes of the analysis map's value (float32)
F32 = np.dtype(np.float32).itemsize
#: bytes per pixel of an RGBA image that matplotlib resamples a panel into (float64) and draws (uint8)
RGBA_F64, RGBA_U8 = 4 * F64, 4 * BYTE


@dataclass(frozen=True)
class GroupShape:
    """One GSD group of an image's bands: ``factor`` input pixels a side per band pixel, ``bands`` of them,
    ``analysed`` of them analysis bands."""

    factor: int
    bands: int
    analysed: int


@dataclass(frozen=True)
class CubeFootprint:
    """``whole``: held through the run; ``per_pixel``: per input pixel of a block as read (its halo included) before
    its GSD groups; ``groups``: the groups the block is sensed in, one after the other; ``finish``: the largest of
    what is apart from the blocks (a generated cube's opening, the analysis' finish, the quicklook) (bytes)."""

    scene: Scene
    cols: int
    whole: list[Allocation]
    per_pixel: list[Allocation]
    groups: list[GroupShape]
    finish: list[Allocation]
    spatial: bool
    device_memory: bool

    def block(self, read_rows: int) -> list[Allocation]:
        """A block of ``read_rows`` input rows (halo included) at its peak: its arrays per input pixel, and the largest
        group's (:meth:`group`) with the analysis bands' rows the analysis keeps of every group."""
        pixels = read_rows * self.cols
        kept = sum((self.real + BYTE) * g.bands * self.out_pixels(g, read_rows) for g in self.groups if g.analysed)
        largest = max((self.group(g, read_rows) for g in self.groups), key=total)
        return [*[Allocation(a.name, a.fixed * pixels) for a in self.per_pixel], *largest,
                *([Allocation("analysis bands' rows kept (reflectance and flags)", kept)] if kept else [])]

    @property
    def real(self) -> int:
        return np.dtype(self.scene.run.precision).itemsize

    def out_pixels(self, g: GroupShape, read_rows: int) -> int:
        """Band pixels of group ``g`` in ``read_rows`` input rows (at most)."""
        return (read_rows // g.factor) * (self.cols // g.factor)

    def group(self, g: GroupShape, read_rows: int) -> list[Allocation]:
        """Group ``g`` of a block: one band's PSF work (float64, and its copy in the working precision) and the sense
        chunk of its band pixels (:func:`~s2cl.app.simulate_footprint.sense_chunk`: its images, the stages' outputs
        and one launch's buffers, or the clipping counts' masks)."""
        work = [Allocation("PSF work (float64 and its copy)", (F64 + self.real) * read_rows * self.cols)]
        return [*(work if self.spatial else []),
                Allocation("band images before their stack", self.real * g.bands * self.out_pixels(g, read_rows)),
                *sense_chunk(self.scene, self.out_pixels(g, read_rows), device_memory=self.device_memory,
                             summary=False, bands=g.bands)]

    def peak(self, read_rows: int) -> float:
        """Bytes at the run's peak with blocks of ``read_rows`` input rows read at a time (halo included)."""
        return total(self.whole) + max(total(self.block(read_rows)), total(self.finish))


def cube_footprint(sc: Scene, rows: int, cols: int, wavelengths: int = 0, interpolated: bool = False,
                   analysis_bands: list[str] | tuple[str, ...] = (), *, on_grid: bool = False,
                   device_memory: bool = True) -> CubeFootprint:
    """The footprint of simulating the scene's ``rows × cols`` cube (``wavelengths`` per pixel in its file; 0:
    generated; ``interpolated``: the resampling kernel puts the file's own samples on the grid; ``on_grid``: they are
    the grid's, used as read), with an analysis on ``analysis_bands`` (none: no analysis); ``device_memory``: the
    kernels' buffers are the host's (PoCL's CPU devices), counted once as the host arrays they are."""
    nb, grid = sc.sensor.size, sc.grid.size
    real = np.dtype(sc.run.precision).itemsize
    gsd_in = sc.spec.surface.gsd_m or 1.0
    instrument = Instrument.of(sc.spec.effects, sc.run.seed, sc.sensor.bands)
    values = nb
    if instrument.smile_spec is not None:
        centres, widths = Smile.of(instrument.smile_spec, cols).node_grid()
        values = nb * len(centres) * len(widths)
    whole, opening = [], []
    if not wavelengths:
        n_lib = fields_library(sc.grid).size  # what the generated cube draws from (its spectra are read by the run)
        whole += [Allocation("labels (int32)", I32 * rows * cols), Allocation("parcel ids (int32)", I32 * rows * cols),
                  Allocation("fields library (float64)", F64 * n_lib * grid),
                  Allocation("its distinct band values", real * values * n_lib)]
        opening = [Allocation("fields library's pieces, before their concatenation", F64 * n_lib * grid)]
    common = 0
    if analysis_bands:
        f = round(max(sc.sensor.band(b).gsd_m for b in analysis_bands) / gsd_in)
        common = (rows // f) * (cols // f)
        whole.append(Allocation("analysis map (float32), status, bounds and flags (uint8)", (F32 + 3 * BYTE) * common))
    per_pixel: list[Allocation] = []
    if wavelengths:
        samples = wavelengths if interpolated else grid
        per_pixel += [Allocation("samples as read (mapped pages and their float64 copy)", 2 * F64 * wavelengths),
                      Allocation("non-finite test", BYTE * wavelengths)]
        if not interpolated and not on_grid:
            per_pixel.append(Allocation("spectra on the grid (float64)", F64 * grid))
        declared = resample_buffers(values, grid, real, atmosphere=True, n_samples=samples if interpolated else None)
        launch = sum(b.per_unit for b in declared)  # the host's arrays, written in place, on CPU devices
        if not device_memory:  # the host's copy in the working precision and the fetched band values
            launch = real * (samples + values)
        per_pixel.append(Allocation("resampling launch (its declared buffers)", launch))
    else:
        per_pixel.append(Allocation("band values taken by label", real * values))
    if values != nb:
        per_pixel.append(Allocation("smile's bands combined", real * nb))
    per_pixel.append(Allocation("NODATA mask", BYTE))
    analysed = set(analysis_bands)
    groups = [GroupShape(factor, len(ids), sum(sc.sensor.bands[k].name in analysed for k in ids))
              for factor, ids in band_groups(sc.sensor, sc.spec.surface.gsd_m)]
    apart = [opening, *([analysis_finish(common), quicklook_arrays(4)] if analysis_bands else [])]
    finish = max(apart, key=total)
    return CubeFootprint(sc, cols, whole, per_pixel, groups, finish, instrument.spatial_on, device_memory)


def analysis_finish(common: int) -> list[Allocation]:
    """The analysis' finish over ``common`` pixels of its grid: the regression and finite masks, the calibration's
    float64 index and truth and uint8 bounds (the rows' pieces and their concatenation) and the regression's work
    for its one row (:func:`s2cl.retrieve.metrics.block_work_bytes`)."""
    return [Allocation("analysis masks", 3 * BYTE * common),
            Allocation("calibration (pieces and concatenation)", 2 * (2 * F64 + BYTE) * common),
            Allocation("calibration's regression (one row)", block_work_bytes(common, classifies=False) / ROW_BLOCK)]


def quicklook_arrays(panels: int) -> list[Allocation]:
    """The quicklook of ``panels`` panels of at most ``MAX_SIDE²`` pixels: each read as float64, resampled into
    float64 RGBA and drawn into uint8 RGBA, and the true colour's three channels, their stack and its stretch."""
    side = MAX_SIDE * MAX_SIDE
    return [Allocation("panels (float64, RGBA float64 and uint8)", panels * (F64 + RGBA_F64 + RGBA_U8) * side),
            Allocation("true colour (channels, stack, stretch)", 4 * 3 * F64 * side)]


def block_rows_fitting(fp: CubeFootprint, room: float, unit: int, halo: int, rows: int) -> int:
    """The most input rows of a block, a multiple of ``unit`` (0: not even ``unit`` rows fit), whose run's peak with
    the block read with ``halo`` rows on each side fits in ``room`` bytes."""
    return unit * most_fitting(lambda n: fp.peak(n * unit + 2 * halo) <= room, -(-rows // unit))


def cube_disk_bytes(sc: Scene, rows: int, cols: int, *, cog: bool = False) -> float:
    """Bytes ``simulation.nc`` holds at most for a ``rows × cols`` cube, from the variables the writer makes per band
    and input pixel (an upper bound: a band's pixels are its GSD's): the radiance in the working precision and each
    output of the sense kernel in its declared type (:func:`~s2cl.forward.sense.sense_args`); with ``cog``, a COG of
    each band's radiance and its strips (float32) at once."""
    real = np.dtype(sc.run.precision).itemsize
    stages = chain(sc.effects)
    outs = {a.name for a in sense_args(stages) if a.kind == "out"}
    per_band = real + sum(b.per_unit for b in sense_buffers(stages, 1, real) if b.name in outs)
    if "flags" not in outs:  # the flags variable is written without the radiometric stage too (uint8)
        per_band += BYTE
    if cog:
        per_band += 2 * F32
    return float(rows * cols * per_band * sc.sensor.size)


def samples_on_grid(cube: ResolvedCube) -> bool:
    """Whether ``cube``'s file holds its spectra at the grid's wavelengths (they are used as read)."""
    return cube.reader is not None and grid_interpolation.on_grid(cube.reader.wavelengths_nm, cube.grid)
