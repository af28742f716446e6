"""Image cubes: per-band images at each band's GSD, files in and out, bad cubes."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from s2cl.app.image_simulation import simulate_image
from s2cl.errors import InputError
from s2cl.forward.cube import aggregate, load_cube
from s2cl.forward.sense import Radiometry
from s2cl.grid import DEFAULT_GRID
from s2cl.io.output import write_netcdf
from s2cl.reference import forward as ref
from s2cl.scene.scene import Scene


def _cube(rows: int = 60, cols: int = 60, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    wl = DEFAULT_GRID.wavelengths
    base = 500.0 * np.exp(-(((wl - 500) / 900) ** 2))
    field = rng.uniform(0.05, 0.6, (rows, cols, 1))
    return (field * base).astype(np.float32)


def _scene(tmp_path=None, **surface) -> Scene:
    surf = {"cube": "cube.nc", "gsd_m": 10.0, **surface}
    return Scene.from_dict({"scene": {"name": "cube"}, "surface": surf, "effects": {"seed": 3}},
                           base_dir=tmp_path)


def test_bands_at_their_own_gsd(rt) -> None:
    cube = _cube()
    scene = _scene()
    ds = simulate_image(rt, scene, cube)
    assert ds["dn_B2"].shape == (60, 60)
    assert ds["dn_B5"].shape == (30, 30)
    assert ds["dn_B1"].shape == (10, 10)
    assert ds["dn_B1"].attrs["gsd_m"] == 60 and ds["dn_B1"].attrs["centre_nm"] == 443
    # noise-free 60 m radiance = 6 x 6 box mean of the resampled 10 m radiance
    w = scene.sensor.band("B1").weights(DEFAULT_GRID)
    fine = ref.resample(cube.reshape(-1, DEFAULT_GRID.size), [w])[0].reshape(60, 60)
    coarse = fine.reshape(10, 6, 10, 6).mean(axis=(1, 3))
    assert np.allclose(ds["radiance_B1"].values, coarse, rtol=3e-6)
    # noise of B1 keys on its own 10 x 10 grid and band id 0
    r = Radiometry.of([scene.sensor.band("B1")], 12, [0])
    noisy = ref.add_noise(ds["radiance_B1"].values.reshape(1, -1).astype(np.float64), r, seed=3)
    sigma = np.sqrt(r.noise_a[0] + r.noise_b[0] * coarse.reshape(-1))
    assert np.max(np.abs(ds["noisy_B1"].values.reshape(-1) - noisy[0]) / sigma) < 1e-3


def test_psf_smooths_but_keeps_flat_fields(rt) -> None:
    flat = np.ones((12, 12), np.float32)
    assert np.allclose(aggregate(flat, 6, psf_fwhm=1.0), 1.0)
    edge = np.zeros((12, 12), np.float32)
    edge[:, 6:] = 1.0
    sharp, blurred = aggregate(edge, 6), aggregate(edge, 6, psf_fwhm=1.0)
    assert sharp.tolist() == [[0.0, 1.0], [0.0, 1.0]]
    assert 0.0 < blurred[0, 0] < 0.5 < blurred[0, 1] < 1.0


def test_netcdf_cube_in_and_out(rt, tmp_path) -> None:
    cube = _cube(12, 12)
    ds_in = xr.Dataset({"radiance": (("y", "x", "wavelength"), cube)},
                       coords={"wavelength": ("wavelength", DEFAULT_GRID.wavelengths / 1000.0, {"units": "um"})})
    ds_in.to_netcdf(tmp_path / "cube.nc", engine="h5netcdf")
    read = load_cube(tmp_path / "cube.nc")
    loaded, wl = read.values, read.wavelengths_nm
    assert loaded.shape == cube.shape and np.allclose(wl, DEFAULT_GRID.wavelengths)
    out = simulate_image(rt, _scene(tmp_path))
    path = write_netcdf(tmp_path / "out" / "simulation.nc", out)
    back = xr.open_dataset(path, engine="h5netcdf")
    assert back["dn_B4"].dtype == np.uint16 and back["dn_B12"].shape == (6, 6)
    assert back.attrs["Conventions"] == "CF-1.10"
    assert back["noisy_B4"].attrs["standard_name"] == "toa_outgoing_radiance_per_unit_wavelength"
    assert back["flags_B4"].attrs["flag_meanings"].split()[0] == "below_lmin"
    assert not list((tmp_path / "out").glob(".*tmp"))


def test_envi_cube(rt, tmp_path) -> None:
    envi = pytest.importorskip("spectral.io.envi")
    cube = _cube(6, 6)
    envi.save_image(str(tmp_path / "cube.hdr"), cube, metadata={"wavelength": list(DEFAULT_GRID.wavelengths),
                                                                "wavelength units": "nm"})
    read = load_cube(tmp_path / "cube.hdr")
    loaded, wl = read.values, read.wavelengths_nm
    assert np.allclose(loaded, cube) and wl.size == DEFAULT_GRID.size
    ds = simulate_image(rt, _scene(tmp_path, cube="cube.hdr"))
    assert ds["dn_B2"].shape == (6, 6)


def test_cube_bad_inputs(rt, tmp_path) -> None:
    with pytest.raises(InputError, match="not a whole multiple"):
        simulate_image(rt, _scene(gsd_m=15.0), _cube(12, 12))
    with pytest.raises(InputError, match="wavelengths"):
        simulate_image(rt, _scene(), _cube(6, 6)[:, :, :2000])
    with pytest.raises(InputError, match="smaller than one"):
        simulate_image(rt, _scene(), _cube(4, 4))
    with pytest.raises(InputError, match="not found"):
        load_cube(tmp_path / "missing.nc")
    (tmp_path / "junk.nc").write_text("not netcdf")
    with pytest.raises(InputError, match="NetCDF"):
        load_cube(tmp_path / "junk.nc")
    xr.Dataset({"a": (("y", "x", "band"), np.zeros((2, 2, 3)))}).to_netcdf(tmp_path / "nowl.nc", engine="h5netcdf")
    with pytest.raises(InputError, match="wavelength"):
        load_cube(tmp_path / "nowl.nc")
    with pytest.raises(InputError, match="shape"):
        simulate_image(rt, _scene(), np.zeros((10, 2101), np.float32))
