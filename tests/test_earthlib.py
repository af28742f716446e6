"""The shipped earthlib soils and NPV: provenance, grid interpolation, water-vapour gaps, range errors, Fe index."""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.libraries import earthlib_spectra as el
from s2cl.libraries.npz import read_library_file
from s2cl.libraries.registry import available_libraries, load_library

GRID = SpectralGrid(400.0, 2450.0, 1.0)
#: the earthlib wheel, when at hand (``pip download earthlib==1.1.0 --no-deps``): the extractor's check runs then
WHEEL = Path(os.environ.get("S2CL_EARTHLIB_WHEEL", "earthlib-1.1.0-py3-none-any.whl"))


def _raw():
    return read_library_file(el.data_path())


def test_provenance_names_source_licence_version_and_wheel_hash():
    meta = el.provenance()
    assert meta["extracted_from"]["package"] == "earthlib"
    assert meta["extracted_from"]["version"] == el.EARTHLIB_VERSION
    assert len(meta["extracted_from"]["sha256"]) == 64
    assert "MIT" in meta["licence"] and "ICRAF-ISRIC" in meta["source"]


def test_raw_file_holds_the_wheels_wavelengths_with_the_water_bands_cut():
    raw = _raw()
    w = raw.wavelength_nm
    assert (w[0], w[-1], w.size) == (400.0, 2450.0, 180)
    steps = np.diff(w)
    gaps = [(w[i], w[i + 1]) for i in np.flatnonzero(steps > 10.0 + 1e-9)]
    assert gaps == list(el.WATER_GAPS_NM)
    np.testing.assert_allclose(steps[steps <= 10.0 + 1e-9], 10.0)
    assert raw.spectra.dtype == np.float32 and np.all(np.isfinite(raw.spectra))
    assert raw.groups.count(el.SOIL_GROUP) == 4168
    assert {g for g in raw.groups if g != el.SOIL_GROUP} == {"npv:litter", "npv:bark", "npv:wood", "npv:npv"}
    assert len(set(raw.names)) == raw.size


def test_loaders_shapes_groups_params_and_linear_interpolation_onto_the_grid():
    soils, npv = el.soil_library(GRID), el.npv_library(GRID)
    assert soils.spectra.shape == (4168, GRID.size) and npv.spectra.shape == (104, GRID.size)
    assert set(soils.groups) == {"soil"} and all(g.startswith("npv:") for g in npv.groups)
    assert set(soils.params) == {"fe_band_depth", "redness_index", "site"} and not npv.params
    site = soils.params["site"]
    assert site.max() > 500 and (site == 0).sum() == 448 and np.all(site == np.round(site))
    raw = _raw()
    i = raw.names.index(soils.names[7])
    # on measured wavelengths the grid holds the measured value; between them, the straight line
    for lam in (400.0, 670.0, 1350.0, 1460.0, 2450.0):
        np.testing.assert_allclose(soils.spectra[7, GRID.index(lam)], raw.spectra[i, raw.wavelength_nm == lam][0],
                                   rtol=1e-6)
    a, b = raw.spectra[i, raw.wavelength_nm == 670.0][0], raw.spectra[i, raw.wavelength_nm == 680.0][0]
    np.testing.assert_allclose(soils.spectra[7, GRID.index(673.0)], 0.7 * a + 0.3 * b, rtol=1e-6)


def test_water_vapour_gaps_are_filled_linearly_and_flagged():
    soils = el.soil_library(GRID)
    mask = el.filled_mask(GRID)
    assert mask.sum() == (1460 - 1350 - 1) + (1960 - 1790 - 1)
    assert not mask[GRID.index(1350.0)] and mask[GRID.index(1375.0)] and not mask[GRID.index(1460.0)]
    assert f"{mask.sum()} grid wavelengths inside the unmeasured water-vapour bands" in soils.source
    w = GRID.wavelengths
    lo, hi = GRID.index(1790.0), GRID.index(1960.0)
    line = soils.spectra[:, [lo]] + (soils.spectra[:, [hi]] - soils.spectra[:, [lo]]) * (w[lo:hi + 1] - 1790.0) / 170.0
    np.testing.assert_allclose(soils.spectra[:, lo:hi + 1], line, rtol=1e-9, atol=1e-12)
    vnir = el.soil_library(SpectralGrid(400.0, 1000.0, 1.0))
    assert not el.filled_mask(vnir.grid).any() and "interpolated" not in vnir.source


@pytest.mark.parametrize("grid", [DEFAULT_GRID, SpectralGrid(350.0, 1000.0, 1.0), SpectralGrid(400.0, 2451.0, 1.0)])
def test_grids_beyond_the_measured_range_are_refused(grid):
    for name in ("earthlib-soils", "earthlib-npv"):
        with pytest.raises(InputError, match=rf"grid: library {name} is measured over 400–2450 nm .* does not "
                                             r"extrapolate: set grid\.start_nm >= 400 and grid\.stop_nm <= 2450"):
            load_library(f"builtin:{name}", grid)


def test_registry_lists_both_libraries():
    names = available_libraries()
    assert "4168 measured ICRAF-ISRIC soils" in names["earthlib-soils"]
    assert "litter, bark, wood" in names["earthlib-npv"]
    assert load_library("builtin:EARTHLIB-NPV", SpectralGrid(2000.0, 2400.0, 5.0)).size == 104


def _synthetic(depth: float, w: np.ndarray) -> np.ndarray:
    """A sloping continuum times a raised-cosine band of ``depth`` centred at 880 nm, zero outside 790-970 nm."""
    continuum = 0.2 + 0.0002 * (w - 400.0)
    band = np.where(np.abs(w - 880.0) < 90.0, 0.5 * (1.0 + np.cos(np.pi * (w - 880.0) / 90.0)), 0.0)
    return continuum * (1.0 - depth * band)


def test_fe_band_depth_matches_an_independent_float64_computation():
    w = np.arange(400.0, 2451.0, 10.0)
    spectra = np.stack([_synthetic(d, w) for d in (0.0, 0.05, 0.3)]).astype(np.float32)
    got = el.fe_band_depth(w, spectra)
    # independent: per spectrum, the straight continuum through the shoulder samples (np.interp) in float64
    inside = (w > 760.0) & (w < 1000.0)
    want = []
    for row in spectra.astype(np.float64):
        rc = np.interp(w[inside], [760.0, 1000.0], [row[w == 760.0][0], row[w == 1000.0][0]])
        want.append(np.max(1.0 - row[inside] / rc))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert np.argmin(spectra[2, inside] / np.interp(w[inside], [760.0, 1000.0], spectra[2, [36, 60]])) == 11  # 880
    np.testing.assert_allclose(got, [0.0, 0.05, 0.3], atol=1e-6)  # float32 storage only
    with pytest.raises(InputError, match="needs 760–1000 nm"):
        el.fe_band_depth(np.arange(400.0, 900.0, 10.0), spectra[:, :50])


def test_redness_index_and_shipped_indices():
    w = np.arange(400.0, 1001.0, 10.0)
    flat = np.full((1, w.size), 0.25)
    np.testing.assert_allclose(el.redness_index(w, flat), 0.25**2 / 0.25**4)
    idx = el.soil_indices()
    assert idx["fe_band_depth"].shape == (4168,) and np.all(np.isfinite(idx["redness_index"]))
    # ferric soils are redder: the two indices agree on the whole
    rho = np.corrcoef(np.argsort(np.argsort(idx["fe_band_depth"])), np.argsort(np.argsort(idx["redness_index"])))
    assert rho[0, 1] > 0.3


@pytest.mark.skipif(not WHEEL.is_file(), reason="set S2CL_EARTHLIB_WHEEL to the earthlib wheel to check the extractor")
def test_extractor_reproduces_the_shipped_file(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "x.npz"
    root = Path(__file__).resolve().parent.parent
    subprocess.run([sys.executable, str(root / "tools" / "extract_earthlib.py"), "--wheel", str(WHEEL),
                    "--out", str(out)], check=True, capture_output=True)
    assert out.read_bytes() == el.data_path().read_bytes()
    assert zipfile.is_zipfile(out)
