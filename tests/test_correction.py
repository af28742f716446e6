"""Inverse effect: band-effective atmospheric correction in the sense kernel against its oracle."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.atmos.correction import BandAtmosphere
from s2cl.errors import InputError
from s2cl.forward.sense import Radiometry, Sensing
from s2cl.grid import DEFAULT_GRID
from s2cl.reference.forward import resample, toa_radiance
from s2cl.scene.effects import EffectSet
from s2cl.sensor.sensor import Sensor

CORRECT_ONLY = EffectSet(atmosphere=True, noise=False, quantise=False, calibrate=False, correct=True)


class _Terms:
    """Smooth synthetic per-wavelength terms (the real ones come from the 6S LUT)."""

    def __init__(self, n: int, spectral: bool = True):
        x = np.linspace(0, 1, n) if spectral else np.zeros(n)
        self.path_radiance = 40.0 - 35.0 * x
        self.ground_term = 120.0 - 60.0 * x
        self.spherical_albedo = 0.2 - 0.15 * x


def _bands():
    s = Sensor.sentinel2()
    return s.bands, [b.weights(DEFAULT_GRID) for b in s.bands]


@pytest.mark.parametrize("rho", [0.1, 0.2])
def test_flat_targets_round_trip_with_constant_terms(rho: float) -> None:
    _, weights = _bands()
    terms = _Terms(DEFAULT_GRID.size, spectral=False)
    toa = toa_radiance(np.full((1, DEFAULT_GRID.size), rho), terms.path_radiance, terms.ground_term,
                       terms.spherical_albedo)
    band = BandAtmosphere.of(terms, weights)
    assert np.allclose(band.reflectance(resample(toa, weights)), rho, rtol=1e-12)


def test_band_averaging_residual_is_small_for_smooth_terms() -> None:
    _, weights = _bands()
    terms = _Terms(DEFAULT_GRID.size)
    toa = toa_radiance(np.full((1, DEFAULT_GRID.size), 0.2), terms.path_radiance, terms.ground_term,
                       terms.spherical_albedo)
    rho = BandAtmosphere.of(terms, weights).reflectance(resample(toa, weights))
    assert np.abs(rho - 0.2).max() < 1e-3


def test_kernel_matches_oracle(rt, real_t: str) -> None:
    bands, weights = _bands()
    band = BandAtmosphere.of(_Terms(DEFAULT_GRID.size), weights)
    rho = np.random.default_rng(0).uniform(0, 0.8, (13, 2000))
    L = band.radiance(rho)
    out = Sensing(rt, Radiometry.of(bands, 12), CORRECT_ONLY, real_t, correction=band)(L.astype(real_t))
    tol = 2e-6 if real_t == "float32" else 1e-12
    assert np.allclose(out.reflectance, rho, rtol=tol * 10, atol=tol)


def test_full_chain_recovers_reflectance_within_quantisation(rt) -> None:
    bands, weights = _bands()
    band = BandAtmosphere.of(_Terms(DEFAULT_GRID.size), weights)
    effects = EffectSet(atmosphere=True, noise=False, quantise=True, calibrate=True, correct=True)
    rho = np.full((13, 10), 0.25)
    r = Radiometry.of(bands, 12)
    L = band.radiance(rho)
    inside = (L[:, 0] > r.lmin) & (L[:, 0] < r.lmax)
    assert inside.sum() >= 10
    out = Sensing(rt, r, effects, "float64", correction=band)(L)
    # half a DN of radiance, converted to reflectance through the band's ground term
    bound = 0.5 * r.gain / band.ground_term * (1 - band.spherical_albedo * 0.25) ** 2 * 1.01 + 1e-12
    assert np.all(np.abs(out.reflectance - 0.25)[inside] <= bound[inside, None])
    assert np.all(out.clipped[1, ~inside] == 10)  # saturated bands are reported, not silently wrong


def test_unphysical_radiance_stays_finite(rt) -> None:
    bands, weights = _bands()
    band = BandAtmosphere.of(_Terms(DEFAULT_GRID.size), weights)
    L = np.tile(np.array([-1e6, -500.0, 0.0, 1e-30, 1e6]), (13, 1))
    out = Sensing(rt, Radiometry.of(bands, 12), CORRECT_ONLY, correction=band)(L)
    assert np.all(np.isfinite(out.reflectance))
    assert np.allclose(out.reflectance, band.reflectance(L.astype(np.float32)).astype(np.float32), rtol=1e-5)


def test_correct_needs_terms_and_atmosphere(rt) -> None:
    bands, _ = _bands()
    with pytest.raises(InputError):
        Sensing(rt, Radiometry.of(bands, 12), CORRECT_ONLY)
    with pytest.raises(InputError, match="atmosphere"):
        EffectSet(atmosphere=False, correct=True).validate()


def test_shipped_lut_round_trip_and_band_averaging_residual() -> None:
    """Real 6S terms, no noise: flat 0.1/0.2 come back within 1e-5; spectra with structure inside a
    band (vegetation, minerals) carry a residual, largest in B10 where the atmosphere is opaque."""
    from s2cl.atmos.residuals import band_averaging_residuals

    flat, lib1, minerals = band_averaging_residuals(("builtin:flat", "builtin:lib1", "builtin:minerals"))
    assert np.allclose(flat.true, [[0.1, 0.2]] * len(flat.bands), atol=1e-12)
    assert flat.max_abs().max() < 1e-5
    for r, bound in ((lib1, 1e-3), (minerals, 1.5e-2)):  # the bounds docs/atmos.md states
        assert np.isfinite(r.difference).all()
        b10 = r.bands.index("B10")
        others = np.delete(r.max_abs(), b10)
        assert others.max() < bound
        assert r.max_abs()[b10] > others.max()  # the opaque band is the worst
    assert lib1.max_abs().max() > 10 * flat.max_abs().max()  # structure inside bands does cost
