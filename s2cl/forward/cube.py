"""Image-cube simulation: a cube ``(rows, cols, wavelengths)`` → per-band images at each band's GSD.

Order of operations (the physical one, the chain of :mod:`s2cl.forward.stages`): spectra → band radiance at the
input GSD (SRFs, and the atmosphere when on) → each band's PSF and co-registration shift → box average over
``GSD_band / GSD_input`` input pixels → per-column non-uniformity → the per-pixel stages (noise, quantisation,
calibration, ...) at the band's own GSD (the SNR table refers to pixels of that size). Trailing rows/columns
that do not fill a whole output pixel are dropped.
Noise of band ``k`` at output pixel ``(y, x)`` keys on pixel index ``y · ncols + x`` of that
band's grid.

No-data (NaN or file-marked values, bad bands: :mod:`s2cl.io.cubes`) never refuses a cube: a pixel with
any no-data sample is NODATA and an output pixel whose footprint touches one is NODATA too
(:mod:`s2cl.forward.nodata` says why; a cube file's NODATA pixels are found block by block, as its rows are read
once for the simulation: the halo a block is read with holds every footprint of its output rows), flagged in every
band's ``flags_<band>`` variable (:attr:`s2cl.status.PixelFlag.NODATA`) with NaN radiance and reflectance.

The image may be simulated in blocks of rows (:mod:`s2cl.forward.row_blocks`, read with the halo of the spatial
filters, :func:`s2cl.forward.reach.cube_halo`) into a store (:mod:`s2cl.io.image_store`): the result is the
same, bit for bit. A generated cube (:mod:`s2cl.libraries.fields`) is simulated from its distinct spectra, each
pixel taking its spectrum's band radiance.

The scene's image effects (:mod:`s2cl.forward.instrument`) act inside this chain: the smile at the SRFs
(node bands, interpolated per column), each band's PSF and shift before its box average (finite filters: blocks
are read with their halo, and the NODATA footprint is their support, :mod:`s2cl.forward.reach`), the detector
non-uniformity per column after it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from s2cl.atmos.correction import BandAtmosphere
from s2cl.cl.runtime import Runtime
from s2cl.errors import InputError
from s2cl.forward.dataset import CONVENTIONS, PIXEL_VARIABLES, RADIANCE_UNITS, band_attrs, pixel_attrs
from s2cl.forward.grid_interpolation import GridInterpolation, on_grid
from s2cl.forward.instrument import FWHM_TO_SIGMA, Instrument, SmileResampler, spatial_response
from s2cl.forward.nodata import check_bad_band_gaps, footprint_nodata, gap_weights, nodata_rows
from s2cl.forward.parts import ChainParts, ResolvedCube
from s2cl.forward.radiometry import Radiometry
from s2cl.forward.reach import band_groups, cube_halo, gsd_factor
from s2cl.forward.row_blocks import RowBlock, box_mean, row_blocks
from s2cl.forward.run_attrs import run_attrs
from s2cl.forward.sense import Sensing
from s2cl.forward.simulate import Progress, Simulator
from s2cl.forward.stages import band_attrs as stage_attrs
from s2cl.forward.stages import senses
from s2cl.grid import SpectralGrid, check_wavelengths
from s2cl.io.cubes import CubeReader, cube_size, load_cube
from s2cl.io.georef import GeoRef, georef_attrs, grid_dimensions, product_attrs
from s2cl.io.image_store import ImageStore, MemoryStore, NetcdfStore
from s2cl.libraries.fields import fields_image
from s2cl.libraries.library import resample_to_grid
from s2cl.sensor.sensor import Sensor
from s2cl.status import PixelFlag

if TYPE_CHECKING:
    import xarray as xr  # the in-memory result's type; xarray is imported where one is built

__all__ = ["FWHM_TO_SIGMA", "SceneCube", "aggregate", "cube_in_memory", "cube_size", "load_cube", "open_scene_cube",
           "simulate_cube", "to_grid"]


def to_grid(cube: np.ndarray, wavelengths_nm: np.ndarray | None, grid: SpectralGrid, source: str | None, *,
            owned: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The cube's spectra ``(rows·cols, grid.size)`` on the grid (interpolated if needed), finite, and the
    NODATA mask ``(rows·cols,)`` of the pixels with any non-finite sample (their spectra set to 0).

    :param owned: ``cube`` may be changed in place (a cube just read from a file); else it is copied first
        when a pixel must be zeroed."""
    cube = np.asarray(cube)
    if cube.ndim != 3:
        raise InputError(f"a cube needs shape (rows, cols, wavelengths), got {cube.shape}", source=source)
    rows, cols, nw = cube.shape
    flat = cube.reshape(rows * cols, nw)
    if wavelengths_nm is None:
        if nw != grid.size:
            raise InputError(f"cube has {nw} wavelengths but the grid {grid.describe()} has {grid.size}; "
                             "give the cube's wavelengths or match the grid", source=source)
        w = grid.wavelengths
    else:
        w = check_wavelengths(wavelengths_nm, source=source)
        if w.size != nw:
            raise InputError(f"{w.size} wavelengths for a cube with {nw} spectral samples", source=source)
    nodata, flat = _zero_nodata(flat, owned)
    if on_grid(w, grid):
        return flat, nodata
    return resample_to_grid(w, flat, grid, source=source), nodata


def _zero_nodata(flat: np.ndarray, owned: bool) -> tuple[np.ndarray, np.ndarray]:
    """NODATA mask of ``flat`` and ``flat`` with those rows zeroed (a copy unless ``owned``)."""
    nodata = nodata_rows(flat)
    if nodata.any():
        if not owned:
            flat = flat.copy()
        flat[nodata] = 0
    return nodata, flat


def aggregate(image: np.ndarray, factor: int, psf_fwhm: float | None = None) -> np.ndarray:
    """Box average of ``factor × factor`` blocks (after an optional Gaussian PSF of FWHM ``psf_fwhm`` output
    pixels, the one PSF filter of :func:`s2cl.forward.instrument.spatial_response`); trailing partial blocks are
    dropped."""
    if psf_fwhm:
        image = spatial_response(image, psf_fwhm * factor * FWHM_TO_SIGMA, 0.0, 0.0)
    if image.shape[0] < factor or image.shape[1] < factor:
        raise InputError(
            f"cube of {image.shape[0]}×{image.shape[1]} pixels is smaller than one {factor}×{factor} block")
    return box_mean(image, factor)


@dataclass(frozen=True, eq=False)
class SceneCube:
    """A scene's cube, checked and on the scene's grid: spectra ``(rows·cols, grid.size)``, finite (zero at NODATA
    pixels), and the NODATA mask ``(rows·cols,)``; or (a generated cube, :mod:`s2cl.libraries.fields`) its
    distinct spectra ``(n, grid.size)`` with ``labels`` ``(rows·cols,)`` naming each pixel's spectrum;
    ``truth_params``: the parameters of each distinct spectrum where the cube knows them, and ``parcels``
    ``(rows, cols)``, the id of the uniform parcel each pixel lies in (None for a cube read from a file). A cube
    file streams: ``spectra`` and ``nodata`` are None and ``read_rows`` gives a band of rows' spectra and NODATA mask,
    read from the file when asked (:meth:`block`): on the grid, or (``interpolation`` given: a file whose wavelengths
    are not the grid's) at the file's own wavelengths, which the resampling kernel puts on the grid."""

    spectra: np.ndarray | None
    rows: int
    cols: int
    source: str
    nodata: np.ndarray | None = None
    labels: np.ndarray | None = None
    truth_params: dict[str, np.ndarray] = field(default_factory=dict)
    parcels: np.ndarray | None = None
    read_rows: Callable[[int, int], tuple[np.ndarray, np.ndarray]] | None = None
    #: the cube's grid on the map (None: it has none) and what its reader says about it (:func:`product_attrs`)
    georef: GeoRef | None = None
    product: dict[str, Any] = field(default_factory=dict)
    #: :meth:`block`'s spectra are at the file's wavelengths, and this table puts them on the grid (None: on the grid)
    interpolation: GridInterpolation | None = None
    #: the cube's ground sampling distance (m)
    gsd_m: float | None = None

    def block(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Spectra ``((stop-start)·cols, grid.size)`` of rows ``start … stop-1`` (a file's, read now; zero at NODATA
        pixels), or ``((stop-start)·cols, interpolation.n_native)`` at the file's wavelengths (:attr:`interpolation`:
        for the resampling kernel, which interpolates them); and their NODATA mask ``((stop-start)·cols,)``."""
        if self.read_rows is not None:
            return self.read_rows(start, stop)
        assert self.spectra is not None and self.labels is None
        rows = slice(start * self.cols, stop * self.cols)
        nodata = np.zeros(rows.stop - rows.start, bool) if self.nodata is None else self.nodata[rows]
        return self.spectra[rows], nodata

    def knows(self, name: str) -> bool:
        """Whether the cube knows the true ``name`` of its pixels."""
        return self.labels is not None and name in self.truth_params

    def truth(self, name: str, rows: slice = slice(None)) -> np.ndarray | None:
        """The true ``name`` of each pixel of ``rows`` ``(n_rows, cols)``, or None when the cube does not know it."""
        if not self.knows(name):
            return None
        return self.truth_params[name][self.labels.reshape(self.rows, self.cols)[rows]]


def open_scene_cube(cube: ResolvedCube, parts: ChainParts) -> SceneCube:
    """A scene's cube resolved from its metadata (:class:`~s2cl.forward.parts.ResolvedCube`: a file opened, or a
    generated cube) made ready for :func:`simulate_cube`, with every check done before anything is written: a file's
    bad bands against the bands' SRFs, a first pixel read, and the cube larger than one block of each GSD group. A
    file's rows are read later, block by block (:meth:`SceneCube.block`)."""
    sensor, grid = parts.sensor, parts.grid
    reader = cube.reader
    if reader is None:
        assert cube.builtin is not None
        generated = fields_image(grid, cube.rows, cube.cols, parts.run.seed)
        _check_blocks(cube.rows, cube.cols, sensor, cube.gsd_m, cube.source)
        lib = generated.library
        return SceneCube(lib.spectra, cube.rows, cube.cols, cube.source, labels=generated.labels.reshape(-1),
                         truth_params={k: lib.params[k] for k in ("cab", "lai")}, parcels=generated.parcels,
                         gsd_m=cube.gsd_m)
    source = cube.source
    if reader.bad_nm.size:
        weights = [b.weights(grid, parts.run.support) for b in sensor.bands]
        check_bad_band_gaps([b.name for b in sensor.bands],
                            gap_weights(weights, grid, reader.wavelengths_nm, reader.bad_nm), cube.quantity, source,
                            reader.bad_bands_by)
    to_grid(reader.read(0, 1)[:, :1], reader.wavelengths_nm, grid, source)  # it reads, before any output
    _check_blocks(reader.rows, reader.cols, sensor, cube.gsd_m, source)
    interpolation = GridInterpolation.covering(reader.wavelengths_nm, grid, source) if cube.interpolates else None
    return SceneCube(None, reader.rows, reader.cols, source, georef=reader.georef, product=product_attrs(reader),
                     read_rows=_file_rows(reader, grid, source, interpolation), interpolation=interpolation,
                     gsd_m=cube.gsd_m)


def cube_in_memory(cube: np.ndarray, wavelengths_nm: np.ndarray | None, grid: SpectralGrid, sensor: Sensor,
                   gsd_m: float | None) -> SceneCube:
    """A cube ``(rows, cols, wavelengths)`` given in memory (NaN marks no data; ``wavelengths_nm`` None: the grid's)
    put on ``grid``, checked as :func:`open_scene_cube` checks a file's (errors name the key, not a file)."""
    rows, cols = np.asarray(cube).shape[:2]
    spectra, nodata = to_grid(cube, wavelengths_nm, grid, None)
    if gsd_m is None:
        raise InputError("an image cube needs surface.gsd_m", key="surface.gsd_m")
    _check_blocks(rows, cols, sensor, gsd_m, None)
    return SceneCube(spectra, rows, cols, "", nodata if nodata.any() else None, gsd_m=gsd_m)


def _check_blocks(rows: int, cols: int, sensor: Sensor, gsd_in: float, source: str | None) -> None:
    """Refuse a cube smaller than one band pixel of a GSD group (or with a GSD that is no whole fraction of a
    band's)."""
    bands = sensor.bands
    for gsd in sorted({b.gsd_m for b in bands}):
        factor = gsd_factor(gsd, gsd_in, [b.name for b in bands if b.gsd_m == gsd])
        if factor > 1 and (rows < factor or cols < factor):
            raise InputError(f"cube of {rows}×{cols} pixels is smaller than one {factor}×{factor} block of the "
                             f"{gsd:g} m bands", source=source, key="surface.gsd_m")


def _file_rows(reader: CubeReader, grid: SpectralGrid, source: str,
               interpolation: GridInterpolation | None) -> Callable[[int, int], tuple[np.ndarray, np.ndarray]]:
    """Rows ``start … stop-1`` of a cube file read, zero at NODATA pixels: put on the grid (:func:`to_grid`), or
    (``interpolation`` given) at the file's wavelengths ``(pixels, bands)``; and their NODATA mask ``(pixels,)``."""
    def read_rows(start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        values = reader.read(start, stop)
        if interpolation is None:
            return to_grid(values, reader.wavelengths_nm, grid, source, owned=True)
        nodata, flat = _zero_nodata(values.reshape(-1, values.shape[-1]), owned=True)
        return flat, nodata
    return read_rows


def simulate_cube(rt: Runtime, parts: ChainParts, cube: SceneCube, *, progress: Progress | None = None,
                  store: ImageStore | None = None, block_rows: int | None = None) -> xr.Dataset | None:
    """Simulate an image cube (:func:`open_scene_cube`, :func:`cube_in_memory`) through the chain's ``parts`` on
    ``rt``: a Dataset, or (``store`` given) nothing, its variables written into ``store``. ``block_rows``: input
    rows simulated at a time (:func:`s2cl.forward.row_blocks.row_blocks`; default all), read with the spatial
    filters' halo (:func:`s2cl.forward.reach.cube_halo`), so the result does not depend on it."""
    prepared = cube
    rows, cols = prepared.rows, prepared.cols
    gsd_in = prepared.gsd_m
    assert gsd_in is not None
    sim = Simulator.of(rt, parts, interpolation=prepared.interpolation)
    instrument = Instrument.of(parts.settings, parts.run.seed, parts.sensor.bands)
    smile = (SmileResampler(sim.rt, parts, cols, prepared.interpolation)
             if instrument.smile_spec is not None else None)
    band_values = smile.nodes if smile is not None else sim.band_radiance  # per band (or smile node), per pixel
    out = store if store is not None else MemoryStore()
    out.attrs.update({**CONVENTIONS, **run_attrs(parts, sim.rt.name, image=True), "input_gsd_m": gsd_in,
                      "psf": "none" if instrument.psf is None else "gaussian",
                      "nodata_input_pixels": 0, "instrument": instrument.describe()})  # counted as read
    out.attrs.update(georef_attrs(prepared.georef, prepared.product))
    by_gsd = band_groups(parts.sensor, gsd_in)
    groups = [_Group(parts, sim, factor, ids, rows, cols, out, instrument, prepared.georef) for factor, ids in by_gsd]
    nodata_pixels = 0
    halo = cube_halo(instrument, by_gsd)
    distinct = band_values(prepared.spectra) if prepared.labels is not None else None
    labels = None if prepared.labels is None else prepared.labels.reshape(rows, cols)
    for block in row_blocks(rows, [g.factor for g in groups], block_rows, halo):
        lo, hi = block.read_start, block.read_stop
        if labels is not None:  # a generated cube: each pixel takes its spectrum's band radiance
            radiance = distinct[:, labels[lo:hi]]
            nodata = np.zeros((hi - lo, cols), bool)
        else:
            spectra, mask = prepared.block(lo, hi)  # a file's rows: read once, NODATA found as they are
            radiance = band_values(spectra).reshape(-1, hi - lo, cols)
            nodata = mask.reshape(hi - lo, cols)
        nodata_pixels += int(nodata[block.start - lo : block.stop - lo].sum())
        if smile is not None:  # each column's bands from the smile's node bands
            radiance = smile.combine(radiance)
        for g in groups:
            g.add(block, radiance, nodata)
        spectra = radiance = None  # this block's arrays go before the next block is read
        if progress:
            progress((block.stop - block.start) * cols)
    for g in groups:
        g.finish()
    out.attrs["nodata_input_pixels"] = nodata_pixels
    return out.dataset() if store is None else None


class _Group:
    """The bands of one GSD: their dimensions, compiled radiometric stage and variables, filled block by block."""

    def __init__(self, parts: ChainParts, sim: Simulator, factor: int, ids: list[int], rows: int, cols: int,
                 store: MemoryStore | NetcdfStore, instrument: Instrument, georef: GeoRef | None = None):
        bands = parts.sensor.bands
        gsd = bands[ids[0]].gsd_m
        self.parts, self.store, self.gsd, self.instrument = parts, store, gsd, instrument
        self.ids, self.factor = ids, factor
        ny, nx = rows // self.factor, cols // self.factor
        self.nx = nx
        self.dims = (f"y_{gsd:g}m", f"x_{gsd:g}m")
        grid_dimensions(store, self.dims, georef, factor, gsd, ny, nx)  # x/y and the CF grid mapping
        self.sensing = None
        if senses(parts.effects):
            correction = None
            if sim.correction is not None:
                c, i = sim.correction, self.ids
                correction = BandAtmosphere(c.path_radiance[i], c.ground_term[i], c.spherical_albedo[i])
            radiometry = Radiometry.of([bands[k] for k in self.ids], parts.sensor.bits, self.ids,
                                       correction=correction, settings=parts.settings, seed=parts.run.seed)
            self.sensing = Sensing(sim.rt, radiometry, parts.effects, sim.precision)
        #: what the per-pixel stages did to each band (attributes of its variables)
        self.stage_attrs = [stage_attrs(self.sensing.stages, self.sensing.radiometry, j) if self.sensing else {}
                            for j in range(len(ids))]
        #: input pixels on each side that the spatial filters reach (:meth:`Instrument.reach`)
        self.reach = instrument.reach(self.ids, self.factor)
        #: pixels below Lmin, above Lmax (no-data pixels apart) and NODATA, per band
        self.counts = np.zeros((3, len(self.ids)), np.int64)

    def add(self, block: RowBlock, radiance: np.ndarray, nodata: np.ndarray) -> None:
        """Sense this group's output rows of ``block`` from ``radiance`` ``(n_bands, read rows, cols)`` and the
        NODATA mask ``(read rows, cols)`` of the input pixels: an output pixel whose footprint (box and the spatial
        filters' support) holds one is NODATA (:func:`s2cl.forward.nodata.footprint_nodata`; the block's halo holds
        every such footprint)."""
        f, out_rows = self.factor, block.output_rows(self.factor)
        ny = out_rows.stop - out_rows.start
        if ny <= 0:
            return
        top = block.start - block.read_start
        spatial = self.instrument.spatial
        images = np.stack([box_mean(spatial(radiance[k], k, f)[top : top + ny * f], f) for k in self.ids])
        images = self.instrument.columns(images[:, :, : self.nx], self.ids)
        nodata = footprint_nodata(nodata, f, self.reach, top, ny)[:, : self.nx]
        images[:, nodata] = np.nan
        result = None
        if self.sensing is not None:
            result = self.sensing(images.reshape(len(self.ids), -1), seed=self.parts.run.seed,
                                  frame=self.parts.run.frame, pixel_offset=out_rows.start * self.nx)
        flags = result.flags if result is not None and result.flags is not None else None
        if flags is not None:
            self.counts[0] += np.count_nonzero(flags & PixelFlag.LOW, axis=1)
            self.counts[1] += np.count_nonzero(flags & PixelFlag.HIGH, axis=1)
        else:  # no radiometric stage: the flags say NODATA alone
            flags = np.where(nodata.reshape(1, -1), np.uint8(PixelFlag.NODATA), np.uint8(0)).repeat(len(self.ids), 0)
        self.counts[2] += np.count_nonzero(flags & PixelFlag.NODATA, axis=1)
        bands = self.parts.sensor.bands
        for j, k in enumerate(self.ids):
            attrs = {**band_attrs(bands[k], self.parts.sensor.bits), **self.stage_attrs[j]}
            name = bands[k].name
            self._put(f"radiance_{name}", out_rows, images[j],
                      {**attrs, **pixel_attrs("radiance", RADIANCE_UNITS, "noise-free band radiance")})
            self._put(f"flags_{name}", out_rows, flags[j].reshape(ny, self.nx),
                      {**attrs, **pixel_attrs("flags", "1", "radiometric pixel flags")})
            if result is None:
                continue
            for var, units, long_name in PIXEL_VARIABLES:
                arr = getattr(result, var)
                if arr is not None and var != "flags":
                    self._put(f"{var}_{name}", out_rows, arr[j].reshape(ny, self.nx),
                              {**attrs, **pixel_attrs(var, units, long_name)})

    def _put(self, name: str, rows: slice, data: np.ndarray, attrs: dict) -> None:
        if name not in self.store:
            self.store.create(name, self.dims, data.dtype, attrs)
        self.store.write(name, rows, data)

    def finish(self) -> None:
        """The clipping and no-data counts, once every block is in (no-data pixels are counted as such, not as
        clipped below Lmin)."""
        flagged = self.sensing is not None and "flags" in self.sensing.outputs
        for j, k in enumerate(self.ids):
            counts: dict = {"nodata_pixels": int(self.counts[2, j]), **self.instrument.band_attrs(k)}
            if flagged:
                counts.update(clipped_below_lmin=int(self.counts[0, j]), clipped_above_lmax=int(self.counts[1, j]))
            self.store.update_attrs(f"radiance_{self.parts.sensor.bands[k].name}", counts)
