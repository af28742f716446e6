"""Kernel templates: strict rendering, effect switches, every scene and effect combination builds."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from s2cl.app.chain_parts import scene_simulator
from s2cl.cl.templates import render
from s2cl.cl.vectypes import VecTypes
from s2cl.errors import InputError, RenderError
from s2cl.forward.resample import ResamplePlan, Resampler
from s2cl.forward.sense import Radiometry, Sensing
from s2cl.forward.simulate import Simulator
from s2cl.forward.stages import senses
from s2cl.grid import DEFAULT_GRID
from s2cl.resources import kernel_dir
from s2cl.scene.effects import EffectSet
from s2cl.scene.scene import Scene, builtin_scenes
from s2cl.sensor.sensor import Sensor

NOISE_MARKERS = ("s2_normal4", "S2_RANDOM_", "noise_a", "seed")
QUANTISE_MARKERS = ("s2_quantise", "S2_QUANTISE_", "maxdn", "dn[", "flags[")
CALIBRATE_MARKERS = ("s2_calibrate", "gain[")


class _Terms:
    def __init__(self, n: int):
        self.path_radiance = np.full(n, 20.0)
        self.ground_term = np.full(n, 100.0)
        self.spherical_albedo = np.full(n, 0.1)


def test_kernel_dir_is_independent_of_cwd(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert (kernel_dir() / "sense.cl.mako").is_file()
    assert "sense_bands" in render("sense.cl.mako", args=[], signature=lambda a, T: "", n_bands=1, band_ids=[0],
                                   stages=[], segments=[("band", [])], site=None, across=None, deviates=False,
                                   T=VecTypes())


def test_missing_template_variable_is_an_error() -> None:
    with pytest.raises(RenderError) as err:
        render("sense.cl.mako", args=[], signature=lambda a, T: "", n_bands=1, stages=[], segments=[("band", [])],
               site=None, across=None, deviates=False, T=VecTypes())
    assert "band_ids" in str(err.value)


def _sensing_source(rt, effects: EffectSet) -> str:
    bands = Sensor.sentinel2().bands
    return Sensing(rt, Radiometry.of(bands, 12), effects).source


@pytest.mark.parametrize("flag", ["noise", "quantise", "calibrate"])
def test_effect_off_is_not_in_the_kernel(rt, flag: str) -> None:
    markers = {"noise": NOISE_MARKERS, "quantise": QUANTISE_MARKERS, "calibrate": CALIBRATE_MARKERS}[flag]
    on = _sensing_source(rt, EffectSet())
    assert all(m in on for m in markers)
    off_kwargs = {flag: False}
    if flag == "quantise":
        off_kwargs["calibrate"] = False
    off = _sensing_source(rt, EffectSet(**off_kwargs))
    assert not any(m in off for m in markers), f"{flag} code left in the kernel with {flag} off"


def test_atmosphere_off_is_not_in_the_kernel(rt) -> None:
    s = Sensor.sentinel2()
    plan = ResamplePlan.of(s.bands, DEFAULT_GRID)
    assert "s2_toa" not in Resampler(rt, plan).source
    assert "s2_toa" in Resampler(rt, plan, atmosphere=_Terms(DEFAULT_GRID.size)).source


def _combinations() -> list[EffectSet]:
    names = ("atmosphere", "resample", "noise", "quantise", "calibrate")
    out = [EffectSet(**dict.fromkeys(names, False)), EffectSet(**dict.fromkeys(names, True))]
    for name in ("atmosphere", "resample", "noise", "quantise"):
        kwargs = dict.fromkeys(("atmosphere", "resample", "noise", "quantise", "calibrate"), False)
        kwargs[name] = True
        out.append(EffectSet(**kwargs))
    out.append(EffectSet(atmosphere=False, resample=False, noise=False, quantise=True, calibrate=True))
    return out


@pytest.mark.parametrize("effects", _combinations(), ids=lambda e: e.describe().replace(", ", "+"))
def test_every_effect_combination_builds(rt, real_t: str, effects: EffectSet) -> None:
    s = Sensor.sentinel2()
    grid = DEFAULT_GRID
    weights = [b.weights(grid) for b in s.bands]
    sim = Simulator(rt, s, grid.size, weights, effects, precision=real_t,
                    atmosphere=_Terms(grid.size) if effects.atmosphere else None)
    spectra = np.full((3, grid.size), 0.2 if effects.atmosphere else 50.0)
    radiance = sim.band_radiance(spectra)
    assert np.all(np.isfinite(radiance))
    out = sim.sense(radiance, seed=1)
    assert (out is None) == (not senses(effects))


@pytest.mark.parametrize("name", sorted(builtin_scenes()))
def test_every_builtin_scene_renders_and_builds(rt, name: str) -> None:
    scene = Scene.load(name)
    from s2cl.scene.terms import scene_atmosphere

    sim = scene_simulator(rt, scene, atmosphere=scene_atmosphere(scene))
    assert sim.resampler.kernel is not None
    assert (sim.sensing is not None) == senses(scene.effects)


def test_scene_files_in_repo_match_builtins() -> None:
    repo_scenes = kernel_dir().parent / "scenes"
    if repo_scenes.is_dir():
        assert {p.stem for p in repo_scenes.glob("*.toml")} == set(builtin_scenes())


def test_effects_validation() -> None:
    with pytest.raises(InputError, match="calibrate"):
        EffectSet(quantise=False, calibrate=True).validate()
    for combo in itertools.product([False, True], repeat=2):
        EffectSet(noise=combo[0], quantise=True, calibrate=combo[1]).validate()
