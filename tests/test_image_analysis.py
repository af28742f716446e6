"""Retrievals on images: the generated fields scene (reproducible, with its truth), the map of a cube scene's
[analysis] against the library pixels' own retrievals and against the float64 numpy twin, the statuses of bare
pixels and of non-finite reflectance, the error map and its metrics, and the files ``s2cl simulate`` writes."""

from __future__ import annotations

import json
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from s2cl.app.analysis import analysis_design, pixel_results, retrieve_pixels
from s2cl.app.chain_parts import scene_simulator
from s2cl.app.checks import check_simulate
from s2cl.app.image_analysis import (
    CommonGrid,
    StreamedAnalysis,
    analyse_image,
    common_grid,
    pure_pixels,
    truth_on_grid,
)
from s2cl.app.image_simulation import scene_cube, simulate_image
from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID
from s2cl.io.image_store import MemoryStore
from s2cl.libraries.fields import CLASSES, fields_image, fields_shape
from s2cl.reference.igrm import fit_numpy_lm
from s2cl.reference.igrm_varpro import fit_numpy_varpro
from s2cl.retrieve.igrm import IgrmSettings
from s2cl.retrieve.metrics import poly2_fit, regression_metrics
from s2cl.scene.scene import Scene
from s2cl.scene.terms import scene_atmosphere
from s2cl.status import FITTED, PixelFlag, Status

RED_EDGE = ["B4", "B5", "B6", "B7"]


def _scene(cube: str = "builtin:fields:40x48", *, noise: bool = True, psf: str = "none", precision: str = "float32",
           kind: str = "igrm", seed: int = 4) -> Scene:
    return Scene.from_dict({
        "scene": {"name": "fields-test"},
        "surface": {"cube": cube, "gsd_m": 10, "quantity": "reflectance"},
        "sensor": {"bands": ["B2", "B3", *RED_EDGE]},
        "effects": {"atmosphere": True, "noise": noise, "seed": seed, "quantise": True, "calibrate": True,
                    "correct": True, "psf": {"fwhm": 1.0} if psf == "gaussian" else False},
        "analysis": {"kind": kind, "parameter": "cab", "bands": RED_EDGE},
        "compute": {"precision": precision},
    })


def _run(rt, scene: Scene, block_rows: int | None = None) -> tuple[xr.Dataset, dict, object, MemoryStore]:
    """Simulate and analyse ``scene`` in memory, ``block_rows`` input rows at a time (the analysis: half as many)."""
    checked = check_simulate(scene)
    cube = scene_cube(scene)
    store = MemoryStore()
    simulate_image(rt, scene, cube=cube, store=store, block_rows=block_rows)
    a = analyse_image(rt, scene, store, cube, checked.analysis_bands, checked.analysis,
                      block_rows=None if block_rows is None else block_rows // 2)
    return store.dataset(), a, cube, store


def test_fields_image_is_reproducible_with_its_truth() -> None:
    a = fields_image(DEFAULT_GRID, 60, 70, seed=3)
    b = fields_image(DEFAULT_GRID, 60, 70, seed=3)
    c = fields_image(DEFAULT_GRID, 60, 70, seed=4)
    assert np.array_equal(a.labels, b.labels) and np.array_equal(a.parcels, b.parcels)
    assert not np.array_equal(a.labels, c.labels)
    groups = np.array(a.library.groups)[a.labels]
    assert set(np.unique(groups)) <= set(CLASSES) and "vegetation" in groups
    truth = a.truth()
    veg = groups == "vegetation"
    assert np.all(np.isfinite(truth["cab"][veg])) and np.all(np.isnan(truth["cab"][~veg]))
    assert np.all(truth["lai"][veg] >= 0.5) and np.all(truth["lai"][~veg] == 0)
    # each parcel is one spectrum; sharp edges: neighbouring parcels differ and most edges cut 20 m pixels
    for p in np.unique(a.parcels):
        assert np.unique(a.labels[a.parcels == p]).size == 1
    edges = np.flatnonzero(np.diff(a.parcels[0]) != 0) + 1
    assert np.any(edges % 2 == 1)


def test_fields_names_are_checked_with_the_scene() -> None:
    assert fields_shape("builtin:fields") == (120, 120)
    assert fields_shape("builtin:FIELDS:30x40") == (30, 40)
    for bad in ("builtin:fields:0x40", "builtin:meadow", "builtin:fields:30"):
        with pytest.raises(InputError, match="builtin:fields") as err:
            _scene(bad)
        assert err.value.key == "surface.cube"


def test_uniform_parcels_give_the_library_pixels_own_retrieval(rt) -> None:
    """Noise off, no PSF: each pixel inside a parcel gets, bit for bit, the retrieval the library path
    (Simulator.run_library + pixel_results) gives that parcel's spectrum."""
    scene = _scene(noise=False)
    ds, _, cube, _ = _run(rt, scene)
    lib = fields_image(scene.grid, 40, 48, scene.run.seed).library
    sim = scene_simulator(rt, scene, atmosphere=scene_atmosphere(scene))
    own = pixel_results(rt, scene, sim.run_library(lib, copies=1, seed=scene.run.seed))
    labels = cube.labels.reshape(40, 48)[::2, ::2][:20, :24]  # the spectrum of each 20 m pixel's first input pixel
    pure = pure_pixels(cube.parcels, 2, 24)
    assert pure.mean() > 0.5
    index, status = ds["analysis_index"].values, ds["analysis_status"].values
    np.testing.assert_array_equal(status[pure], own.status[labels[pure]])
    np.testing.assert_array_equal(index[pure], own.index[labels[pure]].astype(np.float32))


def test_map_is_the_float64_twin_of_the_common_grid(rt) -> None:
    """float64: the map equals the numpy IGRM twin run on the numpy 2 × 2 box average of the band images."""
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    scene = _scene(precision="float64", psf="gaussian")
    ds, _, _, store = _run(rt, scene)
    b4 = ds["reflectance_B4"].values
    b4 = b4.reshape(20, 2, 24, 2).mean(axis=(1, 3))
    refl = np.stack([b4] + [ds[f"reflectance_{b}"].values for b in RED_EDGE[1:]]).reshape(4, -1)
    np.testing.assert_allclose(common_grid(store, scene, RED_EDGE).reshape(4, -1), refl, rtol=1e-12)
    settings = IgrmSettings()
    centres = np.array([scene.sensor.band(b).centre_nm for b in RED_EDGE])
    twin = (fit_numpy_varpro if settings.resolved_solver() == "varpro" else fit_numpy_lm)(
        refl, centres, settings, dtype=np.float64)
    status = ds["analysis_status"].values.reshape(-1)
    assert np.mean(status == twin.status) >= 0.99
    both = (status == twin.status) & np.isin(status, FITTED)
    np.testing.assert_allclose(ds["analysis_index"].values.reshape(-1)[both], twin.lp[both], atol=1e-3)


def test_bare_parcels_report_no_red_edge_and_stay_finite(rt) -> None:
    scene = _scene("builtin:fields:80x80", noise=False, seed=11)
    ds, _, cube, _ = _run(rt, scene)
    groups = np.array(fields_image(scene.grid, 80, 80, 11).library.groups)[cube.labels.reshape(80, 80)]
    pure = pure_pixels(cube.parcels, 2, 40)
    first = groups[::2, ::2]
    index, status = ds["analysis_index"].values, ds["analysis_status"].values
    fitted = np.isin(status, FITTED)
    assert np.all(np.isfinite(index[fitted]))  # a fit has a value; a pixel without one says why
    assert np.all(np.isin(status[~fitted], (Status.DEGENERATE, Status.INVALID)))
    veg, bare = pure & (first == "vegetation"), pure & (first != "vegetation")
    assert bare.any() and veg.any()
    # canopies converge on a red edge; bare soil and minerals have none: the fit says so (degenerate, stalled or
    # on a bound) far more often
    def reported(mask):
        s, b = status[mask], ds["analysis_bounds"].values[mask]
        return np.mean((s != Status.OK) | (b != 0))

    assert reported(veg) < 0.5 < reported(bare)
    assert np.all(np.isnan(ds["cab_truth"].values[bare]))
    assert np.all(np.isnan(ds["cab_error"].values[bare]))


def test_non_finite_reflectance_is_invalid_and_leaves_neighbours(rt) -> None:
    scene = _scene(noise=False)
    bands, settings = analysis_design(scene)
    refl = np.tile(np.array([[0.05], [0.12], [0.3], [0.4]], np.float32), (1, 6))
    refl[2, 1], refl[0, 4] = np.nan, np.inf
    r = retrieve_pixels(rt, scene, bands, settings, refl)
    assert r.status[1] == r.status[4] == Status.INVALID and np.isnan(r.index[[1, 4]]).all()
    assert np.all(r.status[[0, 2, 3, 5]] == r.status[0]) and np.all(np.isfinite(r.index[[0, 2, 3, 5]]))
    # in an image: one NaN input pixel spoils its own 20 m box only
    checked = check_simulate(scene)
    cube = scene_cube(scene)
    store = MemoryStore()
    simulate_image(rt, scene, cube=cube, store=store)
    store.read("reflectance_B4", slice(None))[5, 7] = np.nan
    analyse_image(rt, scene, store, cube, checked.analysis_bands, checked.analysis)
    ds = store.dataset()
    status = ds["analysis_status"].values
    assert status[2, 3] == Status.INVALID and np.isnan(ds["analysis_index"].values[2, 3])
    assert np.count_nonzero(status == Status.INVALID) == 1


def test_error_map_and_metrics_against_the_truth(rt) -> None:
    scene = _scene("builtin:fields:60x60")
    ds, a, cube, _ = _run(rt, scene)
    truth = cube.truth("cab").reshape(30, 2, 30, 2).mean(axis=(1, 3))  # NaN where any of the four has none
    assert np.isnan(truth).sum() > np.all(np.isnan(cube.truth("cab").reshape(30, 2, 30, 2)), axis=(1, 3)).sum()
    np.testing.assert_allclose(ds["cab_truth"].values, truth, rtol=1e-6)
    err = ds["cab_error"].values.astype(np.float64)
    np.testing.assert_allclose(err, ds["cab_map"].values - truth, atol=1e-3, equal_nan=True)
    scored = np.isfinite(err)
    assert a["scored_pixels"] == scored.sum() > 0
    assert a["rms"] == pytest.approx(np.sqrt(np.mean(err[scored] ** 2)), rel=1e-5)
    assert a["bias"] == pytest.approx(err[scored].mean(), abs=1e-3)
    assert a["rms"] > 0 and -1 < a["r2"] <= 1
    # the calibration is regression_metrics' polynomial, fitted on the pure pixels that enter the regression
    status, index = ds["analysis_status"].values.reshape(-1), ds["analysis_index"].values.reshape(-1)
    pure = ds["pure_pixel"].values.reshape(-1).astype(bool)
    use = pure & np.isfinite(truth.reshape(-1)) & np.isin(status, FITTED) & np.isfinite(index)
    assert a["calibration_pixels"] == use.sum()
    m = regression_metrics(index[use][None], status[use][None], np.zeros((1, use.sum()), np.uint8),
                           truth.reshape(-1)[use])
    assert a["calibration_rms"] == pytest.approx(float(m["rms"][0]), rel=1e-9)
    poly = poly2_fit(index[use], np.ones(use.sum(), bool), truth.reshape(-1)[use])
    resid = poly(index[use]) - truth.reshape(-1)[use]
    assert np.sqrt(np.mean(resid**2)) == pytest.approx(float(m["rms"][0]), rel=1e-9)
    total = a["fitted_pixels"] + a["invalid_pixels"] + a["degenerate_pixels"]
    assert total == a["pixels"] == 900
    # the CF attributes a reader decodes the status and the flags with
    st = ds["analysis_status"].attrs
    assert dict(zip(st["flag_values"].tolist(), st["flag_meanings"].split(), strict=True)) == {
        0: "ok", 1: "iteration_limit", 2: "degenerate", 3: "invalid", 4: "stalled", 5: "unclassified"}
    fl = ds["analysis_flags"].attrs
    assert fl["flag_masks"].tolist() == [1, 2, 4]
    assert fl["flag_meanings"] == "below_lmin above_lmax_saturated no_data_nan_radiance"


def test_a_classification_on_an_image_is_refused() -> None:
    scene = Scene.from_dict({"scene": {"name": "x"}, "surface": {"cube": "builtin:fields", "gsd_m": 10,
                                                                 "quantity": "reflectance"},
                             "effects": {"atmosphere": True, "correct": True}, "analysis": {"kind": "sam"}})
    with pytest.raises(InputError, match="class references") as err:
        check_simulate(scene)
    assert err.value.key == "analysis.kind"


def test_simulate_cube_fields_writes_the_map_its_error_and_a_quicklook(tmp_path) -> None:
    from click.testing import CliRunner

    from s2cl.cli.main import cli

    runner = CliRunner()
    listed = runner.invoke(cli, ["scenes"])
    assert listed.exit_code == 0 and "cube-fields" in listed.output
    out = tmp_path / "out"
    r = runner.invoke(cli, ["simulate", "cube-fields", "-o", str(out), "--quiet"])
    assert r.exit_code == 0, r.output
    assert {p.name for p in out.iterdir()} >= {"simulation.nc", "simulation.json", "quicklook.png"}
    with xr.open_dataset(out / "simulation.nc", engine="h5netcdf") as ds:
        for name in ("reflectance_B5", "dn_B4", "analysis_index", "analysis_status", "analysis_flags", "cab_map",
                     "cab_truth", "cab_error"):
            assert name in ds, name
        assert ds["cab_map"].dims == ("y_20m", "x_20m") and ds.attrs["analysis_gsd_m"] == 20
        assert "box average" in ds.attrs["analysis_grid"]
    a = json.loads((out / "simulation.json").read_text())["analysis"]
    assert a["parameter"] == "cab" and np.isfinite(a["rms"]) and a["scored_pixels"] > 1000
    assert (out / "quicklook.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_row_blocks_give_the_whole_image(rt) -> None:
    """With a PSF (its halo read around each block), noise and the analysis: blocks of 12 input rows (the last one
    short, trailing rows filling no 60 m pixel) write exactly the variables of the whole image at once."""
    scene = _scene("builtin:fields:58x44", psf="gaussian")
    scene = Scene.from_dict({**scene.spec.model_dump(exclude_none=True), "sensor": {"bands": ["B1", "B2", "B3",
                                                                                              *RED_EDGE]}})
    whole, a_whole, _, _ = _run(rt, scene)
    blocks, a_blocks, _, _ = _run(rt, scene, block_rows=12)
    assert whole["dn_B1"].shape == (9, 7) and "cab_error" in whole
    assert set(whole.data_vars) == set(blocks.data_vars)
    for name in whole.data_vars:
        np.testing.assert_array_equal(whole[name].values, blocks[name].values, err_msg=name)
        assert whole[name].attrs.keys() == blocks[name].attrs.keys()
    assert whole["radiance_B1"].attrs["clipped_below_lmin"] == blocks["radiance_B1"].attrs["clipped_below_lmin"]
    for key in ("rms", "bias", "r2", "calibration_rms", "fitted_pixels"):
        assert a_blocks[key] == pytest.approx(a_whole[key], rel=1e-9, abs=1e-9), key


@pytest.mark.slow
def test_a_cube_larger_than_the_memory_limit_streams_with_a_bounded_peak(tmp_path) -> None:
    """``s2cl simulate`` of a 960 × 960 image with --max-memory 400MB: the limit leaves the blocks a few tens of MB
    beyond the baseline, a third of what the image takes whole; it runs in row blocks and the peak it allocates
    (tracemalloc, numpy's arrays included, net of a 60 × 60 image's run) stays inside what the limit leaves, while
    the same image simulated whole allocates more than three times that. Same files either way."""

    from s2cl.app.simulate_scene import cube_block_rows
    from s2cl.io.budget import BASELINE_BYTES, Budget

    def peak(cube: str, max_memory: str | None, out: str) -> tuple[int, dict]:
        toml = tmp_path / f"{out}.toml"
        toml.write_text(_toml(cube))
        return _traced_simulation(toml, tmp_path / out, max_memory)

    limit = 400_000_000
    left = limit - BASELINE_BYTES  # what the limit leaves beyond the baseline (which the base run's peak stands for)
    big = "builtin:fields:960x960"
    scene = Scene.from_dict({"scene": {"name": "x"}, "surface": {"cube": big, "gsd_m": 10, "quantity": "reflectance"},
                             "effects": {"atmosphere": True, "psf": {"fwhm": 1.0}}})
    # what the image holds whole, by hand: its labels and parcel ids (int32), the map (float32) and its status, bounds
    # and flags (uint8) on the analysis' 20 m grid
    assert left > 960 * 960 * (4 + 4) + 480 * 480 * (4 + 3)
    assert cube_block_rows(scene, Budget.of(None), 960, 960) is None  # the default limit holds it whole
    assert cube_block_rows(scene, Budget.of(str(limit)), 960, 960) < 960 / 4
    peak("builtin:fields:60x60", None, "warm")  # one-time costs: LUT, libraries, kernel builds
    base, _ = peak("builtin:fields:60x60", None, "base")
    streamed, small = peak(big, str(limit), "small")
    whole, large = peak(big, None, "whole")
    assert small["block_rows"] < 960 / 4 and large["block_rows"] is None
    assert streamed - base < left, (streamed, base, left)
    assert whole - base > 3 * left, (whole, base, left, streamed, small["block_rows"])
    assert small["analysis"]["rms"] == pytest.approx(large["analysis"]["rms"], rel=1e-9)
    with xr.open_dataset(tmp_path / "small" / "simulation.nc", engine="h5netcdf") as a, \
            xr.open_dataset(tmp_path / "whole" / "simulation.nc", engine="h5netcdf") as b:
        for name in ("dn_B5", "reflectance_B2", "analysis_index", "cab_error"):
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


def _toml(cube: str) -> str:
    return (f'[scene]\nname = "big"\n[surface]\ncube = "{cube}"\ngsd_m = 10\nquantity = "reflectance"\n'
            '[effects]\natmosphere = true\nnoise = true\nquantise = true\ncalibrate = true\ncorrect = true\n'
            'psf = {fwhm = 1.0}\n[analysis]\nkind = "igrm"\nparameter = "cab"\n')


def test_a_cube_file_of_the_same_spectra_gives_the_same_images_and_a_map_without_truth(rt, tmp_path) -> None:
    """The generated image written out as a NetCDF cube file: the same band images (the generated path computes
    each distinct spectrum once); the file has no truth, so the map comes without a parameter map or error."""
    from s2cl.app.simulate_scene import simulate_scene

    scene = _scene("builtin:fields:24x30", psf="gaussian")
    image = fields_image(scene.grid, 24, 30, scene.run.seed)
    cube = image.library.spectra[image.labels].astype(np.float32)
    xr.Dataset({"reflectance": (("y", "x", "wavelength"), cube)},
               coords={"wavelength": scene.grid.wavelengths}).to_netcdf(tmp_path / "c.nc", engine="h5netcdf")
    data = scene.spec.model_dump(exclude_none=True)
    data["surface"]["cube"] = "c.nc"
    file_scene = Scene.from_dict(data, base_dir=tmp_path)
    run = simulate_scene(file_scene, tmp_path / "out")
    generated, _, _, _ = _run(rt, scene)
    with xr.open_dataset(run.folder / "simulation.nc", engine="h5netcdf") as ds:
        np.testing.assert_allclose(ds["radiance_B5"].values, generated["radiance_B5"].values, rtol=1e-6)
        assert "analysis_index" in ds and "analysis_status" in ds and "cab_map" not in ds
    assert "rms" not in run.analysis and run.analysis["pixels"] == 12 * 15
    assert (run.folder / "quicklook.png").exists()


def test_an_index_on_bands_of_one_gsd_maps_lai_at_that_gsd(rt) -> None:
    """NDVI (B8, B4: both 10 m) against the LAI truth: the common grid is the bands' own (no averaging), bare
    parcels have a truth too (LAI 0) and enter the calibration."""
    scene = Scene.from_dict({
        "scene": {"name": "ndvi-image"},
        "surface": {"cube": "builtin:fields:40x40", "gsd_m": 10, "quantity": "reflectance"},
        "sensor": {"bands": ["B2", "B3", "B4", "B8"]},
        "effects": {"atmosphere": True, "noise": True, "seed": 2, "quantise": True, "calibrate": True,
                    "correct": True},
        "analysis": {"kind": "ndvi", "parameter": "lai"},
    })
    ds, a, cube, _ = _run(rt, scene)
    assert a["gsd_m"] == 10 and ds["lai_map"].dims == ("y_10m", "x_10m")
    b8, b4 = ds["reflectance_B8"].values.astype(np.float64), ds["reflectance_B4"].values.astype(np.float64)
    np.testing.assert_allclose(ds["analysis_index"].values, (b8 - b4) / (b8 + b4), atol=1e-6)
    np.testing.assert_array_equal(ds["lai_truth"].values, cube.truth("lai"))
    assert a["calibration_pixels"] == a["scored_pixels"] == 1600  # every pixel is pure at 10 m, and has a truth
    assert a["r2"] > 0.5 and a["rms"] == pytest.approx(a["calibration_rms"], rel=1e-6)


@pytest.mark.slow
def test_a_cube_file_larger_than_the_memory_limit_streams_with_a_bounded_peak(tmp_path) -> None:
    """``s2cl simulate`` of a float64 ENVI file (440 × 440 × 211, 327 MB) with --max-memory 450MB, which leaves
    100 MB beyond the baseline: the file is more than three times that, yet it is not refused; it streams in row
    blocks and the peak it allocates (tracemalloc, net of a 60 × 60 file's run) stays inside what the limit leaves, and
    below a third of the file's size."""

    from s2cl.io.budget import BASELINE_BYTES

    wl = np.arange(400.0, 2501.0, 10.0)

    def envi(name: str, n: int) -> Path:
        data = np.memmap(tmp_path / f"{name}.bip", dtype="<f8", mode="w+", shape=(n, n, wl.size))
        shape = 0.05 + 0.4 / (1 + np.exp(-(wl - 715) / 12))
        for r in range(n):
            data[r] = np.linspace(0.5, 1.3, n)[:, None] * shape
        data[n // 2, n // 3, 7] = np.nan  # a no-data pixel
        data.flush()
        del data
        hdr = tmp_path / f"{name}.hdr"
        hdr.write_text(f"ENVI\nsamples = {n}\nlines = {n}\nbands = {wl.size}\nheader offset = 0\ndata type = 5\n"
                       f"interleave = bip\nbyte order = 0\nwavelength = {{{', '.join(f'{w:g}' for w in wl)}}}\n")
        return hdr

    def peak(hdr: Path, max_memory: str | None, out: str) -> tuple[int, dict]:
        toml = tmp_path / f"{out}.toml"
        toml.write_text(f'[scene]\nname = "{out}"\n[grid]\nstep_nm = 5\n[surface]\ncube = "{hdr.name}"\n'
                        'gsd_m = 10\nquantity = "reflectance"\n[effects]\natmosphere = true\nnoise = true\n'
                        'quantise = true\ncalibrate = true\n')
        return _traced_simulation(toml, tmp_path / out, max_memory)

    limit = 450_000_000
    left = limit - BASELINE_BYTES
    small, big = envi("small", 60), envi("big", 440)
    assert (tmp_path / "big.bip").stat().st_size > 3 * left
    peak(small, None, "warm")  # one-time costs: kernel builds
    base, _ = peak(small, None, "base")
    streamed, run = peak(big, str(limit), "streamed")
    assert run["block_rows"] < 440 / 4 and run["attrs"]["nodata_input_pixels"] == 1
    assert streamed - base < left, (streamed, base, left)
    assert streamed < (tmp_path / "big.bip").stat().st_size / 3, streamed  # a whole read allocates the file's size
    with xr.open_dataset(tmp_path / "streamed" / "simulation.nc", engine="h5netcdf") as ds:
        flags = ds["flags_B2"].values
        assert np.count_nonzero(flags & PixelFlag.NODATA) == 1
        assert np.isfinite(ds["calibrated_B4"].values).sum() == 440**2 - 1


def _traced_simulation(toml: Path, out: Path, max_memory: str | None) -> tuple[int, dict]:
    """``s2cl simulate`` of the scene file ``toml`` into ``out`` under ``max_memory``: the peak of traced Python
    allocations (bytes) and the run's ``simulation.json``."""
    from s2cl.app.simulate_scene import simulate_scene

    tracemalloc.start()
    try:
        run = simulate_scene(toml, out, max_memory=max_memory)
        return tracemalloc.get_traced_memory()[1], json.loads((run.folder / "simulation.json").read_text())
    finally:
        tracemalloc.stop()


# ---- the common grid, the truth and the scoring, on images written by hand --------------------------------------

N = np.nan


def _hand_scene() -> Scene:
    """Only its input GSD (10 m) and its sensor's bands (B4 at 10 m, B5 at 20 m) are read."""
    return Scene.from_dict({"scene": {"name": "hand"}, "effects": {"atmosphere": True, "correct": True},
                            "surface": {"cube": "builtin:fields:4x10", "gsd_m": 10, "quantity": "reflectance"}})


def _hand_store(**variables: np.ndarray) -> MemoryStore:
    """A store holding ``variables`` (name: 2-D array; dimensions named after their shape)."""
    store = MemoryStore()
    for name, arr in variables.items():
        dims = (f"y{arr.shape[0]}", f"x{arr.shape[1]}")
        for d, n in zip(dims, arr.shape, strict=True):
            store.dimension(d, np.arange(n), {})
        store.create(name, dims, arr.dtype, {})
        store.write(name, slice(None), arr)
    return store


def test_truth_on_grid_is_nan_where_any_part_of_the_box_has_none() -> None:
    truth = np.array([[1.0, 3.0, 10.0, N, 7.0, 7.0],
                      [5.0, 7.0, 30.0, 40.0, 7.0, 7.0],
                      [N, N, 2.0, 2.0, 1.0, 2.0],
                      [N, N, 4.0, 4.0, 3.0, 4.0],
                      [9.0, 9.0, 9.0, 9.0, 9.0, 9.0]])  # the last row fills no 2 x 2 box
    np.testing.assert_array_equal(truth_on_grid(truth, 2, 3), [[4.0, N, 7.0], [N, 3.0, 2.5]])
    np.testing.assert_array_equal(truth_on_grid(truth, 2, 2), [[4.0, N], [N, 3.0]])
    np.testing.assert_array_equal(truth_on_grid(truth[:2, :2], 1, 2), [[1.0, 3.0], [5.0, 7.0]])


def test_pure_pixels_lie_inside_one_parcel() -> None:
    parcels = np.array([[1, 1, 2, 2, 3, 4],
                        [1, 1, 2, 5, 3, 4],
                        [6, 6, 7, 7, 8, 8],
                        [6, 6, 7, 7, 8, 8]])
    np.testing.assert_array_equal(pure_pixels(parcels, 2, 3), [[True, False, False], [True, True, True]])
    np.testing.assert_array_equal(pure_pixels(parcels, 2, 2), [[True, False], [True, True]])
    np.testing.assert_array_equal(pure_pixels(parcels, 1, 4), np.ones((4, 4), bool))  # every pixel, nx wide


def test_common_grid_box_averages_and_ors_the_flags_by_hand() -> None:
    """B4 (10 m, 5 x 11 pixels) and B5 (20 m, 3 x 4): the grid is 20 m, 2 rows (B4's whole boxes) by 4 columns (B5's);
    B4[r, c] = 11 r + c, so its 2 x 2 box (i, j) averages to 22 i + 2 j + 6."""
    b4 = (11 * np.arange(5)[:, None] + np.arange(11)[None, :]).astype(np.float32)
    b4[3, 5] = N  # box (1, 2)
    b5 = np.array([[0.5, 0.6, 0.7, 0.8], [0.1, 0.2, 0.3, 0.4], [9.0, 9.0, 9.0, 9.0]], np.float32)
    f4, f5 = np.zeros((5, 11), np.uint8), np.zeros((3, 4), np.uint8)
    f4[0, 0], f4[1, 3], f4[2, 2], f4[3, 7], f4[4, 0], f4[0, 8] = 1, 2, 4, 8, 16, 32  # rows 4 and col 8+: no box
    f5[0, 0], f5[1, 2], f5[2, 1] = 64, 1, 128  # B5 row 2: beyond the grid
    store = _hand_store(reflectance_B4=b4, reflectance_B5=b5, flags_B4=f4, flags_B5=f5)
    grid = CommonGrid.of(store, _hand_scene(), ["B4", "B5"])
    assert (grid.bands, grid.factors, grid.gsd_m, grid.ny, grid.nx) == (["B4", "B5"], [2, 1], 20.0, 2, 4)
    assert grid.dims == ("y_20m", "x_20m")
    want = np.array([[[6.0, 8.0, 10.0, 12.0], [28.0, 30.0, N, 34.0]],
                     [[0.5, 0.6, 0.7, 0.8], [0.1, 0.2, 0.3, 0.4]]], np.float32)
    np.testing.assert_array_equal(grid.reflectance(store, slice(0, 2)), want)
    np.testing.assert_array_equal(grid.reflectance(store, slice(1, 2)), want[:, 1:])
    np.testing.assert_array_equal(grid.flags(store, slice(0, 2)), [[1 | 64, 2, 0, 0], [0, 4, 1, 8]])
    np.testing.assert_array_equal(grid.flags(store, slice(1, 2)), [[0, 4, 1, 8]])
    plain = _hand_store(reflectance_B4=b4, reflectance_B5=b5)  # a chain that does not quantise: no flags
    assert CommonGrid.of(plain, _hand_scene(), ["B4", "B5"]).flags(plain, slice(0, 2)) is None


def test_fit_accounting_counts_each_status_by_hand() -> None:
    from s2cl.app.image_analysis import _accounting

    status = np.array([Status.OK, Status.STALLED, Status.ITERATION_LIMIT, Status.DEGENERATE, Status.INVALID,
                       Status.OK, Status.INVALID, Status.OK], np.uint8)
    bounds = np.array([0, 1, 0, 0, 0, 2, 0, 0], np.uint8)
    a = _accounting(status, bounds)
    assert (a["fitted_pixels"], a["invalid_pixels"], a["degenerate_pixels"], a["bound_pixels"]) == (5, 2, 1, 2)
    assert (a["converged_fraction"], a["stalled_fraction"], a["failed_fraction"], a["bound_fraction"]) == (
        3 / 8, 1 / 8, 3 / 8, 2 / 8)


#: labels of a 4 x 10 image at 10 m (also its parcels); the truth (cab) of each label; label 3 is bare (no cab)
LABELS = np.array([[0, 0, 1, 1, 2, 2, 0, 1, 1, 1],
                   [0, 0, 1, 1, 2, 2, 0, 1, 1, 1],
                   [3, 3, 2, 3, 1, 1, 1, 2, 0, 0],
                   [3, 3, 2, 3, 1, 1, 1, 2, 0, 0]])
CAB = np.array([10.0, 20.0, 30.0, N])
#: the 20 m map's index and status: the pure pixels that enter the regression (OK, pure, with a truth) lie on
#: cab = 10 index; a STALLED fit (not regressed on here), a DEGENERATE one with a value, an INVALID one
HAND_INDEX = np.array([[1.0, 2.0, 3.0, 1.625, 5.0], [0.5, 2.5, 4.0, 2.625, N]], np.float32)
HAND_STATUS = np.array([[Status.OK, Status.OK, Status.OK, Status.OK, Status.STALLED],
                        [Status.OK, Status.OK, Status.DEGENERATE, Status.OK, Status.INVALID]], np.uint8)


def _hand_truth_run(status: np.ndarray, step: int, bounds: np.ndarray | None = None) -> tuple[dict, MemoryStore]:
    from s2cl.app.image_analysis import _against_truth
    from s2cl.forward.cube import SceneCube
    from s2cl.retrieve.family import AnalysisSettings

    cube = SceneCube(None, 4, 10, "hand", labels=LABELS.reshape(-1), truth_params={"cab": CAB}, parcels=LABELS)
    grid = CommonGrid(["B4", "B5"], [2, 1], 20.0, 2, 5)
    store = MemoryStore()
    for d, n in zip(grid.dims, (2, 5), strict=True):
        store.dimension(d, np.arange(n), {})
    settings = AnalysisSettings("igrm", "cab", regress=(int(Status.OK),))
    bounds = np.zeros((2, 5), np.uint8) if bounds is None else bounds
    out = _against_truth(store, _hand_scene(), cube, (HAND_INDEX, status, bounds), grid, settings, step)
    return out, store


@pytest.mark.parametrize("step", [1, 2])
def test_the_map_is_scored_where_a_regressed_fit_meets_a_whole_truth(step: int) -> None:
    """Truth box means: [[10, 20, 30, 15, 20], [-, - (half bare), 20, 25, 10]]; calibration on the three pure OK
    pixels with a truth (index 1, 2, 3: cab = 10 index exactly). Scored: the five OK pixels with a truth, edges
    included (errors 0, 0, 0, +1.25, +1.25); not the bare ones, nor the STALLED, DEGENERATE or INVALID fits."""
    out, store = _hand_truth_run(HAND_STATUS, step)
    ds = store.dataset()
    np.testing.assert_allclose(ds["cab_truth"].values, [[10, 20, 30, 15, 20], [N, N, 20, 25, 10]], rtol=1e-7)
    np.testing.assert_allclose(ds["cab_map"].values, [[10, 20, 30, 16.25, N], [5, 25, N, 26.25, N]], rtol=1e-6)
    np.testing.assert_allclose(ds["cab_error"].values, [[0, 0, 0, 1.25, N], [N, N, N, 1.25, N]], atol=1e-5)
    np.testing.assert_array_equal(ds["pure_pixel"].values, [[1, 1, 1, 0, 1], [1, 0, 1, 0, 1]])
    assert out["calibration_pixels"] == 3 and out["calibration_rms"] == pytest.approx(0.0, abs=1e-9)
    assert out["scored_pixels"] == 5
    assert out["rms"] == pytest.approx(np.sqrt(2 * 1.25**2 / 5), rel=1e-9)
    assert out["bias"] == pytest.approx(2 * 1.25 / 5, rel=1e-9)
    # truths scored 10, 20, 30, 15, 25: mean 20, sum of squares about it 250
    assert out["r2"] == pytest.approx(1 - 2 * 1.25**2 / 250, rel=1e-9)
    assert out["map"] == "cab_map" and out["parameter"] == "cab"


def test_fewer_than_three_calibration_pixels_make_no_map() -> None:
    status = HAND_STATUS.copy()
    status[0, 2] = Status.DEGENERATE  # leaves two pure OK pixels with a truth
    out, store = _hand_truth_run(status, 2)
    assert out == {"parameter": "cab", "calibration_pixels": 2,
                   "note": "fewer than 3 pure pixels with a fit: no calibration, no parameter map"}
    assert "cab_map" not in store


def test_the_calibration_refits_without_the_fits_on_a_bound() -> None:
    """The STALLED pixel made OK but on a bound (index 5, cab 20): four calibration pixels, off any parabola, so
    the calibration RMS is numpy's least-squares parabola's; without the bound pixel three remain, which a parabola
    fits exactly (RMS 0 on the bounds' refit)."""
    status, bounds = HAND_STATUS.copy(), np.zeros((2, 5), np.uint8)
    status[0, 4], bounds[0, 4] = Status.OK, 1
    out, _ = _hand_truth_run(status, 2, bounds)
    x, t = np.array([1.0, 2.0, 3.0, 5.0]), np.array([10.0, 20.0, 30.0, 20.0])
    resid = np.polyval(np.polyfit(x, t, 2), x) - t
    assert out["calibration_pixels"] == 4
    assert out["calibration_rms"] == pytest.approx(np.sqrt(np.mean(resid**2)), rel=1e-9) and out["calibration_rms"] > 1
    assert out["calibration_rms_unbounded"] == pytest.approx(0.0, abs=1e-9)


def test_the_analysis_of_simulate_is_fed_as_it_writes_and_reads_nothing_back(rt, monkeypatch) -> None:
    """``s2cl simulate``'s analysis takes the analysis bands' reflectance and flags rows as the simulation writes them
    (:class:`StreamedAnalysis`): in blocks of 12 input rows, with nothing read back from the store, it writes the
    variables and returns the figures that the analysis of the image read back gives."""
    scene = _scene("builtin:fields:58x44", psf="gaussian")
    reference, ref_figures, _, _ = _run(rt, scene, block_rows=12)
    checked = check_simulate(scene)
    cube = scene_cube(scene)
    store, reads = MemoryStore(), []
    read = MemoryStore.read

    def counted(self, name, rows):
        reads.append(name)
        return read(self, name, rows)

    monkeypatch.setattr(MemoryStore, "read", counted)
    streamed = StreamedAnalysis(rt, checked.scene, list(checked.analysis_bands), checked.analysis, cube.rows,
                                cube.cols)
    simulate_image(rt, scene, cube=cube, store=streamed.tee(store), block_rows=12)
    figures = streamed.finish(store, cube, 6)
    assert not [n for n in reads if n.startswith(("reflectance_", "flags_"))]
    ds = store.dataset()
    assert set(ds.data_vars) == set(reference.data_vars) and "cab_error" in ds
    for name in reference.data_vars:
        np.testing.assert_array_equal(ds[name].values, reference[name].values, err_msg=name)
        assert ds[name].attrs.keys() == reference[name].attrs.keys()
    assert json.dumps(figures, sort_keys=True) == json.dumps(ref_figures, sort_keys=True)
