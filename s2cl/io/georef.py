"""A product's georeference (a CRS and the affine transform of its pixel grid), read from what each format ships,
and carried through to every band group's grid of the outputs.

The transform is in GDAL's order ``(x0, a, b, y0, d, e)``: the map position of the *corner* of pixel ``(row, col)``
is ``x = x0 + col·a + row·b``, ``y = y0 + col·d + row·e`` (map units: metres for a projected CRS, degrees for a
geographic one). A band group of ``factor`` input pixels per band pixel has the same origin and CRS and the
transform's four linear terms multiplied by ``factor`` (:meth:`GeoRef.scaled`); its pixel centres are the corners
plus half a pixel. CRS strings are parsed by pyproj (the ``geo`` extra): a CRS pyproj cannot parse is an
:class:`InputError` naming the file and the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import DependencyError, InputError, token

#: the optional extra that holds rasterio (GDAL) and pyproj
GEO_EXTRA = "pip install 's2cl[geo]'"
#: CF grid-mapping variable of each band group's grid (``crs_10m`` …), and the global attribute saying where the
#: georeference came from
GRID_MAPPING_PREFIX = "crs_"
NO_GEOREFERENCE = ("none: the input cube has no georeference; x and y are metres from the upper-left corner of its "
                   "first pixel along columns and rows")


def pyproj_crs() -> Any:
    """The ``pyproj.CRS`` class, or a :class:`DependencyError` naming the extra."""
    try:
        from pyproj import CRS
    except ImportError as err:
        raise DependencyError(f"reading or writing a CRS needs pyproj: {GEO_EXTRA}") from err
    return CRS


def crs_wkt(text: str, source: str | Path, key: str) -> str:
    """``text`` (WKT, ``EPSG:n``, a PROJ string …) as WKT 2, checked by pyproj; an :class:`InputError` naming
    ``source: key`` when pyproj cannot parse it."""
    crs_class = pyproj_crs()
    from pyproj.exceptions import CRSError

    try:
        return str(crs_class.from_user_input(text).to_wkt())
    except (CRSError, TypeError, ValueError) as err:
        raise InputError(f"{token(str(text))} is not a CRS pyproj can parse ({type(err).__name__})", source=source,
                         key=key) from None


@dataclass(frozen=True)
class GeoRef:
    """A pixel grid on the map: ``transform`` (GDAL order, see the module docstring) and ``crs`` (WKT, or None
    where the product gives a transform without a CRS); ``origin`` says where it was read from."""

    transform: tuple[float, float, float, float, float, float]
    crs: str | None
    origin: str

    def __post_init__(self) -> None:
        t = tuple(float(v) for v in self.transform)
        if len(t) != 6 or not all(math.isfinite(v) for v in t):
            raise InputError(f"a geotransform needs 6 finite numbers, got {self.transform}", source=self.origin)
        if t[1] * t[5] - t[2] * t[4] == 0:
            raise InputError(f"the geotransform {t} has no area (its pixel size is zero)", source=self.origin)
        object.__setattr__(self, "transform", t)

    @property
    def rotated(self) -> bool:
        """Whether the grid is rotated on the map (the transform's cross terms are not zero)."""
        return self.transform[2] != 0.0 or self.transform[4] != 0.0

    @property
    def pixel_size(self) -> tuple[float, float]:
        """The pixel's size along columns and along rows (map units, > 0)."""
        a, b, d, e = self.transform[1], self.transform[2], self.transform[4], self.transform[5]
        return math.hypot(a, d), math.hypot(b, e)

    def scaled(self, factor: int) -> GeoRef:
        """The grid of pixels ``factor × factor`` input pixels large, with the same upper-left corner."""
        x0, a, b, y0, d, e = self.transform
        return replace(self, transform=(x0, a * factor, b * factor, y0, d * factor, e * factor))

    def centres(self, ny: int, nx: int) -> tuple[np.ndarray, np.ndarray]:
        """Map coordinates of the pixel centres of the first ``ny`` rows (y) and ``nx`` columns (x) of a grid that
        is not rotated."""
        x0, a, _, y0, _, e = self.transform
        return y0 + (np.arange(ny) + 0.5) * e, x0 + (np.arange(nx) + 0.5) * a

    def units(self) -> str:
        """``metre``, ``degree`` or another unit name of the CRS's axes (``unknown`` without a CRS or pyproj)."""
        if self.crs is None:
            return "unknown"
        try:
            crs = pyproj_crs().from_wkt(self.crs)
        except DependencyError:
            return "unknown"
        if crs.is_geographic:
            return "degree"
        names = {a.unit_name for a in crs.axis_info}
        return "metre" if names <= {"metre", "meter"} else ", ".join(sorted(names))

    def describe(self) -> str:
        """One line: the CRS's name, the upper-left corner and the pixel size."""
        name = "no CRS"
        if self.crs is not None:
            try:
                name = pyproj_crs().from_wkt(self.crs).name
            except DependencyError:
                name = "a CRS"
        px, py = self.pixel_size
        return (f"{name}, upper-left corner ({self.transform[0]:.10g}, {self.transform[3]:.10g}), pixels "
                f"{px:.6g} × {py:.6g}{' (rotated)' if self.rotated else ''}, from {self.origin}")

    def gdal_transform(self) -> str:
        """The transform as GDAL's ``GeoTransform`` attribute writes it (6 numbers separated by spaces)."""
        return " ".join(repr(v) for v in self.transform)


def grid_mapping_attrs(georef: GeoRef) -> dict[str, Any]:
    """Attributes of a CF ``grid_mapping`` variable for ``georef``'s grid: pyproj's CF form of the CRS (``crs_wkt``
    and the projection's parameters), GDAL's ``spatial_ref`` (the same WKT) and ``GeoTransform`` (so GDAL and
    rioxarray take the transform as written, rotated or not)."""
    attrs: dict[str, Any] = {}
    if georef.crs is not None:
        try:
            attrs.update({k: v for k, v in pyproj_crs().from_wkt(georef.crs).to_cf().items()
                          if isinstance(v, str | int | float)})
        except DependencyError:
            pass
        attrs.update(crs_wkt=georef.crs, spatial_ref=georef.crs)
    attrs["GeoTransform"] = georef.gdal_transform()
    attrs["long_name"] = "CRS and pixel grid of this band group"
    return attrs


def axis_attrs(georef: GeoRef | None, axis: str) -> dict[str, Any]:
    """CF attributes of the ``x`` or ``y`` coordinate of a grid: projection coordinates in metres, longitude or
    latitude in degrees, or (no georeference, or a rotated grid) metres along the image's columns or rows."""
    along = "columns" if axis == "x" else "rows"
    if georef is None or georef.rotated or georef.crs is None:
        why = "no georeference" if georef is None else ("a rotated grid: see the grid mapping's GeoTransform"
                                                        if georef.rotated else "no CRS")
        return {"units": "m", "long_name": f"distance of the pixel centre from the image's corner along its {along} "
                f"({why})"}
    unit = georef.units()
    if unit == "degree":
        if axis == "x":
            return {"units": "degrees_east", "standard_name": "longitude", "axis": "X"}
        return {"units": "degrees_north", "standard_name": "latitude", "axis": "Y"}
    return {"units": "m" if unit == "metre" else unit, "standard_name": f"projection_{axis}_coordinate", "axis":
            axis.upper(), "long_name": f"{axis} coordinate of the pixel centre"}


def group_axes(georef: GeoRef | None, factor: int, gsd_m: float, ny: int, nx: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``y`` and ``x`` coordinate values of a band group's ``ny × nx`` grid of ``factor`` input pixels per
    pixel (``gsd_m`` m): its pixel centres on the map, or, without a georeference or on a rotated grid, metres from
    the image's corner."""
    if georef is None or georef.rotated or georef.crs is None:
        return (np.arange(ny) + 0.5) * gsd_m, (np.arange(nx) + 0.5) * gsd_m
    return georef.scaled(factor).centres(ny, nx)


def envi_georef(meta: dict[str, Any], hdr: Path) -> GeoRef | None:
    """The georeference of an ENVI header's ``map info`` (and ``coordinate system string``, the CRS as WKT), as
    GDAL's ENVI driver reads it: the reference pixel (1-based, its upper-left corner) at the given easting and
    northing, the pixel sizes, and ``rotation=`` degrees; None without a ``map info``."""
    info = meta.get("map info")
    if info is None:
        return None
    fields = [str(v).strip() for v in (info if isinstance(info, list) else str(info).strip("{}").split(","))]
    if len(fields) < 7:
        raise InputError(f"needs at least 7 values (projection, reference pixel x y, easting, northing, pixel size "
                         f"x y), got {len(fields)}", source=hdr, key="map info")
    try:
        ref_x, ref_y, east, north, dx, dy = (float(v) for v in fields[1:7])
    except ValueError:
        raise InputError("holds a value that is not a number among its reference pixel, position and pixel size",
                         source=hdr, key="map info") from None
    if not (dx > 0 and dy > 0):
        raise InputError(f"pixel sizes must be > 0, got {dx:g} and {dy:g}", source=hdr, key="map info")
    rotation = 0.0
    for f in fields[7:]:
        name, _, value = f.partition("=")
        if name.strip().lower() == "rotation":
            try:
                rotation = float(value)
            except ValueError:
                raise InputError(f"rotation {token(value)} is not a number", source=hdr, key="map info") from None
    c, s = math.cos(math.radians(rotation)), math.sin(math.radians(rotation))
    # as GDAL's ENVI driver (and so rasterio) reads it: the origin offset by the unrotated pixel sizes, the linear
    # terms turned by `rotation`
    a, b, d, e = (dx, 0.0, 0.0, -dy) if rotation == 0.0 else (c * dx, s * dx, s * dy, -c * dy)
    x0, y0 = east - (ref_x - 1) * dx, north + (ref_y - 1) * dy
    return GeoRef((x0, a, b, y0, d, e), _envi_crs(meta, fields, hdr), f"{hdr.name} (map info)")


def _envi_crs(meta: dict[str, Any], fields: list[str], hdr: Path) -> str | None:
    """The CRS of an ENVI header: its ``coordinate system string``, else a UTM or geographic ``map info`` on
    WGS-84; None for another projection without a coordinate system string."""
    text = meta.get("coordinate system string")
    if text:
        wkt = ",".join(text) if isinstance(text, list) else str(text)
        return crs_wkt(wkt.strip("{} "), hdr, "coordinate system string")
    projection = fields[0].strip().lower()
    datum = " ".join(f.lower() for f in fields[7:])
    if "wgs" not in datum or "84" not in datum:
        return None
    if projection == "utm" and len(fields) >= 9:
        try:
            zone = int(fields[7])
        except ValueError:
            raise InputError(f"UTM zone {token(fields[7])} is not a whole number", source=hdr, key="map info") from None
        south = fields[8].strip().lower().startswith("s")
        return crs_wkt(f"EPSG:{(32700 if south else 32600) + zone}", hdr, "map info")
    if projection.startswith("geographic"):
        return crs_wkt("EPSG:4326", hdr, "map info")
    return None


def grid_dimensions(store: Any, dims: tuple[str, str], georef: GeoRef | None, factor: int, gsd_m: float, ny: int,
                    nx: int) -> None:
    """Create a band group's ``y`` and ``x`` dimensions in ``store`` (:mod:`s2cl.io.image_store`) with their CF
    coordinates (:func:`group_axes`, :func:`axis_attrs`) and, with a georeference, the group's grid-mapping variable
    (``crs_10m`` …, :func:`grid_mapping_attrs` of the input's grid scaled by ``factor``), which every variable
    created on the group's grid names."""
    scaled = None if georef is None else georef.scaled(factor)
    y, x = group_axes(georef, factor, gsd_m, ny, nx)
    store.dimension(dims[0], y, axis_attrs(scaled, "y"))
    store.dimension(dims[1], x, axis_attrs(scaled, "x"))
    if scaled is not None:
        name = GRID_MAPPING_PREFIX + dims[0].split("_", 1)[1]
        store.scalar(name, grid_mapping_attrs(scaled))
        store.grid_mappings[dims[0]] = name


def georef_attrs(georef: GeoRef | None, product: dict[str, Any]) -> dict[str, Any]:
    """Global attributes of a simulation of a cube with ``georef``: where the georeference came from (or that there
    is none) and what the reader said (``product`` of :func:`product_attrs`)."""
    if georef is None:
        return {"georeference": NO_GEOREFERENCE, **product}
    return {"georeference": f"{georef.describe()}; each GSD group's grid: the input's transform scaled by its "
            f"GSD factor (variables name their group's grid mapping)", **product}


def product_attrs(reader: Any) -> dict[str, Any]:
    """What a cube reader (:class:`s2cl.io.cube_reader.CubeReader`) read, as global attributes."""
    attrs: dict[str, Any] = {"input_product": reader.product, "input_file": reader.path.name,
                             "input_bands": int(reader.wavelengths_nm.size),
                             "input_bad_bands": int(reader.bad_nm.size),
                             "input_wavelength_range_nm": f"{reader.wavelengths_nm[0]:g}-{reader.wavelengths_nm[-1]:g}"}
    if reader.georef is not None:
        px, py = reader.georef.pixel_size
        attrs["input_pixel_size"] = f"{px:.10g} x {py:.10g} {reader.georef.units()}"
    if reader.notes:
        attrs["input_notes"] = "; ".join(reader.notes)
    return attrs
