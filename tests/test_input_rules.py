"""The rules every input passes, once, wherever it is read:
regular files only, strict numbers, safe band names, JSON without NaN, cubes of real numbers, ENVI headers
whose keys are named when they lie, scene paths resolved once, output folders that are s2cl's own."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

from s2cl.errors import InputError, OutputError
from s2cl.io.inputs import input_file, number_at, parse_number
from s2cl.io.outdir import check_output_dir, check_output_file
from s2cl.io.output import write_json
from s2cl.sensor.names import check_band_name, safe_file_part

ROOT = Path(__file__).resolve().parent.parent


# --- V3: only regular files are opened ---------------------------------------------------------------

def test_input_file_refuses_what_is_not_a_regular_file(tmp_path) -> None:
    fifo = tmp_path / "cube.nc"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=r"cube\.nc: cube file is a FIFO"):
        input_file(fifo, what="cube file")
    with pytest.raises(InputError, match="is a folder, not a regular file"):
        input_file(tmp_path, what="LUT")
    with pytest.raises(InputError, match=r"s\.toml: surface\.cube: image cube .*gone\.nc not found"):
        input_file(tmp_path / "gone.nc", what="image cube", source="s.toml", key="surface.cube")
    if Path("/dev/zero").exists():
        with pytest.raises(InputError, match="is a device"):
            input_file("/dev/zero")
    real = tmp_path / "real.csv"
    real.write_text("x")
    (tmp_path / "link.csv").symlink_to(real)
    assert input_file(tmp_path / "link.csv") == tmp_path / "link.csv"


def test_a_fifo_cube_is_refused_before_it_is_opened(tmp_path) -> None:
    """A FIFO blocked `simulate` forever (the NetCDF reader waited for a writer)."""
    from s2cl.app.checks import check_simulate
    from s2cl.forward.cube import cube_size, load_cube
    from s2cl.scene.scene import Scene

    os.mkfifo(tmp_path / "fifo.nc")
    with pytest.raises(InputError, match="FIFO"):
        cube_size(tmp_path / "fifo.nc")
    with pytest.raises(InputError, match="FIFO"):
        load_cube(tmp_path / "fifo.nc")
    scene = Scene.from_dict({"scene": {"name": "c"}, "surface": {"cube": "fifo.nc", "gsd_m": 10.0}},
                            path=tmp_path / "c.toml")
    with pytest.raises(InputError, match=r"c\.toml: surface\.cube: image cube .*fifo\.nc is a FIFO"):
        check_simulate(scene)


# --- V9: strict numbers, wavelengths > 0 ----------------------------------------------------------------

@pytest.mark.parametrize("text", ["1", "-1.5e3", ".5", "5.", "+2E-2", "inf", "-Infinity", "nan"])
def test_numbers_in_decimal_notation_are_read(text: str) -> None:
    assert parse_number(text) == float(text) or np.isnan(parse_number(text))


@pytest.mark.parametrize("text", ["0_1", "٠.١", "１", "1,5", "0x10", "", "1 ", "e5", "1e", "--1"])
def test_what_float_would_also_take_is_not_a_number(text: str) -> None:
    with pytest.raises(ValueError):
        parse_number(text)


def test_a_metadata_number_is_read_around_its_spaces_or_refused_in_one_line_naming_file_and_key() -> None:
    """The one rule of the cube readers' header fields, XML nodes and GDAL tags (ENVI, EnMAP, GeoTIFF)."""
    assert number_at(" 0.5 ", source="x.hdr", key="reflectance scale factor") == 0.5
    assert number_at(7, source="x.hdr", key="k") == 7.0
    with pytest.raises(InputError) as err:
        number_at("0_1", source="METADATA.XML", key="bandID 3 wavelengthCenterOfBand")
    assert str(err.value) == "METADATA.XML: bandID 3 wavelengthCenterOfBand: must be a number, got '0_1'"


def test_wavelengths_must_be_positive() -> None:
    from s2cl.grid import check_wavelengths

    with pytest.raises(InputError, match="wavelengths must be > 0, got -1"):
        check_wavelengths(np.array([-1.0, 400.0, 410.0]), source="lib.csv")


# --- V1: band names ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["B1", "B8a", "B12", "swir-1", "nir_2", "7"])
def test_band_names_that_are_allowed(name: str) -> None:
    assert check_band_name(name) == name


@pytest.mark.parametrize("name", ["../../../tmp/ESCAPED", "/tmp/ABS", "B 5", "\x1b[31mB5", "", "-B5", ".B5",
                                  "B5/x", "B" * 33, "B\u00e9"])
def test_band_names_that_are_refused(name: str) -> None:
    with pytest.raises(InputError, match=r"band name .* is not allowed"):
        check_band_name(name, source="sensor.csv", key="band", where="line 6")


def test_a_sensor_table_with_a_path_as_band_name_is_refused_naming_the_line(tmp_path) -> None:
    from s2cl.sensor.sensor import Sensor

    table = (ROOT / "s2cl" / "data" / "sentinel2_mrd_table1.csv").read_text()
    (tmp_path / "s.csv").write_text(table.replace("\nB5,", "\n../../../../tmp/ESCAPED,"))
    with pytest.raises(InputError, match=r"s\.csv: band: line \d+: band name '\.\./\.\./"):
        Sensor.from_csv(tmp_path / "s.csv")


@pytest.mark.parametrize("name", ["../../../tmp/x", "/tmp/ABS", "..", "a\\b", "\x1b[2J"])
def test_a_file_named_after_a_band_stays_in_its_folder(tmp_path, name: str) -> None:
    path = tmp_path / f"heatmap_{safe_file_part(name)}.png"
    assert path.parent == tmp_path and "/" not in path.name and "\\" not in path.name


# --- V9: JSON never holds NaN -----------------------------------------------------------------------------

def test_json_outputs_write_non_finite_numbers_as_null(tmp_path) -> None:
    data = {"nan": float("nan"), "inf": np.float32(np.inf), "arr": np.array([1.0, np.nan]), "n": np.int64(3),
            "ok": 0.5, "nested": [{"x": -np.inf}], "path": tmp_path, "flag": np.bool_(True)}
    path = write_json(tmp_path / "x.json", data)

    def refuse(constant: str) -> None:
        raise ValueError(f"not JSON: {constant}")

    back = json.loads(path.read_text(), parse_constant=refuse)
    assert back == {"nan": None, "inf": None, "arr": [1.0, None], "n": 3, "ok": 0.5, "nested": [{"x": None}],
                    "path": str(tmp_path), "flag": True}


# --- V9: cubes of real numbers; V10: ENVI headers that lie name the key --------------------------------------

@pytest.mark.filterwarnings("ignore:You are writing invalid netcdf features")
def test_a_complex_netcdf_cube_is_refused(tmp_path) -> None:
    import xarray as xr

    from s2cl.forward.cube import load_cube

    wl = np.arange(400.0, 2501.0, 100.0)
    cube = np.full((2, 2, wl.size), 0.3 + 0.1j, dtype=np.complex64)
    xr.Dataset({"refl": (("y", "x", "wavelength"), cube)}, coords={"wavelength": wl}).to_netcdf(
        tmp_path / "c.nc", engine="h5netcdf", invalid_netcdf=True)
    with pytest.raises(InputError, match=r"c\.nc: refl: holds complex64 values"):
        load_cube(tmp_path / "c.nc")


def _envi_cube(tmp_path: Path, **header: str) -> Path:
    wl = np.arange(400.0, 2501.0, 100.0)
    values = {"samples": "2", "lines": "3", "bands": str(wl.size), "header offset": "0", "file type": "ENVI Standard",
              "data type": "4", "interleave": "bip", "byte order": "0",
              "wavelength": "{" + ", ".join(f"{w:g}" for w in wl) + "}", **header}
    hdr = tmp_path / "cube.hdr"
    hdr.write_text("ENVI\n" + "".join(f"{k} = {v}\n" for k, v in values.items()))
    np.full((3, 2, wl.size), 0.3, dtype="<f4").tofile(tmp_path / "cube.img")  # 3 × 2 × 22 × 4 = 528 bytes
    return hdr


@pytest.mark.parametrize(("header", "message"), [
    ({}, None),
    ({"lines": "2e1"}, r"cube\.hdr: lines: must be a whole number >= 1 written in digits, got '2e1'"),
    ({"lines": "200000"}, r"cube\.hdr: lines: .* need [\d,]+ bytes; cube\.img holds 528"),
    ({"data type": "6"}, r"cube\.hdr: data type: holds complex numbers"),
    ({"bands": "5"}, r"cube\.hdr: wavelength: lists 22 values for bands = 5"),
    ({"header offset": "-4"}, r"cube\.hdr: header offset: must be >= 0, got -4"),
])
def test_envi_cube_headers_are_checked_key_by_key(tmp_path, header: dict[str, str], message: str | None) -> None:
    from s2cl.forward.cube import cube_size, load_cube

    hdr = _envi_cube(tmp_path, **header)
    if message is None:
        assert cube_size(hdr) == (6, 22)
        read = load_cube(hdr)
        cube, wl = read.values, read.wavelengths_nm
        assert cube.shape == (3, 2, 22) and wl[0] == 400.0
        return
    for read in (cube_size, load_cube):  # sized from the header before loading, and loaded: the same verdict
        with pytest.raises(InputError, match=message):
            read(hdr)


def test_an_envi_data_file_that_is_a_fifo_is_refused(tmp_path) -> None:
    from s2cl.forward.cube import load_cube

    hdr = _envi_cube(tmp_path)
    (tmp_path / "cube.img").unlink()
    os.mkfifo(tmp_path / "cube.img")
    with pytest.raises(InputError, match=r"cube\.img: ENVI data file is a FIFO"):
        load_cube(hdr)


# --- V10: a scene's relative paths are resolved once, against the scene's folder -------------------------

def test_relative_library_paths_resolve_once_from_another_working_folder(tmp_path, monkeypatch) -> None:
    """From the scene's parent folder, `simulate sub/s.toml` looked for sub/sub/lib.csv."""
    from s2cl.scene.library import scene_library
    from s2cl.scene.scene import Scene

    (tmp_path / "sub" / "data").mkdir(parents=True)
    rows = "\n".join(f"{w},0.25" for w in range(395, 2510, 5))
    (tmp_path / "sub" / "data" / "lib.csv").write_text("wavelength_nm,leaf\n" + rows + "\n")
    (tmp_path / "sub" / "s.toml").write_text('[scene]\nname = "s"\n[surface]\nlibrary = "data/lib.csv"\n'
                                             'quantity = "reflectance"\n[effects]\natmosphere = true\n')
    for cwd, scene in ((tmp_path, "sub/s.toml"), (tmp_path / "sub" / "data", "../s.toml"),
                       (tmp_path / "sub", "s.toml")):
        monkeypatch.chdir(cwd)
        assert scene_library(Scene.load(scene)).names == ["leaf"]


# --- V4: the studies' lists and bands ---------------------------------------------------------------------

@pytest.mark.parametrize(("change", "key"), [
    (("ozone = [250, 410]", "ozone = []"), "study.ozone: the ozone study needs at least one value"),
    (('kind = "ozone"', 'kind = "cirrus"'), "study.water_vapour: the cirrus study needs at least one value"),
    (('kind = "ozone"', 'kind = "cirrus"\nwater_vapour = [1.0]'), "sweep.bands: the cirrus study varies band(s) B10"),
])
def test_a_study_scene_without_what_its_kind_needs_is_refused(tmp_path, change: tuple[str, str], key: str) -> None:
    from s2cl.studies import run_study

    text = (ROOT / "scenes" / "study-ozone.toml").read_text(encoding="utf-8")
    assert change[0] in text
    (tmp_path / "s.toml").write_text(text.replace(*change))
    with pytest.raises(InputError, match=re.escape(key)):
        run_study(str(tmp_path / "s.toml"), quick=True, output=tmp_path / "out")
    assert not (tmp_path / "out").exists()


# --- V1: output folders and files ------------------------------------------------------------------------

def test_output_folders_s2cl_may_write_into(tmp_path) -> None:
    assert check_output_dir(tmp_path / "new") == tmp_path / "new"
    (tmp_path / "empty").mkdir()
    check_output_dir(tmp_path / "empty")
    for marker in (".s2cl.lock", "summary.json", "simulation.nc", "heatmap_B4.png"):
        folder = tmp_path / marker.replace(".", "_")
        folder.mkdir()
        (folder / marker).write_text("")
        (folder / "notes.txt").write_text("the user's")
        check_output_dir(folder)
    (tmp_path / "study").mkdir()
    (tmp_path / "study" / "ozone.json").write_text("{}")
    check_output_dir(tmp_path / "study", writes=("ozone.json", "ozone.png"))


def test_output_folders_s2cl_refuses(tmp_path) -> None:
    for path in ("/", "/etc", "/usr", os.path.expanduser("~")):
        with pytest.raises(OutputError, match="root, a system folder or the home folder"):
            check_output_dir(path, where="output.directory in s.toml")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("the user's")
    with pytest.raises(OutputError, match=r"mine: holds files that s2cl did not write \(such as 'thesis\.tex'\)"):
        check_output_dir(tmp_path / "mine", where="--output")
    (tmp_path / "mine" / "ozone.json").write_text("{}")  # a study's output marks the folder for that study only
    with pytest.raises(OutputError, match="did not write"):
        check_output_dir(tmp_path / "mine")
    check_output_dir(tmp_path / "mine", writes=("ozone.json", "ozone.png"))


def test_a_plot_file_needs_an_existing_folder(tmp_path) -> None:
    assert check_output_file(tmp_path / "srf.png") == tmp_path / "srf.png"
    with pytest.raises(OutputError, match=r"its folder .*nope does not exist"):
        check_output_file(tmp_path / "nope" / "srf.png", where="--plot")
    assert not (tmp_path / "nope").exists()
    with pytest.raises(OutputError, match="is a folder"):
        check_output_file(tmp_path)
