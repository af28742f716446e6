"""PRISMA L2D surface reflectance (``PRS_L2D_STD_20201107101404_20201107101408_0001.he5``), HDF-EOS5 as ASI ships
it, read with h5py:

- ``HDFEOS/SWATHS/PRS_L2D_HCO/Data Fields/VNIR_Cube`` and ``SWIR_Cube``: ``(rows, bands, columns)`` uint16 (band
  interleaved by line), bands in *decreasing* wavelength;
- root attributes ``List_Cw_Vnir``, ``List_Fwhm_Vnir``, ``List_Cw_Vnir_Flags`` (and ``…_Swir``): each band's centre
  and FWHM (nm), and whether it is valid (a band with flag 0 or wavelength 0 is dropped as bad);
  ``L2ScaleVnirMin``, ``L2ScaleVnirMax`` (and ``…Swir…``): reflectance = min + DN · (max − min) / 65535;
- ``Epsg_Code`` and ``Product_ULcorner_easting``, ``…_northing``, ``Product_LRcorner_…``: the map grid (the corners
  are the centres of the corner pixels, as the EnMAP-Box importer reads them).

The detectors overlap (about 920–1010 nm): the VNIR bands at or above the first kept SWIR band are not used (the
SWIR detector's are), so that the wavelengths increase. A pixel whose DNs are 0 in every band is no data (the
geocoded product's fill outside the swath).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError
from s2cl.io.cube_reader import CubeReader
from s2cl.io.georef import GeoRef, crs_wkt
from s2cl.io.products.bands import BandSelection
from s2cl.io.products.hdf5 import open_hdf5

SWATH = "HDFEOS/SWATHS/PRS_L2D_HCO"
CUBES = {"Vnir": f"{SWATH}/Data Fields/VNIR_Cube", "Swir": f"{SWATH}/Data Fields/SWIR_Cube"}
DN_MAX = 65535.0


def is_prisma(p: Path) -> bool:
    """Whether ``p`` is a PRISMA product (an ``HDFEOS/SWATHS/PRS_…`` swath); one of another level than L2D is
    refused here, naming its level."""
    with open_hdf5(p) as f:
        swaths = list(f["HDFEOS/SWATHS"]) if "HDFEOS/SWATHS" in f else []
    prs = [s for s in swaths if s.startswith("PRS_")]
    if not prs:
        return False
    if "PRS_L2D_HCO" not in prs:
        raise InputError(f"is a PRISMA product with swaths {', '.join(prs)}; s2cl reads L2D (geocoded surface "
                         "reflectance, swath PRS_L2D_HCO)", source=p)
    return True


def _attr(f: Any, name: str, p: Path) -> np.ndarray:
    if name not in f.attrs:
        raise InputError("root attribute is missing", source=p, key=name)
    return np.asarray(f.attrs[name]).reshape(-1)


def _scalar(f: Any, name: str, p: Path) -> float:
    value = _attr(f, name, p)
    try:
        return float(value[0])
    except (TypeError, ValueError):
        raise InputError("must be a number", source=p, key=name) from None


def open_prisma(p: Path) -> Any:
    """The PRISMA L2D file ``p`` opened for reading by rows."""
    det: dict[str, dict[str, Any]] = {}
    with open_hdf5(p) as f:
        shape = None
        for d, path in CUBES.items():
            if path not in f:
                raise InputError("is missing", source=p, key=path)
            cube = f[path]
            if cube.ndim != 3:
                raise InputError(f"needs 3 dimensions (rows, bands, columns), got {cube.ndim}", source=p, key=path)
            rows, nb, cols = cube.shape
            if shape is not None and shape != (rows, cols):
                raise InputError(f"is {rows} × {cols} pixels; VNIR_Cube is {shape[0]} × {shape[1]}", source=p,
                                 key=path)
            shape = (rows, cols)
            wl = _attr(f, f"List_Cw_{d}", p).astype(np.float64)
            if wl.size != nb:
                raise InputError(f"lists {wl.size} wavelengths for {nb} bands of {path.rsplit('/', 1)[1]}",
                                 source=p, key=f"List_Cw_{d}")
            flags = (_attr(f, f"List_Cw_{d}_Flags", p) != 0 if f"List_Cw_{d}_Flags" in f.attrs
                     else np.ones(nb, bool))
            lo, hi = _scalar(f, f"L2Scale{d}Min", p), _scalar(f, f"L2Scale{d}Max", p)
            det[d] = {"wl": wl, "good": flags & (wl > 0), "fwhm": _attr(f, f"List_Fwhm_{d}", p).astype(np.float64),
                      "gain": (hi - lo) / DN_MAX, "offset": lo, "bands": nb}
        georef = _georef(f, p, *shape)
    swir_start = det["Swir"]["wl"][det["Swir"]["good"]].min(initial=np.inf)
    overlap = det["Vnir"]["good"] & (det["Vnir"]["wl"] >= swir_start)
    # one band list: VNIR then SWIR, the VNIR bands in the overlap left out (neither kept nor bad)
    wl = np.concatenate([det["Vnir"]["wl"][~overlap], det["Swir"]["wl"]])
    good = np.concatenate([det["Vnir"]["good"][~overlap], det["Swir"]["good"]])
    fwhm = np.concatenate([det["Vnir"]["fwhm"][~overlap], det["Swir"]["fwhm"]])
    bands = BandSelection.of(wl, good, p, "List_Cw_Vnir")
    vnir_pos = np.flatnonzero(~overlap)  # positions in the VNIR cube of the merged list's first entries
    n_vnir = vnir_pos.size
    source = [("Vnir", int(vnir_pos[k])) if k < n_vnir else ("Swir", k - n_vnir) for k in bands.index]
    gains = np.array([det[d]["gain"] for d, _ in source], np.float64)
    offsets = np.array([det[d]["offset"] for d, _ in source], np.float64)

    def read(start: int, stop: int) -> np.ndarray:
        with open_hdf5(p) as f:
            raw = {d: np.asarray(f[CUBES[d]][start:stop]) for d in CUBES}  # (rows, bands, cols)
        empty = np.all(raw["Vnir"] == 0, axis=1) & np.all(raw["Swir"] == 0, axis=1)
        out = np.empty((stop - start, raw["Vnir"].shape[2], len(source)), np.float32)
        for j, (d, b) in enumerate(source):
            out[:, :, j] = raw[d][:, b, :] * np.float32(gains[j]) + np.float32(offsets[j])
        out[empty] = np.nan
        return out

    notes = [f"VNIR bands from {swir_start:.1f} nm up ({int(overlap.sum())}) left out for the SWIR detector's"]
    if not good.all():
        notes.append(f"{int((~good).sum())} bands dropped (flag 0 or wavelength 0)")
    return CubeReader(p, *georef[1], bands.wavelengths_nm, bands.bad_nm, read, georef=georef[0],
                      product="PRISMA L2D", quantity="reflectance", fwhm_nm=fwhm[bands.index], notes=tuple(notes),
                      stored_bands=det["Vnir"]["bands"] + det["Swir"]["bands"],
                      bad_bands_by=("List_Cw_Vnir_Flags", "the band flags (List_Cw_Vnir_Flags and List_Cw_Swir_Flags "
                                    "0, or wavelength 0)"))


def _georef(f: Any, p: Path, rows: int, cols: int) -> tuple[GeoRef, tuple[int, int]]:
    """The map grid from ``Epsg_Code`` and the corner pixels' centres; and the image's (rows, cols)."""
    code = int(_scalar(f, "Epsg_Code", p))
    ul_e, ul_n = _scalar(f, "Product_ULcorner_easting", p), _scalar(f, "Product_ULcorner_northing", p)
    lr_e, lr_n = _scalar(f, "Product_LRcorner_easting", p), _scalar(f, "Product_LRcorner_northing", p)
    dx = (lr_e - ul_e) / (cols - 1) if cols > 1 else 30.0
    dy = (ul_n - lr_n) / (rows - 1) if rows > 1 else 30.0
    if not (dx > 0 and dy > 0):
        raise InputError(f"the lower-right corner ({lr_e:g}, {lr_n:g}) is not right of and below the upper-left "
                         f"({ul_e:g}, {ul_n:g})", source=p, key="Product_LRcorner_easting")
    crs = crs_wkt(f"EPSG:{code}", p, "Epsg_Code")
    return GeoRef((ul_e - dx / 2, dx, 0.0, ul_n + dy / 2, 0.0, -dy), crs, f"{p.name} (Epsg_Code, corners)"), (rows,
                                                                                                            cols)
