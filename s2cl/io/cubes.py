"""Image-cube files (NetCDF-4 and ENVI) read into values, wavelengths (nm) and no-data, as such files ship.

No-data travels as NaN: every value a file marks as missing becomes NaN here, and the forward chain
(:mod:`s2cl.forward.cube`) turns a pixel with any NaN among its spectral samples into a NODATA pixel.
What each format may mark:

- **ENVI**: ``data ignore value`` (compared with the raw values, before scaling); ``reflectance scale
  factor`` (values are divided by it: int16 × 10000 becomes reflectance); ``bbl`` (bad band list, 0 = bad:
  such bands are dropped before anything else, their wavelengths reported in :attr:`CubeFile.bad_nm`);
  ``wavelength units`` Nanometers or Micrometers (absent or Unknown: nm); any real data type, any
  interleave (``bsq``/``bil``/``bip``, from the header), data file ``NAME``, ``NAME.img``, ``NAME.bsq`` ….
- **NetCDF**: CF ``_FillValue``/``missing_value`` and ``scale_factor``/``add_offset`` (decoded by xarray);
  a CF flag variable named in the cube's ``ancillary_variables`` whose ``flag_meanings`` hold a no-data
  meaning (:data:`NODATA_MEANINGS`) marks the pixels it flags: equal to its ``flag_values`` entry, with a bit of
  its ``flag_masks`` entry set, or, where both are given, with ``flags & mask == value`` (CF 1.10 §3.5).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from s2cl.errors import InputError, token
from s2cl.grid import check_wavelengths
from s2cl.io.cube_reader import CubeReader, floating, real, wavelength_scale
from s2cl.io.envi import envi_data_file, envi_layout, header_int, read_envi_header
from s2cl.io.georef import envi_georef
from s2cl.io.inputs import input_file, number_at, parse_number
from s2cl.io.products import file_kind, open_product
from s2cl.io.products.bands import bad_band_flags

if TYPE_CHECKING:
    import xarray as xr

#: CF ``flag_meanings`` words that mean "no data here" (compared in lower case)
NODATA_MEANINGS = frozenset({"no_data", "nodata", "no_data_value", "missing", "missing_data", "missing_value",
                             "fill", "fill_value", "invalid", "invalid_data", "no_data_nan_radiance"})


@dataclass(frozen=True)
class CubeFile:
    """A cube ``(rows, cols, wavelengths)`` as read: floating values, NaN where the file marks no data.

    :param wavelengths_nm: the kept bands' wavelengths (nm, increasing).
    :param bad_nm: wavelengths (nm) of the bands the file's bad band list dropped (empty when none).
    """

    values: np.ndarray
    wavelengths_nm: np.ndarray
    bad_nm: np.ndarray = field(default_factory=lambda: np.empty(0))


def load_cube(path: str | Path, variable: str | None = None) -> CubeFile:
    """The cube at ``path``: NetCDF (a 3-D variable with a ``wavelength`` dimension and coordinate) or ENVI
    (the ``.hdr`` file), read whole. See the module docstring for the no-data conventions honoured."""
    reader = open_cube(path, variable)
    return CubeFile(reader.read(0, reader.rows), reader.wavelengths_nm, reader.bad_nm)


def open_cube(path: str | Path, variable: str | None = None, *, geometry: str = "map") -> CubeReader:
    """The cube at ``path`` opened for reading by rows (:class:`CubeReader`); nothing but metadata is read.

    ``path`` is an ENVI header (``.hdr``) or the data file beside it (``x.bsq`` with ``x.hdr`` or ``x.bsq.hdr``), a
    NetCDF cube, or a product as its mission ships it (:mod:`s2cl.io.products`: an EnMAP L2A folder, image or XML;
    EMIT L2A; PRISMA L2D; a GeoTIFF with GDAL wavelength metadata). ``geometry``: ``map`` (a product in sensor
    geometry with a lookup table is orthorectified onto its map grid) or ``sensor``."""
    p = Path(path)
    if not p.is_dir():
        p = input_file(p, what="cube file")
        if p.suffix.lower() == ".hdr":
            return _open_envi(p)
    product = open_product(p, variable, geometry)
    if product is not None:
        return product
    hdr = envi_header_of(p)
    if hdr is not None:
        return _open_envi(hdr)
    return _open_netcdf_cube(p, variable)


def envi_header_of(data: Path) -> Path | None:
    """The ENVI header of a data file named as GDAL users name it: ``x.hdr`` beside ``x.bsq`` (or ``x.img`` …), or
    ``x.bsq.hdr``; None when there is none (or ``data`` is HDF5 or TIFF)."""
    if file_kind(data) != "other":
        return None
    for hdr in (data.with_suffix(".hdr"), data.with_name(data.name + ".hdr"), data.with_suffix(".HDR"),
                data.with_name(data.name + ".HDR")):
        if hdr != data and hdr.is_file():
            try:
                if envi_data_file(hdr).resolve() == data.resolve():
                    return hdr
            except InputError:
                continue
    return None


def _open_netcdf_cube(p: Path, variable: str | None) -> CubeReader:
    """A NetCDF cube (a 3-D variable with a ``wavelength`` dimension and coordinate)."""
    with _open_netcdf(p) as ds:
        v = _netcdf_cube(ds, p, variable)
        scale = wavelength_scale(ds["wavelength"].attrs.get("units"), p, "wavelength.units")
        wl = np.asarray(ds["wavelength"].values, dtype=np.float64) * scale
        rows, cols = (int(v.sizes[d]) for d in v.dims[:2])
        name = str(v.name)

    def read(start: int, stop: int) -> np.ndarray:
        with _open_netcdf(p) as ds:
            v = _netcdf_cube(ds, p, name)
            window = {v.dims[0]: slice(start, stop)}
            values = floating(np.asarray(v.isel(window).values))
            flagged = _flagged_nodata(ds, v, p, name, window)
            if flagged is not None:
                values[flagged] = np.nan
            return values

    return CubeReader(p, rows, cols, check_wavelengths(wl, source=str(p), key="wavelength"), np.empty(0), read)


def _open_netcdf(p: Path) -> xr.Dataset:
    """The NetCDF-4 file ``p`` opened lazily (nothing loaded)."""
    import xarray as xr  # ~0.35 s with pandas: NetCDF cubes only, not the GeoTIFF, ENVI and HDF5 products

    try:
        return xr.open_dataset(p, engine="h5netcdf")
    except Exception as err:  # h5netcdf/h5py raise many types for a bad file
        raise InputError(f"cannot read as NetCDF-4 ({type(err).__name__}); s2cl reads NetCDF-4 cubes, EMIT L2A, "
                         "PRISMA L2D, EnMAP L2A, GeoTIFF with wavelengths, and ENVI (the .hdr, or the data file "
                         "beside it)", source=p) from err


def _netcdf_cube(ds: xr.Dataset, p: Path, variable: str | None) -> xr.DataArray:
    """The cube variable of ``ds`` (lazy), dimensions ``(row, column, wavelength)``, checked."""
    candidates = [n for n, v in ds.data_vars.items() if v.ndim == 3 and "wavelength" in v.dims]
    name = variable or (candidates[0] if len(candidates) == 1 else None)
    if name is None or name not in ds:
        raise InputError(f"choose the cube variable (surface.variable); 3-D variables with a 'wavelength' "
                         f"dimension: {candidates or 'none'}", source=p, key="surface.variable")
    v = ds[name]
    if "wavelength" not in v.dims or v.ndim != 3:
        raise InputError("needs 3 dimensions, one of them 'wavelength'", source=p, key=name)
    v = v.transpose(*[d for d in v.dims if d != "wavelength"], "wavelength")
    real(v.dtype, p, name)
    return v


def cube_size(path: str | Path) -> tuple[int, int]:
    """(pixels, wavelengths read per pixel) of the cube at ``path`` from its metadata only (nothing is loaded);
    (0, 0) when a NetCDF file cannot tell (then :func:`load_cube` says what is wrong).

    :raises InputError: ``path`` is not a regular file (or a product folder), or an ENVI header's layout is wrong or
        lies about its data file (:func:`s2cl.io.envi.envi_layout`), or a product's metadata is wrong."""
    p = Path(path)
    if not p.is_dir():
        p = input_file(p, what="cube file")
    hdr = p if p.suffix.lower() == ".hdr" else None
    if hdr is None:
        product = open_product(p)
        if product is not None:
            return product.rows * product.cols, product.bands_read
        hdr = envi_header_of(p)
    if hdr is not None:
        meta = read_envi_header(hdr)
        layout = envi_layout(meta, hdr, envi_data_file(hdr))
        _envi_wavelengths(meta, layout.bands, hdr)
        return layout.samples * layout.lines, layout.bands
    try:
        with _open_netcdf(p) as ds:
            cubes = [v for v in ds.data_vars.values() if v.ndim == 3 and "wavelength" in v.dims]
            if not cubes:
                return 0, 0
            v = max(cubes, key=lambda c: c.size)
            return int(v.size // v.sizes["wavelength"]), int(v.sizes["wavelength"])
    except Exception:  # a bad file is reported by load_cube, with its reason
        return 0, 0


def _flagged_nodata(ds: xr.Dataset, v: xr.DataArray, p: Path, name: str,
                    window: dict[Any, slice]) -> np.ndarray | None:
    """``(rows, cols)`` mask of the pixels of ``window`` (the cube's rows read) a CF flag variable named in
    ``ancillary_variables`` marks as no data."""
    mask = None
    spatial = v.dims[:2]
    for flag_name in str(v.attrs.get("ancillary_variables", "")).split():
        if flag_name not in ds:
            raise InputError(f"names {token(flag_name)}, which the file lacks", source=p,
                             key=f"{name}.ancillary_variables")
        f = ds[flag_name]
        meanings = str(f.attrs.get("flag_meanings", "")).lower().split()
        hits = [i for i, m in enumerate(meanings) if m in NODATA_MEANINGS]
        if not hits:
            continue
        if sorted(f.dims) != sorted(spatial):
            raise InputError(f"flags no data but has dimensions {f.dims}; the cube's pixels are {spatial}",
                             source=p, key=flag_name)
        flags = np.asarray(f.isel(window).transpose(*spatial).values)
        known = np.isfinite(flags) if flags.dtype.kind == "f" else np.ones(flags.shape, bool)
        flags_int = np.where(known, flags, 0).astype(np.int64)[..., None]
        values, masks = (_flag_table(f, attr, len(meanings), p, flag_name) for attr in ("flag_values", "flag_masks"))
        if masks is None:  # enumerated values
            if values is None:
                continue
            marked = flags_int == values[hits]
        elif values is None:  # bits
            marked = (flags_int & masks[hits]) != 0
        else:  # CF: the meaning holds where the masked flags equal its value
            marked = (flags_int & masks[hits]) == values[hits]
        hit = marked.any(axis=-1) & known
        mask = hit if mask is None else mask | hit
    return mask


def _flag_table(f: xr.DataArray, attr: str, n_meanings: int, p: Path, flag_name: str) -> np.ndarray | None:
    """The flag variable's ``flag_values`` or ``flag_masks`` as integers, one per meaning (None when absent)."""
    table = np.atleast_1d(np.asarray(f.attrs.get(attr, []), dtype=np.int64))
    if table.size == 0:
        return None
    if table.size != n_meanings:
        raise InputError(f"{attr} has {table.size} values for {n_meanings} flag_meanings", source=p, key=flag_name)
    return table


def _envi_wavelengths(meta: dict, bands: int, p: Path) -> np.ndarray:
    """The header's ``wavelength`` list as numbers, one per band (in the header's units)."""
    wl = meta.get("wavelength")
    if not wl:
        raise InputError("ENVI header has no 'wavelength' field", source=p, key="wavelength")
    if len(wl) != bands:
        raise InputError(f"lists {len(wl)} values for bands = {bands}", source=p, key="wavelength")
    try:
        return np.array([parse_number(str(x).strip()) for x in wl])
    except ValueError:
        raise InputError("holds a value that is not a number", source=p, key="wavelength") from None


def _header_number(meta: dict, key: str, p: Path) -> float | None:
    """The number at ``key`` (None when absent)."""
    text = meta.get(key)
    if text is None:
        return None
    return number_at(text, source=p, key=key)


#: numpy types of the ENVI data types (:data:`s2cl.io.envi.ENVI_ITEM_BYTES`), before the header's byte order
_ENVI_TYPES = {"1": "u1", "2": "i2", "3": "i4", "4": "f4", "5": "f8", "12": "u2", "13": "u4", "14": "i8", "15": "u8"}
#: axes of the data file per interleave, named l(ines), s(amples), b(ands)
_INTERLEAVES = {"bsq": "bls", "bil": "lbs", "bip": "lsb"}


def _open_envi(p: Path) -> CubeReader:
    meta = read_envi_header(p)
    data = envi_data_file(p)
    layout = envi_layout(meta, p, data)
    w = _envi_wavelengths(meta, layout.bands, p) * wavelength_scale(meta.get("wavelength units"), p,
                                                                     "wavelength units")
    ignore = _header_number(meta, "data ignore value", p)
    scale = _header_number(meta, "reflectance scale factor", p)
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise InputError(f"must be a finite number > 0, got {scale:g}", source=p, key="reflectance scale factor")
    bbl = meta.get("bbl")
    good = bad_band_flags(None if bbl is None else bbl if isinstance(bbl, list) else [bbl], layout.bands, p)
    interleave = str(meta.get("interleave", "bsq")).strip().lower()
    if interleave not in _INTERLEAVES:
        raise InputError(f"is {token(interleave)}; ENVI interleaves are bsq, bil and bip", source=p, key="interleave")
    order = header_int(meta, "byte order", p, minimum=0, default=0)
    if order > 1:
        raise InputError(f"must be 0 (little endian) or 1 (big endian), got {order}", source=p, key="byte order")
    dtype = np.dtype(_ENVI_TYPES[str(meta["data type"]).strip()]).newbyteorder("<" if order == 0 else ">")
    real(dtype, p, "data type")
    axes = _INTERLEAVES[interleave]
    sizes = {"l": layout.lines, "s": layout.samples, "b": layout.bands}

    def read(start: int, stop: int) -> np.ndarray:
        try:
            mm = np.memmap(data, dtype=dtype, mode="r", offset=layout.offset, shape=tuple(sizes[a] for a in axes))
        except (OSError, ValueError) as err:
            raise InputError(f"cannot read ENVI image ({type(err).__name__})", source=p) from err
        rows = mm[tuple(slice(start, stop) if a == "l" else slice(None) for a in axes)]
        rows = rows.transpose(*(axes.index(a) for a in "lsb"))
        raw = np.asarray(rows[:, :, good] if not good.all() else rows, dtype=dtype.newbyteorder("="))
        del mm, rows
        values = floating(raw)
        if ignore is not None:
            # a float file holds the ignore value at its own precision; an integer file compares exactly
            values[raw == (raw.dtype.type(ignore) if raw.dtype.kind == "f" else ignore)] = np.nan
        del raw
        if scale is not None and scale != 1.0:
            values /= values.dtype.type(scale)
        return values

    return CubeReader(p, layout.lines, layout.samples, check_wavelengths(w[good], source=str(p), key="wavelength"),
                      w[~good], read, georef=envi_georef(meta, p), product="ENVI", stored_bands=layout.bands)
