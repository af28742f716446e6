"""Scene files: schema, defaults, and every bad input named with file, key and allowed range."""

from __future__ import annotations

import copy

import pytest

from s2cl.errors import InputError
from s2cl.scene.scene import Scene, builtin_scenes, find_scene

BASE = {"scene": {"name": "t"}, "surface": {"library": "lib.csv"}}


def _load(tmp_path, text: str) -> Scene:
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return Scene.load(path)


def test_builtin_scenes_load() -> None:
    names = builtin_scenes()
    assert "default" in names
    for name in names:
        scene = Scene.load(name)
        assert scene.name
        assert scene.sensor.size >= 1


def test_defaults() -> None:
    scene = Scene.from_dict(copy.deepcopy(BASE))
    assert scene.spec.surface.copies == 100
    assert scene.grid.size == 2101
    assert scene.sensor.bits == 12
    assert scene.effects.noise and scene.effects.quantise and scene.effects.calibrate


def test_run_config_is_read_once_and_frozen() -> None:
    """Everything downstream reads scene.run; [compute] sets precision, lanes and device."""
    import dataclasses

    scene = Scene.from_dict({**copy.deepcopy(BASE), "compute": {"precision": "float64", "lanes": 4, "device": "pocl"},
                             "effects": {"seed": 7, "frame": 2}, "surface": {"library": "a.csv", "copies": 3}})
    r = scene.run
    assert (r.precision, r.lanes, r.device, r.seed, r.frame, r.copies) == ("float64", 4, "pocl", 7, 2, 3)
    assert not hasattr(r, "bits")  # the sensor holds the radiometric resolution: scene.sensor.bits
    assert r.effects == scene.effects
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.seed = 1  # type: ignore[misc]
    assert Scene.from_dict(copy.deepcopy(BASE)).run.precision == "float32"


def test_output_precision_still_works_and_says_it_moved(caplog) -> None:
    scene = Scene.from_dict({**copy.deepcopy(BASE), "output": {"precision": "float64"}})
    assert scene.run.precision == "float64"
    assert "compute.precision" in caplog.text and "deprecated" in caplog.text


def test_relative_paths_resolve_against_scene_file(tmp_path) -> None:
    scene = _load(tmp_path, '[scene]\nname = "t"\n[surface]\nlibrary = "data/lib.csv"\n')
    assert scene.resolve("data/lib.csv") == tmp_path / "data" / "lib.csv"


@pytest.mark.parametrize(
    ("change", "key", "message"),
    [
        ({"effects": {"bits": 20}}, "effects.bits", ">= 1 and <= 16"),
        ({"effects": {"bits": 0}}, "effects.bits", ">= 1 and <= 16"),
        ({"effects": {"nosie": True}}, "effects.nosie", "did you mean 'noise'"),
        ({"efects": {}}, "efects", "did you mean 'effects'"),
        ({"surface": {"library": "a.csv", "copies": 0}}, "surface.copies", ">= 1"),
        ({"surface": {"library": "a.csv", "layout": "grid"}}, "surface.layout", "'rows' or 'blocks'"),
        ({"sensor": {"bands": ["B4", "B13"]}}, "sensor.bands", "B13"),
        ({"sensor": {"support": 0}}, "sensor.support", "> 0"),
        ({"sensor": {"srf": "gaussian"}}, "sensor.srf", "model"),
        ({"grid": {"stop_nm": 2000}}, "B12", "outside the spectral grid"),
        ({"grid": {"step_nm": -1}}, "grid.step_nm", "> 0"),
        ({"grid": {"step_nm": 0.9}}, "grid.step_nm", "whole number"),
        ({"effects": {"quantise": False}}, "effects.calibrate", "needs quantise"),
        ({"effects": {"seed": -1}}, "effects.seed", ">= 0"),
        ({"effects": {"seed": 2**32}}, "effects.seed", "<= 4294967295"),
        ({"surface": {"library": "a.csv", "cube": "b.nc", "gsd_m": 10}}, "surface", "exactly one"),
        ({"surface": {"cube": "builtin:fields"}}, "surface.gsd_m", "gsd_m"),  # a file: its product may give it
        ({"surface": {"library": "a.csv", "quantity": "reflectance"}}, "surface.quantity", "atmosphere"),
        ({"output": {"precision": "float16"}}, "output.precision", "float32"),
        ({"compute": {"precision": "half"}}, "compute.precision", "float32"),
        ({"compute": {"lanes": 3}}, "compute.lanes", "(1, 2, 4, 8, 16)"),
        ({"compute": {"precision": "float32"}, "output": {"precision": "float64"}}, "output.precision", "disagree"),
        ({"scene": {}}, "scene.name", "missing"),
    ],
)
def test_bad_scene_values(change: dict, key: str, message: str) -> None:
    data = {**copy.deepcopy(BASE), **change}  # each change replaces whole sections
    with pytest.raises(InputError) as err:
        Scene.from_dict(data)
    text = str(err.value)
    assert key in text and message in text, text


def test_file_errors(tmp_path) -> None:
    with pytest.raises(InputError, match="not found"):
        Scene.load(tmp_path / "missing.toml")
    with pytest.raises(InputError, match="not valid TOML") as err:
        _load(tmp_path, "[scene\nname = 1")
    assert "scene.toml" in str(err.value)
    with pytest.raises(InputError, match="built-in"):
        find_scene("no-such-scene")


def test_sensor_file_in_scene(tmp_path) -> None:
    (tmp_path / "s.csv").write_text(
        "band,centre_nm,fwhm_nm,lmin,lref,lmax,snr_lmin,snr_lref,snr_lmax,gsd_m\nX1,665,0,3,100,400,,100,,10\n")
    with pytest.raises(InputError) as err:
        _load(tmp_path, '[scene]\nname = "t"\n[surface]\nlibrary = "l.csv"\n[sensor]\nfile = "s.csv"\n')
    assert "s.csv" in str(err.value) and "X1.fwhm_nm" in str(err.value)


def test_results_name_scenes_without_machine_folders(tmp_path, monkeypatch) -> None:
    """Result files (study JSONs) name a scene portably: built-in as scenes/NAME.toml, below the working
    folder relative to it, elsewhere by file name alone."""
    builtin = Scene.load("default")
    assert builtin.portable_source == "scenes/default.toml"
    own = tmp_path / "mine" / "s.toml"
    own.parent.mkdir()
    own.write_text(builtin.path.read_text(encoding="utf-8"), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert Scene.load(own).portable_source == "mine/s.toml"
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    assert Scene.load(own).portable_source == "s.toml"
