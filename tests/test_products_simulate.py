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

from s2cl.app.image_simulation import scene_cube, simulate_image  # noqa: E402
from s2cl.app.product_scene import resolve_product_scene  # noqa: E402
from s2cl.app.simulate_scene import simulate_scene  # noqa: E402
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
    scene = Scene.from_dict(_scene_dict(cube_name(path), gsd, output={"format": "cog"}), base_dir=tmp_path)
    run = simulate_scene(scene, tmp_path / "out")
    assert {p.name for p in run.written} == {"simulation.nc", "simulation.json", "quicklook.png", "bands_10m.tif",
                                             "bands_20m.tif", "bands_60m.tif", "analysis_index.tif",
                                             "analysis_status.tif"}
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
    reference = simulate_image(rt, Scene.from_dict(plain, base_dir=tmp_path))
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
    _check_cogs(run.folder, truth.epsg, truth.transform, gsd_in, ("analysis_index", "analysis_status"))


def test_a_cube_without_georeference_says_so(rt, tmp_path) -> None:
    """A plain NetCDF cube: x/y in metres from the corner, no grid mapping, and the attribute saying why."""
    from s2cl.io.georef import NO_GEOREFERENCE

    wl = np.arange(400.0, 2501.0, 10.0)
    cube = pf.reflectance(wl, 12, 12).astype(np.float32)
    xr.Dataset({"reflectance": (("y", "x", "wavelength"), cube)}, coords={"wavelength": wl}).to_netcdf(
        tmp_path / "c.nc", engine="h5netcdf")
    ds = simulate_image(rt, Scene.from_dict(_scene_dict("c.nc", 10.0), base_dir=tmp_path))
    assert ds.attrs["georeference"] == NO_GEOREFERENCE
    assert "grid_mapping" not in ds["radiance_B5"].attrs
    np.testing.assert_allclose(ds["x_20m"].values, [10, 30, 50, 70, 90, 110])
    assert "no georeference" in ds["x_20m"].attrs["long_name"]


@pytest.mark.parametrize("name", ["emit", "prisma", "enmap"])
def test_a_product_in_row_blocks_gives_the_whole_image(rt, tmp_path, name: str) -> None:
    """Blocks of 6 input rows (each read from the product alone, EMIT's through its lookup table) give the image
    simulated at once, bit for bit."""
    from s2cl.io.image_store import MemoryStore

    writer, cube_name, gsd = PRODUCTS[name]
    path, _ = writer(tmp_path)
    scene = Scene.from_dict(_scene_dict(cube_name(path), gsd), base_dir=tmp_path)
    whole = simulate_image(rt, scene)
    store = MemoryStore()
    simulate_image(rt, scene, scene_cube(scene), store=store, block_rows=6)
    blocks = store.dataset()
    for var in ("radiance_B2", "noisy_B5", "dn_B1", "reflectance_B12", "flags_B4"):
        np.testing.assert_array_equal(blocks[var].values, whole[var].values, err_msg=f"{name} {var}")


def _cog_run(tmp_path: Path, toml: str) -> Path:
    from click.testing import CliRunner

    from s2cl.cli.main import cli

    (tmp_path / "s.toml").write_text(toml)
    out = tmp_path / "out"
    r = CliRunner().invoke(cli, ["simulate", str(tmp_path / "s.toml"), "-o", str(out), "--format", "cog", "-q"])
    assert r.exit_code == 0, r.output
    return out


def _check_cogs(out: Path, epsg: int | None, transform: tuple[float, ...], gsd_in: float,
                maps: tuple[str, ...]) -> None:
    """Every GeoTIFF read back with rasterio: a COG; CRS; the transform's corner and pixel size per group (the
    input's scaled by band GSD / input GSD, by hand); no-data; values against simulation.nc (reflectance decoded
    with the file's own BOA_ADD_OFFSET and BOA_QUANTIFICATION_VALUE, and through GDAL's scale and offset)."""
    x0, a, b, y0, d, e = transform
    with xr.open_dataset(out / "simulation.nc", engine="h5netcdf") as ds:
        for gsd, bands in ((10, ("B2", "B3", "B4", "B8")), (20, ("B5", "B6", "B7", "B8a", "B11", "B12")),
                           (60, ("B1", "B9", "B10"))):
            f = round(gsd / gsd_in)
            with rasterio.open(out / f"bands_{gsd}m.tif") as src:
                assert src.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG"
                assert (src.crs.to_epsg() if src.crs else None) == epsg
                assert src.transform.to_gdal() == pytest.approx((x0, a * f, b * f, y0, d * f, e * f), rel=1e-12)
                assert src.descriptions == bands and src.nodata == 0 and src.dtypes[0] == "uint16"
                tags = src.tags()
                assert "DN = 10000 * rho + 1000" in tags["RADIOMETRY"]
                offset, quantification = float(tags["BOA_ADD_OFFSET"]), float(tags["BOA_QUANTIFICATION_VALUE"])
                assert (offset, quantification) == (-1000, 10000)
                for i, band in enumerate(bands, 1):
                    dn = src.read(i).astype(np.float64)
                    rho = ds[f"reflectance_{band}"].values.astype(np.float64)
                    assert src.tags(i)["BAND_NAME"] == band
                    assert np.array_equal(dn == 0, ~np.isfinite(rho)), band
                    ok = np.isfinite(rho) & (rho > -0.0999)
                    np.testing.assert_allclose((dn[ok] + offset) / quantification, rho[ok], atol=0.5 / quantification
                                               + 1e-7, err_msg=band)
                    np.testing.assert_allclose(dn[ok] * src.scales[i - 1] + src.offsets[i - 1], rho[ok],
                                               atol=0.5 / quantification + 1e-7)
        analysis_gsd = float(ds.attrs["analysis_gsd_m"])
        f = round(analysis_gsd / gsd_in)
        for name in maps:
            with rasterio.open(out / f"{name}.tif") as src:
                assert src.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG"
                assert (src.crs.to_epsg() if src.crs else None) == epsg
                assert src.transform.to_gdal() == pytest.approx((x0, a * f, b * f, y0, d * f, e * f), rel=1e-12)
                values = src.read(1)
                if name == "analysis_status":
                    assert src.nodata is None and src.dtypes[0] == "uint8"
                    np.testing.assert_array_equal(values, ds[name].values)
                else:
                    assert np.isnan(src.nodata) and src.dtypes[0] == "float32"
                    np.testing.assert_array_equal(values, ds[name].values)


@pytest.mark.parametrize("rotation", [0.0, 75.0])
def test_cog_outputs_read_back_with_their_georeference_no_data_and_values(tmp_path, rotation: float) -> None:
    """An AVIRIS-NG product (5 m pixels: 10, 20, 60 m groups of 2, 4, 12 pixels) with --format cog; its grid
    rotated on the map or not (the transform GDAL reads from its header, scaled per group)."""
    data, truth = pf.write_aviris(tmp_path, rotation=rotation)
    with rasterio.open(data) as src:
        truth.transform = src.transform.to_gdal()
    out = _cog_run(tmp_path, f'[scene]\nname = "av"\n[surface]\ncube = "{data.name}"\nquantity = "reflectance"\n'
                             '[effects]\natmosphere = true\ncorrect = true\n'
                             '[analysis]\nkind = "igrm"\nparameter = "cab"\n')
    _check_cogs(out, 32611, truth.transform, 5.0, ("analysis_index", "analysis_status"))
    with rasterio.open(f"netcdf:{out / 'simulation.nc'}:radiance_B5") as src:  # GDAL reads the NetCDF's the same
        x0, a, b, y0, d, e = truth.transform
        assert src.transform.to_gdal() == pytest.approx((x0, 4 * a, 4 * b, y0, 4 * d, 4 * e), rel=1e-12)
    assert {p.name for p in out.iterdir()} == {"simulation.nc", "simulation.json", "quicklook.png", "bands_10m.tif",
                                               "bands_20m.tif", "bands_60m.tif", "analysis_index.tif",
                                               "analysis_status.tif"}


def test_cog_outputs_of_an_image_without_georeference_say_so(tmp_path) -> None:
    """The generated image (no georeference, a truth): metres from the corner, no CRS, the parameter map and its
    error as GeoTIFFs too."""
    from s2cl.io.georef import NO_GEOREFERENCE

    out = _cog_run(tmp_path, '[scene]\nname = "f"\n[surface]\ncube = "builtin:fields:24x30"\ngsd_m = 10\n'
                             'quantity = "reflectance"\n[effects]\natmosphere = true\ncorrect = true\nseed = 1\n'
                             '[analysis]\nkind = "igrm"\nparameter = "cab"\n')
    maps = ("analysis_index", "analysis_status", "cab_map", "cab_error")
    _check_cogs(out, None, (0.0, 10.0, 0.0, 0.0, 0.0, -10.0), 10.0, maps)
    with rasterio.open(out / "cab_error.tif") as src:
        assert src.tags()["GEOREFERENCE"] == NO_GEOREFERENCE


def test_cog_of_a_library_scene_is_refused_before_anything_is_written(tmp_path) -> None:
    from click.testing import CliRunner

    from s2cl.cli.main import cli
    from s2cl.errors import InputError

    r = CliRunner().invoke(cli, ["simulate", "default", "-o", str(tmp_path / "o"), "--format", "cog"])
    assert isinstance(r.exception, InputError)
    assert str(r.exception).endswith("default.toml: output.format: 'cog' writes GeoTIFFs of an image; a library "
                                     "scene has none (simulation.nc holds its pixels)")
    assert not (tmp_path / "o").exists()


def test_a_products_metadata_is_opened_once_per_simulate(tmp_path, monkeypatch) -> None:
    """``s2cl simulate`` of an EnMAP product opens its reader and parses its XML once (the checks open it; the memory
    rules, the block size and the engines take what they opened): counted by wrapping the reader and the parser. It
    was 6 times before the scene was resolved once (issue 34)."""
    import xml.etree.ElementTree as ET

    import s2cl.io.products.enmap as enmap

    folder, _ = pf.write_enmap(tmp_path)
    opened: list[Path] = []
    parsed: list[str] = []
    open_enmap, parse = enmap.open_enmap, ET.parse

    def counted_open(p: Path):
        opened.append(p)
        return open_enmap(p)

    def counted_parse(source, *args, **kwargs):
        if str(source).upper().endswith("METADATA.XML"):
            parsed.append(str(source))
        return parse(source, *args, **kwargs)

    monkeypatch.setattr(enmap, "open_enmap", counted_open)
    monkeypatch.setattr(ET, "parse", counted_parse)
    scene = Scene.from_dict(_scene_dict(folder.name, 10.0), base_dir=tmp_path)
    run = simulate_scene(scene, tmp_path / "out")
    assert (tmp_path / "out" / "simulation.nc") in run.written
    assert len(opened) == 1 and len(parsed) == 1
