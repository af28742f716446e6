"""Image-cube simulation: a cube ``(rows, cols, wavelengths)`` → per-band images at each band's GSD.

Order of operations (the physical one): spectra → band radiance at the input GSD (SRFs, and the
atmosphere when on) → optional Gaussian PSF → box average over ``GSD_band / GSD_input`` input
pixels → noise → quantisation → calibration at the band's own GSD (the SNR table refers to
pixels of that size). Trailing rows/columns that do not fill a whole output pixel are dropped.
Noise of band ``k`` at output pixel ``(y, x)`` keys on pixel index ``y · ncols + x`` of that
band's grid.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.ndimage import gaussian_filter

from s2cl.atmos.correction import BandAtmosphere
from s2cl.cl.runtime import Runtime
from s2cl.errors import InputError
from s2cl.forward.dataset import CONVENTIONS, PIXEL_VARIABLES, RADIANCE_UNITS, band_attrs, pixel_attrs
from s2cl.forward.instrument import Instrument, smile_radiance
from s2cl.forward.sense import Radiometry, Sensing
from s2cl.forward.simulate import Progress, Simulator, scene_atmosphere
from s2cl.grid import SpectralGrid, check_wavelengths
from s2cl.io.envi import envi_data_file, envi_layout, read_envi_header
from s2cl.io.inputs import input_file, parse_number
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
    """A scene's cube, checked and on the scene's grid: spectra ``(rows·cols, grid.size)``."""

    spectra: np.ndarray
    rows: int
    cols: int
    source: str


def load_scene_cube(scene: Scene, cube: np.ndarray | None = None,
                    wavelengths_nm: np.ndarray | None = None) -> SceneCube:
    """The scene's ``surface.cube`` file (or ``cube`` given in memory) loaded onto the scene's grid, with
    every check of :func:`simulate_cube` done: ``s2cl simulate`` calls it before it creates the folder."""
    s = scene.spec
    source = scene.source
    if cube is None:
        if s.surface.cube is None:
            raise InputError("the scene has no surface.cube", source=source, key="surface.cube")
        cube, wavelengths_nm = load_cube(scene.resolve(s.surface.cube), s.surface.variable)
        source = str(scene.resolve(s.surface.cube))
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
    return SceneCube(spectra, rows, cols, source)


def simulate_cube(rt: Runtime, scene: Scene, cube: np.ndarray | SceneCube | None = None,
                  wavelengths_nm: np.ndarray | None = None, *, progress: Progress | None = None) -> xr.Dataset:
    """Simulate an image cube (the scene's ``surface.cube`` file, ``cube`` given in memory, or a cube
    already loaded by :func:`load_scene_cube`) on ``rt``."""
    s = scene.spec
    prepared = cube if isinstance(cube, SceneCube) else load_scene_cube(scene, cube, wavelengths_nm)
    rows, cols, spectra = prepared.rows, prepared.cols, prepared.spectra
    gsd_in = s.surface.gsd_m
    assert gsd_in is not None
    atmosphere = scene_atmosphere(scene)
    sim = Simulator.for_scene(rt, scene, atmosphere=atmosphere)
    instrument = Instrument.of(scene)
    if instrument.spec.smile:
        radiance = smile_radiance(sim.rt, scene, spectra, rows, cols, atmosphere)
    else:
        radiance = sim.band_radiance(spectra).reshape(scene.sensor.size, rows, cols)
    if progress:
        progress(rows * cols)
    psf = s.spatial.psf_fwhm if s.spatial.psf == "gaussian" else None
    ds = xr.Dataset(attrs={**CONVENTIONS, "scene": scene.name, "s2cl_version": __version__, "device": sim.rt.name,
                           "effects": scene.effects.describe(), "seed": scene.run.seed,
                           "input_gsd_m": gsd_in, "psf": s.spatial.psf, "instrument": instrument.spec.describe()})
    bands = scene.sensor.bands
    for gsd in sorted({b.gsd_m for b in bands}):
        ids = [k for k, b in enumerate(bands) if b.gsd_m == gsd]
        factor = _factor(gsd, gsd_in, [bands[k].name for k in ids], scene.source)
        images = np.stack([aggregate(instrument.spatial(radiance[k], k, factor), factor, psf) for k in ids])
        images = instrument.columns(images, ids)
        _add_group(ds, scene, sim, ids, images, gsd)
    for k, band in enumerate(bands):
        ds[f"radiance_{band.name}"].attrs.update(instrument.band_attrs(k))
    return ds


def _factor(gsd: float, gsd_in: float, names: list[str], source: str) -> int:
    ratio = gsd / gsd_in
    factor = round(ratio)
    if factor < 1 or abs(ratio - factor) > 1e-6:
        raise InputError(f"band GSD {gsd:g} m is not a whole multiple of the cube's GSD {gsd_in:g} m "
                         f"(bands {', '.join(names)})", source=source, key="surface.gsd_m")
    return factor


def _add_group(ds: xr.Dataset, scene: Scene, sim: Simulator, ids: list[int], images: np.ndarray,
               gsd: float) -> None:
    """Sense one GSD group's band images and add their variables to ``ds``."""
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
    for j, k in enumerate(ids):
        attrs = band_attrs(bands[k], scene.sensor.bits)
        name = bands[k].name
        ds[f"radiance_{name}"] = ((ydim, xdim), images[j],
                                  {**attrs, **pixel_attrs("radiance", RADIANCE_UNITS, "noise-free band radiance")})
        if result is None:
            continue
        for var, units, long_name in PIXEL_VARIABLES:
            arr = getattr(result, var)
            if arr is not None:
                ds[f"{var}_{name}"] = ((ydim, xdim), arr[j].reshape(ny, nx),
                                       {**attrs, **pixel_attrs(var, units, long_name)})
        if result.clipped is not None:
            ds[f"radiance_{name}"].attrs.update(clipped_below_lmin=int(result.clipped[0, j]),
                                               clipped_above_lmax=int(result.clipped[1, j]))
