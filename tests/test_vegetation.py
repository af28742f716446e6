"""PROSAIL libraries: shipped data, metadata, plausibility, regeneration with prosail, user cache."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from s2cl.errors import DependencyError, InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.libraries import minerals, vegetation
from s2cl.libraries.npz import read_library_file, write_library_file
from s2cl.libraries.vegetation import LEAF_WATER, LIB1, LIB2, VegetationSpec, load_vegetation

HAVE_PROSAIL = importlib.util.find_spec("prosail") is not None
needs_prosail = pytest.mark.skipif(not HAVE_PROSAIL, reason="prosail not installed (pip install 's2cl[prosail]')")
ROOT = Path(__file__).resolve().parent.parent
CABS = [5.0 * k for k in range(1, 21)]


@pytest.mark.parametrize(
    ("name", "size", "lais", "ewts"),
    [
        ("lib1", 120, [3.0, 4.0], [100.0]),
        ("lib2", 180, [0.5, 1.0, 2.0], [100.0]),
        ("leaf-water", 246, [3.0, 4.0], [100.0 + 10.0 * k for k in range(41)]),
    ],
)
def test_shipped_library_shape_and_metadata(name, size, lais, ewts):
    lib = load_vegetation(name)
    assert lib.spectra.shape == (size, DEFAULT_GRID.size)
    assert lib.spectra.dtype == np.float64
    assert sorted(set(lib.params["lai"])) == lais
    np.testing.assert_allclose(sorted(set(lib.params["ewt"])), ewts)
    if name != "leaf-water":
        np.testing.assert_allclose(sorted(set(lib.params["cab"])), CABS)
    else:
        assert set(lib.params["cab"]) == {40.0}
    assert set(lib.groups) == {"jarosite-muscovite", "siderite", "chlorite"}
    assert len(set(lib.names)) == size
    assert "PROSAIL" in lib.source and "ds1035" in lib.source
    assert np.all(np.isfinite(lib.spectra)) and lib.spectra.min() > 0.0 and lib.spectra.max() < 1.0


def test_shipped_files_fit_the_package_data_budget():
    total = sum(vegetation.shipped_path(n).stat().st_size for n in vegetation.SHIPPED)
    total += minerals.data_path().stat().st_size
    assert total < 6e6


def test_loading_is_deterministic():
    a, b = load_vegetation("lib2"), load_vegetation("lib2")
    np.testing.assert_array_equal(a.spectra, b.spectra)
    assert a.names == b.names


def _red_edge_inflection(lib) -> np.ndarray:
    """Wavelength of steepest slope between 680 and 760 nm (nm), per spectrum."""
    w = lib.grid.wavelengths
    band = (w >= 680.0) & (w <= 760.0)
    return w[band][np.argmax(np.gradient(lib.spectra[:, band], w[band], axis=1), axis=1)]


def test_red_edge_moves_to_longer_wavelengths_with_chlorophyll():
    lib = load_vegetation("lib1")
    rep = _red_edge_inflection(lib)
    for bg in set(lib.groups):
        for lai in (3.0, 4.0):
            sel = (np.asarray(lib.groups) == bg) & (lib.params["lai"] == lai)
            order = np.argsort(lib.params["cab"][sel])
            shift = rep[sel][order]
            assert np.all(np.diff(shift) >= 0), (bg, lai, shift)
            assert shift[-1] - shift[0] >= 30.0


def test_red_edge_also_rises_with_chlorophyll_over_sparse_canopies():
    lib = load_vegetation("lib2")
    rep = _red_edge_inflection(lib)
    for bg in set(lib.groups):
        for lai in (0.5, 1.0, 2.0):
            sel = (np.asarray(lib.groups) == bg) & (lib.params["lai"] == lai)
            r = np.corrcoef(lib.params["cab"][sel], rep[sel])[0, 1]
            assert r > 0.8, (bg, lai, r)


def test_reflectance_at_1650nm_falls_with_leaf_water():
    lib = load_vegetation("leaf-water")
    j = DEFAULT_GRID.index(1650.0)
    for bg in set(lib.groups):
        for lai in (3.0, 4.0):
            sel = (np.asarray(lib.groups) == bg) & (lib.params["lai"] == lai)
            order = np.argsort(lib.params["ewt"][sel])
            assert np.all(np.diff(lib.spectra[sel, j][order]) < 0)


def test_lai_controls_the_background_share():
    """Sparse canopies show more of the background: the spectra spread more across backgrounds."""
    lib = load_vegetation("lib2")
    j = DEFAULT_GRID.index(2200.0)
    spread = {}
    for lai in (0.5, 2.0):
        sel = (lib.params["lai"] == lai) & (lib.params["cab"] == 40.0)
        spread[lai] = np.ptp(lib.spectra[sel, j])
    assert spread[0.5] > 2.0 * spread[2.0]


def test_on_another_grid_and_outside_prosail_range():
    coarse = SpectralGrid(400.0, 2500.0, 5.0)
    lib = load_vegetation("lib1", coarse)
    full = load_vegetation("lib1")
    np.testing.assert_array_equal(lib.spectra, full.spectra[:, ::5])
    with pytest.raises(InputError, match="PROSAIL libraries cover 400–2500 nm"):
        load_vegetation("lib1", SpectralGrid(350.0, 2500.0, 1.0))
    with pytest.raises(InputError, match="unknown PROSAIL library 'lib3'; shipped: lib1, lib2, leaf-water"):
        load_vegetation("lib3")


def test_stale_shipped_file_is_detected(tmp_path, monkeypatch):
    src = read_library_file(vegetation.shipped_path("lib1"))
    meta = dict(src.metadata)
    meta["spec"] = dict(meta["spec"], lai=[3.0])
    fake = tmp_path / "prosail_lib1.npz"
    write_library_file(
        fake,
        wavelength_nm=src.wavelength_nm,
        spectra=src.spectra,
        names=src.names,
        groups=src.groups,
        params=src.params,
        metadata=meta,
    )
    monkeypatch.setattr(vegetation, "shipped_path", lambda name: fake)
    with pytest.raises(InputError, match="stale data"):
        load_vegetation("lib1")


def test_spec_from_dict_and_validation():
    spec = VegetationSpec.from_dict(
        {"name": "mine", "cab": {"start": 10, "stop": 30, "step": 10}, "lai": [1.5], "backgrounds": ["siderite"]}
    )
    assert spec.cab == (10.0, 20.0, 30.0) and spec.size == 3
    assert VegetationSpec.from_dict(LIB1.to_dict()) == LIB1
    with pytest.raises(InputError, match=r"scene\.toml: surface\.prosail\.cab: values must lie in \[0, 300\]"):
        VegetationSpec.from_dict({"cab": [-5], "lai": [3]}, source="scene.toml", key="surface.prosail")
    with pytest.raises(InputError, match="unknown background 'hematite'"):
        VegetationSpec.from_dict({"cab": [5], "lai": [3], "backgrounds": ["hematite"]})
    with pytest.raises(InputError, match=r"unknown keys \['chl'\]"):
        VegetationSpec.from_dict({"chl": [5], "lai": [3]})
    with pytest.raises(InputError, match="needs at least 'cab' and 'lai'"):
        VegetationSpec.from_dict({"cab": [5]})
    with pytest.raises(InputError, match=r"prosail\.constants\.sza: must be in \[0, 90\) degrees, got 95"):
        VegetationSpec.from_dict({"cab": [5], "lai": [3], "constants": {"sza": 95.0}})
    with pytest.raises(InputError, match=r"prosail\.constants\.cm: must be a finite number, got 'x'"):
        VegetationSpec.from_dict({"cab": [5], "lai": [3], "constants": {"cm": "x"}})
    custom = VegetationSpec.from_dict({"cab": [5], "lai": [3], "constants": {"sza": 30.0, "n": 1.8}})
    assert custom.constants.sza == 30.0 and custom.constants.car == 8.0


def test_shipped_libraries_need_neither_prosail_nor_numba():
    code = (
        "import sys; from s2cl.libraries.registry import load_library; from s2cl.grid import DEFAULT_GRID\n"
        "for n in ('lib1', 'lib2', 'leaf-water'): load_library('builtin:' + n, DEFAULT_GRID)\n"
        "bad = [m for m in ('prosail', 'numba') if m in sys.modules]\n"
        "assert not bad, bad\n"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env, check=False)
    assert run.returncode == 0, run.stderr


def test_other_specs_without_prosail_raise_dependency_error(monkeypatch):
    real_version = importlib.metadata.version

    def no_prosail(name):
        if name == "prosail":
            raise importlib.metadata.PackageNotFoundError(name)
        return real_version(name)

    monkeypatch.setattr(importlib.metadata, "version", no_prosail)
    monkeypatch.setitem(sys.modules, "prosail", None)
    spec = VegetationSpec("custom", cab=(30.0,), lai=(2.5,), backgrounds=("siderite",))
    with pytest.raises(DependencyError, match=r"s2cl\[prosail\]"):
        load_vegetation(spec)
    assert load_vegetation("lib1").size == 120  # shipped data still loads


@needs_prosail
@pytest.mark.parametrize(
    ("spec", "index"), [(LIB1, [0, 19, 57, 119]), (LIB2, [0, 61, 179]), (LEAF_WATER, [0, 40, 245])]
)
def test_prosail_regenerates_a_slice_of_the_shipped_file(spec, index):
    shipped = load_vegetation(spec.name)
    bgs = {bg: minerals.background_spectrum(bg, vegetation.PROSAIL_GRID) for bg in spec.backgrounds}
    for i in index:
        p = {k: float(v[i]) for k, v in shipped.params.items()}
        rho = vegetation.simulate(spec, cab=p["cab"], lai=p["lai"], ewt=p["ewt"], background=bgs[shipped.groups[i]])
        # float32 storage: |error| <= half an ulp at reflectance < 0.6, i.e. < 3e-8
        np.testing.assert_allclose(shipped.spectra[i], rho, rtol=0, atol=3e-8)
        assert not np.array_equal(shipped.spectra[i], rho)  # the comparison really sees float32 rounding


@needs_prosail
def test_custom_spec_generated_once_then_read_from_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("S2CL_CACHE", str(tmp_path))
    spec = VegetationSpec("custom run", cab=(20.0, 60.0), lai=(2.5,), ewt=(150.0,), backgrounds=("siderite",))
    lib = load_vegetation(spec)
    files = list((tmp_path / "prosail").iterdir())
    assert len(files) == 1 and files[0].name.startswith("custom_run-") and files[0].suffix == ".npz"
    assert lib.size == 2 and list(lib.params["cab"]) == [20.0, 60.0]
    direct = vegetation.generate(spec)
    np.testing.assert_allclose(lib.spectra, direct.spectra, atol=3e-8)

    def fail(_spec):
        raise AssertionError("should have been read from the cache")

    monkeypatch.setattr(vegetation, "generate", fail)
    again = load_vegetation(spec)
    np.testing.assert_array_equal(again.spectra, lib.spectra)
    files[0].write_bytes(b"garbage")  # a corrupt entry is regenerated, not trusted
    monkeypatch.undo()
    monkeypatch.setenv("S2CL_CACHE", str(tmp_path))
    np.testing.assert_array_equal(load_vegetation(spec).spectra, lib.spectra)
    assert not list((tmp_path / "prosail").glob("*.tmp"))


def test_cache_key_depends_on_spec_and_prosail_version():
    k = vegetation.cache_key(LIB1, "2.0.5")
    assert k == vegetation.cache_key(LIB1, "2.0.5")
    assert k != vegetation.cache_key(LIB1, "2.0.6")
    assert k != vegetation.cache_key(LIB2, "2.0.5")


@needs_prosail
def test_earthlib_soil_backgrounds_cut_the_library_at_2450nm(tmp_path, monkeypatch):
    from s2cl.libraries import earthlib_spectra

    monkeypatch.setenv("S2CL_CACHE", str(tmp_path))
    soil = "FS15R_FS4275"
    spec = VegetationSpec("over soil", cab=(10.0, 60.0), lai=(0.5,), backgrounds=(f"earthlib:{soil}", "siderite"))
    assert spec.grid == SpectralGrid(400.0, 2450.0, 1.0)
    lib = load_vegetation(spec, spec.grid)
    assert lib.size == 4 and lib.groups == [f"earthlib:{soil}"] * 2 + ["siderite"] * 2
    assert "ICRAF-ISRIC soils from earthlib" in lib.source and "USGS" in lib.source
    # the file ends where the soil's measurement ends: nothing held beyond 2450 nm reaches the library
    assert read_library_file(vegetation.library_file(spec)).wavelength_nm[-1] == 2450.0
    with pytest.raises(InputError, match=r"grid: PROSAIL library over soil covers 400–2450 nm .*; "
                                         r"set grid\.stop_nm <= 2450"):
        load_vegetation(spec, DEFAULT_GRID)
    # a sparse canopy over a brighter soil is brighter in the red, where leaves transmit little
    red = spec.grid.index(660.0)
    soil_red = earthlib_spectra.soil_spectrum(soil, spec.grid)[red]
    bg_red = minerals.background_spectrum("siderite", spec.grid)[red]
    assert (lib.spectra[0, red] > lib.spectra[2, red]) == (soil_red > bg_red)


def test_unknown_earthlib_background_is_refused():
    with pytest.raises(InputError, match=r"prosail\.backgrounds: unknown earthlib soil 'earthlib:FS0'"):
        VegetationSpec("x", cab=(20.0,), lai=(1.0,), backgrounds=("earthlib:FS0",)).validate()
    with pytest.raises(InputError, match=r"unknown background 'goethite'; available: .* or earthlib:<ICRAF soil id>"):
        VegetationSpec("x", cab=(20.0,), lai=(1.0,), backgrounds=("goethite",)).validate()
