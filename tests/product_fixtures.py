"""Small products in the layouts the missions ship (names, groups, attributes, XML structure), written from one
known reflectance field, so that a reader that only works on s2cl's own files fails. Where each layout comes from:
docs/images.md ("Products as shipped").

Every writer returns the path a user would name and a :class:`Truth`: the reflectance each stored pixel and band
holds (before quantisation), the wavelengths, which bands and pixels the product marks bad or empty, and the grid.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ENMAP_NAME = "ENMAP01-____L2A-DT0000025905_20230707T192008Z_001_V010303_20230922T131734Z"
EMIT_NAME = "EMIT_L2A_RFL_001_20220815T042838_2222703_003.nc"
PRISMA_NAME = "PRS_L2D_STD_20201107101404_20201107101408_0001.he5"
AVIRIS_NAME = "ang20180814t224053_rfl_v2r2_img"
#: absorption windows the products mark bad (nm)
WATER = ((1340.0, 1445.0), (1790.0, 1960.0))


@dataclass
class Truth:
    """What a fixture holds: ``reflectance`` ``(rows, cols, bands)`` in the file's band order (the stored
    geometry), ``wavelengths_nm`` in the same order, ``good`` bands, ``empty`` pixels (no data), the map
    ``transform`` (GDAL order) and ``epsg``; ``step``: the quantisation step of a stored value; ``stored``: the
    reflectance the stored numbers encode exactly (NaN where no data), in the same order."""

    reflectance: np.ndarray | None
    wavelengths_nm: np.ndarray
    good: np.ndarray
    empty: np.ndarray
    transform: tuple[float, ...] | None
    epsg: int | None
    step: float = 0.0
    extra: dict = field(default_factory=dict)
    stored: np.ndarray | None = None


def reflectance(wl: np.ndarray, rows: int, cols: int, seed: int = 0) -> np.ndarray:
    """A vegetation field with a bare patch, smooth in wavelength, in [0.02, 0.7]: ``(rows, cols, wl.size)``."""
    rng = np.random.default_rng(seed)
    veg = 0.03 + 0.42 / (1 + np.exp(-(wl - 718.0) / 14.0)) * np.exp(-(((wl - 1000.0) / 1100.0) ** 2))
    veg += 0.04 * np.exp(-(((wl - 550.0) / 30.0) ** 2))
    soil = 0.08 + 0.25 * (wl - 350.0) / 2200.0
    cover = rng.uniform(0.55, 1.0, (rows, cols, 1))
    cover[rows // 2 :, : cols // 3] = 0.0  # a bare parcel
    out = cover * veg + (1 - cover) * soil
    return np.clip(out, 0.02, 0.7)


def _corner(rows: int, cols: int, size: int) -> np.ndarray:
    """Pixels of the upper-left triangle of ``size`` (the empty corner of an orthorectified scene)."""
    r, c = np.mgrid[:rows, :cols]
    return r + c < size


# --- EnMAP L2A: folder, SPECTRAL_IMAGE.TIF, METADATA.XML ------------------------------------------------------------

def enmap_wavelengths() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """224 bands sorted by wavelength as the L2A product orders them: (wavelength, FWHM, is VNIR, channel no.)."""
    vnir = np.linspace(418.42, 993.05, 91)
    swir = np.linspace(902.55, 2445.53, 133)
    wl = np.concatenate([vnir, swir])
    fwhm = np.concatenate([np.linspace(6.5, 8.3, 91), np.linspace(9.4, 8.6, 133)])
    is_vnir = np.arange(224) < 91
    order = np.argsort(wl, kind="stable")
    return wl[order], fwhm[order], is_vnir[order], np.arange(1, 225)


def write_enmap(tmp: Path, rows: int = 24, cols: int = 30, *, xml_bands: int | None = None,
                level: str = "L2A", rho_rows: Callable[[int, int], np.ndarray] | None = None,
                empty_corner: int = 7) -> tuple[Path, Truth]:
    """An EnMAP L2A product folder (GeoTIFF+Metadata): int16 reflectance × 10000, no data -32768 in an empty
    corner and in six bands filled with it (so flagged in bandStatistics), UTM zone 33N at 30 m.

    ``rho_rows(start, stop)``: the reflectance ``(stop - start, cols, 224)`` of those rows on :func:`enmap_wavelengths`
    (default: :func:`reflectance`, held whole); the image is written 64 rows at a time, and a product written from
    ``rho_rows`` keeps no truth arrays (``Truth.reflectance`` and ``stored`` are None)."""
    import rasterio
    from rasterio.transform import Affine
    from rasterio.windows import Window

    wl, fwhm, is_vnir, channels = enmap_wavelengths()
    folder = tmp / ENMAP_NAME
    folder.mkdir()
    whole = reflectance(wl, rows, cols, seed=3) if rho_rows is None else None
    empty = _corner(rows, cols, empty_corner)
    water = np.zeros(wl.size, bool)
    for lo, hi in WATER:
        water |= (wl > lo) & (wl < hi)
    filled = np.flatnonzero(water)[[0, 2, 4, -5, -3, -1]]  # six bands filled with no data

    def stored_rows(start: int, stop: int) -> np.ndarray:
        rho = whole[start:stop] if whole is not None else rho_rows(start, stop)
        ints = np.round(rho * 10000).astype(np.int16)
        ints[empty[start:stop]] = -32768
        ints[:, :, filled] = -32768
        return ints

    transform = (399960.0, 30.0, 0.0, 5800020.0, 0.0, -30.0)
    image = folder / f"{ENMAP_NAME}-SPECTRAL_IMAGE.TIF"
    with rasterio.open(image, "w", driver="GTiff", width=cols, height=rows, count=wl.size, dtype="int16",
                       crs="EPSG:32633", transform=Affine.from_gdal(*transform), nodata=-32768,
                       interleave="band") as dst:
        for r0 in range(0, rows, 64):
            r1 = min(rows, r0 + 64)
            dst.write(np.moveaxis(stored_rows(r0, r1), -1, 0), window=Window(0, r0, cols, r1 - r0))
    with rasterio.open(folder / f"{ENMAP_NAME}-QL_PIXELMASK.TIF", "w", driver="GTiff", width=cols, height=rows,
                       count=1, dtype="uint8", crs="EPSG:32633", transform=Affine.from_gdal(*transform)) as dst:
        dst.write(np.zeros((1, rows, cols), np.uint8))
    n = xml_bands or wl.size
    bands = "".join(
        f'<bandID number="{i + 1}"><wavelengthCenterOfBand>{wl[i % wl.size]:.3f}</wavelengthCenterOfBand>'
        f"<FWHMOfBand>{fwhm[i % wl.size]:.3f}</FWHMOfBand><GainOfBand>0.0001</GainOfBand>"
        f"<OffsetOfBand>0</OffsetOfBand></bandID>" for i in range(n))
    stats = "".join(
        f'<bandID number="{i + 1}"><minimum>{-1000000 if i in filled else 0}</minimum>'
        f"<maximum>{-1000000 if i in filled else 7000}</maximum>"
        f"<mean>{-1000000 if i in filled else 2500}</mean><stdDeviation>{0 if i in filled else 900}</stdDeviation>"
        "</bandID>" for i in range(wl.size))
    vnir = ",".join(str(c) for c in channels[is_vnir])
    swir = ",".join(str(c) for c in channels[~is_vnir])
    corners = "".join(f"<point><frame>{f}</frame><latitude>52.{k}</latitude><longitude>13.{k}</longitude></point>"
                      for k, f in enumerate(("upper_left", "upper_right", "lower_right", "lower_left", "center")))
    xml = f"""<?xml version="1.0" encoding="UTF-8"?>
<level_X xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <metadata><schema><versionSchema>01.05.00</versionSchema></schema>
    <name>{ENMAP_NAME}-METADATA.XML</name></metadata>
  <base><level>{level}</level><revision>01.03.03</revision><format>L2A_GeoTIFF</format>
    <spatialCoverage><boundingPolygon>{corners}</boundingPolygon></spatialCoverage>
    <temporalCoverage><startTime>2023-07-07T19:20:08.000000Z</startTime>
      <stopTime>2023-07-07T19:20:12.000000Z</stopTime></temporalCoverage></base>
  <processing><productFormat>GeoTIFF+Metadata</productFormat></processing>
  <product>
    <productFileInformation><file><name>{ENMAP_NAME}-SPECTRAL_IMAGE.TIF</name></file>
      <file><name>{ENMAP_NAME}-QL_PIXELMASK.TIF</name></file></productFileInformation>
    <ortho><projection>UTM_Zone33_North</projection><resolution>30</resolution><resampling>cubic</resampling></ortho>
    <bandStatistics>{stats}</bandStatistics>
  </product>
  <specific>
    <widthOfOrthoScene>{cols}</widthOfOrthoScene><heightOfOrthoScene>{rows}</heightOfOrthoScene>
    <pixelSizeOfOrthoScene>30</pixelSizeOfOrthoScene>
    <numberOfVNIRBands>91</numberOfVNIRBands><numberOfSWIRBands>133</numberOfSWIRBands>
    <bandCharacterisation>{bands}</bandCharacterisation>
    <vnirProductQuality><numChannelsExpected>91</numChannelsExpected>
      <expectedChannelsList>{vnir}</expectedChannelsList></vnirProductQuality>
    <swirProductQuality><numChannelsExpected>133</numChannelsExpected>
      <expectedChannelsList>{swir}</expectedChannelsList></swirProductQuality>
  </specific>
</level_X>
"""
    (folder / f"{ENMAP_NAME}-METADATA.XML").write_text(xml, encoding="utf-8")
    good = np.ones(wl.size, bool)
    good[filled] = False
    stored = None
    if whole is not None:
        ints = stored_rows(0, rows)
        stored = np.where(ints == -32768, np.nan, ints * 1e-4)
    return folder, Truth(whole, wl, good, empty, transform, 32633, step=1e-4, extra={"fwhm": fwhm}, stored=stored)


# --- EMIT L2A RFL: NetCDF-4 groups, GLT ---------------------------------------------------------------------------

EMIT_PIXEL_DEG = 0.000542232520256367


def emit_glt(down: int, cross: int, pad: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A lookup table that flips the swath left-right and shifts it by ``pad`` rows and columns onto a map grid
    ``pad`` pixels larger on each side (0: no sensor pixel), with one map pixel (row pad, col 0) repeating its
    neighbour's sensor pixel, as nearest-neighbour tables do at edges: (glt_x, glt_y), 1-based."""
    gx = np.zeros((down + 2 * pad, cross + 2 * pad), np.int32)
    gy = np.zeros_like(gx)
    for r in range(down):
        for c in range(cross):
            gy[r + pad, c + pad] = r + 1
            gx[r + pad, c + pad] = cross - c  # flipped: map column pad + c shows crosstrack cross - 1 - c
    gx[pad, 0], gy[pad, 0] = gx[pad, pad], gy[pad, pad]
    return gx, gy


def write_emit(tmp: Path, down: int = 20, cross: int = 18, *, glt: tuple[np.ndarray, np.ndarray] | None = None,
               spatial_ref: str | None = None) -> tuple[Path, Truth]:
    """An EMIT L2A RFL file: ``reflectance`` (downtrack, crosstrack, bands) with fill -9999 at a few sensor pixels,
    ``sensor_band_parameters`` (285 bands, good_wavelengths 0 in the water windows), ``location`` with a GLT that
    flips and shifts (:func:`emit_glt`), and the global ``geotransform`` and ``spatial_ref`` (EPSG:4326)."""
    import h5netcdf
    from pyproj import CRS

    wl = np.linspace(381.0055, 2492.5, 285)
    fwhm = np.full(wl.size, 8.5)
    good = np.ones(wl.size, bool)
    for lo, hi in WATER:
        good &= ~((wl > lo) & (wl < hi))
    rho = reflectance(wl, down, cross, seed=5).astype(np.float32)
    empty = np.zeros((down, cross), bool)
    empty[0, :3] = True
    empty[down - 1, cross - 1] = True
    stored = rho.copy()
    stored[empty] = -9999.0
    gx, gy = glt if glt is not None else emit_glt(down, cross)
    transform = (-112.5, EMIT_PIXEL_DEG, 0.0, 36.25, 0.0, -EMIT_PIXEL_DEG)
    path = tmp / EMIT_NAME
    with h5netcdf.File(path, "w") as f:
        f.dimensions = {"downtrack": down, "crosstrack": cross, "bands": wl.size, "ortho_y": gx.shape[0],
                        "ortho_x": gx.shape[1]}
        v = f.create_variable("reflectance", ("downtrack", "crosstrack", "bands"), np.float32, fillvalue=-9999.0)
        v[...] = stored
        v.attrs.update(long_name="Surface Reflectance", units="unitless")
        p = f.create_group("sensor_band_parameters")
        for name, values, attrs in (("wavelengths", wl.astype(np.float32), {"long_name": "Wavelength Centers",
                                                                            "units": "nm"}),
                                    ("fwhm", fwhm.astype(np.float32), {"long_name": "Full Width at Half Max",
                                                                       "units": "nm"}),
                                    ("good_wavelengths", good.astype(np.uint8),
                                     {"long_name": "Wavelengths where reflectance is useable: 1 = good data, "
                                                   "0 = bad data"})):
            var = p.create_variable(name, ("bands",), values.dtype)
            var[...] = values
            var.attrs.update(attrs)
        loc = f.create_group("location")
        lat = 36.25 - (np.arange(down)[:, None] + 0.5 + np.zeros(cross)) * EMIT_PIXEL_DEG
        lon = -112.5 + (np.arange(cross)[None, :] + 0.5 + np.zeros((down, 1))) * EMIT_PIXEL_DEG
        for name, values in (("lat", lat), ("lon", lon), ("elev", np.full((down, cross), 1500.0))):
            var = loc.create_variable(name, ("downtrack", "crosstrack"), np.float64, fillvalue=-9999.0)
            var[...] = values
        for name, values in (("glt_x", gx), ("glt_y", gy)):
            var = loc.create_variable(name, ("ortho_y", "ortho_x"), np.int32, fillvalue=0)
            var[...] = values
            var.attrs["long_name"] = "GLT Sample Lookup" if name == "glt_x" else "GLT Line Lookup"
        f.attrs.update({
            "ncei_template_version": "NCEI_NetCDF_Swath_Template_v2.0", "title": "EMIT L2A Estimated Surface "
            "Reflectance 60 m V001", "summary": "surface reflectance", "keywords": "Imaging Spectroscopy",
            "Conventions": "CF-1.63", "institution": "NASA Jet Propulsion Laboratory/California Institute of "
            "Technology", "platform": "ISS", "instrument": "EMIT", "processing_level": "L2A",
            "time_coverage_start": "2022-08-15T04:28:38+0000", "time_coverage_end": "2022-08-15T04:28:50+0000",
            "spatialResolution": EMIT_PIXEL_DEG, "spatial_ref": spatial_ref or CRS.from_epsg(4326).to_wkt("WKT1_GDAL"),
            "geotransform": np.array(transform, np.float64),
            "northernmost_latitude": transform[3], "southernmost_latitude": transform[3] - gx.shape[0] * EMIT_PIXEL_DEG,
            "westernmost_longitude": transform[0], "easternmost_longitude": transform[0] + gx.shape[1] * EMIT_PIXEL_DEG,
        })
    return path, Truth(rho.astype(np.float64), wl, good, empty, transform, 4326, extra={"glt": (gx, gy)},
                       stored=np.where(empty[:, :, None], np.nan, rho.astype(np.float64)))


# --- PRISMA L2D: HDF-EOS5 -----------------------------------------------------------------------------------------

def write_prisma(tmp: Path, rows: int = 24, cols: int = 30) -> tuple[Path, Truth]:
    """A PRISMA L2D file: VNIR (66) and SWIR (173) cubes (rows, bands, cols) uint16 in decreasing wavelength, the
    first three VNIR and last two SWIR bands flagged (wavelength 0), L2Scale attributes, UTM 32N corners at 30 m,
    DN 0 in every band at an empty corner."""
    import h5py

    vnir = np.linspace(1010.0, 402.4, 66)
    swir = np.linspace(2497.0, 920.0, 173)
    vnir_flags, swir_flags = np.ones(66, np.int8), np.ones(173, np.int8)
    vnir_flags[:3], swir_flags[-2:] = 0, 0
    vnir_cw, swir_cw = np.where(vnir_flags == 1, vnir, 0.0), np.where(swir_flags == 1, swir, 0.0)
    scales = {"Vnir": (0.0, 0.85), "Swir": (0.0, 0.72)}
    empty = _corner(rows, cols, 6)
    cubes, truth, stored = {}, {}, {}
    for d, w in (("Vnir", vnir), ("Swir", swir)):
        rho = reflectance(w, rows, cols, seed=7)
        lo, hi = scales[d]
        dn = np.round((rho - lo) / (hi - lo) * 65535).astype(np.uint16)
        dn[empty] = 0
        cubes[d] = np.ascontiguousarray(np.moveaxis(dn, -1, 1))  # (rows, bands, cols)
        truth[d] = rho
        stored[d] = np.where(empty[:, :, None], np.nan, np.float32(lo) + dn * np.float32((hi - lo) / 65535))
    ul_e, ul_n = 600015.0, 5100015.0  # centre of the upper-left pixel
    path = tmp / PRISMA_NAME
    with h5py.File(path, "w") as f:
        f.create_dataset("HDFEOS INFORMATION/StructMetadata.0",
                         data=np.bytes_("GROUP=SwathStructure\nGROUP=SWATH_1\nSwathName=\"PRS_L2D_HCO\"\n"))
        f.create_dataset("HDFEOS/SWATHS/PRS_L2D_HCO/Data Fields/VNIR_Cube", data=cubes["Vnir"])
        f.create_dataset("HDFEOS/SWATHS/PRS_L2D_HCO/Data Fields/SWIR_Cube", data=cubes["Swir"])
        f.create_dataset("HDFEOS/SWATHS/PRS_L2D_HCO/Data Fields/VNIR_PIXEL_L2_ERR_MATRIX",
                         data=np.zeros_like(cubes["Vnir"], np.uint8))
        f.create_dataset("HDFEOS/SWATHS/PRS_L2D_HCO/Geolocation Fields/Latitude", data=np.zeros((rows, cols), "f4"))
        f.create_dataset("HDFEOS/SWATHS/PRS_L2D_HCO/Geolocation Fields/Longitude", data=np.zeros((rows, cols), "f4"))
        f.create_dataset("HDFEOS/SWATHS/PRS_L2D_PCO/Data Fields/Cube", data=np.zeros((rows * 6, cols * 6), "u2"))
        f.attrs.update({
            "Product_ID": np.bytes_("PRS_L2D_STD"), "Processing_Level": np.bytes_("2D"), "Epsg_Code": np.int32(32632),
            "List_Cw_Vnir": vnir_cw.astype(np.float32), "List_Fwhm_Vnir": np.full(66, 10.5, np.float32),
            "List_Cw_Vnir_Flags": vnir_flags, "List_Cw_Swir": swir_cw.astype(np.float32),
            "List_Fwhm_Swir": np.full(173, 11.8, np.float32), "List_Cw_Swir_Flags": swir_flags,
            "L2ScaleVnirMin": np.float32(scales["Vnir"][0]), "L2ScaleVnirMax": np.float32(scales["Vnir"][1]),
            "L2ScaleSwirMin": np.float32(scales["Swir"][0]), "L2ScaleSwirMax": np.float32(scales["Swir"][1]),
            "Product_ULcorner_easting": ul_e, "Product_ULcorner_northing": ul_n,
            "Product_LRcorner_easting": ul_e + (cols - 1) * 30.0, "Product_LRcorner_northing": ul_n - (rows - 1) * 30.0,
            "Product_center_easting": ul_e + (cols - 1) * 15.0, "Product_center_northing": ul_n - (rows - 1) * 15.0,
        })
    wl = np.concatenate([vnir, swir])
    good = np.concatenate([vnir_flags, swir_flags]) == 1
    rho = np.concatenate([truth["Vnir"], truth["Swir"]], axis=-1)
    step = max((hi - lo) / 65535 for lo, hi in scales.values())
    return path, Truth(rho, wl, good, empty, (ul_e - 15.0, 30.0, 0.0, ul_n + 15.0, 0.0, -30.0), 32632, step=step,
                       stored=np.concatenate([stored["Vnir"], stored["Swir"]], axis=-1))


# --- AVIRIS-NG L2 reflectance: ENVI with map info -----------------------------------------------------------------

def write_aviris(tmp: Path, rows: int = 48, cols: int = 36, *, rotation: float = 0.0,
                 coordinate_system: str | None = None) -> tuple[Path, Truth]:
    """An AVIRIS-NG L2 reflectance pair: data file ``ang…_rfl_v2r2_img`` (no extension, float32, BIL) and its
    ``.hdr`` with map info (UTM zone 11 North, 5 m pixels, optional rotation), the coordinate system string (ESRI
    WKT), 425 bands in nm with FWHM, a bbl over the water windows and data ignore value -9999."""
    from pyproj import CRS

    wl = np.linspace(376.86, 2500.6, 425)
    good = np.ones(wl.size, bool)
    for lo, hi in WATER:
        good &= ~((wl > lo) & (wl < hi))
    rho = reflectance(wl, rows, cols, seed=11).astype(np.float32)
    empty = _corner(rows, cols, 9)
    stored = rho.copy()
    stored[empty] = -9999.0
    data = tmp / AVIRIS_NAME
    np.ascontiguousarray(np.moveaxis(stored, -1, 1)).astype("<f4").tofile(data)  # BIL: (lines, bands, samples)
    east, north = 724522.127, 4074620.759
    wkt = coordinate_system or CRS.from_epsg(32611).to_wkt("WKT1_ESRI")
    rot = f" , rotation={rotation:.8f}" if rotation else ""
    header = (
        "ENVI\ndescription = {\n  AVIRIS-NG Atmospherically corrected reflectance}\n"
        f"samples = {cols}\nlines = {rows}\nbands = {wl.size}\nheader offset = 0\nfile type = ENVI Standard\n"
        "data type = 4\ninterleave = bil\nbyte order = 0\n"
        f"map info = {{ UTM , 1.000 , 1.000 , {east} , {north} , 5.0000000000e+00 , 5.0000000000e+00 , 11 , North , "
        f"WGS-84 , units=Meters{rot} }}\n"
        f"coordinate system string = {{{wkt}}}\n"
        "wavelength units = Nanometers\n"
        "wavelength = { " + " , ".join(f"{w:.6f}" for w in wl) + " }\n"
        "fwhm = { " + " , ".join("5.5" for _ in wl) + " }\n"
        "bbl = { " + " , ".join("1" if g else "0" for g in good) + " }\n"
        "data ignore value = -9999\n")
    (tmp / f"{AVIRIS_NAME}.hdr").write_text(header)
    return data, Truth(rho.astype(np.float64), wl, good, empty, (east, 5.0, 0.0, north, 0.0, -5.0), 32611,
                       stored=np.where(empty[:, :, None], np.nan, rho.astype(np.float64)))


# --- a generic GeoTIFF with GDAL band metadata --------------------------------------------------------------------

def write_geotiff(tmp: Path, rows: int = 24, cols: int = 24, *, wavelengths: bool = True,
                  name: str = "cube.tif") -> tuple[Path, Truth]:
    """A GeoTIFF as GDAL writes one from an ENVI cube: int16 with each band's scale 1e-4, no data -9999, and the
    band metadata items ``wavelength`` (µm, ``wavelength_units = Micrometers``) and ``fwhm``; UTM 33N at 10 m."""
    import rasterio
    from rasterio.transform import Affine

    wl = np.arange(400.0, 2501.0, 10.0)
    rho = reflectance(wl, rows, cols, seed=13)
    ints = np.round(rho * 10000).astype(np.int16)
    empty = _corner(rows, cols, 4)
    ints[empty] = -9999
    transform = (500000.0, 10.0, 0.0, 5300000.0, 0.0, -10.0)
    path = tmp / name
    with rasterio.open(path, "w", driver="GTiff", width=cols, height=rows, count=wl.size, dtype="int16",
                       crs="EPSG:32633", transform=Affine.from_gdal(*transform), nodata=-9999) as dst:
        dst.write(np.moveaxis(ints, -1, 0))
        dst.scales = [1e-4] * wl.size
        dst.offsets = [0.0] * wl.size
        dst.update_tags(wavelength_units="Micrometers")
        for b in range(1, wl.size + 1):
            if wavelengths:
                dst.update_tags(b, wavelength=f"{wl[b - 1] / 1000:.4f}", fwhm="0.0100",
                                wavelength_units="Micrometers")
            dst.set_band_description(b, f"band {b}")
    return path, Truth(rho, wl, np.ones(wl.size, bool), empty, transform, 32633, step=1e-4,
                       stored=np.where(empty[:, :, None], np.nan, ints * 1e-4))
