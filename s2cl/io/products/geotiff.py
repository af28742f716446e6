"""GeoTIFF cubes read through rasterio (GDAL; the ``geo`` extra): a generic GeoTIFF whose bands carry their
wavelengths as GDAL metadata, and the reading of rows that the EnMAP reader (:mod:`s2cl.io.products.enmap`) shares.

Band metadata, as GDAL writes it: each band's ``wavelength`` and ``fwhm`` items (default domain; units from the
band's or the dataset's ``wavelength_units``, nm when absent), or GDAL's ``IMAGERY`` domain ``CENTRAL_WAVELENGTH_UM``
and ``FWHM_UM`` (µm). No data: each band's no-data value (compared with the stored numbers); scale: each band's
``scale`` and ``offset`` (value = stored · scale + offset); bad bands: a ``bbl`` item in the dataset's default or
``ENVI`` domain (``{1, 0, …}``, 0 = bad) as GDAL's ENVI driver writes it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import DependencyError, InputError
from s2cl.io.cube_reader import CubeReader, wavelength_scale
from s2cl.io.georef import GEO_EXTRA, GeoRef, crs_wkt
from s2cl.io.inputs import number_at
from s2cl.io.products.bands import BandSelection, bad_band_flags, scaled

#: rasterio data types s2cl reads (real numbers)
REAL_TYPES = ("uint8", "int8", "uint16", "int16", "uint32", "int32", "int64", "uint64", "float32", "float64")


def rasterio_module() -> Any:
    """rasterio, or a :class:`DependencyError` naming the extra."""
    try:
        import rasterio
    except ImportError as err:
        raise DependencyError(f"reading a GeoTIFF needs rasterio (GDAL): {GEO_EXTRA}") from err
    return rasterio


def open_dataset(p: Path) -> Any:
    """``p`` opened by rasterio; an :class:`InputError` naming the file when GDAL cannot."""
    rasterio = rasterio_module()
    try:
        return rasterio.open(p)
    except rasterio.errors.RasterioIOError as err:
        raise InputError(f"cannot read as GeoTIFF ({type(err).__name__})", source=p) from None


def tiff_georef(src: Any, p: Path) -> GeoRef | None:
    """The dataset's CRS and transform (None when it has neither)."""
    transform = tuple(src.transform.to_gdal())
    identity = transform == (0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    if src.crs is None and identity:
        return None
    crs = crs_wkt(src.crs.to_wkt(), p, "CRS") if src.crs is not None else None
    return GeoRef(transform, crs, f"{p.name} (GeoTIFF)")


def check_real(src: Any, p: Path) -> None:
    """Refuse complex or non-numeric bands."""
    for i, dtype in enumerate(src.dtypes, 1):
        if dtype not in REAL_TYPES:
            raise InputError(f"band {i} holds {dtype} values; a cube holds real numbers", source=p, key="data type")


def row_reader(p: Path, index: np.ndarray, nodata: np.ndarray, gain: np.ndarray,
               offset: np.ndarray) -> Callable[[int, int], np.ndarray]:
    """A reader of rows ``start … stop-1`` of the bands ``index`` (0-based, in the order wanted) of the GeoTIFF
    ``p``: ``(rows, cols, bands)`` values, NaN at each band's ``nodata``, scaled by ``gain`` and ``offset``."""
    rasterio = rasterio_module()
    from rasterio.windows import Window

    bands = [int(i) + 1 for i in index]

    def read(start: int, stop: int) -> np.ndarray:
        try:
            with rasterio.open(p) as src:
                raw = src.read(bands, window=Window(0, start, src.width, stop - start))
        except rasterio.errors.RasterioIOError as err:
            raise InputError(f"cannot read rows {start}-{stop - 1} ({type(err).__name__})", source=p) from None
        return scaled(np.moveaxis(raw, 0, -1), nodata, gain, offset)

    return read


def open_geotiff(p: Path) -> Any:
    """A generic GeoTIFF cube (see the module docstring for the metadata it needs)."""
    with open_dataset(p) as src:
        check_real(src, p)
        wl, fwhm = _band_wavelengths(src, p)
        good = _bad_band_list(src, p)
        nodata = np.array([np.nan if v is None else v for v in src.nodatavals], dtype=np.float64)
        gain = np.array([1.0 if s is None else s for s in src.scales], dtype=np.float64)
        offset = np.array([0.0 if o is None else o for o in src.offsets], dtype=np.float64)
        georef = tiff_georef(src, p)
        rows, cols, count = src.height, src.width, src.count
    bands = BandSelection.of(wl, good, p, "wavelength")
    i = bands.index
    return CubeReader(p, rows, cols, bands.wavelengths_nm, bands.bad_nm,
                      row_reader(p, i, nodata[i], gain[i], offset[i]), georef=georef, product="GeoTIFF",
                      fwhm_nm=None if fwhm is None else fwhm[i], stored_bands=count)


def _band_wavelengths(src: Any, p: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Each band's wavelength and FWHM (nm) from its GDAL metadata; an :class:`InputError` naming the first band
    without one."""
    wl, fwhm = [], []
    units_all = src.tags().get("wavelength_units")
    for b in range(1, src.count + 1):
        tags = {k.lower(): v for k, v in src.tags(b).items()}
        imagery = src.tags(b, ns="IMAGERY")
        if "wavelength" in tags:
            scale = wavelength_scale(tags.get("wavelength_units", units_all), p, f"band {b} wavelength_units")
            wl.append(number_at(tags["wavelength"], source=p, key=f"band {b} wavelength") * scale)
            fwhm.append(number_at(tags["fwhm"], source=p, key=f"band {b} fwhm") * scale if "fwhm" in tags else np.nan)
        elif "CENTRAL_WAVELENGTH_UM" in imagery:
            centre = imagery["CENTRAL_WAVELENGTH_UM"]
            wl.append(number_at(centre, source=p, key=f"band {b} CENTRAL_WAVELENGTH_UM") * 1000.0)
            f = imagery.get("FWHM_UM")
            fwhm.append(number_at(f, source=p, key=f"band {b} FWHM_UM") * 1000.0 if f is not None else np.nan)
        else:
            raise InputError(f"band {b} has no wavelength: a GeoTIFF cube needs each band's GDAL metadata item "
                             "'wavelength' (with 'wavelength_units') or IMAGERY CENTRAL_WAVELENGTH_UM", source=p,
                             key="wavelength")
    f = np.array(fwhm)
    return np.array(wl), (None if np.isnan(f).all() else f)


def _bad_band_list(src: Any, p: Path) -> np.ndarray:
    """The ``bbl`` item (default or ``ENVI`` domain) as booleans (True: good; :func:`bad_band_flags`)."""
    text = src.tags().get("bbl") or src.tags(ns="ENVI").get("bbl")
    values = None if text is None else [v for v in str(text).strip("{} ").split(",") if v.strip()]
    return bad_band_flags(values, src.count, p)
