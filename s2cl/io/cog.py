"""Cloud-Optimised GeoTIFFs of an image simulation (``s2cl simulate --format cog``), written from its store
(:mod:`s2cl.io.image_store`) row block by row block through rasterio (GDAL; the ``geo`` extra):

- ``bands_10m.tif``, ``bands_20m.tif``, ``bands_60m.tif``: one per GSD group, a band per sensor band named by its
  description (``B2`` … ``B12``), each band's centre, FWHM and GSD in its metadata. The radiometry is stated in the
  ``RADIOMETRY`` item: with atmospheric correction, L2 surface reflectance as Sentinel-2 L2A encodes it since
  processing baseline 04.00, ``DN = 10000 · ρ + 1000`` (uint16; ``BOA_QUANTIFICATION_VALUE`` 10000 and
  ``BOA_ADD_OFFSET`` −1000 in the metadata, and GDAL's scale 1e-4 and offset −0.1 so that readers that apply them
  get ρ; DN clipped to 1 … 65535, 0 is no data); otherwise TOA radiance in W m-2 sr-1 um-1 (float32, the
  calibrated radiance where the chain calibrates, else the noisy, else the noise-free; no data NaN).
- the retrieval map (``analysis_index.tif``, and with a truth ``<parameter>_map.tif`` and ``<parameter>_error.tif``,
  float32, no data NaN) and its status (``analysis_status.tif``, uint8, every pixel has one, so no no-data value),
  on the analysis grid.

Each file carries its group's CRS and transform (the input's scaled by the group's GSD factor,
:mod:`s2cl.io.georef`), or, without a georeference, a transform in metres from the image's corner and no CRS,
with a ``GEOREFERENCE`` item saying so. Every file is written whole beside its target and renamed onto it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.io.georef import NO_GEOREFERENCE, GeoRef
from s2cl.io.output import atomic_path

#: Sentinel-2 L2A encoding since processing baseline 04.00: DN = QUANTIFICATION · ρ − ADD_OFFSET
L2A_QUANTIFICATION, L2A_ADD_OFFSET = 10000.0, -1000.0
L2A_NODATA = 0
L2A_RADIOMETRY = ("L2A surface reflectance as Sentinel-2 encodes it since processing baseline 04.00: "
                  "DN = 10000 * rho + 1000 (rho = (DN + BOA_ADD_OFFSET) / BOA_QUANTIFICATION_VALUE), 0 = no data")
#: radiance variables of a band, the first present is written when there is no reflectance
RADIANCE_ORDER = ("calibrated", "noisy", "radiance")
#: rows written at a time
ROWS_PER_WRITE = 256


def l2a_dn(reflectance: np.ndarray) -> np.ndarray:
    """Reflectance as Sentinel-2 L2A digital numbers: ``round(10000 · ρ + 1000)`` clipped to 1 … 65535 (uint16),
    0 where ρ is not finite."""
    r = np.asarray(reflectance, dtype=np.float64)
    dn = np.clip(np.rint(L2A_QUANTIFICATION * r - L2A_ADD_OFFSET), 1, 65535)
    return np.where(np.isfinite(r), dn, L2A_NODATA).astype(np.uint16)


def group_transform(georef: GeoRef | None, factor: int, gsd_m: float) -> tuple[float, ...]:
    """The GDAL transform of a band group's grid: the input's scaled by ``factor``, or (no georeference) metres
    from the image's corner, rows downwards."""
    if georef is None:
        return (0.0, gsd_m, 0.0, 0.0, 0.0, -gsd_m)
    return georef.scaled(factor).transform


def write_cogs(store: Any, folder: Path, scene: Any, georef: GeoRef | None, analysis: dict[str, Any] | None,
               groups: list[tuple[int, list[int]]]) -> list[Path]:
    """Write the COGs of the simulation in ``store`` into ``folder`` (see the module docstring); the paths written.
    ``groups``: the scene's bands by GSD, ``(input pixels per band pixel, band indices)``
    (:func:`s2cl.forward.reach.band_groups`)."""
    bands = scene.sensor.bands
    gsd_in = float(scene.spec.surface.gsd_m)
    written = []
    for factor, ids in groups:
        gsd = bands[ids[0]].gsd_m
        names = [bands[k].name for k in ids]
        kind = _radiometry(store, names[0])
        variables = [f"{kind}_{n}" for n in names]
        tags = _radiometry_tags(kind, store.attrs_of(variables[0]))
        band_tags = [{"BAND_NAME": n, "CENTRE_NM": f"{bands[k].centre_nm:g}", "FWHM_NM": f"{bands[k].fwhm_nm:g}",
                      "GSD_M": f"{bands[k].gsd_m:g}", "VARIABLE": v} for n, k, v in zip(names, ids, variables,
                                                                                       strict=True)]
        path = folder / f"bands_{gsd:g}m.tif"
        written.append(_write(store, path, variables, names, band_tags, tags, georef, factor, gsd, kind))
    if analysis is not None:
        gsd = float(analysis["gsd_m"])
        factor = round(gsd / gsd_in)
        maps = ["analysis_index", "analysis_status"]
        parameter = analysis.get("parameter")
        if parameter and f"{parameter}_map" in store:
            maps += [f"{parameter}_map", f"{parameter}_error"]
        for name in maps:
            if name not in store:
                continue
            attrs = store.attrs_of(name)
            kind = "status" if name == "analysis_status" else "map"
            tags = {"QUANTITY": str(attrs.get("long_name", name)), "UNITS": str(attrs.get("units", "1"))}
            if kind == "status":
                tags.update(FLAG_VALUES=" ".join(str(int(v)) for v in np.atleast_1d(attrs.get("flag_values", []))),
                            FLAG_MEANINGS=str(attrs.get("flag_meanings", "")))
            written.append(_write(store, folder / f"{name}.tif", [name], [name], [{}], tags, georef, factor, gsd,
                                  kind))
    return written


def _radiometry(store: Any, band: str) -> str:
    """``reflectance`` where the chain corrects, else the first radiance variable present."""
    for kind in ("reflectance", *RADIANCE_ORDER):
        if f"{kind}_{band}" in store:
            return kind
    raise KeyError(band)


def _radiometry_tags(kind: str, attrs: dict[str, Any]) -> dict[str, str]:
    if kind == "reflectance":
        return {"RADIOMETRY": L2A_RADIOMETRY, "BOA_QUANTIFICATION_VALUE": f"{L2A_QUANTIFICATION:g}",
                "BOA_ADD_OFFSET": f"{L2A_ADD_OFFSET:g}", "PROCESSING_BASELINE_ENCODING": "04.00"}
    what = {"calibrated": "calibrated from DN", "noisy": "with sensor noise, before digitisation",
            "radiance": "noise-free band radiance"}[kind]
    return {"RADIOMETRY": f"TOA radiance, {attrs.get('units', 'W m-2 sr-1 um-1')} ({what})"}


def _write(store: Any, path: Path, variables: list[str], names: list[str], band_tags: list[dict[str, str]],
           tags: dict[str, str], georef: GeoRef | None, factor: int, gsd: float, kind: str) -> Path:
    """One COG of ``variables`` (all on one grid) at ``path``: a tiled GeoTIFF written by rows beside it, copied
    into the COG layout, renamed onto ``path``."""
    import rasterio
    from rasterio.shutil import copy as gdal_copy
    from rasterio.transform import Affine
    from rasterio.windows import Window

    ny, nx = store.shape(variables[0])
    dtype, nodata = {"reflectance": ("uint16", L2A_NODATA), "status": ("uint8", None)}.get(kind, ("float32",
                                                                                                 float("nan")))
    profile = {"driver": "GTiff", "width": nx, "height": ny, "count": len(variables), "dtype": dtype,
               "nodata": nodata, "tiled": True, "blockxsize": 256, "blockysize": 256, "compress": "deflate",
               "transform": Affine.from_gdal(*group_transform(georef, factor, gsd)),
               "crs": georef.crs if georef is not None and georef.crs is not None else None}
    if georef is None:
        tags = {**tags, "GEOREFERENCE": NO_GEOREFERENCE}
    strips = path.with_name(f".{path.name}.{os.getpid()}.strips.tmp")  # a killed run's is removed as stale
    try:
        with rasterio.open(strips, "w", **profile) as dst:
            for r0 in range(0, ny, ROWS_PER_WRITE):
                rows = slice(r0, min(ny, r0 + ROWS_PER_WRITE))
                for b, var in enumerate(variables, 1):
                    data = store.read(var, rows)
                    data = l2a_dn(data) if kind == "reflectance" else data.astype(dtype)
                    dst.write(data, b, window=Window(0, r0, nx, rows.stop - r0))
            dst.update_tags(**tags)
            for b, (name, bt) in enumerate(zip(names, band_tags, strict=True), 1):
                dst.set_band_description(b, name)
                if bt:
                    dst.update_tags(b, **bt)
            if kind == "reflectance":
                dst.scales = [1.0 / L2A_QUANTIFICATION] * len(variables)
                dst.offsets = [L2A_ADD_OFFSET / L2A_QUANTIFICATION] * len(variables)
        with atomic_path(path) as tmp:
            gdal_copy(strips, tmp, driver="COG", compress="DEFLATE", blocksize=256)
    finally:
        strips.unlink(missing_ok=True)
    return path
