"""The library registry: builtin names, file paths, errors that list what is available."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.libraries.registry import available_libraries, load_library

SWIR = SpectralGrid(1500.0, 2500.0, 1.0)
EXPECTED_SIZES = {"flat": 2, "lib1": 120, "lib2": 180, "leaf-water": 246, "minerals": 8, "iron-backgrounds": 3,
                  "earthlib-soils": 4168, "earthlib-npv": 104}
EARTHLIB_GRID = SpectralGrid(400.0, 2450.0, 1.0)  # earthlib is measured to 2450 nm only


def test_every_builtin_is_listed_with_a_description_and_loads():
    names = available_libraries()
    assert set(names) == {*EXPECTED_SIZES, "minerals-swir"}
    for name, desc in names.items():
        assert desc and "\n" not in desc
        grid = SWIR if name == "minerals-swir" else EARTHLIB_GRID if name.startswith("earthlib") else DEFAULT_GRID
        lib = load_library(f"builtin:{name}", grid)
        assert lib.grid == grid
        assert np.all(np.isfinite(lib.spectra))
        if name in EXPECTED_SIZES:
            assert lib.size == EXPECTED_SIZES[name], name


def test_builtin_names_ignore_case():
    assert load_library("builtin:LIB1", DEFAULT_GRID).size == 120


def test_flat_with_values():
    lib = load_library("builtin:flat:0.05, 0.3,0.6", DEFAULT_GRID)
    np.testing.assert_array_equal(lib.params["rho"], [0.05, 0.3, 0.6])
    with pytest.raises(InputError, match="flat values must be numbers"):
        load_library("builtin:flat:0.1,x", DEFAULT_GRID)
    with pytest.raises(InputError, match=r"reflectance must lie in \[0, 1\]"):
        load_library("builtin:flat:1.5", DEFAULT_GRID)


def test_unknown_builtin_lists_the_available_ones():
    with pytest.raises(InputError) as info:
        load_library("builtin:goethite", DEFAULT_GRID, source="scenes/a.toml", key="surface.library")
    msg = str(info.value)
    assert msg.startswith("scenes/a.toml: surface.library: unknown builtin library 'goethite'; available:")
    for name in available_libraries():
        assert name in msg


def test_unknown_file_type():
    with pytest.raises(InputError, match=r"'spectra\.txt' is neither builtin:NAME .* nor a \.csv/\.sli/\.hdr/\.npz"):
        load_library("spectra.txt", DEFAULT_GRID)


def test_relative_path_resolves_against_the_scene_file(tmp_path):
    grid = SpectralGrid(400.0, 410.0, 1.0)
    (tmp_path / "data").mkdir()
    rows = "\n".join(f"{w:g},0.25" for w in range(395, 416))
    (tmp_path / "data" / "lib.csv").write_text("wavelength_nm,leaf\n" + rows + "\n")
    lib = load_library("data/lib.csv", grid, source=tmp_path / "scene.toml")
    assert lib.names == ["leaf"]
    np.testing.assert_array_equal(lib.spectra, 0.25)
    with pytest.raises(InputError, match=r"scene\.toml: library: spectral library file .*lib\.csv not found"):
        load_library("data/lib.csv", grid, source=tmp_path / "elsewhere" / "scene.toml")
    # a scene passes its own folder: a relative path is resolved once, never against the scene's folder twice
    lib = load_library("data/lib.csv", grid, source="scene.toml", base_dir=tmp_path)
    assert lib.names == ["leaf"]


def test_builtin_respects_grid_limits():
    with pytest.raises(InputError, match="minerals-swir covers 1500–2500 nm"):
        load_library("builtin:minerals-swir", DEFAULT_GRID)
    lib = load_library("builtin:minerals", SWIR)
    assert lib.spectra.shape == (8, SWIR.size)
    swir = load_library("builtin:minerals-swir", SWIR)
    assert swir.size == 24 and sorted(set(swir.groups)) == ["Al-OH", "Mg-OH/C-O"]
