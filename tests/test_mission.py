"""Issue 35's worked example (``scenes/mission-s2.toml``, docs/mission.md) and the scorecard's balanced design
(``--sensor results:FOLDER:balanced``): the scene loads and its joint space is the product of the paper's grids
(counted by hand, not run); the balanced design of a small two-application run is the design with the lowest
relative sum, found here from results.parquet by hand; a folder without a pareto record is refused in one line."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_cli_errors import run_main
from test_multi_application import TWO

import s2cl
from s2cl.app.optimise import count_sweep
from s2cl.app.scorecard import resolve_sensor
from s2cl.errors import InputError
from s2cl.scene.applications import scene_applications
from s2cl.scene.scene import Scene, builtin_scenes

SCENES = Path(__file__).resolve().parent.parent / "scenes"


def _window_variants(left: float, right: float, min_w: float, max_w: float, step: float = 5.0) -> int:
    """Designs of a Table 2 window by brute force: every width on the step grid, every centre on the step grid
    whose band (centre ± width/2) lies inside the window."""
    n = 0
    for w in np.arange(min_w, max_w + step / 2, step):
        for c in np.arange(0.0, 3000.0, step):
            n += int(c - w / 2 >= left - 1e-9 and c + w / 2 <= right + 1e-9)
    return n


def test_mission_scene_is_built_in_and_counts_its_joint_space() -> None:
    assert "mission-s2" in builtin_scenes()
    scene = Scene.load("mission-s2")
    apps = scene_applications(scene)
    assert [a.name for a in apps] == ["chlorophyll", "lai", "leaf_water", "minerals"]
    spec = tomllib.loads((SCENES / "mission-s2.toml").read_text(encoding="utf-8"))
    every = {a["name"]: a for a in spec["application"]}
    assert every["chlorophyll"]["analysis"]["bands"] == ["B4", "B5", "B6", "B7"]
    assert "B5" in every["lai"]["analysis"]["expression"]                       # chlorophyll and LAI share B5
    assert every["leaf_water"]["analysis"]["swir"] == "B11" and "B11" in every["minerals"]["analysis"]["bands"]
    assert all("target" in a for a in spec["application"])
    # Table 2 (Segl et al. 2012): B5 700-740 nm x 15-40 nm, B6 720-750 x 15-30, B8a 840-890 x 20-50, 5 nm steps;
    # Table 5's six B11 centres x the widths 50 and 75 nm; 4 x 4 points of Table 6's B12 grid
    b5, b6, b8a = _window_variants(700, 740, 15, 40), _window_variants(720, 750, 15, 30), \
        _window_variants(840, 890, 20, 50)
    assert (b5, b6, b8a) == (18, 8, 25)
    count = count_sweep("mission-s2")
    assert count.configurations == b5 * b6 * b8a * 12 * 16 == 691_200
    assert every["minerals"]["grid"] == {"start_nm": 1500, "stop_nm": 2500}  # the SWIR minerals' own grid


@pytest.fixture(scope="module")
def two_run(tmp_path_factory):  # type: ignore[no-untyped-def]
    tmp = tmp_path_factory.mktemp("balanced")
    path = tmp / "two.toml"
    path.write_text(TWO)
    s2cl.optimise(path, tmp / "out")
    return path, tmp / "out"


def test_balanced_is_the_lowest_relative_sum_and_best_stays_the_first(two_run) -> None:  # type: ignore[no-untyped-def]
    path, out = two_run
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    refs = {a["column"]: a["reference"] for a in summary["applications"]}
    table = pd.read_parquet(out / "results.parquet")
    table = table[~table["underdetermined"]]
    rel = sum(table[c] / r for c, r in refs.items())
    lowest = table.assign(rel=rel).sort_values(["rel", "config"]).iloc[0]
    scene = Scene.load(path)
    balanced = resolve_sensor(f"results:{out}:balanced", scene)
    assert balanced.name == "balanced:out"
    for band in ("B5", "B6", "B11"):
        b = balanced.sensor.band(band)
        assert (b.centre_nm, b.fwhm_nm) == (lowest[f"{band}_centre_nm"], lowest[f"{band}_width_nm"])
    best = resolve_sensor(f"results:{out}", scene)
    same = resolve_sensor(f"results:{out}:best", scene)
    for band, (c, w) in summary["best"]["bands"].items():
        assert (best.sensor.band(band).centre_nm, best.sensor.band(band).fwhm_nm) == (c, w)
        assert (same.sensor.band(band).centre_nm, same.sensor.band(band).fwhm_nm) == (c, w)


def test_balanced_without_a_pareto_record_is_one_line(tmp_path, monkeypatch, capsys) -> None:
    folder = tmp_path / "single"
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"scene": "default", "metric": "rms",
                                                     "best": {"bands": {"B5": [705.0, 15.0]}, "rms": 5.0}}))
    with pytest.raises(InputError, match="has no pareto record"):
        resolve_sensor(f"results:{folder}:balanced", Scene.load("default"))
    assert resolve_sensor(f"results:{folder}", Scene.load("default")).sensor.band("B5").centre_nm == 705.0
    monkeypatch.chdir(tmp_path)
    code, _out, err = run_main(["scorecard", "default", "-q", "-o", "card", "-s", "results:single:balanced"], capsys)
    assert code == 2 and err.count("\n") == 1 and "has no pareto record" in err and "summary.json" in err, err


def test_a_scorecard_without_sensors_adds_the_scene_s_finished_sweep(two_run, tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """``s2cl scorecard SCENE`` after ``s2cl optimise SCENE``: the default sensors, then the sweep's #1 and balanced
    designs from the scene's output folder; a folder of another scene, or none, adds nothing."""
    from s2cl.app.scorecard import DEFAULT_SENSORS, default_sensors

    path, out = two_run
    text = path.read_text(encoding="utf-8").replace('[scene]\nname = "two"',
                                                    f'[scene]\nname = "two"\n[output]\ndirectory = "{out}"', 1)
    assert text != path.read_text(encoding="utf-8")
    here = tmp_path / "two.toml"
    here.write_text(text, encoding="utf-8")
    assert default_sensors(Scene.load(here)) == [*DEFAULT_SENSORS, f"results:{out}", f"results:{out}:balanced"]
    other = tmp_path / "other.toml"
    other.write_text(text.replace('name = "two"', 'name = "other"', 1), encoding="utf-8")
    assert default_sensors(Scene.load(other)) == list(DEFAULT_SENSORS)  # its folder holds "two"'s sweep
    monkeypatch.chdir(tmp_path)
    assert default_sensors(Scene.load(path)) == list(DEFAULT_SENSORS)   # s2cl-out/two: no sweep there
