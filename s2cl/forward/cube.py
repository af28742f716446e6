"""Image-cube simulation: a cube ``(rows, cols, wavelengths)`` → per-band images at each band's GSD.

Order of operations (the physical one): spectra → band radiance at the input GSD (SRFs, and the
atmosphere when on) → optional Gaussian PSF → box average over ``GSD_band / GSD_input`` input
pixels → noise → quantisation → calibration at the band's own GSD (the SNR table refers to
pixels of that size). Trailing rows/columns that do not fill a whole output pixel are dropped.
Noise of band ``k`` at output pixel ``(y, x)`` keys on pixel index ``y · ncols + x`` of that
band's grid. The image may be simulated in blocks of rows (:mod:`s2cl.forward.row_blocks`, read with the PSF's
halo) into a store (:mod:`s2cl.io.image_store`): the result is the same. A generated cube
(:mod:`s2cl.libraries.fields`) is simulated from its distinct spectra, each pixel taking its spectrum's band
radiance.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.ndimage import gaussian_filter

from s2cl.atmos.correction import BandAtmosphere
from s2cl.cl.runtime import Runtime
from s2cl.errors import InputError
from s2cl.forward.dataset import CONVENTIONS, PIXEL_VARIABLES, RADIANCE_UNITS, band_attrs, pixel_attrs
from s2cl.forward.row_blocks import RowBlock, box_mean, gaussian_radius, row_blocks
from s2cl.forward.sense import Radiometry, Sensing
from s2cl.forward.simulate import Progress, Simulator, scene_atmosphere
from s2cl.grid import SpectralGrid, check_wavelengths
from s2cl.io.envi import envi_data_file, envi_layout, read_envi_header
from s2cl.io.image_store import ImageStore, MemoryStore, NetcdfStore
from s2cl.io.inputs import input_file, parse_number
from s2cl.libraries.fields import fields_image, fields_shape, is_builtin_cube
from s2cl.libraries.library import check_finite, resample_to_grid
from s2cl.scene.scene import Scene
from s2cl.version import __version__

FWHM_TO_SIGMA = 1.0 / (2.0 * np.sqrt(2.0 * np.log(2.0)))


def load_cube(path: str | Path, variable: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A cube ``(rows, cols, wavelengths)`` and its wavelengths (nm) from NetCDF or ENVI.

    NetCDF: a 3-D variable with a ``wavelength`` dimension and coordinate (nm, or µm if its
    ``units`` say so). ENVI: the ``.hdr`` file, wavelengths from its ``wavelength`` field.
    """
    p = input_file(path, what="cube file")
    if p.suffix.lower() == ".hdr":
        return _load_envi(p)
    try:
        ds = xr.open_dataset(p, engine="h5netcdf")
    except Exception as err:  # h5netcdf/h5py raise many types for a bad file
        raise InputError(f"cannot read as NetCDF-4 ({type(err).__name__})", source=p) from err
    with ds:
        candidates = [n for n, v in ds.data_vars.items() if v.ndim == 3 and "wavelength" in v.dims]
        name = variable or (candidates[0] if len(candidates) == 1 else None)
        if name is None or name not in ds:
            raise InputError(f"choose the cube variable (surface.variable); 3-D variables with a 'wavelength' "
                             f"dimension: {candidates or 'none'}", source=p, key="surface.variable")
        v = ds[name]
        if "wavelength" not in v.dims or v.ndim != 3:
            raise InputError("needs 3 dimensions, one of them 'wavelength'", source=p, key=name)
        v = v.transpose(*[d for d in v.dims if d != "wavelength"], "wavelength")
        _real(v.dtype, p, name)
        wl = np.asarray(ds["wavelength"].values, dtype=np.float64)
        if str(ds["wavelength"].attrs.get("units", "nm")).lower() in ("um", "µm", "micrometer", "micrometers"):
            wl = wl * 1000.0
        return np.asarray(v.values), check_wavelengths(wl, source=str(p), key="wavelength")


def cube_size(path: str | Path) -> tuple[int, int]:
    """(pixels, wavelengths) of the cube at ``path`` from its metadata only (nothing is loaded);
    (0, 0) when a NetCDF file cannot tell (then :func:`load_cube` says what is wrong).

    :raises InputError: ``path`` is not a regular file, or an ENVI header's layout is wrong or lies
        about its data file (:func:`s2cl.io.envi.envi_layout`)."""
    p = input_file(path, what="cube file")
    if p.suffix.lower() == ".hdr":
        meta = read_envi_header(p)
        layout = envi_layout(meta, p, envi_data_file(p))
        _envi_wavelengths(meta, layout.bands, p)
        return layout.samples * layout.lines, layout.bands
    try:
        with xr.open_dataset(p, engine="h5netcdf") as ds:
            cubes = [v for v in ds.data_vars.values() if v.ndim == 3 and "wavelength" in v.dims]
            if not cubes:
                return 0, 0
            v = max(cubes, key=lambda c: c.size)
            return int(v.size // v.sizes["wavelength"]), int(v.sizes["wavelength"])
    except Exception:  # a bad file is reported by load_cube, with its reason
        return 0, 0


def _real(dtype: np.dtype, p: Path, key: str) -> None:
    """Refuse a cube of complex (or non-numeric) values: casting would drop the imaginary part silently."""
    if np.dtype(dtype).kind not in "fiu":
        raise InputError(f"holds {np.dtype(dtype)} values; a cube holds real numbers (radiance or reflectance)",
                         source=p, key=key)


def _envi_wavelengths(meta: dict, bands: int, p: Path) -> np.ndarray:
    """The header's ``wavelength`` list as numbers, one per band."""
    wl = meta.get("wavelength")
    if not wl:
        raise InputError("ENVI header has no 'wavelength' field", source=p, key="wavelength")
    if len(wl) != bands:
        raise InputError(f"lists {len(wl)} values for bands = {bands}", source=p, key="wavelength")
    try:
        return np.array([parse_number(str(x).strip()) for x in wl])
    except ValueError:
        raise InputError("holds a value that is not a number", source=p, key="wavelength") from None


def _load_envi(p: Path) -> tuple[np.ndarray, np.ndarray]:
    import spectral.io.envi as envi

    meta = read_envi_header(p)
    data = envi_data_file(p)
    layout = envi_layout(meta, p, data)
    w = _envi_wavelengths(meta, layout.bands, p)
    try:
        img = envi.open(str(p), str(data))
        cube = np.asarray(img.load())
    except Exception as err:  # SPy raises many types for a bad header or data file
        raise InputError(f"cannot read ENVI image ({type(err).__name__})", source=p) from err
    _real(cube.dtype, p, "data type")
    if str(meta.get("wavelength units", "nm")).lower().startswith(("micro", "um", "µm")):
        w *= 1000.0
    return cube, check_wavelengths(w, source=str(p), key="wavelength")


def to_grid(cube: np.ndarray, wavelengths_nm: np.ndarray | None, grid: SpectralGrid, source: str) -> np.ndarray:
    """The cube's spectra ``(rows·cols, grid.size)`` on the grid (interpolated if needed)."""
    cube = np.asarray(cube)
    if cube.ndim != 3:
        raise InputError(f"a cube needs shape (rows, cols, wavelengths), got {cube.shape}", source=source)
    rows, cols, nw = cube.shape
    flat = cube.reshape(rows * cols, nw)
    if wavelengths_nm is None:
        if nw != grid.size:
            raise InputError(f"cube has {nw} wavelengths but the grid {grid.describe()} has {grid.size}; "
                             "give the cube's wavelengths or match the grid", source=source)
        check_finite(flat, source=source)
        return flat
    w = check_wavelengths(wavelengths_nm, source=source)
    if w.size != nw:
        raise InputError(f"{w.size} wavelengths for a cube with {nw} spectral samples", source=source)
    check_finite(flat, source=source)
    if w.size == grid.size and np.allclose(w, grid.wavelengths, atol=1e-6):
        return flat
    return resample_to_grid(w, flat, grid, source=source)


def aggregate(image: np.ndarray, factor: int, psf_fwhm: float | None = None) -> np.ndarray:
    """Box average of ``factor × factor`` blocks (after an optional Gaussian PSF of FWHM
    ``psf_fwhm`` output pixels); trailing partial blocks are dropped."""
    image = _psf(image, factor, psf_fwhm)
    if image.shape[0] < factor or image.shape[1] < factor:
        raise InputError(
            f"cube of {image.shape[0]}×{image.shape[1]} pixels is smaller than one {factor}×{factor} block")
    return box_mean(image, factor)


@dataclass(frozen=True, eq=False)
class SceneCube:
    """A scene's cube, checked and on the scene's grid: spectra ``(rows·cols, grid.size)``, or (a generated cube,
    :mod:`s2cl.libraries.fields`) its distinct spectra ``(n, grid.size)`` with ``labels`` ``(rows·cols,)`` naming
    each pixel's spectrum; ``truth_params``: the parameters of each distinct spectrum where the cube knows them,
    and ``parcels`` ``(rows, cols)``, the id of the uniform parcel each pixel lies in (None for a cube read from a
    file)."""

    spectra: np.ndarray
    rows: int
    cols: int
    source: str
    labels: np.ndarray | None = None
    truth_params: dict[str, np.ndarray] = field(default_factory=dict)
    parcels: np.ndarray | None = None

    def knows(self, name: str) -> bool:
        """Whether the cube knows the true ``name`` of its pixels."""
        return self.labels is not None and name in self.truth_params

    def truth(self, name: str, rows: slice = slice(None)) -> np.ndarray | None:
        """The true ``name`` of each pixel of ``rows`` ``(n_rows, cols)``, or None when the cube does not know it."""
        if not self.knows(name):
            return None
        return self.truth_params[name][self.labels.reshape(self.rows, self.cols)[rows]]


def scene_cube_size(scene: Scene) -> tuple[int, int]:
    """(pixels, wavelengths held per pixel) of the scene's cube from its metadata only: a generated cube holds
    no spectrum per pixel (0)."""
    cube = scene.spec.surface.cube
    assert cube is not None
    if is_builtin_cube(cube):
        rows, cols = fields_shape(cube, source=scene.source)
        return rows * cols, 0
    return cube_size(scene.resolve(cube))


def load_scene_cube(scene: Scene, cube: np.ndarray | None = None,
                    wavelengths_nm: np.ndarray | None = None) -> SceneCube:
    """The scene's ``surface.cube`` file (or ``cube`` given in memory) loaded onto the scene's grid, with
    every check of :func:`simulate_cube` done: ``s2cl simulate`` calls it before it creates the folder."""
    s = scene.spec
    source = scene.source
    generated = None
    if cube is None:
        if s.surface.cube is None:
            raise InputError("the scene has no surface.cube", source=source, key="surface.cube")
        if is_builtin_cube(s.surface.cube):
            rows, cols = fields_shape(s.surface.cube, source=source)
            generated = fields_image(scene.grid, rows, cols, scene.run.seed)
        else:
            cube, wavelengths_nm = load_cube(scene.resolve(s.surface.cube), s.surface.variable)
            source = str(scene.resolve(s.surface.cube))
    if generated is not None:
        spectra = generated.library.spectra
    else:
        rows, cols = np.asarray(cube).shape[:2]
        spectra = to_grid(cube, wavelengths_nm, scene.grid, source)
    gsd_in = s.surface.gsd_m
    if gsd_in is None:
        raise InputError("an image cube needs surface.gsd_m", source=scene.source, key="surface.gsd_m")
    bands = scene.sensor.bands
    for gsd in sorted({b.gsd_m for b in bands}):
        factor = _factor(gsd, gsd_in, [b.name for b in bands if b.gsd_m == gsd], scene.source)
        if factor > 1 and (rows < factor or cols < factor):
            raise InputError(f"cube of {rows}×{cols} pixels is smaller than one {factor}×{factor} block of the "
                             f"{gsd:g} m bands", source=source, key="surface.gsd_m")
    if generated is not None:
        lib = generated.library
        return SceneCube(spectra, rows, cols, source, generated.labels.reshape(-1),
                         {k: lib.params[k] for k in ("cab", "lai")}, generated.parcels)
    return SceneCube(spectra, rows, cols, source)


def simulate_cube(rt: Runtime, scene: Scene, cube: np.ndarray | SceneCube | None = None,
                  wavelengths_nm: np.ndarray | None = None, *, progress: Progress | None = None,
                  store: ImageStore | None = None, block_rows: int | None = None) -> xr.Dataset | None:
    """Simulate an image cube (the scene's ``surface.cube`` file, ``cube`` given in memory, or a cube
    already loaded by :func:`load_scene_cube`) on ``rt``: a Dataset, or (``store`` given) nothing, its variables
    written into ``store``. ``block_rows``: input rows simulated at a time (:func:`s2cl.forward.row_blocks.row_blocks`;
    default all), read with the PSF's halo, so the result does not depend on it."""
    s = scene.spec
    prepared = cube if isinstance(cube, SceneCube) else load_scene_cube(scene, cube, wavelengths_nm)
    rows, cols = prepared.rows, prepared.cols
    gsd_in = s.surface.gsd_m
    assert gsd_in is not None
    sim = Simulator.for_scene(rt, scene, atmosphere=scene_atmosphere(scene))
    psf = s.spatial.psf_fwhm if s.spatial.psf == "gaussian" else None
    out = store if store is not None else MemoryStore()
    out.attrs.update({**CONVENTIONS, "scene": scene.name, "s2cl_version": __version__, "device": sim.rt.name,
                      "effects": scene.effects.describe(), "seed": scene.run.seed, "input_gsd_m": gsd_in,
                      "psf": s.spatial.psf})
    groups = [_Group(scene, sim, gsd, gsd_in, rows, cols, out) for gsd in sorted({b.gsd_m for b in scene.sensor.bands})]
    halo = max(gaussian_radius(psf * g.factor * FWHM_TO_SIGMA) for g in groups) if psf else 0
    distinct = sim.band_radiance(prepared.spectra) if prepared.labels is not None else None
    labels = None if prepared.labels is None else prepared.labels.reshape(rows, cols)
    for block in row_blocks(rows, [g.factor for g in groups], block_rows, halo):
        lo, hi = block.read_start, block.read_stop
        if labels is not None:  # a generated cube: each pixel takes its spectrum's band radiance
            radiance = distinct[:, labels[lo:hi]]
        else:
            radiance = sim.band_radiance(prepared.spectra[lo * cols : hi * cols]).reshape(-1, hi - lo, cols)
        for g in groups:
            g.add(block, radiance, psf)
        if progress:
            progress((block.stop - block.start) * cols)
    for g in groups:
        g.finish()
    return out.dataset() if store is None else None


def _factor(gsd: float, gsd_in: float, names: list[str], source: str) -> int:
    ratio = gsd / gsd_in
    factor = round(ratio)
    if factor < 1 or abs(ratio - factor) > 1e-6:
        raise InputError(f"band GSD {gsd:g} m is not a whole multiple of the cube's GSD {gsd_in:g} m "
                         f"(bands {', '.join(names)})", source=source, key="surface.gsd_m")
    return factor


class _Group:
    """The bands of one GSD: their dimensions, compiled radiometric stage and variables, filled block by block."""

    def __init__(self, scene: Scene, sim: Simulator, gsd: float, gsd_in: float, rows: int, cols: int,
                 store: MemoryStore | NetcdfStore):
        bands = scene.sensor.bands
        self.scene, self.store, self.gsd = scene, store, gsd
        self.ids = [k for k, b in enumerate(bands) if b.gsd_m == gsd]
        self.factor = _factor(gsd, gsd_in, [bands[k].name for k in self.ids], scene.source)
        ny, nx = rows // self.factor, cols // self.factor
        self.nx = nx
        self.dims = (f"y_{gsd:g}m", f"x_{gsd:g}m")
        store.dimension(self.dims[0], (np.arange(ny) + 0.5) * gsd, {"units": "m"})
        store.dimension(self.dims[1], (np.arange(nx) + 0.5) * gsd, {"units": "m"})
        self.sensing = None
        if scene.effects.senses:
            correction = None
            if sim.correction is not None:
                c, i = sim.correction, self.ids
                correction = BandAtmosphere(c.path_radiance[i], c.ground_term[i], c.spherical_albedo[i])
            self.sensing = Sensing(sim.rt, Radiometry.of([bands[k] for k in self.ids], scene.sensor.bits, self.ids),
                                   scene.effects, sim.precision, correction=correction)
        self.clipped = np.zeros((2, len(self.ids)), np.int64)

    def add(self, block: RowBlock, radiance: np.ndarray, psf: float | None) -> None:
        """Sense this group's output rows of ``block`` from ``radiance`` ``(n_bands, read rows, cols)``."""
        f, out_rows = self.factor, block.output_rows(self.factor)
        ny = out_rows.stop - out_rows.start
        if ny <= 0:
            return
        top = block.start - block.read_start
        images = np.stack([box_mean(_psf(radiance[k], f, psf)[top : top + ny * f], f) for k in self.ids])
        images = images[:, :, : self.nx]
        result = None
        if self.sensing is not None:
            result = self.sensing(images.reshape(len(self.ids), -1), seed=self.scene.run.seed,
                                  frame=self.scene.run.frame, pixel_offset=out_rows.start * self.nx)
            if result.clipped is not None:
                self.clipped += result.clipped
        bands = self.scene.sensor.bands
        for j, k in enumerate(self.ids):
            attrs = band_attrs(bands[k], self.scene.sensor.bits)
            name = bands[k].name
            self._put(f"radiance_{name}", out_rows, images[j],
                      {**attrs, **pixel_attrs("radiance", RADIANCE_UNITS, "noise-free band radiance")})
            if result is None:
                continue
            for var, units, long_name in PIXEL_VARIABLES:
                arr = getattr(result, var)
                if arr is not None:
                    self._put(f"{var}_{name}", out_rows, arr[j].reshape(ny, self.nx),
                              {**attrs, **pixel_attrs(var, units, long_name)})

    def _put(self, name: str, rows: slice, data: np.ndarray, attrs: dict) -> None:
        if name not in self.store:
            self.store.create(name, self.dims, data.dtype, attrs)
        self.store.write(name, rows, data)

    def finish(self) -> None:
        """The clipping counts, once every block is in."""
        if self.sensing is None or not self.scene.effects.quantise:
            return
        for j, k in enumerate(self.ids):
            self.store.update_attrs(f"radiance_{self.scene.sensor.bands[k].name}",
                                    {"clipped_below_lmin": int(self.clipped[0, j]),
                                     "clipped_above_lmax": int(self.clipped[1, j])})


def _psf(image: np.ndarray, factor: int, psf_fwhm: float | None) -> np.ndarray:
    """The Gaussian PSF of FWHM ``psf_fwhm`` output pixels (``factor`` input pixels each), or the image itself."""
    if not psf_fwhm:
        return image
    return gaussian_filter(image.astype(np.float64), sigma=psf_fwhm * factor * FWHM_TO_SIGMA, mode="nearest")
