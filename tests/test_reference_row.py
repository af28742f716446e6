"""The reference row (the sensor's own band set) reuses the sweep's tables and kernel when that design is one of
the sweep's configurations, and gives exactly the row a separately built one-configuration sweep gives; off the
sweep's grid its own tables are built once, from the checked scene's parts (the library is never read again)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from s2cl.app.checks import check_sweep
from s2cl.app.plan import configuration_of, fixed_row, own_design, plan_sweep, reference_pixels, reference_row
from s2cl.scene.scene import Scene
from s2cl.sensor.variants import BandRange, SweepSpace
from tests.sweep_fixtures import SMALL_SWEEP_TOML

OFF_GRID = SMALL_SWEEP_TOML.format(copies=4).replace("centres = [665, 675, 685]", "centres = [670, 680]")


def _scene(tmp_path: Path, text: str) -> Scene:
    path = tmp_path / "small.toml"
    path.write_text(text, encoding="utf-8")
    return Scene.load(path)


def _fixed(checked, job) -> dict:
    scene = checked.scene
    bands = job.tables.bands
    space = SweepSpace(tuple(BandRange.fixed(b, scene.sensor.band(b).centre_nm, scene.sensor.band(b).fwhm_nm)
                             for b in bands)).validate(scene.source)
    return fixed_row(checked, job, space, job.analysis)


def test_the_sensors_design_on_the_grid_is_read_from_the_sweep(tmp_path: Path) -> None:
    scene = _scene(tmp_path, SMALL_SWEEP_TOML.format(copies=4))
    checked = check_sweep(scene)
    job = plan_sweep(scene, checked=checked)
    shapes = [(scene.sensor.band(b).centre_nm, scene.sensor.band(b).fwhm_nm) for b in job.tables.bands]
    config = configuration_of(job.tables, shapes)
    assert config is not None and 0 < config < job.tables.n_configs  # B4 at 665/30, one of its six variants
    assert own_design(checked, job).job is job  # no tables of its own
    row, separate = reference_row(checked, job), _fixed(checked, job)
    assert row["config"] == config and separate["config"] == 0
    assert (row["B4_centre_nm"], row["B4_width_nm"]) == (665.0, 30.0)
    for key, value in separate.items():
        if key != "config":
            assert np.array_equal(np.asarray(row[key]), np.asarray(value), equal_nan=True), key


def test_a_design_off_the_grid_gets_its_own_tables(tmp_path: Path) -> None:
    scene = _scene(tmp_path, OFF_GRID)
    checked = check_sweep(scene)
    job = plan_sweep(scene, checked=checked)
    shapes = [(scene.sensor.band(b).centre_nm, scene.sensor.band(b).fwhm_nm) for b in job.tables.bands]
    assert configuration_of(job.tables, shapes) is None
    row, separate = reference_row(checked, job), _fixed(checked, job)
    assert row == separate and row["B4_centre_nm"] == 665.0


def test_a_design_off_the_grid_is_built_from_the_checked_library_without_reading_it_again(tmp_path: Path,
                                                                                          monkeypatch) -> None:
    """The reference row and its pixels build their own tables from the library the checks loaded and never load
    the library again; the row equals the one of a fresh check."""
    import s2cl.app.checks as checks
    import s2cl.scene.library as library

    scene = _scene(tmp_path, OFF_GRID)
    checked = check_sweep(scene)
    job = plan_sweep(scene, checked=checked)
    fresh = reference_row(check_sweep(scene), job)

    def no_reload(*args, **kwargs):
        raise AssertionError("the library was loaded again")

    monkeypatch.setattr(checks, "scene_library", no_reload)
    monkeypatch.setattr(library, "scene_library", no_reload)
    own = own_design(checked, job)
    row = reference_row(checked, job, own=own)
    pixels = reference_pixels(checked, job, own=own)
    assert row == fresh and row["B4_centre_nm"] == 665.0
    assert pixels is not None and pixels.index.shape[0] == 1


def test_optimise_builds_an_off_grid_reference_once_from_one_load_of_the_library(tmp_path: Path,
                                                                                monkeypatch) -> None:
    """``optimise`` checks the scene once (one load of the library file) and builds tables twice: the sweep's, and
    the sensor's own design's (off the sweep's grid), which serve both the reference row and its pixels."""
    import s2cl.app.checks as checks
    import s2cl.app.optimise as optimise_module
    import s2cl.app.plan as plan

    scene = _scene(tmp_path, OFF_GRID)  # the sensor's B4 (665 nm) off the sweep's grid: the reference needs tables
    loads, built = [], []
    real_load, real_build = checks.scene_library, plan.build_tables

    def spy_load(*args, **kwargs):
        loads.append(1)
        return real_load(*args, **kwargs)

    def spy_build(space, *args, **kwargs):
        built.append(space.size)
        return real_build(space, *args, **kwargs)

    monkeypatch.setattr(checks, "scene_library", spy_load)
    monkeypatch.setattr(plan, "build_tables", spy_build)
    result = optimise_module.optimise(scene, tmp_path / "out")
    assert len(loads) == 1
    assert built == [4, 1]  # the sweep's 2 × 2 configurations, then the own design's one
    assert result.reference is not None and result.reference["bands"]["B4"] == [665.0, 30.0]
