"""EMIT L2A surface reflectance (``EMIT_L2A_RFL_001_20220815T042838_2222703_003.nc``), NetCDF-4 as the LP DAAC
ships it, read with h5py:

- ``reflectance`` ``(downtrack, crosstrack, bands)`` float32, ``_FillValue`` -9999, in sensor geometry;
- group ``sensor_band_parameters``: ``wavelengths`` and ``fwhm`` (nm) per band, ``good_wavelengths`` (0: a band in a
  water-vapour window, dropped as bad);
- group ``location``: the geometry lookup table ``glt_x``, ``glt_y`` ``(ortho_y, ortho_x)``: for each pixel of the
  map grid, the 1-based crosstrack (``glt_x``) and downtrack (``glt_y``) index of the sensor pixel that lands there,
  0 where none does;
- global attributes ``geotransform`` (the map grid, GDAL order) and ``spatial_ref`` (its CRS, WKT; EPSG:4326).

``surface.geometry = "map"`` (the default) orthorectifies through the lookup table onto the map grid, as EMIT's
``emit_tools.apply_glt`` does (nearest sensor pixel; no data where the table has none), and carries the grid's
georeference; ``"sensor"`` keeps the cube as the sensor saw it, without a georeference. A table that points outside
the cube is refused, naming the first such map pixel.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError
from s2cl.io.cube_reader import CubeReader, real, wavelength_scale
from s2cl.io.georef import GeoRef, crs_wkt
from s2cl.io.products.bands import BandSelection, scaled
from s2cl.io.products.hdf5 import open_hdf5

#: EMIT's fill value of reflectance where the variable does not carry one
FILL = -9999.0
#: bytes of sensor rows read at a time while a block of map rows is gathered through the lookup table
SOURCE_CHUNK_BYTES = 8_000_000


def is_emit(p: Path, variable: str | None = None) -> bool:
    """Whether ``p`` holds an EMIT L2A layout (a reflectance variable, ``sensor_band_parameters`` and
    ``location``)."""
    with open_hdf5(p) as f:
        return ("sensor_band_parameters" in f and "location" in f and (variable or "reflectance") in f
                and "wavelengths" in f["sensor_band_parameters"])


def _attr_text(value: Any) -> str:
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray) and value.size == 1:
        return _attr_text(value.reshape(-1)[0])
    return str(value)


def open_emit(p: Path, geometry: str = "map", variable: str | None = None) -> Any:
    """The EMIT L2A file ``p`` opened for reading by rows, on its map grid or in sensor geometry."""
    name = variable or "reflectance"
    with open_hdf5(p) as f:
        v = f[name]
        if v.ndim != 3:
            raise InputError(f"needs 3 dimensions (downtrack, crosstrack, bands), got {v.ndim}", source=p, key=name)
        real(v.dtype, p, name)
        down, cross, nb = v.shape
        params = f["sensor_band_parameters"]
        wl_var = params["wavelengths"]
        wl = np.asarray(wl_var[()], dtype=np.float64) * wavelength_scale(
            _attr_text(wl_var.attrs["units"]) if "units" in wl_var.attrs else None, p,
            "sensor_band_parameters/wavelengths.units")
        if wl.size != nb:
            raise InputError(f"has {wl.size} values for {nb} bands of {name}", source=p,
                             key="sensor_band_parameters/wavelengths")
        fwhm = np.asarray(params["fwhm"][()], dtype=np.float64) if "fwhm" in params else None
        good = (np.asarray(params["good_wavelengths"][()]) != 0 if "good_wavelengths" in params
                else np.ones(nb, bool))
        fill = float(np.asarray(v.attrs["_FillValue"]).reshape(-1)[0]) if "_FillValue" in v.attrs else FILL
        glt_shape = None
        if geometry == "map":
            loc = f["location"]
            if "glt_x" not in loc or "glt_y" not in loc:
                raise InputError("has no geometry lookup table (location/glt_x, glt_y); set surface.geometry = "
                                 "'sensor' to read the cube as the sensor saw it", source=p, key="location")
            if loc["glt_x"].shape != loc["glt_y"].shape or len(loc["glt_x"].shape) != 2:
                raise InputError(f"glt_x {loc['glt_x'].shape} and glt_y {loc['glt_y'].shape} must be one 2-D grid",
                                 source=p, key="location")
            glt_shape = loc["glt_x"].shape
            georef = _map_georef(f, p)
    bands = BandSelection.of(wl, good, p, "sensor_band_parameters/good_wavelengths")
    index = bands.index
    notes = [f"{bands.bad_nm.size} bands dropped (good_wavelengths = 0)"] if bands.bad_nm.size else []
    common = {"product": "EMIT L2A", "quantity": "reflectance", "stored_bands": nb,
              "bad_bands_by": ("sensor_band_parameters/good_wavelengths", "good_wavelengths (0: a bad band)"),
              "fwhm_nm": None if fwhm is None else fwhm[index]}
    if glt_shape is None:
        def read_sensor(start: int, stop: int) -> np.ndarray:
            with open_hdf5(p) as f:
                raw = f[name][start:stop]
            return scaled(raw[:, :, index], fill, 1.0, 0.0)

        notes.append("kept in sensor geometry (surface.geometry = 'sensor'): no georeference")
        return CubeReader(p, down, cross, bands.wavelengths_nm, bands.bad_nm, read_sensor,
                          notes=tuple(notes), **common)

    def read_map(start: int, stop: int) -> np.ndarray:
        with open_hdf5(p) as f:
            gx = np.asarray(f["location/glt_x"][start:stop], dtype=np.int64)
            gy = np.asarray(f["location/glt_y"][start:stop], dtype=np.int64)
            _check_glt(gx, gy, start, down, cross, p)
            out = np.full((*gx.shape, index.size), np.nan, np.float32 if f[name].dtype.itemsize <= 4 else np.float64)
            hit = (gx != 0) & (gy != 0)
            rows, cols = gy[hit] - 1, gx[hit] - 1
            if rows.size:
                target = np.flatnonzero(hit.reshape(-1))
                flat = out.reshape(-1, index.size)
                step = max(1, SOURCE_CHUNK_BYTES // max(1, cross * nb * f[name].dtype.itemsize))
                for c0 in range(int(rows.min()), int(rows.max()) + 1, step):
                    inside = (rows >= c0) & (rows < c0 + step)
                    if not inside.any():
                        continue
                    chunk = f[name][c0 : min(down, c0 + step)]
                    raw = chunk[rows[inside] - c0, cols[inside]][:, index]
                    flat[target[inside]] = scaled(raw, fill, 1.0, 0.0)
        return out

    notes.append(f"orthorectified through the geometry lookup table onto its map grid ({glt_shape[0]} × "
                 f"{glt_shape[1]} pixels)")
    return CubeReader(p, glt_shape[0], glt_shape[1], bands.wavelengths_nm, bands.bad_nm, read_map, georef=georef,
                      notes=tuple(notes), **common)


def _map_georef(f: Any, p: Path) -> GeoRef:
    """The map grid of the lookup table: the ``geotransform`` and ``spatial_ref`` global attributes."""
    if "geotransform" not in f.attrs:
        raise InputError("has no global attribute 'geotransform' for its lookup table's map grid", source=p,
                         key="geotransform")
    t = np.asarray(f.attrs["geotransform"], dtype=np.float64).reshape(-1)
    if t.size != 6:
        raise InputError(f"needs 6 numbers (GDAL order), got {t.size}", source=p, key="geotransform")
    crs = crs_wkt(_attr_text(f.attrs["spatial_ref"]), p, "spatial_ref") if "spatial_ref" in f.attrs else None
    return GeoRef(tuple(t.tolist()), crs, f"{p.name} (geometry lookup table grid)")


def _check_glt(gx: np.ndarray, gy: np.ndarray, start: int, down: int, cross: int, p: Path) -> None:
    """Refuse a lookup table that names a sensor pixel outside the cube (1-based; 0: none)."""
    for name, g, size, what in (("glt_x", gx, cross, "crosstrack"), ("glt_y", gy, down, "downtrack")):
        bad = (g < 0) | (g > size)
        if bad.any():
            r, c = (int(v) for v in np.argwhere(bad)[0])
            raise InputError(f"points outside the cube: map pixel (row {start + r}, column {c}) names {what} "
                             f"{int(g[r, c])} of 1 … {size}", source=p, key=f"location/{name}")
