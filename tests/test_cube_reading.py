"""Cube files read by :mod:`s2cl.io.cubes`, small enough to write out by hand: which pixels a CF flag variable
marks as no data (``flag_values``, ``flag_masks``, both together), rows read alone, CF decoding, and an ENVI
file's ignore value, scale factor and data types. Every expected array is written out by hand; nothing runs a
kernel."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import xarray as xr

from s2cl.errors import InputError
from s2cl.io.cubes import load_cube, open_cube

WL = np.array([500.0, 600.0, 700.0])  # nm
ROWS, COLS = 4, 3
N = np.nan


def _netcdf(tmp_path: Path, flags: dict[str, tuple[tuple[str, str], np.ndarray, dict[str, Any]]],
            ancillary: str | None = None, refl: np.ndarray | None = None, name: str = "cube.nc") -> Path:
    """A float32 cube ``(y, x, wavelength)`` of 0.3 everywhere (or ``refl``) with the flag variables ``flags``
    (name: (dims, values, attributes)), named in its ``ancillary_variables`` (default: all of them)."""
    values = np.full((ROWS, COLS, WL.size), 0.3, np.float32) if refl is None else refl
    attrs = {"ancillary_variables": " ".join(flags) if ancillary is None else ancillary}
    data: dict[str, Any] = {"refl": (("y", "x", "wavelength"), values, attrs)}
    data.update(flags)
    xr.Dataset(data, coords={"wavelength": ("wavelength", WL, {"units": "nm"})}).to_netcdf(tmp_path / name,
                                                                                            engine="h5netcdf")
    return tmp_path / name


def _nodata(path: Path) -> np.ndarray:
    """The pixels read as no data (NaN in every band; a partly NaN pixel fails the test)."""
    values = load_cube(path).values
    nan = np.isnan(values)
    assert np.array_equal(nan.any(axis=-1), nan.all(axis=-1))
    assert np.all(values[~nan] == np.float32(0.3))
    return nan.all(axis=-1)


def _qa(values: list[list[float]], dtype: Any = np.uint8, **attrs: Any) -> tuple[tuple[str, str], np.ndarray,
                                                                                dict[str, Any]]:
    return ("y", "x"), np.array(values, dtype), attrs


T, F = True, False


def test_flag_masks_are_bits(tmp_path) -> None:
    """A bit field: ``no_data`` is bit 1 (mask 2), set alone or with the cloud (1) or shadow (4) bits."""
    qa = _qa([[0, 1, 2], [3, 4, 6], [7, 5, 8], [10, 0, 0]], flag_masks=np.array([1, 2, 4], np.uint8),
             flag_meanings="cloud no_data shadow")
    expected = [[F, F, T], [T, F, T], [T, F, F], [T, F, F]]
    np.testing.assert_array_equal(_nodata(_netcdf(tmp_path, {"qa": qa})), expected)


def test_flag_values_are_values(tmp_path) -> None:
    """Enumerated values: only the value of ``no_data`` (2) marks; 3 and 6 hold bit 1 but are other values."""
    qa = _qa([[0, 1, 2], [3, 6, 2], [0, 0, 0], [0, 0, 1]], flag_values=np.array([0, 1, 2], np.uint8),
             flag_meanings="clear cloud no_data")
    expected = [[F, F, T], [F, F, T], [F, F, F], [F, F, F]]
    np.testing.assert_array_equal(_nodata(_netcdf(tmp_path, {"qa": qa})), expected)


def test_flag_values_and_masks_together_are_the_masked_value(tmp_path) -> None:
    """CF 3.5: with both, a meaning holds where ``flags & mask == value``: the low two bits an enumerated state
    (0 clear, 1 cloud, 2 no data, 3 haze) and bit 2 snow. 6 is no data under snow; 3 (haze), 1 and 5 are not."""
    qa = _qa([[0, 1, 2], [3, 6, 5], [4, 7, 2], [0, 0, 0]], flag_masks=np.array([3, 3, 3, 3, 4], np.uint8),
             flag_values=np.array([0, 1, 2, 3, 4], np.uint8), flag_meanings="clear cloud no_data haze snow")
    expected = [[F, F, T], [F, T, F], [F, F, T], [F, F, F]]
    np.testing.assert_array_equal(_nodata(_netcdf(tmp_path, {"qa": qa})), expected)


def test_every_no_data_meaning_marks_and_meanings_ignore_case(tmp_path) -> None:
    """Two no-data meanings in one variable (``Missing``, ``FILL``), written in any case."""
    qa = _qa([[0, 1, 2], [3, 0, 0], [0, 3, 0], [0, 0, 1]], flag_values=np.array([0, 1, 2, 3], np.uint8),
             flag_meanings="clear Missing cloud FILL")
    expected = [[F, T, F], [T, F, F], [F, T, F], [F, F, T]]
    np.testing.assert_array_equal(_nodata(_netcdf(tmp_path, {"qa": qa})), expected)


def test_a_float_flag_variable_leaves_its_nan_pixels_alone(tmp_path) -> None:
    """A NaN flag says nothing (its pixel keeps its values), even where no data is the value 0."""
    qa = _qa([[0, 1, N], [1, 0, 1], [N, N, 1], [1, 1, 0]], np.float32, flag_values=np.array([0, 1], np.float32),
             flag_meanings="no_data clear")
    expected = [[T, F, F], [F, T, F], [F, F, F], [F, F, T]]
    np.testing.assert_array_equal(_nodata(_netcdf(tmp_path, {"qa": qa})), expected)


def test_several_flag_variables_add_up_and_one_without_no_data_is_skipped(tmp_path) -> None:
    """``cloudmask`` (no no-data meaning, listed first) marks nothing; ``qa`` and ``fill`` each mark their own."""
    flags = {"cloudmask": _qa([[1, 1, 1], [1, 1, 1], [1, 1, 1], [1, 1, 1]], flag_values=np.array([0, 1], np.uint8),
                              flag_meanings="clear cloud"),
             "qa": _qa([[1, 0, 0], [0, 0, 0], [0, 0, 0], [0, 1, 0]], flag_values=np.array([0, 1], np.uint8),
                       flag_meanings="clear no_data"),
             "fill": _qa([[0, 0, 0], [0, 0, 4], [0, 0, 0], [0, 4, 0]], flag_masks=np.array([4], np.uint8),
                         flag_meanings="nodata")}
    expected = [[T, F, F], [F, F, T], [F, F, F], [F, T, F]]
    np.testing.assert_array_equal(_nodata(_netcdf(tmp_path, flags)), expected)


def test_flags_stored_across_and_a_cube_stored_band_first(tmp_path) -> None:
    """The flag variable as ``(x, y)`` and the cube as ``(wavelength, y, x)``: pixels still meet by their names."""
    qa = np.zeros((COLS, ROWS), np.uint8)  # (x, y)
    qa[2, 0] = qa[0, 3] = 1  # pixels (row 0, col 2) and (row 3, col 0)
    cube = np.full((WL.size, ROWS, COLS), 0.3, np.float32)
    xr.Dataset({"refl": (("wavelength", "y", "x"), cube, {"ancillary_variables": "qa"}),
                "qa": (("x", "y"), qa, {"flag_values": np.array([0, 1], np.uint8), "flag_meanings": "clear no_data"})},
               coords={"wavelength": WL}).to_netcdf(tmp_path / "c.nc", engine="h5netcdf")
    assert load_cube(tmp_path / "c.nc").values.shape == (ROWS, COLS, WL.size)
    expected = [[F, F, T], [F, F, F], [F, F, F], [T, F, F]]
    np.testing.assert_array_equal(_nodata(tmp_path / "c.nc"), expected)


def test_rows_read_alone_carry_their_own_flags(tmp_path) -> None:
    refl = (np.arange(ROWS * COLS * WL.size, dtype=np.float32).reshape(ROWS, COLS, WL.size) / 100)
    qa = _qa([[0, 0, 0], [0, 1, 0], [1, 0, 0], [0, 0, 1]], flag_values=np.array([0, 1], np.uint8),
             flag_meanings="clear no_data")
    reader = open_cube(_netcdf(tmp_path, {"qa": qa}, refl=refl))
    for start, stop, holes in ((1, 3, [(0, 1), (1, 0)]), (3, 4, [(0, 2)]), (0, 1, [])):
        want = refl[start:stop].copy()
        for r, c in holes:
            want[r, c] = np.nan
        np.testing.assert_array_equal(reader.read(start, stop), want, err_msg=f"rows {start}..{stop - 1}")


@pytest.mark.filterwarnings("ignore:variable 'refl' has multiple fill values")
def test_cf_fill_missing_scale_and_offset_are_decoded(tmp_path) -> None:
    """int16 values ``v``: reflectance 0.001 v + 0.01; -1 (_FillValue) and -2 (missing_value) are no data."""
    raw = np.array([[100, -1, 200], [0, 300, -2], [10, 20, 30], [1000, 0, 0]], np.int16)
    refl = np.repeat(raw[:, :, None], WL.size, axis=2)
    xr.Dataset({"refl": (("y", "x", "wavelength"), refl, {"scale_factor": 0.001, "add_offset": 0.01,
                                                          "_FillValue": np.int16(-1), "missing_value": np.int16(-2)})},
               coords={"wavelength": WL}).to_netcdf(tmp_path / "c.nc", engine="h5netcdf")
    with xr.open_dataset(tmp_path / "c.nc", engine="h5netcdf", decode_cf=False) as stored:
        assert stored["refl"].dtype == np.int16 and stored["refl"].values[0, 1, 0] == -1
    expected = np.array([[0.11, N, 0.21], [0.01, 0.31, N], [0.02, 0.03, 0.04], [1.01, 0.01, 0.01]])
    values = load_cube(tmp_path / "c.nc").values
    for k in range(WL.size):
        np.testing.assert_allclose(values[:, :, k], expected, rtol=1e-6)


@pytest.mark.parametrize(("attrs", "ancillary", "message"), [
    ({"flag_values": np.array([0, 1], np.uint8), "flag_meanings": "clear cloud no_data"}, "qa",
     r"c\.nc: qa: flag_values has 2 values for 3 flag_meanings"),
    ({"flag_masks": np.array([1, 2, 4, 8], np.uint8), "flag_meanings": "clear cloud no_data"}, "qa",
     r"c\.nc: qa: flag_masks has 4 values for 3 flag_meanings"),
    ({"flag_values": np.array([0, 1], np.uint8), "flag_meanings": "clear no_data"}, "qa mask",
     r"c\.nc: refl\.ancillary_variables: names 'mask', which the file lacks"),
])
def test_flag_variables_that_do_not_add_up_are_refused(tmp_path, attrs: dict, ancillary: str, message: str) -> None:
    path = _netcdf(tmp_path, {"qa": _qa([[0] * COLS] * ROWS, **attrs)}, ancillary=ancillary, name="c.nc")
    with pytest.raises(InputError, match=message):
        load_cube(path)


def test_a_no_data_flag_of_other_dimensions_is_refused(tmp_path) -> None:
    qa = (("y",), np.zeros(ROWS, np.uint8), {"flag_values": np.array([0, 1], np.uint8),
                                              "flag_meanings": "clear no_data"})
    with pytest.raises(InputError, match=r"c\.nc: qa: flags no data but has dimensions \('y',\); the cube's pixels "
                                         r"are \('y', 'x'\)"):
        load_cube(_netcdf(tmp_path, {"qa": qa}, name="c.nc"))


# ---- ENVI ------------------------------------------------------------------------------------------------------

def _envi(tmp_path: Path, values: np.ndarray, code: int, **header: str) -> Path:
    """``cube.hdr`` + ``cube.bsq`` (little endian) of ``values`` ``(ROWS, COLS, WL)``; no bad band list unless
    ``header`` has one."""
    np.ascontiguousarray(values.transpose(2, 0, 1)).astype(values.dtype.newbyteorder("<")).tofile(
        tmp_path / "cube.bsq")
    lines = {"samples": str(COLS), "lines": str(ROWS), "bands": str(WL.size), "header offset": "0",
             "data type": str(code), "interleave": "bsq", "byte order": "0",
             "wavelength": "{" + ", ".join(f"{w:g}" for w in WL) + "}", **header}
    hdr = tmp_path / "cube.hdr"
    hdr.write_text("ENVI\n" + "".join(f"{k} = {v}\n" for k, v in lines.items()))
    return hdr


def test_envi_float_ignore_value_at_the_file_precision_then_scale(tmp_path) -> None:
    """float32, no bad band list (the data read straight from the file), ignore value -0.1 (not a float32 number:
    the file holds float32(-0.1)), scale factor 4: -0.1 becomes NaN, every other value is divided by 4."""
    raw = np.full((ROWS, COLS, WL.size), 0.5, np.float32)
    raw[1, 2, :] = -0.1
    raw[3, 0, 1] = -0.1
    raw[0, 0, :] = [-0.2, 2.0, 1.0]
    read = load_cube(_envi(tmp_path, raw, 4, **{"data ignore value": "-0.1", "reflectance scale factor": "4"}))
    expected = np.full((ROWS, COLS, WL.size), 0.125)
    expected[1, 2, :] = N
    expected[3, 0, 1] = N
    expected[0, 0, :] = [-0.05, 0.5, 0.25]
    np.testing.assert_array_equal(read.values, expected.astype(np.float32))
    assert read.bad_nm.size == 0 and np.array_equal(read.wavelengths_nm, WL)


def test_envi_ignore_value_zero_is_an_ignore_value(tmp_path) -> None:
    raw = np.full((ROWS, COLS, WL.size), 3000, np.int16)
    raw[2, 1, :] = 0
    raw[0, 2, 2] = 0
    hdr = _envi(tmp_path, raw, 2, **{"data ignore value": "0", "reflectance scale factor": "10000"})
    values = load_cube(hdr).values
    expected = np.full((ROWS, COLS, WL.size), 0.3, np.float32)
    expected[2, 1, :] = N
    expected[0, 2, 2] = N
    np.testing.assert_array_equal(values, expected)


@pytest.mark.parametrize(("dtype", "code", "value", "read_as"), [
    ("u1", 1, 255, np.float32), ("i2", 2, -32768, np.float32), ("u2", 12, 65535, np.float32),
    ("i4", 3, 16777217, np.float64), ("u4", 13, 4294967295, np.float64), ("f4", 4, 0.1, np.float32),
    ("f8", 5, 0.1, np.float64)])
def test_envi_values_are_read_exactly(tmp_path, dtype: str, code: int, value: float, read_as: type) -> None:
    """Each data type's extreme (or, float, 0.1) comes back exactly: 8/16-bit integers and float32 fit float32,
    2^24 + 1 and 2^32 - 1 do not (float64)."""
    raw = np.full((ROWS, COLS, WL.size), value, np.dtype(dtype))
    values = load_cube(_envi(tmp_path, raw, code)).values
    assert values.dtype == read_as
    assert np.all(values == np.dtype(dtype).type(value))


@pytest.mark.parametrize(("line", "message"), [
    ("reflectance scale factor = -10000", r"reflectance scale factor: must be a finite number > 0, got -10000"),
    ("reflectance scale factor = 1e999", r"reflectance scale factor: must be a finite number > 0, got inf"),
    ("interleave = bsx", r"interleave: is 'bsx'; ENVI interleaves are bsq, bil and bip"),
    ("byte order = 2", r"byte order: must be 0 \(little endian\) or 1 \(big endian\), got 2"),
    ("bbl = {1, 0, 0.5}", r"bbl: holds 0\.5; bad band list values are 0 \(bad\) or 1 \(good\)"),
])
def test_envi_header_values_out_of_their_range_are_refused(tmp_path, line: str, message: str) -> None:
    key, value = (s.strip() for s in line.split("="))
    hdr = _envi(tmp_path, np.zeros((ROWS, COLS, WL.size), np.float32), 4, **{key: value})
    with pytest.raises(InputError, match=r"cube\.hdr: " + message):
        load_cube(hdr)


def test_envi_bad_bands_are_dropped_and_reported(tmp_path) -> None:
    raw = np.stack([np.full((ROWS, COLS), v, np.float32) for v in (0.1, 0.2, 0.3)], axis=-1)
    read = load_cube(_envi(tmp_path, raw, 4, bbl="{1, 0, 1}"))
    np.testing.assert_array_equal(read.wavelengths_nm, [500.0, 700.0])
    np.testing.assert_array_equal(read.bad_nm, [600.0])
    np.testing.assert_array_equal(read.values[0, 0], np.array([0.1, 0.3], np.float32))
