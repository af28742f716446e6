"""Image cubes as real data ship: no-data pixels, ignore values, scale factors, bad band lists, µm
wavelengths, integer data, ``NAME.bsq``; NetCDF fill values, scale factors and CF flag variables.

The test cubes are EnMAP-like: reflectance on 10 nm bands, stored as int16 × 10000 with ``data ignore
value = -99`` and a bad band list over the water-vapour windows. Each runs, flags exactly the pixels
whose footprint holds no data, and its valid pixels equal the result of the same reflectance given as a
plain float32 cube in nm (the good bands only, no holes).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from s2cl.app.image_simulation import scene_cube, simulate_image
from s2cl.errors import InputError
from s2cl.forward.cube import load_cube
from s2cl.forward.nodata import gap_weights
from s2cl.grid import DEFAULT_GRID
from s2cl.scene.scene import Scene
from s2cl.status import PixelFlag

WL = np.arange(400.0, 2501.0, 10.0)  # nm, 211 bands
BAD = ((WL > 1340) & (WL < 1460)) | ((WL > 1790) & (WL < 1960))  # water-vapour windows
ROWS = COLS = 12
#: input pixels marked no data: (row, col) -> how
HOLES = {(1, 1): "ignore all bands", (4, 9): "ignore one good band", (10, 3): "nan"}
#: an ignore value in a bad band only: the band is dropped, the pixel stays valid
BAD_BAND_ONLY = (7, 7)
#: input pixels the Gaussian PSF of FWHM 1 band pixel reaches, per input pixel per band pixel, by hand: σ = factor /
#: (2 √(2 ln 2)) = 0.42466 · factor, the one filter's radius ⌈4 σ + taper + 1⌉ - 1 with taper round(8 exp(-π² σ² / 2))
#: (s2cl.forward.instrument.fir_radius): 1 → ⌈1.699 + 3 + 1⌉ - 1, 2 → ⌈3.397 + 0 + 1⌉ - 1, 6 → ⌈10.192 + 0 + 1⌉ - 1
PSF_RADIUS = {1: 5, 2: 4, 6: 11}


def _reflectance() -> np.ndarray:
    """A smooth vegetation-like reflectance field ``(ROWS, COLS, WL)``, int16-exact after × 10000."""
    rng = np.random.default_rng(5)
    shape = 0.05 + 0.4 / (1 + np.exp(-(WL - 715) / 12)) * np.exp(-(((WL - 900) / 900) ** 2))
    field = rng.uniform(0.5, 1.3, (ROWS, COLS, 1)) * shape
    return np.round(field * 10000).astype(np.int16)


def _scene(tmp_path: Path, cube: str, psf: str = "none", quantity: str = "reflectance") -> Scene:
    return Scene.from_dict({"scene": {"name": "enmap"}, "surface": {"cube": cube, "gsd_m": 10.0, "quantity": quantity},
                            "effects": {"seed": 7, "atmosphere": quantity == "reflectance",
                                        "correct": quantity == "reflectance",
                                        "psf": {"fwhm": 1.0} if psf == "gaussian" else False}}, base_dir=tmp_path)


def _write_envi(tmp_path: Path, ints: np.ndarray, *, dtype: str = "int16", interleave: str = "bsq",
                ignore: str = "-99", name: str = "enmap", big_endian: bool = False) -> Path:
    """ENVI pair ``name.hdr`` + ``name.<interleave>`` as EnMAP-like products ship (µm, scale factor, bbl)."""
    data = ints.astype(dtype)
    order = {"bsq": (2, 0, 1), "bil": (0, 2, 1), "bip": (0, 1, 2)}[interleave]
    np.ascontiguousarray(data.transpose(order)).astype(data.dtype.newbyteorder(">" if big_endian else "<")).tofile(
        tmp_path / f"{name}.{interleave}")
    code = {"int16": 2, "float32": 4, "uint16": 12}[dtype]
    um = ", ".join(f"{w / 1000:.4f}" for w in WL)
    bbl = ", ".join("0" if b else "1" for b in BAD)
    hdr = tmp_path / f"{name}.hdr"
    hdr.write_text(f"ENVI\nsamples = {COLS}\nlines = {ROWS}\nbands = {WL.size}\nheader offset = 0\n"
                   f"data type = {code}\ninterleave = {interleave}\nbyte order = {int(big_endian)}\n"
                   f"data ignore value = {ignore}\nreflectance scale factor = 10000\n"
                   f"wavelength units = Micrometers\nwavelength = {{{um}}}\nbbl = {{{bbl}}}\n")
    return hdr


def _holes(ints: np.ndarray, ignore: float, nan: bool) -> tuple[np.ndarray, np.ndarray]:
    """``ints`` with the no-data of :data:`HOLES` punched in (float when NaN is asked), and the input mask."""
    out = ints.astype(np.float32) if nan else ints.copy()
    mask = np.zeros((ROWS, COLS), bool)
    good = np.flatnonzero(~BAD)
    for (r, c), how in HOLES.items():
        if how == "nan" and not nan:
            out[r, c, :] = ignore
        elif how == "nan":
            out[r, c, 5] = np.nan
        elif how == "ignore all bands":
            out[r, c, :] = ignore
        else:
            out[r, c, good[40]] = ignore
        mask[r, c] = True
    out[BAD_BAND_ONLY[0], BAD_BAND_ONLY[1], np.flatnonzero(BAD)[0]] = ignore
    return out, mask


def _reference(rt, tmp_path: Path, ints: np.ndarray, psf: str) -> xr.Dataset:
    """The same reflectance as a plain float32 NetCDF cube in nm, good bands only, no holes."""
    refl = (ints[:, :, ~BAD] / 10000.0).astype(np.float32)
    xr.Dataset({"reflectance": (("y", "x", "wavelength"), refl)},
               coords={"wavelength": ("wavelength", WL[~BAD], {"units": "nm"})}).to_netcdf(
        tmp_path / "plain.nc", engine="h5netcdf")
    return simulate_image(rt, _scene(tmp_path, "plain.nc", psf))


def _expected(mask: np.ndarray, factor: int, psf: str) -> np.ndarray:
    """Output NODATA mask, by its definition: any no-data input pixel within the box widened by the PSF radius."""
    radius = PSF_RADIUS[factor] if psf == "gaussian" else 0
    n = ROWS // factor
    out = np.zeros((n, n), bool)
    for i in range(n):
        for j in range(n):
            r0, r1 = max(i * factor - radius, 0), min((i + 1) * factor + radius, ROWS)
            c0, c1 = max(j * factor - radius, 0), min((j + 1) * factor + radius, COLS)
            out[i, j] = mask[r0:r1, c0:c1].any()
    return out


def _check_against_reference(ds: xr.Dataset, ref: xr.Dataset, mask: np.ndarray, psf: str) -> None:
    assert not (ref["flags_B2"].values & PixelFlag.NODATA).any()
    for band in ("B1", "B5", "B8a", "B11", "B2"):
        factor = int(ds[f"radiance_{band}"].attrs["gsd_m"] // 10)
        expected = _expected(mask, factor, psf)
        flags = ds[f"flags_{band}"].values
        assert np.array_equal((flags & PixelFlag.NODATA) != 0, expected), band
        assert ds[f"radiance_{band}"].attrs["nodata_pixels"] == expected.sum()
        for var in ("radiance", "noisy", "calibrated", "reflectance"):
            values = ds[f"{var}_{band}"].values
            assert np.array_equal(np.isnan(values), expected), (band, var)
            np.testing.assert_allclose(values[~expected], ref[f"{var}_{band}"].values[~expected], rtol=2e-5,
                                       err_msg=f"{band} {var}")
        dn = ds[f"dn_{band}"].values.astype(int)
        assert (dn[expected] == 0).all()
        assert np.abs(dn[~expected] - ref[f"dn_{band}"].values[~expected].astype(int)).max(initial=0) <= 1
    assert expected.any() and not expected.all()  # B2 (10 m): both kinds of pixel


@pytest.mark.parametrize("psf", ["none", "gaussian"])
def test_enmap_like_envi_cube_flags_exactly_its_no_data(rt, tmp_path, psf: str, caplog) -> None:
    """int16 × 10000, µm wavelengths, data ignore value -99, a bbl, data file NAME.bsq."""
    ints = _reflectance()
    holed, mask = _holes(ints, -99, nan=False)
    hdr = _write_envi(tmp_path, holed)
    read = load_cube(hdr)
    assert read.values.dtype == np.float32 and read.values.shape == (ROWS, COLS, (~BAD).sum())
    np.testing.assert_allclose(read.wavelengths_nm, WL[~BAD]) and np.testing.assert_allclose(read.bad_nm, WL[BAD])
    with caplog.at_level(logging.WARNING, logger="s2cl"):
        ds = simulate_image(rt, _scene(tmp_path, hdr.name, psf))
    (gap,) = [r.getMessage() for r in caplog.records if "bad band list" in r.getMessage()]
    assert "B10" in gap and "interpolated" in gap  # 1375 nm lies in the dropped window
    assert ds.attrs["nodata_input_pixels"] == mask.sum()
    _check_against_reference(ds, _reference(rt, tmp_path, ints, psf), mask, psf)


def test_float_envi_cube_with_nan_ignore_value_and_scale(rt, tmp_path) -> None:
    """NaN pixels and an ignore value in one float32 cube (scale factor 10000, bbl, BIL interleave)."""
    ints = _reflectance()
    holed, mask = _holes(ints, -9999.5, nan=True)
    hdr = _write_envi(tmp_path, holed, dtype="float32", interleave="bil", ignore="-9999.5")
    ds = simulate_image(rt, _scene(tmp_path, hdr.name))
    _check_against_reference(ds, _reference(rt, tmp_path, ints, "none"), mask, "none")


def test_netcdf_cube_with_fill_value_scale_factor_and_cf_flags(rt, tmp_path) -> None:
    """int16 with _FillValue and scale_factor (decoded by CF rules), µm, and an ancillary CF flag variable."""
    ints = _reflectance()
    holed, mask = _holes(ints, -99, nan=False)
    flagged = (6, 0)
    qa = np.zeros((ROWS, COLS), np.uint8)
    qa[flagged] = 2
    qa[0, 11] = 1  # "cloud": not no-data, the pixel stays valid
    mask[flagged] = True
    refl = np.where(holed == -99, np.nan, holed / 10000.0)[:, :, ~BAD]
    xr.Dataset({"refl": (("y", "x", "wavelength"), refl, {"ancillary_variables": "qa"}),
                "qa": (("y", "x"), qa, {"flag_values": np.array([0, 1, 2], np.uint8),
                                        "flag_meanings": "clear cloud no_data"})},
               coords={"wavelength": ("wavelength", WL[~BAD] / 1000, {"units": "micrometers"})}).to_netcdf(
        tmp_path / "enmap.nc", engine="h5netcdf",
        encoding={"refl": {"dtype": "int16", "scale_factor": 1e-4, "_FillValue": -99}})
    with xr.open_dataset(tmp_path / "enmap.nc", engine="h5netcdf", decode_cf=False) as raw:
        assert raw["refl"].dtype == np.int16  # stored as integers, decoded by the reader
    ds = simulate_image(rt, _scene(tmp_path, "enmap.nc"))
    _check_against_reference(ds, _reference(rt, tmp_path, ints, "none"), mask, "none")


def test_in_memory_nan_pixels_become_nodata_not_an_error(rt, tmp_path) -> None:
    """A NaN pixel (even a partly NaN one) of a cube given in memory: NODATA, its neighbours untouched, the
    caller's array unchanged; without quantisation the flags variable still carries NODATA."""
    wl = DEFAULT_GRID.wavelengths
    cube = np.repeat((300.0 * np.exp(-(((wl - 500) / 900) ** 2)))[None, None], 36, axis=0).reshape(6, 6, -1)
    cube = cube.astype(np.float32)
    cube[2, 3, 100] = np.nan
    before = cube.copy()
    scene = Scene.from_dict({"scene": {"name": "c"}, "surface": {"cube": "c.nc", "gsd_m": 10.0},
                             "effects": {"seed": 1, "noise": False, "quantise": False, "calibrate": False}})
    ds = simulate_image(rt, scene, cube)
    assert np.array_equal(np.isnan(cube), np.isnan(before)) and np.array_equal(cube[~np.isnan(cube)],
                                                                               before[~np.isnan(before)])
    b2 = ds["radiance_B2"].values
    assert np.isnan(b2[2, 3]) and np.isfinite(np.delete(b2.reshape(-1), 2 * 6 + 3)).all()
    assert np.ptp(np.delete(b2.reshape(-1), 2 * 6 + 3)) == 0  # every valid pixel the same, as the input
    assert ds["flags_B2"].values[2, 3] == PixelFlag.NODATA and ds["flags_B2"].values.sum() == PixelFlag.NODATA
    assert np.isnan(ds["radiance_B5"].values[1, 1]) and np.isfinite(ds["radiance_B5"].values).sum() == 8


def test_bad_band_gap_weights() -> None:
    """A band's weight in a gap is the SRF weight on grid wavelengths strictly between the kept neighbours."""
    scene = Scene.from_dict({"scene": {"name": "c"}, "surface": {"cube": "c.nc", "gsd_m": 10.0}})
    bands = [scene.sensor.band(n) for n in ("B4", "B10", "B9")]
    weights = [b.weights(DEFAULT_GRID) for b in bands]
    f = gap_weights(weights, DEFAULT_GRID, WL[~BAD], WL[BAD])
    assert f[0] == 0.0 and f[1] == pytest.approx(1.0) and f[2] == 0.0
    # one dropped band at 950 nm: the gap is 940-960 nm (open), B9 (945 nm) draws part of its weight there
    kept = WL[WL != 950]
    part = gap_weights([weights[2]], DEFAULT_GRID, kept, np.array([950.0]))[0]
    w = weights[2]
    grid_wl = DEFAULT_GRID.wavelengths[w.start : w.stop]
    assert part == pytest.approx(w.weights[(grid_wl > 940) & (grid_wl < 960)].sum()) and 0 < part < 1


def test_a_radiance_cube_cannot_interpolate_over_bad_bands(tmp_path) -> None:

    hdr = _write_envi(tmp_path, _reflectance())
    message = r"enmap\.hdr: bbl: SRF weight on wavelengths the bad band list \(bbl\) dropped: B10 100 %; .*bands\)"
    with pytest.raises(InputError, match=message) as err:
        scene_cube(_scene(tmp_path, hdr.name, quantity="radiance"))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(("line", "message"), [
    ("bbl = {1, 0}", r"bbl: lists 2 values for bands = 211"),
    ("bbl = {" + ", ".join(["2"] * WL.size) + "}", r"bbl: holds 2; bad band list values are 0"),
    ("bbl = {" + ", ".join(["0"] * WL.size) + "}", r"bbl: marks every band bad"),
    ("wavelength units = GHz", r"wavelength units: wavelength units 'GHz' are not known"),
    ("reflectance scale factor = 0", r"reflectance scale factor: must be a finite number > 0"),
    ("data ignore value = none", r"data ignore value: must be a number, got 'none'"),
])
def test_envi_no_data_keys_are_checked(tmp_path, line: str, message: str) -> None:
    hdr = _write_envi(tmp_path, _reflectance())
    key = line.split("=")[0].strip()
    text = [ln for ln in hdr.read_text().splitlines() if not ln.startswith(key + " =")]
    hdr.write_text("\n".join([*text, line]) + "\n")
    with pytest.raises(InputError, match=message):
        load_cube(hdr)


@pytest.mark.parametrize("ext", ["bsq", "bil", "bip", "img", "dat"])
def test_envi_data_file_names_and_interleaves(tmp_path, ext: str) -> None:
    """NAME.bsq/.bil/.bip (interleave from the header) as well as NAME.img/.dat read the same cube (the
    latter two big-endian)."""
    ints = _reflectance()
    interleave = ext if ext in ("bsq", "bil", "bip") else "bip"
    hdr = _write_envi(tmp_path, ints, dtype="uint16", interleave=interleave, big_endian=ext in ("img", "dat"))
    if ext not in ("bsq", "bil", "bip"):
        (tmp_path / f"enmap.{interleave}").rename(tmp_path / f"enmap.{ext}")
    np.testing.assert_array_equal(load_cube(hdr).values, (ints[:, :, ~BAD] / np.float32(10000)).astype(np.float32))


@pytest.mark.parametrize(("interleave", "dtype", "big_endian", "offset"),
                         [("bsq", "int16", False, 0), ("bil", "float32", True, 64), ("bip", "uint16", True, 7)])
def test_envi_rows_read_alone_equal_the_whole_read(tmp_path, interleave: str, dtype: str, big_endian: bool,
                                                   offset: int) -> None:
    """Rows read alone (a memory map of the data file) equal the same rows of the whole read and SPy's own read
    (interleave, byte order, data type, header offset, ignore value, scale factor and bad bands)."""
    import spectral.io.envi as envi

    from s2cl.io.cubes import open_cube

    holed, _ = _holes(_reflectance(), -99, nan=False)
    hdr = _write_envi(tmp_path, holed, dtype=dtype, interleave=interleave, big_endian=big_endian)
    data = tmp_path / f"enmap.{interleave}"
    data.write_bytes(b"\0" * offset + data.read_bytes())
    hdr.write_text(hdr.read_text().replace("header offset = 0", f"header offset = {offset}"))
    whole = load_cube(hdr).values
    spy = envi.open(str(hdr), str(data)).load(scale=False).astype(np.float64)[:, :, ~BAD]
    expected = np.where(spy == -99, np.nan, spy / 10000)
    np.testing.assert_allclose(whole, expected, rtol=1e-7)
    reader = open_cube(hdr)
    assert (reader.rows, reader.cols) == (ROWS, COLS)
    for start, stop in ((0, 1), (3, 8), (11, 12)):
        np.testing.assert_array_equal(reader.read(start, stop), whole[start:stop])


def test_file_cubes_simulated_by_row_blocks_equal_the_whole_image(rt, tmp_path) -> None:
    """An ENVI cube (ignore value, bad bands, scale factor, with a PSF) and a NetCDF cube (fill value, CF flags) read
    block by block with their halo (block_rows 4, 6): every variable bit-identical to the whole image, no-data
    included."""
    from s2cl.io.image_store import MemoryStore

    ints = _reflectance()
    holed, mask = _holes(ints, -99, nan=False)
    hdr = _write_envi(tmp_path, holed, interleave="bil")
    qa = np.zeros((ROWS, COLS), np.uint8)
    qa[6, 0] = 1
    refl = np.where(holed == -99, np.nan, holed / 10000.0)[:, :, ~BAD]
    xr.Dataset({"refl": (("y", "x", "wavelength"), refl, {"ancillary_variables": "qa"}),
                "qa": (("y", "x"), qa, {"flag_values": np.array([0, 1], np.uint8), "flag_meanings": "clear no_data"})},
               coords={"wavelength": ("wavelength", WL[~BAD], {"units": "nm"})}).to_netcdf(
        tmp_path / "cube.nc", engine="h5netcdf", encoding={"refl": {"dtype": "int16", "scale_factor": 1e-4,
                                                                    "_FillValue": -99}})
    for cube, psf in ((hdr.name, "gaussian"), ("cube.nc", "none")):
        scene = _scene(tmp_path, cube, psf)
        whole = simulate_image(rt, scene)
        assert whole.attrs["nodata_input_pixels"] == mask.sum() + (cube == "cube.nc")
        for block_rows in (4, 6):
            store = MemoryStore()
            simulate_image(rt, scene, store=store, block_rows=block_rows)
            blocks = store.dataset()
            assert set(blocks.data_vars) == set(whole.data_vars)
            for name in whole.data_vars:
                np.testing.assert_array_equal(blocks[name].values, whole[name].values, err_msg=f"{cube} {name}")
            assert blocks["radiance_B2"].attrs == whole["radiance_B2"].attrs
