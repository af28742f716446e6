"""The reference row (the sensor's own band set) reuses the sweep's tables and kernel when that design is one of
the sweep's configurations, and gives exactly the row a separately built one-configuration sweep gives."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from s2cl.app.plan import configuration_of, fixed_row, plan_sweep, reference_row
from s2cl.scene.scene import Scene
from s2cl.sensor.variants import BandRange, SweepSpace
from tests.sweep_fixtures import SMALL_SWEEP_TOML


def _scene(tmp_path: Path, text: str) -> Scene:
    path = tmp_path / "small.toml"
    path.write_text(text, encoding="utf-8")
    return Scene.load(path)


def _fixed(scene: Scene, job) -> dict:
    bands = job.tables.bands
    space = SweepSpace(tuple(BandRange.fixed(b, scene.sensor.band(b).centre_nm, scene.sensor.band(b).fwhm_nm)
                             for b in bands)).validate(scene.source)
    return fixed_row(scene, job, space, job.analysis)


def test_the_sensors_design_on_the_grid_is_read_from_the_sweep(tmp_path: Path) -> None:
    scene = _scene(tmp_path, SMALL_SWEEP_TOML.format(copies=4))
    job = plan_sweep(scene)
    shapes = [(scene.sensor.band(b).centre_nm, scene.sensor.band(b).fwhm_nm) for b in job.tables.bands]
    config = configuration_of(job.tables, shapes)
    assert config is not None and 0 < config < job.tables.n_configs  # B4 at 665/30, one of its six variants
    row, separate = reference_row(scene, job), _fixed(scene, job)
    assert row["config"] == config and separate["config"] == 0
    assert (row["B4_centre_nm"], row["B4_width_nm"]) == (665.0, 30.0)
    for key, value in separate.items():
        if key != "config":
            assert np.array_equal(np.asarray(row[key]), np.asarray(value), equal_nan=True), key


def test_a_design_off_the_grid_gets_its_own_tables(tmp_path: Path) -> None:
    text = SMALL_SWEEP_TOML.format(copies=4).replace("centres = [665, 675, 685]", "centres = [670, 680]")
    scene = _scene(tmp_path, text)
    job = plan_sweep(scene)
    shapes = [(scene.sensor.band(b).centre_nm, scene.sensor.band(b).fwhm_nm) for b in job.tables.bands]
    assert configuration_of(job.tables, shapes) is None
    row, separate = reference_row(scene, job), _fixed(scene, job)
    assert row == separate and row["B4_centre_nm"] == 665.0


def test_a_design_off_the_grid_is_built_from_the_library_given_without_reading_it_again(tmp_path: Path,
                                                                                         monkeypatch) -> None:
    """With the sweep's library given (as ``optimise`` gives the one its checks loaded), the reference row and its
    pixels build their own tables from it and never load the library again; the row equals the one built from a
    fresh load."""
    import s2cl.app.plan as plan
    from s2cl.app.checks import check_sweep

    text = SMALL_SWEEP_TOML.format(copies=4).replace("centres = [665, 675, 685]", "centres = [670, 680]")
    scene = _scene(tmp_path, text)
    checked = check_sweep(scene)
    job = plan_sweep(scene, checked=checked)
    fresh = reference_row(scene, job)

    def no_reload(*args, **kwargs):
        raise AssertionError("the library was loaded again")

    monkeypatch.setattr(plan, "scene_library", no_reload)
    row = reference_row(scene, job, library=checked.library)
    pixels = plan.reference_pixels(scene, job, library=checked.library)
    assert row == fresh and row["B4_centre_nm"] == 665.0
    assert pixels is not None and pixels.index.shape[0] == 1


def test_optimise_gives_the_reference_the_library_its_checks_loaded(tmp_path: Path, monkeypatch) -> None:
    """``optimise`` passes the library object the checks loaded to both the reference row and its pixels (one load
    of the library file per run)."""
    import s2cl.app.checks as checks
    import s2cl.app.optimise as optimise_module

    text = SMALL_SWEEP_TOML.format(copies=4).replace("centres = [665, 675, 685]", "centres = [670, 680]")
    scene = _scene(tmp_path, text)  # the sensor's B4 (665 nm) off the sweep's grid: the reference needs the library
    loaded, seen = [], []
    real_check = checks.check_sweep

    def spy_check(*args, **kwargs):
        out = real_check(*args, **kwargs)
        loaded.append(out.library)
        return out

    def spy(real):
        def call(scene, job, device=None, library=None):
            seen.append((real.__name__, library))
            return real(scene, job, device, library)
        return call

    monkeypatch.setattr(optimise_module, "check_sweep", spy_check)
    monkeypatch.setattr(optimise_module, "reference_row", spy(optimise_module.reference_row))
    monkeypatch.setattr(optimise_module, "reference_pixels", spy(optimise_module.reference_pixels))
    optimise_module.optimise(scene, tmp_path / "out")
    assert len(loaded) == 1 and loaded[0] is not None
    assert [name for name, _ in seen] == ["reference_row", "reference_pixels"]
    assert all(library is loaded[0] for _, library in seen)
