"""Library simulation end to end against the float64 oracle chain, summaries and datasets."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.app.library_simulation import simulate
from s2cl.errors import InputError
from s2cl.forward.dataset import image_layout
from s2cl.forward.sense import Radiometry
from s2cl.grid import DEFAULT_GRID
from s2cl.libraries.library import SpectralLibrary
from s2cl.reference import forward as ref
from s2cl.reference import stages
from s2cl.scene.scene import Scene
from s2cl.status import PixelFlag


def _radiance_library(n: int = 6) -> SpectralLibrary:
    wl = DEFAULT_GRID.wavelengths
    solar = 1800.0 * np.exp(-(((wl - 500) / 900) ** 2))  # smooth TOA-radiance-like shape, W m-2 sr-1 um-1
    spectra = np.stack([solar * (0.05 + 0.05 * i) / np.pi for i in range(n)])
    return SpectralLibrary(DEFAULT_GRID, spectra, [f"s{i}" for i in range(n)], quantity="radiance",
                           params={"level": np.arange(n, dtype=float)})


def _scene(**effects) -> Scene:
    return Scene.from_dict({"scene": {"name": "t"}, "surface": {"library": "unused.csv", "copies": 50},
                            "effects": {"seed": 11, **effects}})


def test_chain_matches_oracle(rt) -> None:
    lib = _radiance_library()
    scene = _scene()
    res = simulate(scene, library=lib)
    weights = [b.weights(scene.grid) for b in scene.sensor.bands]
    band = ref.resample(lib.spectra.astype(np.float32), weights)
    assert np.allclose(res.band_radiance, band, rtol=2e-6)
    r = Radiometry.of(scene.sensor.bands, 12)
    expanded = np.repeat(res.band_radiance.astype(np.float64), 50, axis=1)
    noisy = ref.add_noise(expanded, r, seed=11)
    sigma = np.sqrt(r.noise_a[:, None] + r.noise_b[:, None] * expanded)
    got = res.noisy.reshape(13, -1)
    assert np.max(np.abs(got - noisy) / sigma) < 1e-3
    dn, flags = stages.quantise(got.astype(np.float64), r.lmin[:, None], r.lmax[:, None], r.maxdn)
    assert np.mean(res.dn.reshape(13, -1) != dn) < 1e-3  # float32 rounding at .5 boundaries only
    low = (flags & (PixelFlag.LOW | PixelFlag.NODATA)) != 0
    assert np.array_equal(res.clipped, np.stack([low.sum(axis=1), ((flags & PixelFlag.HIGH) != 0).sum(axis=1)]))
    calibrated = r.lmin[:, None] + res.dn.reshape(13, -1).astype(np.float64) * r.gain[:, None]
    assert np.allclose(res.calibrated.reshape(13, -1), calibrated, rtol=1e-6)


def test_measured_snr_follows_the_noise_model(rt) -> None:
    lib = _radiance_library(3)
    scene = Scene.from_dict({"scene": {"name": "t"}, "surface": {"library": "x.csv", "copies": 2000},
                             "effects": {"quantise": False, "calibrate": False}})
    rows = simulate(scene, library=lib).summary()
    for row in rows:
        # SNR estimated from 2000 copies has a standard error of ~1.6 %
        assert row["snr_measured_median"] == pytest.approx(row["snr_model_median"], rel=0.08), row["band"]


def test_effects_off_leave_outputs_empty(rt) -> None:
    res = simulate(_scene(noise=False, quantise=False, calibrate=False), library=_radiance_library())
    assert res.noisy is None and res.dn is None and res.calibrated is None and res.clipped is None
    assert res.sensed.shape == (13, 6, 50)


def test_noise_free_quantisation_of_identical_copies(rt) -> None:
    res = simulate(_scene(noise=False), library=_radiance_library())
    assert np.all(res.dn == res.dn[:, :, :1])


def test_copies_share_spectrum_but_not_noise(rt) -> None:
    res = simulate(_scene(), library=_radiance_library())
    assert np.unique(res.noisy[3, 2]).size > 45


def test_dataset_layouts(rt) -> None:
    res = simulate(_scene(), library=_radiance_library(5))
    ds = res.to_dataset("rows")
    assert ds["dn"].shape == (13, 5, 50)
    assert ds["pixel_spectrum"].values[3, 7] == 3
    assert list(ds["band"].values[:2]) == ["B1", "B2"]
    scene = Scene.from_dict({"scene": {"name": "t"}, "surface": {"library": "x.csv", "copies": 16,
                                                                    "layout": "blocks"}})
    blocks = simulate(scene, library=_radiance_library(5)).to_dataset("blocks")
    assert blocks["dn"].shape == (13, 8, 12)
    assert (blocks["pixel_spectrum"].values == -1).sum() == 16
    assert np.all(np.isnan(blocks["noisy"].values[:, blocks["pixel_spectrum"].values == -1]))


def test_image_layout_needs_square_copies() -> None:
    assert image_layout(2, 3, "rows").tolist() == [[0, 1, 2], [3, 4, 5]]
    with pytest.raises(InputError, match="square"):
        image_layout(2, 3, "blocks")
