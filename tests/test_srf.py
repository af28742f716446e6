"""Band SRFs: the paper's eq. (1), the support cut-off, tabulated and measured responses."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.sensor.srf import (
    ALPHA,
    X0,
    XS,
    band_weights,
    load_srf_csv,
    measured_sentinel2_srf,
    point_weights,
    super_gaussian,
)


def test_eq1_constants_and_fwhm() -> None:
    c, w = 665.0, 30.0
    assert super_gaussian(np.array([c]), c, w)[0] == pytest.approx(X0 + XS)
    half = super_gaussian(np.array([c - w / 2, c + w / 2]), c, w)
    # alpha makes the exponential term exactly 1/2 at +-FWHM/2 (to the 6 digits of alpha)
    assert np.allclose(half, X0 + XS / 2, rtol=2e-5)
    assert ALPHA == 1.06299


def test_support_cut_keeps_shape_and_drops_floor() -> None:
    w = band_weights(DEFAULT_GRID, name="B4", centre_nm=665, fwhm_nm=30)
    wl = DEFAULT_GRID.wavelengths[w.start : w.stop]
    assert wl[0] == 635 and wl[-1] == 695
    assert w.weights.sum() == pytest.approx(1.0)
    # without the cut-off the floor alone would hold ~1% of the weight of this band
    full = super_gaussian(DEFAULT_GRID.wavelengths, 665, 30)
    floor_share_uncut = X0 * DEFAULT_GRID.size / full.sum()
    assert floor_share_uncut > 0.005
    # with it, samples in the floor hold < 0.05 % of the weight
    floor = w.weights[np.abs(wl - 665) > 0.768 * 30]
    assert floor.sum() < 5e-4


def test_wider_support_changes_little() -> None:
    spectrum = np.linspace(0.1, 0.5, DEFAULT_GRID.size)
    vals = []
    for support in (1.0, 1.5, 2.0):
        w = band_weights(DEFAULT_GRID, name="B5", centre_nm=705, fwhm_nm=15, support=support)
        vals.append(spectrum[w.start : w.stop] @ w.weights)
    assert np.ptp(vals) / vals[0] < 1e-3


@pytest.mark.parametrize(("centre", "fwhm"), [(410, 30), (2495, 20), (1000, 0), (1000, -5)])
def test_bad_bands_are_named(centre: float, fwhm: float) -> None:
    with pytest.raises(InputError) as err:
        band_weights(DEFAULT_GRID, name="BX", centre_nm=centre, fwhm_nm=fwhm)
    assert "BX" in str(err.value)


def test_band_narrower_than_grid_step() -> None:
    coarse = SpectralGrid(400, 2500, 10)
    with pytest.raises(InputError, match="no grid sample"):
        band_weights(coarse, name="B", centre_nm=705, fwhm_nm=2)


def test_point_weights_interpolate_linearly() -> None:
    w = point_weights(DEFAULT_GRID, 665.25)
    assert w.start == 265 and np.allclose(w.weights, [0.75, 0.25])
    assert point_weights(DEFAULT_GRID, 700).weights.tolist() == [1.0]


def test_tabulated_csv(tmp_path) -> None:
    path = tmp_path / "srf.csv"
    wl = np.arange(600, 731, 1.0)
    r = np.exp(-0.5 * ((wl - 665) / 10) ** 2)
    rows = "\n".join(f"{a},{b},{b * 0.5}" for a, b in zip(wl, r, strict=True))
    path.write_text("# test\nwavelength_nm,B4,B5\n" + rows + "\n")
    table = load_srf_csv(str(path))
    w = band_weights(DEFAULT_GRID, name="B4", centre_nm=665, fwhm_nm=23.5, tabulated=table["B4"])
    centroid = DEFAULT_GRID.wavelengths[w.start : w.stop] @ w.weights
    assert centroid == pytest.approx(665.0, abs=1e-6)


@pytest.mark.parametrize(
    ("text", "message"),
    [("wl,B4\n600,1\n601,1\n", "wavelength_nm"), ("wavelength_nm,B4\n600,1\n599,1\n", "increasing"),
     ("wavelength_nm,B4\n600,1\n601,x\n", "not a number"), ("wavelength_nm,B4\n600,-1\n601,1\n", ">= 0"),
     ("wavelength_nm,B4\n600,0\n601,0\n", "zero everywhere"), ("wavelength_nm,B4\n600,1,3\n", "fields")],
)
def test_tabulated_csv_errors(tmp_path, text: str, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as err:
        load_srf_csv(str(path))
    assert str(path) in str(err.value)


def test_missing_csv(tmp_path) -> None:
    with pytest.raises(InputError, match="not found"):
        load_srf_csv(str(tmp_path / "nope.csv"))


def test_measured_sentinel2a_b1() -> None:
    pytest.importorskip("Py6S")
    m = measured_sentinel2_srf("S2A", "B1")
    w = band_weights(DEFAULT_GRID, name="B1", centre_nm=443, fwhm_nm=20, tabulated=m)
    centroid = DEFAULT_GRID.wavelengths[w.start : w.stop] @ w.weights
    assert 438 < centroid < 448
    with pytest.raises(InputError):
        measured_sentinel2_srf("S2C", "B1")


def test_small_negative_responses_are_clipped_with_a_warning(tmp_path, caplog) -> None:
    """Measured tables carry noise in the wings (Py6S's OLI B4: -0.00034 at 625 nm): clipped to 0, logged."""
    path = tmp_path / "srf.csv"
    wl = np.arange(600, 731, 1.0)
    r = np.exp(-0.5 * ((wl - 665) / 10) ** 2)
    r[25] = -0.00034  # 625 nm, -0.034 % of the peak
    r[120] = -0.009  # 720 nm, -0.9 %: still noise
    path.write_text("wavelength_nm,B4\n" + "\n".join(f"{a},{b}" for a, b in zip(wl, r, strict=True)) + "\n")
    with caplog.at_level("WARNING", logger="s2cl"):
        table = load_srf_csv(str(path))
    assert table["B4"].response.min() == 0.0 and table["B4"].response[25] == 0.0
    assert np.array_equal(table["B4"].response[r >= 0], r[r >= 0])
    (record,) = [rec for rec in caplog.records if "negative response" in rec.getMessage()]
    assert "B4" in record.getMessage() and "720 nm" in record.getMessage() and "2 negative" in record.getMessage()


@pytest.mark.parametrize(("value", "message"), [(-0.02, r"B4: .*got -0\.02 at 625 nm, below the noise allowance"),
                                                ("nan", r"B4: responses must be finite.*got nan at 625 nm")])
def test_garbage_responses_are_refused_in_one_line(tmp_path, value, message: str) -> None:
    path = tmp_path / "srf.csv"
    wl = np.arange(600, 731, 1.0)
    cells = [f"{b}" for b in np.exp(-0.5 * ((wl - 665) / 10) ** 2)]
    cells[25] = str(value)
    path.write_text("wavelength_nm,B4\n" + "\n".join(f"{a},{c}" for a, c in zip(wl, cells, strict=True)) + "\n")
    with pytest.raises(InputError, match=message) as err:
        load_srf_csv(str(path))
    assert "\n" not in str(err.value)


def test_py6s_oli_b4_table_loads_with_its_wing_noise_clipped(tmp_path, caplog) -> None:
    """The measured table that motivated the rule: Py6S's Landsat 8 OLI B4 holds -0.000342 at 625 nm."""
    p6 = pytest.importorskip("Py6S")
    _, start_um, _, values = p6.PredefinedWavelengths.LANDSAT_OLI_B4
    wl = 1000.0 * (start_um + 0.0025 * np.arange(len(values)))
    path = tmp_path / "oli.csv"
    path.write_text("wavelength_nm,B4\n" + "\n".join(f"{a:.4f},{b}" for a, b in zip(wl, values, strict=True)) + "\n")
    with caplog.at_level("WARNING", logger="s2cl"):
        table = load_srf_csv(str(path))
    assert table["B4"].response.min() == 0.0
    assert any("B4" in r.getMessage() and "at 625 nm" in r.getMessage() for r in caplog.records)
