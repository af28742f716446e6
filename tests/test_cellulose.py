"""The 2.1 µm cellulose study (`s2cl study cellulose`): mixtures, CAI and NDTI against
plain float64 numpy, the regression, the scene's errors, and the 6S CO₂ absorption that the chain carries."""

from __future__ import annotations

import json
import tomllib
from typing import Any

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.resources import scene_dir
from s2cl.scene.scene import Scene
from s2cl.studies import STUDIES, run_study
from s2cl.studies.cellulose import CO2, score
from s2cl.studies.common import load_study
from s2cl.studies.npv import band_radiance, cai, gas_signal_fraction, linear_mixtures, ndti


def _scene_data() -> dict[str, Any]:
    return tomllib.loads((scene_dir() / "study-cellulose.toml").read_text())


def _setup(data: dict[str, Any], quick: bool = True):
    return load_study(Scene.from_dict(data, base_dir=scene_dir()), quick=quick)


# ---- mixtures and indices against float64 numpy -------------------------------------------------------------

def test_mixtures_match_explicit_loops():
    rng = np.random.default_rng(3)
    soil, npv, green = rng.uniform(0.1, 0.5, (2, 7)), rng.uniform(0.1, 0.5, (3, 7)), rng.uniform(0.0, 0.5, (2, 7))
    fn, fg = [0.0, 0.25, 0.6], [0.0, 0.3]
    mix = linear_mixtures(soil, npv, green, fn, fg)
    assert mix.size == 2 * 3 * 3 * 2
    k = 0
    for i in range(2):
        for j in range(3):
            g = green[(i * 3 + j) % 2]
            for a in fn:
                for b in fg:
                    want = a * npv[j] + b * g + (1 - a - b) * soil[i]
                    np.testing.assert_allclose(mix.reflectance[k], want, rtol=0, atol=1e-15)
                    assert (mix.f_npv[k], mix.f_green[k], mix.soil[k], mix.npv[k]) == (a, b, i, j)
                    k += 1


def test_mixture_fractions_are_checked():
    s = np.full((1, 3), 0.3)
    with pytest.raises(ValueError, match="at most 1"):
        linear_mixtures(s, s, s, [0.8], [0.3])
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        linear_mixtures(s, s, None, [-0.1])
    with pytest.raises(ValueError, match="need green spectra"):
        linear_mixtures(s, s, None, [0.5], [0.1])


def test_cai_and_ndti_formulas():
    r20, r21, r22 = np.array([0.30, 0.40]), np.array([0.25, 0.45]), np.array([0.32, 0.38])
    np.testing.assert_allclose(cai(r20, r21, r22), [0.06, -0.06], rtol=0, atol=1e-15)
    np.testing.assert_allclose(ndti(np.array([0.4, 0.3]), np.array([0.2, 0.3])), [1 / 3, 0.0], atol=1e-15)
    assert np.isnan(ndti(np.array([0.1, 0.0]), np.array([-0.1, 0.0]))).all()


def test_linear_mixture_cai_is_linear_in_the_fraction():
    """With one soil and one NPV spectrum the CAI of the surface is exactly linear in f_NPV: the regression
    recovers f_NPV with zero error and the slope 1 / (CAI_npv − CAI_soil)."""
    wl = np.arange(2000.0, 2221.0)
    soil = 0.35 + 0.0002 * (wl - 2000)
    npv = 0.30 - 0.05 * np.exp(-((wl - 2100) / 25) ** 2)
    mix = linear_mixtures(soil[None], npv[None], None, np.linspace(0, 1, 11))

    def band(rho: np.ndarray, c: float) -> np.ndarray:
        return rho[:, (wl >= c - 10) & (wl <= c + 10)].mean(axis=1)

    index = cai(band(mix.reflectance, 2030), band(mix.reflectance, 2100), band(mix.reflectance, 2210))
    from s2cl.retrieve.quantify import fit_polynomial

    fit = fit_polynomial(index, mix.f_npv, degree=1)
    assert fit.rms < 1e-12
    end = cai(band(np.stack([soil, npv]), 2030), band(np.stack([soil, npv]), 2100), band(np.stack([soil, npv]), 2210))
    np.testing.assert_allclose(fit.coefficients_in_index()[1], 1 / (end[1] - end[0]), rtol=1e-9)


# ---- the 6S CO2 absorption in the chain ------------------------------------------------------------------

def test_co2_absorption_lowers_the_toa_signal_inside_the_feature():
    """The LUT's CO₂ takes a large share of a band in the 2.06 µm CO₂ band and almost nothing in the window
    at 2.14 µm; without the CO₂ (column factor 0) the band radiance is higher by that share. Fails if the
    chain drops the CO₂ absorption."""
    setup = _setup(_scene_data())
    terms = setup.terms(setup.truth())
    rho = np.full(setup.scene.grid.size, 0.3)
    in_co2 = setup.band("B12").with_shape(2065, 10)
    window = setup.band("B12").with_shape(2140, 10)
    ratios = {}
    for name, band in (("co2", in_co2), ("window", window)):
        w = band.weights(setup.scene.grid, setup.scene.run.support)
        with_gas = band_radiance(terms, rho, w)
        without = band_radiance(terms.with_gas_column(CO2, 0.0), rho, w)
        ratios[name] = with_gas / without
        assert gas_signal_fraction(terms, CO2, w) == pytest.approx(
            (with_gas - w.weights @ terms.path_radiance[w.start:w.stop])
            / (without - w.weights @ terms.with_gas_column(CO2, 0.0).path_radiance[w.start:w.stop]), rel=0.02)
    assert ratios["co2"] < 0.75
    assert ratios["window"] > 0.995


def test_gas_column_scaling_is_beer_law_on_the_terms():
    setup = _setup(_scene_data())
    terms = setup.terms(setup.truth())
    t = terms.transmittance[CO2]
    more = terms.with_gas_column(CO2, 1.1)
    np.testing.assert_allclose(more.transmittance[CO2], t ** 1.1, rtol=1e-12)
    np.testing.assert_allclose(more.ground_term, terms.ground_term * t ** 0.1, rtol=1e-12)
    np.testing.assert_allclose(more.path_radiance, terms.path_radiance * t ** 0.1, rtol=1e-12)
    np.testing.assert_array_equal(more.spherical_albedo, terms.spherical_albedo)
    # Beer's law composes: scaling by a then b is scaling by a·b, and by 1 changes nothing; the other gases
    # and the terms' gas-free part (G / T_co2) are untouched
    both = terms.with_gas_column(CO2, 1.1).with_gas_column(CO2, 0.5)
    np.testing.assert_allclose(both.ground_term, terms.with_gas_column(CO2, 0.55).ground_term, rtol=1e-12)
    np.testing.assert_allclose(terms.with_gas_column(CO2, 1.0).path_radiance, terms.path_radiance, rtol=1e-15)
    keep = t > 1e-12
    np.testing.assert_allclose((more.ground_term / more.transmittance[CO2])[keep],
                               (terms.ground_term / t)[keep], rtol=1e-12)
    for gas, tr in terms.transmittance.items():
        if gas != CO2:
            np.testing.assert_array_equal(more.transmittance[gas], tr)
    with pytest.raises(InputError, match="cannot scale 'water'"):
        terms.with_gas_column("water", 2.0)
    with pytest.raises(InputError, match=">= 0"):
        terms.with_gas_column(CO2, -1.0)


# ---- the study end to end (quick) -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def quick(tmp_path_factory) -> dict[str, Any]:
    out = tmp_path_factory.mktemp("cellulose")
    _, js, png = run_study("cellulose", quick=True, output=out)
    assert png.stat().st_size > 1000
    return json.loads(js.read_text())["data"]


def test_quick_study_scores_cai_against_ndti(quick):
    rms = np.array(quick["rms"])
    variants = np.array(quick["variants"])
    assert np.isfinite(rms).all() and rms.size == variants.shape[0]
    # the 2.1 um band helps over what Sentinel-2 has today
    assert rms.min() < quick["base"]["rms"]
    # noise costs: the chain with noise is worse than without, and a narrow band is noisier than a wide one
    assert np.all(rms >= np.array(quick["rms_noise_free"]) - 1e-3)
    nedr = np.array(quick["ne_delta_rho"])
    at = variants[:, 0] == 2100
    widths = variants[at, 1]
    assert np.all(np.diff(nedr[at][np.argsort(widths)]) < 0)
    # CO2 takes more of a band that reaches into the 2.06 um CO2 band
    co2 = np.array(quick["co2_signal_fraction"])
    assert co2[(variants[:, 0] == 2070) & (variants[:, 1] == 10)][0] < 0.8
    assert co2[(variants[:, 0] == 2140) & (variants[:, 1] == 10)][0] > 0.995


def test_score_regresses_each_output_on_its_own_truth():
    f = np.linspace(0, 1, 5)
    truth = (np.repeat(f, 2), f, f[:3])
    exact = tuple((t - 1) / 2 for t in truth)          # index 2x + 1 of these gives back the truth
    s = score(truth, lambda x: 2 * x + 1, exact)
    assert s.rms < 1e-12 and s.rms_noise_free < 1e-12 and s.rms_surface < 1e-12 and s.r2 == pytest.approx(1)
    noisy = (exact[0] + np.tile([0.01, -0.01], 5), exact[1], exact[2])
    s = score(truth, lambda x: 2 * x + 1, noisy)
    x = 2 * noisy[0] + 1                                # float64 numpy least squares of the same line
    resid = np.polyval(np.polyfit(x, truth[0], 1), x) - truth[0]
    assert s.rms == pytest.approx(np.sqrt(np.mean(resid**2)), rel=1e-9) and s.rms > 0.01
    assert s.rms_noise_free < 1e-12


# ---- scene errors -----------------------------------------------------------------------------------------

def _error(data: dict[str, Any]) -> str:
    with pytest.raises(InputError) as exc:
        setup = _setup(data)
        STUDIES["cellulose"](setup)
    return str(exc.value)


def test_fraction_outside_unit_interval_is_an_error():
    data = _scene_data()
    data["study"]["npv_fractions"] = [0.0, 1.2]
    assert "study.npv_fractions: fractions must be in [0, 1], got 1.2" in _error(data)


def test_fractions_adding_up_past_one_are_an_error():
    data = _scene_data()
    data["study"]["quick"] = {}
    data["study"]["npv_fractions"] = [0.0, 0.95]
    assert "study.green_fractions" in _error(data)


def test_bad_band_ranges_are_errors():
    data = _scene_data()
    data["sweep"]["ranges"]["B12"]["centres"] = [2020, 2100]
    assert "sweep.ranges.B12: the 2.1 µm band centre 2020 nm must lie between the shoulders" in _error(data)
    data = _scene_data()
    data["study"]["shoulders"] = [[2030, 20], [2440, 40]]
    assert "study.shoulders" in _error(data)
    data = _scene_data()
    data["study"]["shoulders"] = [[2210, 20], [2030, 20]]
    assert "study.shoulders: the first shoulder must lie below the second" in _error(data)
    data = _scene_data()
    data["study"]["shoulders"] = [[2030, 0], [2210, 20]]
    assert "study.shoulders" in _error(data)


def test_missing_library_and_target_labels_are_errors():
    data = _scene_data()
    data["study"]["targets"]["npv"] = "no-such-npv.csv"
    assert "study.targets.npv" in _error(data)
    data = _scene_data()
    del data["study"]["targets"]["npv"]
    assert "study.targets: no 'npv' target" in _error(data)
    data = _scene_data()
    del data["study"]["targets"]["green"]
    assert "green fractions above 0 need a 'green' target library" in _error(data)
