"""Products as the missions ship them (tests/product_fixtures.py writes each in its real layout), read through the
one interface ``open_cube``: the values against the reflectance each fixture stored (within its quantisation step),
the bands kept and dropped, the no-data pixels, the georeference (against GDAL's reading of the same file where
GDAL reads it), rows read alone, and one line for each kind of bad input. No kernel runs here."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from s2cl.errors import DependencyError, InputError
from s2cl.io.cubes import load_cube, open_cube

rasterio = pytest.importorskip("rasterio", reason="the geo extra (rasterio, pyproj) reads GeoTIFF and CRS")
sys.path.insert(0, str(Path(__file__).parent))
import product_fixtures as pf  # noqa: E402


def _kept(truth: pf.Truth) -> tuple[np.ndarray, np.ndarray]:
    """The good bands of a fixture sorted by wavelength: (their wavelengths, the reflectance there), by hand."""
    order = [i for i in np.argsort(truth.wavelengths_nm, kind="stable") if truth.good[i]]
    return truth.wavelengths_nm[order], truth.reflectance[:, :, order]


def _check_values(read: np.ndarray, truth: pf.Truth, kept: np.ndarray) -> None:
    """Valid pixels hold the stored reflectance within half a quantisation step; empty pixels are NaN throughout."""
    assert np.isnan(read[truth.empty]).all()
    assert np.isfinite(read[~truth.empty]).all()
    np.testing.assert_allclose(read[~truth.empty], kept[~truth.empty], rtol=1e-6, atol=truth.step / 2 + 1e-6)


def _epsg(wkt: str) -> int:
    from pyproj import CRS

    return CRS.from_wkt(wkt).to_epsg()


# --- EnMAP L2A -------------------------------------------------------------------------------------------------

def test_enmap_folder_image_and_xml_open_the_same_product(tmp_path) -> None:
    folder, truth = pf.write_enmap(tmp_path)
    image = folder / f"{pf.ENMAP_NAME}-SPECTRAL_IMAGE.TIF"
    xml = folder / f"{pf.ENMAP_NAME}-METADATA.XML"
    wl, kept = _kept(truth)
    for named in (folder, image, xml):
        reader = open_cube(named)
        assert reader.product == "EnMAP L2A" and reader.quantity == "reflectance"
        assert (reader.rows, reader.cols) == truth.reflectance.shape[:2]
        np.testing.assert_allclose(reader.wavelengths_nm, np.round(wl, 3))  # the XML writes 3 decimals
        np.testing.assert_allclose(reader.bad_nm, np.sort(np.round(truth.wavelengths_nm[~truth.good], 3)))
        assert reader.bad_nm.size == 6
        _check_values(reader.read(0, reader.rows), truth, kept)
        assert reader.georef.transform == truth.transform and _epsg(reader.georef.crs) == truth.epsg


def test_enmap_rows_read_alone_are_the_whole_products_rows(tmp_path) -> None:
    folder, _ = pf.write_enmap(tmp_path)
    reader = open_cube(folder)
    whole = reader.read(0, reader.rows)
    for start, stop in ((0, 5), (5, 17), (17, reader.rows)):
        np.testing.assert_array_equal(reader.read(start, stop), whole[start:stop])


def test_enmap_xml_that_does_not_match_the_image_is_refused(tmp_path) -> None:
    folder, _ = pf.write_enmap(tmp_path, xml_bands=230)
    with pytest.raises(InputError, match=r"METADATA\.XML: specific/bandCharacterisation: describes 230 bands; "
                                         r".*SPECTRAL_IMAGE\.TIF has 224"):
        open_cube(folder)


def test_enmap_of_another_level_is_refused_naming_it(tmp_path) -> None:
    folder, _ = pf.write_enmap(tmp_path, level="L1C")
    with pytest.raises(InputError, match=r"METADATA\.XML: base/level: is an EnMAP 'L1C' product; s2cl reads L2A"):
        open_cube(folder)


def test_enmap_folder_without_its_xml_is_refused(tmp_path) -> None:
    folder, _ = pf.write_enmap(tmp_path)
    (folder / f"{pf.ENMAP_NAME}-METADATA.XML").unlink()
    with pytest.raises(InputError, match=r"needs one \*-METADATA\.XML file, found 0"):
        open_cube(folder)


# --- EMIT L2A: the GLT --------------------------------------------------------------------------------------------

def test_emit_pixels_land_where_the_lookup_table_says(tmp_path) -> None:
    """Brute force over the map grid: each map pixel holds the sensor pixel its (glt_y, glt_x) names (1-based), NaN
    where the table names none or the sensor pixel is filled; the table flips and shifts the swath."""
    path, truth = pf.write_emit(tmp_path)
    gx, gy = truth.extra["glt"]
    reader = open_cube(path)
    assert (reader.rows, reader.cols) == gx.shape
    wl, kept = _kept(truth)
    np.testing.assert_allclose(reader.wavelengths_nm, wl.astype(np.float32))
    got = reader.read(0, reader.rows)
    landed = 0
    for r in range(gx.shape[0]):
        for c in range(gx.shape[1]):
            if gx[r, c] == 0:
                assert np.isnan(got[r, c]).all(), (r, c)
                continue
            sr, sc = gy[r, c] - 1, gx[r, c] - 1
            if truth.empty[sr, sc]:
                assert np.isnan(got[r, c]).all(), (r, c)
                continue
            np.testing.assert_array_equal(got[r, c], kept[sr, sc].astype(np.float32))
            landed += 1
    assert landed == (~truth.empty).sum() + 1  # every valid sensor pixel, one of them twice
    # the flip, spelled out: map row 2 + r, column 2 + c shows sensor row r, column 17 - c
    np.testing.assert_array_equal(got[2 + 5, 2 + 3], kept[5, 17 - 3].astype(np.float32))
    assert reader.georef.transform == truth.transform and _epsg(reader.georef.crs) == 4326


def test_emit_map_rows_read_alone_are_the_whole_grids_rows(tmp_path, monkeypatch) -> None:
    """Blocks of map rows gathered a few sensor rows at a time give the whole grid's rows."""
    from s2cl.io.products import emit

    path, _ = pf.write_emit(tmp_path)
    whole = open_cube(path).read(0, 24)
    monkeypatch.setattr(emit, "SOURCE_CHUNK_BYTES", 1)  # one sensor row at a time
    reader = open_cube(path)
    for start, stop in ((0, 3), (3, 11), (11, 24)):
        np.testing.assert_array_equal(reader.read(start, stop), whole[start:stop])


def test_emit_in_sensor_geometry_has_no_georeference(tmp_path) -> None:
    path, truth = pf.write_emit(tmp_path)
    reader = open_cube(path, geometry="sensor")
    assert (reader.rows, reader.cols) == truth.reflectance.shape[:2] and reader.georef is None
    _, kept = _kept(truth)
    _check_values(reader.read(0, reader.rows), truth, kept)


def test_emit_lookup_table_pointing_outside_the_cube_is_refused(tmp_path) -> None:
    gx, gy = pf.emit_glt(20, 18)
    gx[4, 6] = 19  # crosstrack 19 of 18
    path, _ = pf.write_emit(tmp_path, glt=(gx, gy))
    with pytest.raises(InputError, match=r"EMIT_L2A_RFL.*\.nc: location/glt_x: points outside the cube: map pixel "
                                         r"\(row 4, column 6\) names crosstrack 19 of 1 … 18"):
        load_cube(path)


def test_emit_crs_pyproj_cannot_parse_is_refused(tmp_path) -> None:
    path, _ = pf.write_emit(tmp_path, spatial_ref='GEOGCS["nowhere",DATUM["none"]]')
    with pytest.raises(InputError, match=r"EMIT_L2A_RFL.*\.nc: spatial_ref: .* is not a CRS pyproj can parse"):
        open_cube(path)


# --- PRISMA L2D -----------------------------------------------------------------------------------------------

def test_prisma_detectors_merge_in_increasing_wavelength(tmp_path) -> None:
    """Flagged bands dropped; the VNIR bands at or above the first SWIR band left for the SWIR detector's; DN scaled
    by each detector's L2Scale; DN 0 throughout is no data; the grid from the corner pixels' centres."""
    path, truth = pf.write_prisma(tmp_path)
    reader = open_cube(path)
    swir_first = truth.wavelengths_nm[66:][truth.good[66:]].min()
    use = truth.good.copy()
    use[:66] &= truth.wavelengths_nm[:66] < swir_first
    order = [i for i in np.argsort(truth.wavelengths_nm) if use[i]]
    np.testing.assert_allclose(reader.wavelengths_nm, truth.wavelengths_nm[order].astype(np.float32))
    assert np.all(np.diff(reader.wavelengths_nm) > 0)
    got = reader.read(0, reader.rows)
    assert np.isnan(got[truth.empty]).all()
    np.testing.assert_allclose(got[~truth.empty], truth.reflectance[:, :, order][~truth.empty], atol=truth.step)
    assert reader.georef.transform == pytest.approx(truth.transform) and _epsg(reader.georef.crs) == 32632


def test_prisma_of_another_level_is_refused(tmp_path) -> None:
    import h5py

    with h5py.File(tmp_path / "PRS_L2C_STD_x.he5", "w") as f:
        f.create_dataset("HDFEOS/SWATHS/PRS_L2C_HCO/Data Fields/VNIR_Cube", data=np.zeros((2, 3, 2), "u2"))
    with pytest.raises(InputError, match=r"swaths PRS_L2C_HCO; s2cl reads L2D"):
        open_cube(tmp_path / "PRS_L2C_STD_x.he5")


# --- AVIRIS-NG: ENVI with map info ---------------------------------------------------------------------------

@pytest.mark.parametrize("rotation", [0.0, 75.0])
def test_aviris_map_info_is_the_georeference_gdal_reads(tmp_path, rotation: float) -> None:
    """The data file named as GDAL users name it (no .hdr): values, bbl, ignore value; the transform and CRS equal
    GDAL's ENVI driver's reading of the same header, rotated or not."""
    data, truth = pf.write_aviris(tmp_path, rotation=rotation)
    reader = open_cube(data)
    assert reader.product == "ENVI"
    wl, kept = _kept(truth)
    np.testing.assert_allclose(reader.wavelengths_nm, np.round(wl, 6))
    _check_values(reader.read(0, reader.rows), truth, kept.astype(np.float32))
    with rasterio.open(data) as src:
        np.testing.assert_allclose(reader.georef.transform, src.transform.to_gdal(), rtol=0, atol=1e-6)
        assert _epsg(reader.georef.crs) == src.crs.to_epsg() == 32611
    assert reader.georef.rotated == (rotation != 0)


def test_an_envi_cube_named_by_its_data_file_reads_as_its_header(tmp_path) -> None:
    """``x.bsq`` beside ``x.hdr``, and ``y.bsq`` beside ``y.bsq.hdr`` (GDAL's naming), read as their headers."""
    data, _ = pf.write_aviris(tmp_path)
    hdr = tmp_path / f"{pf.AVIRIS_NAME}.hdr"
    bsq = tmp_path / "x.bsq"
    bsq.write_bytes(data.read_bytes())
    (tmp_path / "x.hdr").write_text(hdr.read_text())
    (tmp_path / "y.bsq").write_bytes(data.read_bytes())
    (tmp_path / "y.bsq.hdr").write_text(hdr.read_text())
    whole = load_cube(hdr).values
    for named in (bsq, tmp_path / "y.bsq"):
        np.testing.assert_array_equal(load_cube(named).values, whole)


def test_an_envi_coordinate_system_pyproj_cannot_parse_is_refused(tmp_path) -> None:
    data, _ = pf.write_aviris(tmp_path, coordinate_system='PROJCS["mystery",GEOGCS["x"]]')
    with pytest.raises(InputError, match=r"_img\.hdr: coordinate system string: .* is not a CRS pyproj can parse"):
        open_cube(data)


# --- generic GeoTIFF -----------------------------------------------------------------------------------------

def test_geotiff_with_gdal_wavelengths_scales_and_masks(tmp_path) -> None:
    path, truth = pf.write_geotiff(tmp_path)
    reader = open_cube(path)
    np.testing.assert_allclose(reader.wavelengths_nm, truth.wavelengths_nm)  # µm × 1000
    np.testing.assert_allclose(reader.fwhm_nm, 10.0)
    _check_values(reader.read(0, reader.rows), truth, truth.reflectance)
    with rasterio.open(path) as src:
        assert reader.georef.transform == src.transform.to_gdal() == truth.transform


def test_geotiff_without_wavelengths_is_refused(tmp_path) -> None:
    path, _ = pf.write_geotiff(tmp_path, wavelengths=False)
    with pytest.raises(InputError, match=r"cube\.tif: wavelength: band 1 has no wavelength: a GeoTIFF cube needs"):
        open_cube(path)


def test_without_the_geo_extra_a_geotiff_is_refused_naming_it(tmp_path) -> None:
    """In a process where rasterio cannot be imported (the geo extra not installed)."""
    path, _ = pf.write_geotiff(tmp_path)
    code = textwrap.dedent(f"""
        import sys
        sys.modules["rasterio"] = None
        from s2cl.io.cubes import open_cube
        from s2cl.errors import DependencyError
        try:
            open_cube({str(path)!r})
        except DependencyError as err:
            print(err)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "reading a GeoTIFF needs rasterio (GDAL): pip install 's2cl[geo]'"
    assert issubclass(DependencyError, Exception)


# --- the scene completed from the product ---------------------------------------------------------------------

def _scene(tmp_path: Path, cube: str, **surface):
    from s2cl.scene.scene import Scene

    return Scene.from_dict({"scene": {"name": "p"}, "surface": {"cube": cube, "quantity": "reflectance", **surface},
                            "effects": {"atmosphere": True, "correct": True}}, base_dir=tmp_path)


def test_a_cube_covering_less_than_the_grid_gives_the_grid_its_coverage(tmp_path) -> None:
    """EnMAP covers 418.42–2445.53 nm: the default 400–2500 nm grid becomes 419–2445 nm (1 nm steps inside the
    coverage), said in one line; the GSD comes from the product's 30 m pixels."""
    from s2cl.app.product_scene import resolve_product_scene

    folder, _ = pf.write_enmap(tmp_path)
    scene, notes = resolve_product_scene(_scene(tmp_path, folder.name))
    assert (scene.grid.start_nm, scene.grid.stop_nm, scene.grid.step_nm) == (419.0, 2445.0, 1.0)
    assert scene.spec.surface.gsd_m == 30.0
    assert [str(n) for n in notes] == ["grid: the cube covers 418.42–2445.53 nm, not the grid 400–2500 nm: the grid "
                                       "is taken from its coverage, 419–2445 nm, step 1 nm (2027 wavelengths) (every "
                                       "band's SRF support lies inside)"]


def test_a_gsd_other_than_the_products_pixels_is_kept_and_said(tmp_path) -> None:
    from s2cl.app.product_scene import resolve_product_scene

    folder, _ = pf.write_enmap(tmp_path)
    scene, notes = resolve_product_scene(_scene(tmp_path, folder.name, gsd_m=10.0))
    assert scene.spec.surface.gsd_m == 10.0
    assert [n.key for n in notes] == ["surface.gsd_m", "grid"]
    assert "the pixels of" in notes[0].message and "are 30 m" in notes[0].message


def test_a_geographic_product_needs_a_gsd(tmp_path) -> None:
    from s2cl.app.product_scene import resolve_product_scene

    path, _ = pf.write_emit(tmp_path)
    with pytest.raises(InputError, match=r"surface\.gsd_m: an image cube needs surface\.gsd_m .* EMIT L2A "
                                         r"EMIT_L2A_RFL.* does not give it in metres \(its pixels are 0\.000542233"):
        resolve_product_scene(_scene(tmp_path, path.name))


def test_a_product_whose_wavelengths_miss_a_bands_support_is_refused(tmp_path) -> None:
    """A cube from 450 nm: B1 (443 nm, FWHM 20: support 423–463 nm) leaves it."""
    from s2cl.app.product_scene import resolve_product_scene

    path, _ = pf.write_geotiff(tmp_path)
    import rasterio as rio

    with rio.open(path, "r+") as dst:
        for b in range(1, dst.count + 1):
            w = float(dst.tags(b)["wavelength"])
            dst.update_tags(b, wavelength=f"{w + 0.05:.4f}")  # 450–2550 nm
    with pytest.raises(InputError, match=r"cube\.tif: wavelength: GeoTIFF covers 450–2550 nm; band B1's SRF support "
                                         r"423–463 nm leaves it"):
        resolve_product_scene(_scene(tmp_path, path.name))


def test_a_product_of_reflectance_needs_a_reflectance_scene(tmp_path) -> None:
    from s2cl.app.product_scene import resolve_product_scene
    from s2cl.scene.scene import Scene

    path, _ = pf.write_prisma(tmp_path)
    scene = Scene.from_dict({"scene": {"name": "p"}, "surface": {"cube": path.name, "gsd_m": 30.0}},
                            base_dir=tmp_path)
    with pytest.raises(InputError, match=r"surface\.quantity: PRISMA L2D holds surface reflectance"):
        resolve_product_scene(scene)


def test_a_cube_without_georeference_needs_a_gsd(tmp_path) -> None:
    import xarray as xr

    from s2cl.app.product_scene import resolve_product_scene

    wl = np.arange(400.0, 2501.0, 100.0)
    xr.Dataset({"r": (("y", "x", "wavelength"), np.full((2, 2, wl.size), 0.3, np.float32))},
               coords={"wavelength": wl}).to_netcdf(tmp_path / "c.nc", engine="h5netcdf")
    with pytest.raises(InputError, match=r"surface\.gsd_m: .* NetCDF c\.nc does not give it in metres \(it has no "
                                         r"georeference\)"):
        resolve_product_scene(_scene(tmp_path, "c.nc"))


def test_a_bad_band_without_a_wavelength_is_not_listed_among_the_bad() -> None:
    """The kept bands sorted by wavelength with their file positions; the bad ones listed by wavelength, except a
    slot with none (0 nm: PRISMA's unused detector slots)."""
    from s2cl.io.products.bands import BandSelection

    sel = BandSelection.of(np.array([450.0, 0.0, 520.0, 400.0, 0.0]), np.array([True, False, False, True, False]),
                           "p.he5", "List_Cw_Vnir")
    assert sel.index.tolist() == [3, 0] and sel.wavelengths_nm.tolist() == [400.0, 450.0]
    assert sel.bad_nm.tolist() == [520.0]


def test_a_geotiffs_bad_band_list_follows_the_envi_rule(tmp_path) -> None:
    """GDAL's ``bbl`` item on a GeoTIFF is read by the same rule as an ENVI header's: a wrong count is refused in one
    line naming ``bbl``, and a 0 drops its band (reported among the bad)."""
    rasterio = pytest.importorskip("rasterio")
    path, _ = pf.write_geotiff(tmp_path)
    with rasterio.open(path) as src:
        n = src.count
    with rasterio.open(path, "r+") as dst:
        dst.update_tags(bbl="{1, 0}")
    with pytest.raises(InputError, match=rf"cube\.tif: bbl: lists 2 values for bands = {n}"):
        open_cube(path)
    with rasterio.open(path, "r+") as dst:
        dst.update_tags(bbl="{" + ", ".join(["0"] + ["1"] * (n - 1)) + "}")
    reader = open_cube(path)
    assert reader.wavelengths_nm.size == n - 1 and reader.wavelengths_nm[0] == pytest.approx(410.0)
    assert np.asarray(reader.bad_nm).tolist() == pytest.approx([400.0])
