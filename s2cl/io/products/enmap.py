"""EnMAP L2A products (GeoTIFF+Metadata format), as DLR ships them: a folder named after the product, e.g.
``ENMAP01-____L2A-DT0000025905_20230707T192008Z_001_V010303_20230922T131734Z/``, holding
``<name>-SPECTRAL_IMAGE.TIF`` (224 bands, int16 surface reflectance × 10000, no data -32768) and
``<name>-METADATA.XML`` (root ``level_X``), with quality layers (``-QL_PIXELMASK.TIF`` …) beside them.

From the XML: ``base/level`` (must be ``L2A``); each band's ``specific/bandCharacterisation/bandID`` (attribute
``number``) ``wavelengthCenterOfBand`` and ``FWHMOfBand`` (nm), ``GainOfBand`` and ``OffsetOfBand`` (reflectance =
stored · gain + offset); the VNIR and SWIR ``specific/*ProductQuality/expectedChannelsList`` (a band in neither is
dropped as bad); ``product/bandStatistics/bandID`` (a band whose ``mean`` is -1000000 with ``stdDeviation`` 0 is
filled with no data, as the EnMAP-Box importer reads it: dropped as bad); ``specific/widthOfOrthoScene``,
``heightOfOrthoScene`` and ``pixelSizeOfOrthoScene`` and ``product/ortho/projection`` (``UTM_Zone33_North``,
``Geographic``, ``LAEA_ETRS89``), checked against the GeoTIFF's own grid and CRS (the GeoTIFF's georeference is
the one used). The band count of the XML must be the image's.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError, token
from s2cl.io.cube_reader import CubeReader
from s2cl.io.georef import GeoRef, crs_wkt, pyproj_crs
from s2cl.io.inputs import input_file, number_at, parse_number
from s2cl.io.products.bands import BandSelection
from s2cl.io.products.geotiff import check_real, open_dataset, row_reader, tiff_georef

IMAGE_SUFFIX = "-SPECTRAL_IMAGE.TIF"
XML_SUFFIX = "-METADATA.XML"
#: the no-data value of EnMAP L2A reflectance where the GeoTIFF does not set one
NODATA = -32768
#: largest metadata XML read (bytes)
MAX_XML_BYTES = 50_000_000
#: ``bandStatistics`` of a band filled with no data
EMPTY_BAND_MEAN = -1000000.0


def _named(folder: Path, suffix: str) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.name.upper().endswith(suffix))


def enmap_xml_beside(tif: Path) -> Path | None:
    """The ``…-METADATA.XML`` of an EnMAP ``…-SPECTRAL_IMAGE.TIF`` (None when ``tif`` is not one, or has none)."""
    if not tif.name.upper().endswith(IMAGE_SUFFIX):
        return None
    stem = tif.name[: -len(IMAGE_SUFFIX)]
    for p in (tif.with_name(stem + XML_SUFFIX), tif.with_name(stem + XML_SUFFIX.lower())):
        if p.exists():
            return p
    return None


def _files(p: Path) -> tuple[Path, Path]:
    """(image, XML) of the product named by its folder, its image or its XML."""
    if p.is_dir():
        xmls = _named(p, XML_SUFFIX)
        if len(xmls) != 1:
            raise InputError(f"a folder is read as an EnMAP L2A product: it needs one *{XML_SUFFIX} file, found "
                             f"{len(xmls)}", source=p)
        xml = xmls[0]
    elif p.name.upper().endswith(XML_SUFFIX):
        xml = p
    else:
        found = enmap_xml_beside(p)
        if found is None:
            raise InputError(f"an EnMAP product is opened by its folder, its *{IMAGE_SUFFIX} or its *{XML_SUFFIX}",
                             source=p)
        xml = found
    stem = xml.name[: -len(XML_SUFFIX)]
    images = [xml.with_name(stem + s) for s in (IMAGE_SUFFIX, IMAGE_SUFFIX.lower(), IMAGE_SUFFIX[:-4] + ".tif")]
    image = next((i for i in images if i.exists()), None)
    if image is None:
        raise InputError(f"the EnMAP image {stem}{IMAGE_SUFFIX} is not beside it (s2cl reads the GeoTIFF+Metadata "
                         "format)", source=xml)
    return input_file(image, what="EnMAP image"), input_file(xml, what="EnMAP metadata")


def _xml(xml: Path) -> ET.Element:
    if xml.stat().st_size > MAX_XML_BYTES:
        raise InputError(f"is larger than {MAX_XML_BYTES:,} bytes: not an EnMAP metadata file", source=xml)
    try:
        root = ET.parse(xml).getroot()
    except (ET.ParseError, UnicodeDecodeError) as err:
        raise InputError(f"is not readable XML ({type(err).__name__})", source=xml) from None
    if root.tag != "level_X":
        raise InputError(f"root element is {token(root.tag)}; EnMAP metadata has 'level_X'", source=xml)
    return root


def _float(node: ET.Element | None, xml: Path, key: str) -> float:
    if node is None or node.text is None:
        raise InputError("is missing", source=xml, key=key)
    return number_at(node.text, source=xml, key=key)


def _band_table(root: ET.Element, xml: Path) -> dict[str, np.ndarray]:
    """Per band (in the file's order): wavelength, FWHM, gain, offset; checked to be numbered 1 … n."""
    key = "specific/bandCharacterisation/bandID"
    nodes = root.findall(key)
    if not nodes:
        raise InputError("has no band (no specific/bandCharacterisation/bandID)", source=xml, key=key)
    numbers = [n.get("number") for n in nodes]
    if numbers != [str(i) for i in range(1, len(nodes) + 1)]:
        raise InputError("bandID numbers must run 1, 2, … in order", source=xml, key=key)
    table = {name: np.array([_float(n.find(tag), xml, f"bandID {i + 1} {tag}") for i, n in enumerate(nodes)])
             for name, tag in (("wavelength", "wavelengthCenterOfBand"), ("fwhm", "FWHMOfBand"),
                               ("gain", "GainOfBand"), ("offset", "OffsetOfBand"))}
    return table


#: what marks EnMAP's bad bands (:attr:`s2cl.io.cube_reader.CubeReader.bad_bands_by`)
BAD_BANDS_BY = ("expectedChannelsList",
                "the XML's band quality (outside the expected channels, or filled with no data)")


def _good(root: ET.Element, n: int, xml: Path) -> np.ndarray:
    """Bands in a detector's expected channels and not filled with no data (True: good)."""
    good = np.ones(n, bool)
    lists = [root.findtext(f"specific/{d}ProductQuality/expectedChannelsList") for d in ("vnir", "swir")]
    if all(text is not None for text in lists):
        expected = np.zeros(n, bool)
        for text in lists:
            for item in str(text).split(","):
                if item.strip():
                    if not item.strip().isdigit():
                        raise InputError(f"{token(item.strip())} is not a channel number", source=xml,
                                         key="expectedChannelsList")
                    k = int(item.strip())
                    if not 1 <= k <= n:
                        raise InputError(f"names channel {k}; the product has {n}", source=xml,
                                         key="expectedChannelsList")
                    expected[k - 1] = True
        good &= expected
    stats = root.findall("product/bandStatistics/bandID")
    if len(stats) == n:
        for i, node in enumerate(stats):
            mean, std = node.findtext("mean"), node.findtext("stdDeviation")
            if mean is not None and std is not None:
                try:
                    empty = parse_number(mean.strip()) == EMPTY_BAND_MEAN and parse_number(std.strip()) == 0.0
                except ValueError:
                    continue
                good[i] &= not empty
    return good


def _projection_crs(name: str, xml: Path) -> str | None:
    """The CRS of ``product/ortho/projection``: ``UTM_Zone33_North`` → EPSG:32633, ``Geographic`` → EPSG:4326,
    ``LAEA_ETRS89`` → EPSG:3035 (None for anything else)."""
    m = re.fullmatch(r"UTM_Zone(\d{1,2})_(North|South)", name.strip(), re.IGNORECASE)
    if m:
        return crs_wkt(f"EPSG:{(32600 if m.group(2).lower() == 'north' else 32700) + int(m.group(1))}", xml,
                       "product/ortho/projection")
    code = {"geographic": 4326, "laea_etrs89": 3035}.get(name.strip().lower())
    return crs_wkt(f"EPSG:{code}", xml, "product/ortho/projection") if code else None


def _check_grid(root: ET.Element, xml: Path, rows: int, cols: int, georef: GeoRef | None) -> GeoRef | None:
    """The XML's scene size and projection against the image's; the georeference used (the image's, its CRS from
    the XML where the image has none)."""
    for tag, have in (("widthOfOrthoScene", cols), ("heightOfOrthoScene", rows)):
        text = root.findtext(f"specific/{tag}")
        if text is not None and text.strip() and int(_float(root.find(f"specific/{tag}"), xml, tag)) != have:
            raise InputError(f"says {text.strip()}; the image has {have}", source=xml, key=f"specific/{tag}")
    name = root.findtext("product/ortho/projection")
    crs = _projection_crs(name, xml) if name else None
    if georef is None:
        return None
    if georef.crs is None and crs is not None:
        return GeoRef(georef.transform, crs, f"{georef.origin}, CRS from {xml.name}")
    if crs is not None and georef.crs is not None:
        CRS = pyproj_crs()
        if not CRS.from_wkt(crs).equals(CRS.from_wkt(georef.crs), ignore_axis_order=True):
            raise InputError(f"{token(name or '')} is not the image's CRS ({CRS.from_wkt(georef.crs).name})",
                             source=xml, key="product/ortho/projection")
    return georef


def open_enmap(p: Path) -> Any:
    """The EnMAP L2A product named by ``p`` (its folder, image or XML) opened for reading by rows."""
    image, xml = _files(p)
    root = _xml(xml)
    level = (root.findtext("base/level") or "").strip()
    if level != "L2A":
        raise InputError(f"is an EnMAP {token(level or 'unknown-level')} product; s2cl reads L2A (surface "
                         "reflectance)", source=xml, key="base/level")
    table = _band_table(root, xml)
    with open_dataset(image) as src:
        check_real(src, image)
        if src.count != table["wavelength"].size:
            raise InputError(f"describes {table['wavelength'].size} bands; {image.name} has {src.count}", source=xml,
                             key="specific/bandCharacterisation")
        nodata = np.array([NODATA if v is None else v for v in src.nodatavals], dtype=np.float64)
        rows, cols = src.height, src.width
        georef = _check_grid(root, xml, rows, cols, tiff_georef(src, image))
    bands = BandSelection.of(table["wavelength"], _good(root, table["wavelength"].size, xml), xml,
                             "specific/bandCharacterisation")
    i = bands.index
    notes = []
    if bands.bad_nm.size:
        notes.append(f"{bands.bad_nm.size} bands dropped as bad (outside the expected channels, or filled with no "
                     "data)")
    return CubeReader(image, rows, cols, bands.wavelengths_nm, bands.bad_nm,
                      row_reader(image, i, nodata[i], table["gain"][i], table["offset"][i]), georef=georef,
                      product="EnMAP L2A", quantity="reflectance", fwhm_nm=table["fwhm"][i], notes=tuple(notes),
                      stored_bands=int(i.size), bad_bands_by=BAD_BANDS_BY)
