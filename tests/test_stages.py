"""The forward chain as declared stages (s2cl/forward/stages.py): one ordered registry; one home for every effect's
settings ([effects]; the deprecated [instrument] and [spatial] keys still read, each with a one-line note); one PSF
with one reach; image-only stages named in a caveat where they cannot run."""

from __future__ import annotations

import json
import logging
import math

import numpy as np
import pytest
import xarray as xr
from scipy.ndimage import gaussian_filter

from s2cl.app.chain_parts import scene_instrument
from s2cl.forward.instrument import fir_radius
from s2cl.forward.reach import band_groups, cube_halo
from s2cl.forward.stages import STAGES, chain, image_only, segments, stage
from s2cl.scene.effects import SWITCHES, EffectSet
from s2cl.scene.scene import Scene

CUBE = {"scene": {"name": "cube"}, "surface": {"cube": "cube.nc", "gsd_m": 10.0}}
LIBRARY = {"scene": {"name": "lib"}, "surface": {"library": "builtin:lib1", "quantity": "reflectance", "copies": 2,
                                                 "select": {"cab": [30, 32]}},
           "effects": {"atmosphere": True, "correct": True}}


# -- the registry --------------------------------------------------------------------------------------------------

def test_every_switch_of_effects_is_a_declared_stage_in_the_chains_order() -> None:
    names = [s.name for s in STAGES]
    assert len(set(names)) == len(names)
    assert [n for n in names if n in SWITCHES] == list(SWITCHES)  # [effects] lists them in the chain's order
    assert set(SWITCHES) == set(names)
    for s in STAGES:
        assert s.key == f"effects.{s.name}" and s.twin and ":" in s.twin, s.name
        if s.per_pixel:
            assert s.device is not None and s.compute is not None, s.name


def test_the_chain_is_the_switched_on_per_pixel_stages_in_order() -> None:
    e = EffectSet(atmosphere=True, correct=True, noise=False)
    assert [s.name for s in chain(e)] == ["quantise", "calibrate", "correct"]
    assert segments(chain(e)) == [("band", [stage("quantise"), stage("calibrate"), stage("correct")])]
    assert EffectSet(atmosphere=True, correct=True).describe() == (
        "atmosphere, resample, noise, quantise, calibrate, correct")


# -- one home ------------------------------------------------------------------------------------------------------

def test_deprecated_sections_are_read_with_one_note_per_key(caplog) -> None:
    legacy = {**CUBE, "instrument": {"mtf": True, "mtf_nyquist": 0.2, "coregistration": True,
                                     "coregistration_shifts": {"B5": [0.1, -0.2]}, "smile_centre_nm": [0.0, 1.0]}}
    home = {**CUBE, "effects": {"psf": {"mtf_nyquist": 0.2}, "coregistration": {"shifts": {"B5": [0.1, -0.2]}},
                                "smile": {"on": False, "centre_nm": [0.0, 1.0]}}}
    with caplog.at_level(logging.WARNING, logger="s2cl"):
        old = Scene.from_dict(legacy)
    notes = [r.getMessage() for r in caplog.records]
    assert notes == [
        "scene: instrument.mtf is deprecated: write it as effects.psf = {mtf_nyquist = 0.2}",
        "scene: instrument.mtf_nyquist is deprecated: write it as effects.psf = {mtf_nyquist = 0.2}",
        "scene: instrument.coregistration is deprecated: write it as effects.coregistration = {shifts = "
        "{B5 = [0.1, -0.2]}}",
        "scene: instrument.coregistration_shifts is deprecated: write it as effects.coregistration = {shifts = "
        "{B5 = [0.1, -0.2]}}",
        "scene: instrument.smile_centre_nm is deprecated: write it as effects.smile = {on = false, centre_nm = "
        "[0, 1]}"]
    new = Scene.from_dict(home)
    assert old.spec.effects == new.spec.effects and old.effects == new.effects
    assert old.effects.describe() == "resample, psf, coregistration, noise, quantise, calibrate"
    a, b = scene_instrument(old), scene_instrument(new)
    assert [a.response(k, 2) for k in range(13)] == [b.response(k, 2) for k in range(13)]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="s2cl"):
        spatial = Scene.from_dict({**CUBE, "spatial": {"psf": "gaussian", "psf_fwhm": 1.5}})
    assert [r.getMessage() for r in caplog.records] == [
        f"scene: spatial.{k} is deprecated: write it as effects.psf = {{fwhm = 1.5}}" for k in ("psf", "psf_fwhm")]
    assert spatial.spec.effects.psf.fwhm == 1.5 and spatial.effects.on("psf")


def test_a_scene_in_the_one_home_gives_no_note(caplog) -> None:
    with caplog.at_level(logging.WARNING, logger="s2cl"):
        for name in ("cube-fields", "study-instrument"):
            Scene.load(name)
    assert not caplog.records


# -- one PSF, one reach ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("fwhm", [1.0, 2.5])
def test_the_fwhm_psf_is_the_gaussian_of_that_fwhm(fwhm: float) -> None:
    """A PSF given by its FWHM runs through the one filter (the MTF's): its transfer function is the Gaussian's,
    exp(-2π²σ²f²) with σ = FWHM / (2 √(2 ln 2)) (a sine at f = 1/4 cycle per input pixel, to 2e-3), and on a smooth
    image, inside where neither border rule reaches, it is scipy's sampled Gaussian (the former [spatial] PSF) to
    5e-4 of the image's range (the two differ by the sampled Gaussian's aliasing: most on fine detail)."""
    scene = Scene.from_dict({**CUBE, "effects": {"psf": {"fwhm": fwhm}}})
    inst = scene_instrument(scene)
    k = scene.sensor.band_names.index("B5")  # 20 m over 10 m: 2 input pixels per band pixel
    sigma = fwhm * 2 / (2.0 * math.sqrt(2.0 * math.log(2.0)))
    assert inst.response(k, 2) == pytest.approx((sigma, 0.0, 0.0), rel=1e-12)
    sine = np.repeat(np.sin(2 * np.pi * 0.25 * np.arange(200))[None, :], 40, axis=0)
    amplitude = np.abs(inst.spatial(sine, k, 2)[20, 60:140]).max()
    assert amplitude == pytest.approx(math.exp(-2 * math.pi**2 * sigma**2 * 0.25**2), rel=2e-3)
    image = gaussian_filter(np.random.default_rng(1).random((90, 80)), 2.0) * 100.0
    ours = inst.spatial(image, k, 2)
    theirs = gaussian_filter(image, sigma, mode="nearest", truncate=8.0)
    r = fir_radius(sigma, 0.0) + 1 + int(8 * sigma)
    assert np.abs(ours - theirs)[r:-r, r:-r].max() < 5e-4 * np.ptp(image)


def test_one_reach_rule_for_the_footprint_the_halo_and_memory() -> None:
    """Shift and PSF in one filter: the reach is its radius (by hand for the 60 m bands: σ = 1.5 · 6 / 2.3548 =
    3.8219 input pixels, shift 0.5 · 6 = 3 along y: ⌈3 + 4 σ + 0 + 1⌉ - 1 = 19 rows, ⌈4 σ + 1⌉ - 1 = 16 columns)."""
    scene = Scene.from_dict({**CUBE, "effects": {"psf": {"fwhm": 1.5}, "coregistration": {
        "px": 0.0, "shifts": {"B1": [0.0, 0.5], "B9": [0.0, 0.5], "B10": [0.0, 0.5]}}}})
    ids = [scene.sensor.band_names.index(b) for b in ("B1", "B9", "B10")]
    assert scene_instrument(scene).reach(ids, 6) == (19, 16)
    assert cube_halo(scene_instrument(scene), band_groups(scene.sensor, scene.spec.surface.gsd_m)) == 19


# -- image-only stages where they cannot run ------------------------------------------------------------------------

def test_image_only_stages_in_a_library_scene_are_named_in_one_line(tmp_path, caplog) -> None:
    from s2cl.app.simulate_scene import simulate_scene

    scene = Scene.from_dict({**LIBRARY, "effects": {**LIBRARY["effects"], "psf": True, "smile": {"width_pct": [1.0]},
                                                    "nonuniformity": {"on": False}}})
    (caveat,) = _image_only(scene)
    line = ("effects.smile, effects.psf: image-only stages, not run on this library scene (they act on image cubes: "
            "surface.cube)")
    assert str(caveat) == line
    with caplog.at_level(logging.WARNING, logger="s2cl"):
        simulate_scene(scene, tmp_path / "out")
    assert [r.getMessage() for r in caplog.records if "image-only" in r.getMessage()] == [line]
    written = json.loads((tmp_path / "out" / "simulation.json").read_text())
    assert line in written["warnings"]
    with xr.open_dataset(tmp_path / "out" / "simulation.nc") as ds:  # the stages run: neither psf nor smile
        assert ds.attrs["effects"] == "atmosphere, resample, noise, quantise, calibrate, correct"
    assert _image_only(Scene.from_dict(LIBRARY)) == []
    assert _image_only(Scene.from_dict({**CUBE, "effects": {"psf": True}})) == []


def _image_only(scene: Scene) -> list:
    return image_only(scene.effects, image=scene.spec.surface.cube is not None, sweep=scene.spec.sweep is not None)


def test_image_only_stages_in_a_sweep_scene_are_named_in_its_caveats() -> None:
    from s2cl.app.checks import check_sweep

    scene = Scene.from_dict({**LIBRARY, "effects": {**LIBRARY["effects"], "coregistration": True},
                             "analysis": {"kind": "igrm", "parameter": "cab"},
                             "sweep": {"bands": ["B4", "B5", "B6", "B7"], "ranges": {
                                 "B4": {"centre": 665, "width": 30}, "B5": {"centre": 705, "width": 15},
                                 "B6": {"centre": 740, "width": 15}, "B7": {"centre": 783, "width": 20}}}})
    caveats = [str(c) for c in check_sweep(scene).caveats]
    assert ("effects.coregistration: image-only stage, not run on this library scene or its sweep (they act on "
            "image cubes: surface.cube)") in caveats
