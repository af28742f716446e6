"""Image-cube simulation: a cube ``(rows, cols, wavelengths)`` → per-band images at each band's GSD.

Order of operations (the physical one): spectra → band radiance at the input GSD (SRFs, and the
atmosphere when on) → optional Gaussian PSF → box average over ``GSD_band / GSD_input`` input
pixels → noise → quantisation → calibration at the band's own GSD (the SNR table refers to
pixels of that size). Trailing rows/columns that do not fill a whole output pixel are dropped.
Noise of band ``k`` at output pixel ``(y, x)`` keys on pixel index ``y · ncols + x`` of that
band's grid.

No-data (NaN or file-marked values, bad bands: :mod:`s2cl.io.cubes`) never refuses a cube: a pixel with
any no-data sample is NODATA and an output pixel whose footprint touches one is NODATA too
(:mod:`s2cl.forward.nodata` says why), flagged in every band's ``flags_<band>`` variable
(:attr:`s2cl.status.PixelFlag.NODATA`) with NaN radiance and reflectance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr
from scipy.ndimage import gaussian_filter

from s2cl.atmos.correction import BandAtmosphere
from s2cl.cl.runtime import Runtime
from s2cl.errors import InputError
from s2cl.forward.dataset import CONVENTIONS, PIXEL_VARIABLES, RADIANCE_UNITS, band_attrs, pixel_attrs
from s2cl.forward.nodata import check_bad_band_gaps, footprint_nodata, gap_weights, nodata_rows, psf_radius
from s2cl.forward.sense import Radiometry, Sensing
from s2cl.forward.simulate import Progress, Simulator, scene_atmosphere
from s2cl.grid import SpectralGrid, check_wavelengths
from s2cl.io.cubes import CubeFile, cube_size, load_cube
from s2cl.libraries.library import resample_to_grid
from s2cl.scene.scene import Scene
from s2cl.status import PixelFlag
from s2cl.version import __version__

FWHM_TO_SIGMA = 1.0 / (2.0 * np.sqrt(2.0 * np.log(2.0)))
__all__ = ["SceneCube", "aggregate", "cube_size", "load_cube", "load_scene_cube", "simulate_cube", "to_grid"]


def to_grid(cube: np.ndarray, wavelengths_nm: np.ndarray | None, grid: SpectralGrid, source: str, *,
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
    if w.size == grid.size and np.allclose(w, grid.wavelengths, atol=1e-6):
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
    """Box average of ``factor × factor`` blocks (after an optional Gaussian PSF of FWHM
    ``psf_fwhm`` output pixels); trailing partial blocks are dropped."""
    if psf_fwhm:
        image = gaussian_filter(image.astype(np.float64), sigma=psf_fwhm * factor * FWHM_TO_SIGMA, mode="nearest")
    if factor == 1:
        return image
    rows, cols = (image.shape[0] // factor) * factor, (image.shape[1] // factor) * factor
    if rows == 0 or cols == 0:
        raise InputError(
            f"cube of {image.shape[0]}×{image.shape[1]} pixels is smaller than one {factor}×{factor} block")
    blocks = image[:rows, :cols].reshape(rows // factor, factor, cols // factor, factor)
    return blocks.mean(axis=(1, 3), dtype=np.float64).astype(image.dtype)


@dataclass(frozen=True)
class SceneCube:
    """A scene's cube, checked and on the scene's grid: spectra ``(rows·cols, grid.size)``, finite (zero at
    NODATA pixels), and the NODATA mask ``(rows·cols,)``."""

    spectra: np.ndarray
    rows: int
    cols: int
    source: str
    nodata: np.ndarray | None = None

    @property
    def nodata_image(self) -> np.ndarray:
        """NODATA mask ``(rows, cols)`` (all False when the cube has none)."""
        if self.nodata is None:
            return np.zeros((self.rows, self.cols), bool)
        return self.nodata.reshape(self.rows, self.cols)


def load_scene_cube(scene: Scene, cube: np.ndarray | None = None,
                    wavelengths_nm: np.ndarray | None = None) -> SceneCube:
    """The scene's ``surface.cube`` file (or ``cube`` given in memory: NaN marks no data) loaded onto the
    scene's grid, with every check of :func:`simulate_cube` done: ``s2cl simulate`` calls it before it
    creates the folder."""
    s = scene.spec
    source = scene.source
    owned = False
    if cube is None:
        if s.surface.cube is None:
            raise InputError("the scene has no surface.cube", source=source, key="surface.cube")
        source = str(scene.resolve(s.surface.cube))
        read: CubeFile = load_cube(scene.resolve(s.surface.cube), s.surface.variable)
        cube, wavelengths_nm, owned = read.values, read.wavelengths_nm, True
        if read.bad_nm.size:
            weights = [b.weights(scene.grid, scene.run.support, scene.source) for b in scene.sensor.bands]
            check_bad_band_gaps([b.name for b in scene.sensor.bands],
                                gap_weights(weights, scene.grid, read.wavelengths_nm, read.bad_nm),
                                s.surface.quantity, source)
    rows, cols = np.asarray(cube).shape[:2]
    spectra, nodata = to_grid(cube, wavelengths_nm, scene.grid, source, owned=owned)
    gsd_in = s.surface.gsd_m
    if gsd_in is None:
        raise InputError("an image cube needs surface.gsd_m", source=scene.source, key="surface.gsd_m")
    bands = scene.sensor.bands
    for gsd in sorted({b.gsd_m for b in bands}):
        factor = _factor(gsd, gsd_in, [b.name for b in bands if b.gsd_m == gsd], scene.source)
        if factor > 1 and (rows < factor or cols < factor):
            raise InputError(f"cube of {rows}×{cols} pixels is smaller than one {factor}×{factor} block of the "
                             f"{gsd:g} m bands", source=source, key="surface.gsd_m")
    return SceneCube(spectra, rows, cols, source, nodata if nodata.any() else None)


def simulate_cube(rt: Runtime, scene: Scene, cube: np.ndarray | SceneCube | None = None,
                  wavelengths_nm: np.ndarray | None = None, *, progress: Progress | None = None) -> xr.Dataset:
    """Simulate an image cube (the scene's ``surface.cube`` file, ``cube`` given in memory, or a cube
    already loaded by :func:`load_scene_cube`) on ``rt``."""
    s = scene.spec
    prepared = cube if isinstance(cube, SceneCube) else load_scene_cube(scene, cube, wavelengths_nm)
    rows, cols, spectra = prepared.rows, prepared.cols, prepared.spectra
    gsd_in = s.surface.gsd_m
    assert gsd_in is not None
    sim = Simulator.for_scene(rt, scene, atmosphere=scene_atmosphere(scene))
    radiance = sim.band_radiance(spectra).reshape(scene.sensor.size, rows, cols)
    if progress:
        progress(rows * cols)
    psf = s.spatial.psf_fwhm if s.spatial.psf == "gaussian" else None
    ds = xr.Dataset(attrs={**CONVENTIONS, "scene": scene.name, "s2cl_version": __version__, "device": sim.rt.name,
                           "effects": scene.effects.describe(), "seed": scene.run.seed,
                           "input_gsd_m": gsd_in, "psf": s.spatial.psf,
                           "nodata_input_pixels": int(prepared.nodata_image.sum())})
    bands = scene.sensor.bands
    for gsd in sorted({b.gsd_m for b in bands}):
        ids = [k for k, b in enumerate(bands) if b.gsd_m == gsd]
        factor = _factor(gsd, gsd_in, [bands[k].name for k in ids], scene.source)
        images = np.stack([aggregate(radiance[k], factor, psf) for k in ids])
        nodata = footprint_nodata(prepared.nodata_image, factor, psf_radius(factor, psf, FWHM_TO_SIGMA))
        images[:, nodata] = np.nan
        _add_group(ds, scene, sim, ids, images, gsd, nodata)
    return ds


def _factor(gsd: float, gsd_in: float, names: list[str], source: str) -> int:
    ratio = gsd / gsd_in
    factor = round(ratio)
    if factor < 1 or abs(ratio - factor) > 1e-6:
        raise InputError(f"band GSD {gsd:g} m is not a whole multiple of the cube's GSD {gsd_in:g} m "
                         f"(bands {', '.join(names)})", source=source, key="surface.gsd_m")
    return factor


def _add_group(ds: xr.Dataset, scene: Scene, sim: Simulator, ids: list[int], images: np.ndarray,
               gsd: float, nodata: np.ndarray) -> None:
    """Sense one GSD group's band images (NaN at the ``nodata`` pixels) and add their variables to ``ds``;
    every band gets ``flags_<band>`` (the radiometric stage's when it quantises, else NODATA alone)."""
    bands = scene.sensor.bands
    ny, nx = images.shape[1:]
    ydim, xdim = f"y_{gsd:g}m", f"x_{gsd:g}m"
    ds.coords[ydim] = (ydim, (np.arange(ny) + 0.5) * gsd, {"units": "m"})
    ds.coords[xdim] = (xdim, (np.arange(nx) + 0.5) * gsd, {"units": "m"})
    flat = images.reshape(len(ids), ny * nx)
    result = None
    if scene.effects.senses:
        group_bands = [bands[k] for k in ids]
        correction = None
        if sim.correction is not None:
            c = sim.correction
            correction = BandAtmosphere(c.path_radiance[ids], c.ground_term[ids], c.spherical_albedo[ids])
        sensing = Sensing(sim.rt, Radiometry.of(group_bands, scene.sensor.bits, ids), scene.effects, sim.precision,
                          correction=correction)
        result = sensing(flat, seed=scene.run.seed, frame=scene.run.frame)
    flags = result.flags if result is not None else None
    if flags is None:
        flags = np.where(nodata.reshape(1, -1), np.uint8(PixelFlag.NODATA), np.uint8(0)).repeat(len(ids), axis=0)
    for j, k in enumerate(ids):
        attrs = band_attrs(bands[k], scene.sensor.bits)
        name = bands[k].name
        ds[f"radiance_{name}"] = ((ydim, xdim), images[j],
                                  {**attrs, **pixel_attrs("radiance", RADIANCE_UNITS, "noise-free band radiance")})
        ds[f"flags_{name}"] = ((ydim, xdim), flags[j].reshape(ny, nx),
                               {**attrs, **pixel_attrs("flags", "1", "radiometric pixel flags")})
        if result is None:
            continue
        for var, units, long_name in PIXEL_VARIABLES:
            arr = getattr(result, var)
            if arr is not None and var != "flags":
                ds[f"{var}_{name}"] = ((ydim, xdim), arr[j].reshape(ny, nx),
                                       {**attrs, **pixel_attrs(var, units, long_name)})
        if result.flags is not None:  # no-data pixels are counted as such, not as clipped below Lmin
            f = result.flags[j]
            ds[f"radiance_{name}"].attrs.update(
                clipped_below_lmin=int(np.count_nonzero(f & PixelFlag.LOW)),
                clipped_above_lmax=int(np.count_nonzero(f & PixelFlag.HIGH)),
                nodata_pixels=int(np.count_nonzero(f & PixelFlag.NODATA)))
