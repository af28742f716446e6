"""The bad-band gap warning names what marked the bands bad in each format: ENVI's bad band list (``bbl``) for an
AVIRIS cube, EnMAP's band quality in its XML, EMIT's ``good_wavelengths``; PRISMA's readers say its band flags."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import pytest

pytest.importorskip("rasterio", reason="the geo extra (rasterio, pyproj) reads GeoTIFF and CRS")
sys.path.insert(0, str(Path(__file__).parent))
import product_fixtures as pf

from s2cl.app.image_simulation import scene_cube
from s2cl.io.cubes import open_cube
from s2cl.scene.scene import Scene

#: format: (fixture writer, the warning's key, words of the warning that name the marking)
FORMATS = {
    "aviris": (pf.write_aviris, "bbl", "the bad band list (bbl)"),
    "enmap": (pf.write_enmap, "expectedChannelsList", "the XML's band quality"),
    "emit": (pf.write_emit, "sensor_band_parameters/good_wavelengths", "good_wavelengths (0: a bad band)"),
}


@pytest.mark.parametrize("name", list(FORMATS))
def test_the_gap_warning_names_the_formats_own_bad_band_marking(tmp_path, caplog, name: str) -> None:
    writer, key, words = FORMATS[name]
    path, truth = writer(tmp_path)
    assert not truth.good.all()  # the fixture marks bands bad, B10's water window among them
    scene = Scene.from_dict({"scene": {"name": "p"}, "effects": {"atmosphere": True},
                             "surface": {"cube": path.name, "quantity": "reflectance", "gsd_m": 10.0}},
                            base_dir=tmp_path)
    with caplog.at_level(logging.WARNING, logger="s2cl"):
        scene_cube(scene)
    (gap,) = [r.getMessage() for r in caplog.records if "interpolated linearly over the gap" in r.getMessage()]
    assert f": {key}: SRF weight on wavelengths {words}" in gap and "B10 100 %" in gap
    if name != "aviris":
        assert "bbl" not in gap


def test_prisma_says_its_band_flags(tmp_path) -> None:
    path, truth = pf.write_prisma(tmp_path)
    assert not truth.good.all()
    key, words = open_cube(path).bad_bands_by
    assert key == "List_Cw_Vnir_Flags" and "List_Cw_Swir_Flags" in words and "bbl" not in words
