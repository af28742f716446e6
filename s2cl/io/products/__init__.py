"""Imaging-spectrometer products as the missions ship them, opened behind :func:`s2cl.io.cubes.open_cube`: each
reader gives a :class:`s2cl.io.cube_reader.CubeReader` (rows read on demand, NaN where the product marks no data, bad
bands dropped, wavelengths in nm, increasing) with the product's georeference.

=================  ==========================================================  =================================
product            what is opened                                              module
=================  ==========================================================  =================================
EnMAP L2A          the product folder, its ``…-SPECTRAL_IMAGE.TIF`` or its     :mod:`s2cl.io.products.enmap`
                   ``…-METADATA.XML``
EMIT L2A RFL       the NetCDF-4 file (groups ``sensor_band_parameters``,        :mod:`s2cl.io.products.emit`
                   ``location``)
PRISMA L2D         the HDF-EOS5 file (``HDFEOS/SWATHS/PRS_L2D_HCO``)            :mod:`s2cl.io.products.prisma`
GeoTIFF            any GeoTIFF whose bands carry GDAL ``wavelength`` (and       :mod:`s2cl.io.products.geotiff`
                   ``fwhm``) metadata
=================  ==========================================================  =================================

ENVI files (AVIRIS-NG, AVIRIS-3 …, with ``map info``) and s2cl's own NetCDF cubes are read by
:mod:`s2cl.io.cubes` itself. What a file is comes from its first bytes (HDF5, TIFF) and, for HDF5, from its groups,
never from its name alone.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from s2cl.io.cube_reader import CubeReader

HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"
TIFF_MAGICS = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")
#: ``surface.geometry`` values: a product in sensor geometry with a lookup table (EMIT) is orthorectified onto its
#: map grid (``map``) or kept as the sensor saw it (``sensor``)
GEOMETRIES = ("map", "sensor")


def file_kind(p: Path) -> str:
    """``hdf5``, ``tiff`` or ``other``, from the file's first bytes."""
    try:
        with open(p, "rb") as f:
            head = f.read(8)
    except OSError:
        return "other"
    if head == HDF5_MAGIC:
        return "hdf5"
    if head[:4] in TIFF_MAGICS:
        return "tiff"
    return "other"


def open_product(p: Path, variable: str | None = None, geometry: str = "map") -> CubeReader | None:
    """The product at ``p`` opened (a folder, or a regular file already checked), or None when ``p`` is none of the
    products of this package (then :func:`s2cl.io.cubes.open_cube` reads it as ENVI or NetCDF)."""
    if p.is_dir():
        from s2cl.io.products.enmap import open_enmap

        return open_enmap(p)
    if p.suffix.lower() == ".xml":
        from s2cl.io.products.enmap import open_enmap

        return open_enmap(p)
    kind = file_kind(p)
    if kind == "tiff":
        from s2cl.io.products.enmap import enmap_xml_beside, open_enmap

        if enmap_xml_beside(p) is not None:
            return open_enmap(p)
        from s2cl.io.products.geotiff import open_geotiff

        return open_geotiff(p)
    if kind == "hdf5":
        from s2cl.io.products.emit import is_emit, open_emit
        from s2cl.io.products.prisma import is_prisma, open_prisma

        if is_prisma(p):
            return open_prisma(p)
        if is_emit(p, variable):
            return open_emit(p, geometry, variable)
    return None
