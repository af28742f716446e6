"""Three-channel water vapour (`s2cl study water-vapour-1020`): the APDA ratio with two windows against an
independent numpy evaluation, a linearly sloped surface retrieved like a flat one with three channels (6S LUT),
the second window's validation, and the two-channel path kept as it was."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner

from s2cl.cli.main import cli
from s2cl.errors import InputError
from s2cl.libraries.library import SpectralLibrary
from s2cl.resources import scene_dir
from s2cl.scene.scene import Scene
from s2cl.studies import STUDIES, check_needs
from s2cl.studies import water_vapour as wv
from s2cl.studies.common import load_study

KIND = "water-vapour-1020"


def _scene(noise: bool = True, **study) -> Scene:
    data = tomllib.loads((scene_dir() / f"study-{KIND}.toml").read_text())
    data["effects"]["noise"] = noise
    data["study"].update(study)
    return Scene.from_dict(data, base_dir=scene_dir())


def _toy_terms(axis: np.ndarray, k: float) -> dict[str, np.ndarray]:
    """Band terms on ``axis`` whose ground term falls as exp(−k √w) (k = 0: a window)."""
    return {"lp": 2.0 + 0.1 * np.sqrt(axis), "g": 90.0 * np.exp(-k * np.sqrt(axis)), "s": 0.1 + 0.01 * axis}


def _forward(t: dict[str, np.ndarray], rho: float, node: int) -> np.ndarray:
    return np.array([t["lp"][node] + t["g"][node] * rho / (1 - t["s"][node] * rho)])


def test_three_channel_ratio_matches_numpy_and_a_linear_continuum_is_exact():
    axis = np.linspace(0.5, 2.2, 30) ** 2
    t8, t9, tw = _toy_terms(axis, 0.01), _toy_terms(axis, 0.6), _toy_terms(axis, 0.02)
    c8, c9, cw = 865.0, 945.0, 1020.0
    rho8, rho9, rhow = (0.2 + 0.0008 * (c - 865.0) for c in (c8, c9, cw))   # linear in wavelength
    node = 17
    L8, L9, Lw = _forward(t8, rho8, node), _forward(t9, rho9, node), _forward(tw, rhow, node)
    a = wv.interpolation_weights([c8, cw], c9)
    diff = wv.apda_difference(L9, t9, wv.continuum([wv.reference(L8, t8), wv.reference(Lw, tw)], a))

    # independent: Schläpfer et al. (1998) ratio with both windows, float64 numpy
    aw = (c9 - c8) / (cw - c8)
    r8 = (L8[:, None] - t8["lp"]) / (t8["g"] + t8["s"] * (L8[:, None] - t8["lp"]))
    rw = (Lw[:, None] - tw["lp"]) / (tw["g"] + tw["s"] * (Lw[:, None] - tw["lp"]))
    denom = (1 - aw) * (L8[:, None] - t8["lp"]) + aw * (Lw[:, None] - tw["lp"])
    rc = (1 - aw) * r8 + aw * rw
    expected = (L9[:, None] - t9["lp"]) / denom - t9["g"] * rc / (1 - t9["s"] * rc) / denom
    np.testing.assert_allclose(diff, expected, rtol=1e-12, atol=1e-14)
    assert a == pytest.approx([1 - aw, aw])
    assert abs(diff[0, node]) < 1e-12 and np.all(np.diff(diff[0]) > 0)   # one crossing, at the node

    three = wv.retrieve_continuum(L9, t9, axis, wv.continuum([wv.reference(L8, t8), wv.reference(Lw, tw)], a))
    two = wv.retrieve(L9, L8, t9, t8, axis)
    assert three[0] == pytest.approx(axis[node], rel=1e-9)
    assert abs(two[0] / axis[node] - 1) > 0.05        # ρ(B9) ≠ ρ(B8a): the two-channel assumption fails


def test_two_channel_difference_is_the_original_formula():
    """The two-channel path is the one-window case: the ratio minus G9/G8 · (1 − S8ρ)/(1 − S9ρ), as before."""
    axis = np.linspace(0.5, 2.2, 12) ** 2
    t8, t9 = _toy_terms(axis, 0.01), _toy_terms(axis, 0.6)
    L8, L9 = np.array([40.0, 55.0]), np.array([20.0, 18.0])
    diff = wv.apda_difference(L9, t9, wv.continuum([wv.reference(L8, t8)], wv.interpolation_weights([865.0], 945.0)))
    d8 = L8[:, None] - t8["lp"]
    rho8 = d8 / (t8["g"] + t8["s"] * d8)
    original = (L9[:, None] - t9["lp"]) / d8 - t9["g"] / t8["g"] * (1 - t8["s"] * rho8) / (1 - t9["s"] * rho8)
    np.testing.assert_allclose(diff, original, rtol=1e-12, atol=1e-14)


def test_sloped_surface_is_retrieved_like_flat_with_three_channels_only():
    """6S LUT, no noise: a surface linear in wavelength (0.26 at 865 nm, 0.34 at 1020 nm) gives the flat
    target's column with three channels; with two the slope biases it by several per cent."""
    setup = load_study(_scene(noise=False, water_vapour=[0.5, 1.0, 2.0, 3.0], pixels=1))
    grid = setup.scene.grid
    wl = grid.wavelengths
    spectra = np.stack([np.full(wl.size, 0.3), np.clip(0.3 + 0.0005 * (wl - 945.0), 0.01, 1.0)])
    targets = {"flat": SpectralLibrary(grid, spectra[:1], ["flat"]), "slope": SpectralLibrary(grid, spectra[1:], ["s"])}
    variants = {"B9": np.array([[945.0, 20.0]]), "B8a": np.array([[865.0, 20.0]]),
                "N1020": np.array([[1020.0, 20.0]])}
    weights = wv.band_weights(setup, variants)
    axis = wv.wv_axis(setup)
    truth = wv.Truth(setup, wv.SUMMER, variants, weights, targets)
    lut = wv.lut_terms(setup, wv.SUMMER, axis, weights)
    R, T = truth.radiance, lut
    refs = [wv.reference(R["B8a"][0], T["B8a"][0]), wv.reference(R["N1020"][0], T["N1020"][0])]
    three = wv.retrieve_continuum(R["B9"][0], T["B9"][0], axis,
                                  wv.continuum(refs, wv.interpolation_weights([865.0, 1020.0], 945.0)))[..., 0]
    two = wv.retrieve(R["B9"][0], R["B8a"][0], T["B9"][0], T["B8a"][0], axis)[..., 0]
    np.testing.assert_allclose(three[1], three[0], rtol=2e-3)       # sloped = flat, three channels
    np.testing.assert_allclose(three[0], truth.truth, rtol=2e-3)
    np.testing.assert_allclose(two[0], truth.truth, rtol=2e-3)       # flat: both retrievals exact
    assert np.all(np.abs(two[1] / two[0] - 1) > 0.03)                # sloped: two channels are biased


@pytest.mark.parametrize(("window2", "match"), [
    ({"centres": [950.0], "widths": [20.0], "centre": 950.0},
     r"study\.window2: the channel's variants reach down to 940 nm .* into the absorption band B9"),
    ({"centres": [1000.0], "widths": [100.0], "centre": 1000.0, "width": 100.0},
     r"study\.window2: .*into the absorption band B9"),
    ({"centres": [2495.0], "widths": [20.0], "centre": 2495.0}, r"study\.window2: the channel's SRFs .* outside the "
                                                                r"spectral grid"),
    ({"centres": [1020.0], "widths": [20.0], "name": "B9"}, r"study\.window2\.name: 'B9' is a sensor band"),
    ({"centres": [1020.0], "widths": [20.0], "noise_band": "B99"}, r"study\.window2\.noise_band: .*no band 'B99'"),
])
def test_bad_window_is_a_one_line_error(window2, match):
    with pytest.raises(InputError, match=match) as err:
        STUDIES[KIND](load_study(_scene(window2=window2)))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(("window2", "match"), [
    ({"centres": [1000.0, 1010.0], "widths": [20.0]}, r"study\.window2: .*headline channel 1020/20 nm"),
    ({"centres": [1020.0, 1020.0], "widths": [20.0]}, r"study\.window2\.centres: values hold duplicates"),
    ({"centres": [1020.0], "widths": [0.0]}, r"study\.window2\.widths: values must be finite and > 0"),
    ({"centres": [1020.0], "widths": [20.0], "name": "a/b"}, r"study\.window2\.name: band name 'a/b' is not allowed"),
])
def test_bad_window_keys_fail_when_the_scene_is_read(window2, match):
    with pytest.raises(InputError, match=match):
        _scene(window2=window2)


def test_missing_window_names_the_key():
    data = tomllib.loads((scene_dir() / f"study-{KIND}.toml").read_text())
    del data["study"]["window2"]
    data["study"]["quick"].pop("window2")
    setup = load_study(Scene.from_dict(data, path=scene_dir() / f"study-{KIND}.toml"))
    with pytest.raises(InputError, match=r"study\.window2: the water-vapour-1020 study needs"):
        check_needs(setup)


def test_quick_run_through_the_cli(tmp_path):
    res = CliRunner().invoke(cli, ["study", KIND, "--quick", "-o", str(tmp_path)])
    assert res.exit_code == 0, res.output
    saved = json.loads((tmp_path / f"{KIND}.json").read_text())
    assert (tmp_path / f"{KIND}.png").stat().st_size > 1000
    d = saved["data"]
    k, head = d["nominal_configuration"], d["window"]["headline"]
    two, three = d["two_channel"], d["three_channel"]
    # flat targets without noise: the continuum is exact either way
    assert two["rel_rms_pct_no_noise"]["flat"][k] < 0.2
    assert three["rel_rms_pct_no_noise"]["flat"][k][head] < 0.2
    # the surface-shape error over soil and vegetation falls with the second window
    for c in ("vegetation", "soil"):
        assert three["rel_rms_pct_no_noise"][c][k][head] < 0.8 * two["rel_rms_pct_no_noise"][c][k]
        assert d["continuum_error_pct"]["three"][c] < d["continuum_error_pct"]["two"][c]
    # B8a and the window barely absorb, B9 does
    sens = d["water_sensitivity_pct"]
    assert sens["B9"][0] > 50 and sens["B8a"][0] < 1 and max(sens["N1020"]) < 5
    assert set(d["winter"]) == {"two", "three", "three_best"}
