"""The scene is resolved once (:class:`s2cl.app.checks.Checked`): an ``optimise`` run computes the atmosphere terms
once per state (the true one and the one the correction assumes), loads the library once, and builds the sweep's
tables and, for a sensor design off the sweep's grid, that design's tables once each."""

from __future__ import annotations

from pathlib import Path

import pytest

import s2cl.app.checks as checks
import s2cl.app.plan as plan
import s2cl.scene.terms as terms
from s2cl.app.optimise import optimise
from s2cl.scene.scene import Scene
from tests.test_band_addition import MINERALS


@pytest.fixture
def counted(monkeypatch) -> dict[str, list]:
    """Calls of the terms (each state's section), of the library load and of the table builder (each space's size)."""
    seen: dict[str, list] = {"terms": [], "library": [], "tables": []}
    real_terms, real_load, real_build = terms.state_terms, checks.scene_library, plan.build_tables

    def spy_terms(scene, state, section):
        seen["terms"].append(section)
        return real_terms(scene, state, section)

    def spy_load(*args, **kwargs):
        seen["library"].append(1)
        return real_load(*args, **kwargs)

    def spy_build(space, *args, **kwargs):
        seen["tables"].append(space.size)
        return real_build(space, *args, **kwargs)

    monkeypatch.setattr(terms, "state_terms", spy_terms)
    monkeypatch.setattr(checks, "scene_library", spy_load)
    monkeypatch.setattr(plan, "build_tables", spy_build)
    return seen


def test_optimise_of_the_default_scene_computes_each_thing_once(tmp_path: Path, counted: dict[str, list]) -> None:
    """The default scene: 3,312 configurations; the sensor's B8 (842 nm) is off the sweep's grid (832.5 nm steps), so
    the reference has tables of its own, built once for its row and its pixels (before: the terms 8 times, the
    tables 3 times)."""
    result = optimise("default", tmp_path / "out")
    assert counted["terms"] == ["atmosphere", "correction"]
    assert counted["library"] == [1]
    assert counted["tables"] == [3312, 1]
    assert result.reference is not None and result.reference["bands"]["B8"] == [842.0, 115.0]


def test_a_band_addition_needs_no_terms_of_its_own(counted: dict[str, list]) -> None:
    """The base set's row is built from the same terms and library (its own tables: one configuration)."""
    job = plan.plan_sweep(Scene.from_dict(MINERALS))
    assert job.base_row is not None
    assert counted["terms"] == ["atmosphere", "correction"]
    assert counted["library"] == [1]
    assert counted["tables"] == [4, 1]


#: modules whose functions receive the scene or the resolved object through ``plan_sweep`` of the default scene
#: (``python tools/follow_scene.py``: a dynamic trace): 13 before the scene was resolved once (sweep.tables,
#: sweep.space, sweep.addition, retrieve.analysis, retrieve.family and forward.stages took it), 7 after: the
#: application and scene layers only
MAX_SCENE_MODULES = 7
#: the engine modules that still take the scene on this path: none
SCENE_ENGINES: set[str] = set()


def test_the_scene_through_plan_sweep_visits_few_modules_and_nothing_reloads() -> None:
    from tools.follow_scene import ENGINES, follow, plan_default

    trace = follow(plan_default)
    counts = trace.report()
    assert counts["modules"] <= MAX_SCENE_MODULES, sorted(trace.modules)
    assert {m for m in trace.modules if m.startswith(ENGINES)} <= SCENE_ENGINES, sorted(trace.modules)
    assert counts["climbs"] == 0, sorted(trace.climbs)
    assert counts["library_loads"] == 1 and counts["terms_computed"] == 2


def test_simulate_computes_the_terms_once(tmp_path: Path, counted: dict[str, list]) -> None:
    """``s2cl simulate`` of the default library scene and of a generated image: the checks compute each state's terms,
    and the chain takes them from there (before: computed again for the chain)."""
    from s2cl.app.simulate_scene import simulate_scene

    simulate_scene(Scene.load("default"), tmp_path / "lib")
    assert counted["terms"] == ["atmosphere", "correction"]
    counted["terms"].clear()
    simulate_scene(Scene.load("cube-fields"), tmp_path / "cube")
    assert counted["terms"] == ["atmosphere", "correction"]
