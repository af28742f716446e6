"""Each product fixture (tests/product_fixtures.py) through ``s2cl simulate`` with an IGRM retrieval map:

- its band images equal those of the same reflectance given as a plain float NetCDF cube in nm (the good bands
  in increasing wavelength, on the map grid; EMIT's built through the lookup table by hand), so the reader, not
  the chain, is what is tested;
- every band group's grid and the map's carry the product's georeference, as GDAL (rasterio's netCDF driver) and
  xarray read it: the CRS, and the transform of the input scaled by the group's GSD factor (by hand).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

rasterio = pytest.importorskip("rasterio", reason="the geo extra (rasterio, pyproj) reads GeoTIFF and CRS")
sys.path.insert(0, str(Path(__file__).parent))
import product_fixtures as pf  # noqa: E402

from s2cl.app.simulate_scene import simulate_scene  # noqa: E402
from s2cl.forward.cube import simulate_cube  # noqa: E402
from s2cl.forward.product_scene import resolve_product_scene  # noqa: E402
from s2cl.scene.scene import Scene  # noqa: E402

#: (writer, the name the scene gives, surface.gsd_m: None to take the product's)
PRODUCTS = {
    "enmap": (pf.write_enmap, lambda p: p.name, 10.0),
    "emit": (pf.write_emit, lambda p: p.name, 10.0),
    "prisma": (pf.write_prisma, lambda p: p.name, 10.0),
    "aviris": (pf.write_aviris, lambda p: p.name, None),
    "geotiff": (pf.write_geotiff, lambda p: p.name, None),
}
GROUPS = {"B2": 10, "B5": 20, "B1": 60}


def _scene_dict(cube: str, gsd: float | None, **extra) -> dict:
    surface = {"cube": cube, "quantity": "reflectance"}
    if gsd is not None:
        surface["gsd_m"] = gsd
    return {"scene": {"name": "product"}, "surface": surface, "effects": {"atmosphere": True, "correct": True,
                                                                           "seed": 3},
            "analysis": {"kind": "igrm", "parameter": "cab", "bands": ["B4", "B5", "B6", "B7"]}, **extra}


def _plain_cube(truth: pf.Truth) -> tuple[np.ndarray, np.ndarray]:
    """The product's stored reflectance, good bands in increasing wavelength, on its map grid, by hand."""
    order = [i for i in np.argsort(truth.wavelengths_nm, kind="stable") if truth.good[i]]
    cube = truth.stored[:, :, order]
    if "glt" in truth.extra:  # EMIT: each map pixel takes the sensor pixel the lookup table names
        gx, gy = truth.extra["glt"]
        out = np.full((*gx.shape, len(order)), np.nan)
        for r, c in zip(*np.nonzero(gx), strict=True):
            out[r, c] = cube[gy[r, c] - 1, gx[r, c] - 1]
        cube = out
    return cube.astype(np.float32), truth.wavelengths_nm[order]


@pytest.mark.parametrize("name", list(PRODUCTS))
def test_a_product_through_simulate_keeps_its_values_and_its_georeference(rt, tmp_path, name: str) -> None:
    writer, cube_name, gsd = PRODUCTS[name]
    path, truth = writer(tmp_path)
    scene = Scene.from_dict(_scene_dict(cube_name(path), gsd), base_dir=tmp_path)
    run = simulate_scene(scene, tmp_path / "out")
    assert {p.name for p in run.written} == {"simulation.nc", "simulation.json", "quicklook.png"}
    resolved, _ = resolve_product_scene(scene)
    gsd_in = resolved.spec.surface.gsd_m
    # the same reflectance as a plain cube: same grid, same GSD, the chain's own reading
    cube, wl = _plain_cube(truth)
    if name == "prisma":  # PRISMA's VNIR bands in the detector overlap are left for the SWIR detector's
        keep = np.ones(wl.size, bool)
        swir_first = truth.wavelengths_nm[66:][truth.good[66:]].min()
        vnir = np.isin(wl, truth.wavelengths_nm[:66])
        keep &= ~(vnir & (wl >= swir_first))
        cube, wl = cube[:, :, keep], wl[keep]
    xr.Dataset({"reflectance": (("y", "x", "wavelength"), cube)},
               coords={"wavelength": ("wavelength", wl, {"units": "nm"})}).to_netcdf(tmp_path / "plain.nc",
                                                                                    engine="h5netcdf")
    plain = _scene_dict("plain.nc", gsd_in, grid={"start_nm": resolved.grid.start_nm,
                                                  "stop_nm": resolved.grid.stop_nm})
    reference = simulate_cube(rt, Scene.from_dict(plain, base_dir=tmp_path))
    with xr.open_dataset(run.folder / "simulation.nc", engine="h5netcdf", decode_coords="all") as ds:
        for band in ("B2", "B4", "B5", "B8a", "B12", "B1"):
            np.testing.assert_allclose(ds[f"radiance_{band}"].values, reference[f"radiance_{band}"].values,
                                       rtol=2e-5, equal_nan=True, err_msg=f"{name} {band}")
        assert np.isfinite(ds["analysis_index"].values).sum() > 20
        assert ds.attrs["input_product"] == {"enmap": "EnMAP L2A", "emit": "EMIT L2A", "prisma": "PRISMA L2D",
                                             "aviris": "ENVI", "geotiff": "GeoTIFF"}[name]
        x0, a, _, y0, _, e = truth.transform
        for band, band_gsd in GROUPS.items():
            f = round(band_gsd / gsd_in)
            var = ds[f"radiance_{band}"]
            ny, nx = var.shape
            np.testing.assert_allclose(var[var.dims[1]].values, x0 + (np.arange(nx) + 0.5) * a * f)
            np.testing.assert_allclose(var[var.dims[0]].values, y0 + (np.arange(ny) + 0.5) * e * f)
            assert var.encoding["grid_mapping"] == f"crs_{band_gsd}m"  # decode_coords="all" moves it there
            assert ds[f"crs_{band_gsd}m"].attrs["crs_wkt"]
    for var, band_gsd in (("radiance_B2", 10), ("radiance_B5", 20), ("radiance_B1", 60), ("analysis_index", 20)):
        f = round(band_gsd / gsd_in)
        with rasterio.open(f"netcdf:{run.folder / 'simulation.nc'}:{var}") as src:
            assert src.crs.to_epsg() == truth.epsg, (name, var)
            np.testing.assert_allclose(src.transform.to_gdal(), (x0, a * f, 0.0, y0, 0.0, e * f), rtol=1e-12,
                                       err_msg=f"{name} {var}")
    record = json.loads((run.folder / "simulation.json").read_text())
    assert record["analysis"]["kind"] == "igrm"


def test_a_cube_without_georeference_says_so(rt, tmp_path) -> None:
    """A plain NetCDF cube: x/y in metres from the corner, no grid mapping, and the attribute saying why."""
    from s2cl.io.georef import NO_GEOREFERENCE

    wl = np.arange(400.0, 2501.0, 10.0)
    cube = pf.reflectance(wl, 12, 12).astype(np.float32)
    xr.Dataset({"reflectance": (("y", "x", "wavelength"), cube)}, coords={"wavelength": wl}).to_netcdf(
        tmp_path / "c.nc", engine="h5netcdf")
    ds = simulate_cube(rt, Scene.from_dict(_scene_dict("c.nc", 10.0), base_dir=tmp_path))
    assert ds.attrs["georeference"] == NO_GEOREFERENCE
    assert "grid_mapping" not in ds["radiance_B5"].attrs
    np.testing.assert_allclose(ds["x_20m"].values, [10, 30, 50, 70, 90, 110])
    assert "no georeference" in ds["x_20m"].attrs["long_name"]


@pytest.mark.parametrize("name", ["emit", "prisma", "enmap"])
def test_a_product_in_row_blocks_gives_the_whole_image(rt, tmp_path, name: str) -> None:
    """Blocks of 6 input rows (each read from the product alone, EMIT's through its lookup table) give the image
    simulated at once, bit for bit."""
    from s2cl.forward.cube import load_scene_cube
    from s2cl.io.image_store import MemoryStore

    writer, cube_name, gsd = PRODUCTS[name]
    path, _ = writer(tmp_path)
    scene = Scene.from_dict(_scene_dict(cube_name(path), gsd), base_dir=tmp_path)
    whole = simulate_cube(rt, scene)
    store = MemoryStore()
    simulate_cube(rt, scene, load_scene_cube(scene), store=store, block_rows=6)
    blocks = store.dataset()
    for var in ("radiance_B2", "noisy_B5", "dn_B1", "reflectance_B12", "flags_B4"):
        np.testing.assert_array_equal(blocks[var].values, whole[var].values, err_msg=f"{name} {var}")
