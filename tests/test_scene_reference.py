"""The Scene reference (docs/scenes.md) is generated from the scene schema and committed: every key is
described, and the committed page is what the schema renders now."""

from __future__ import annotations

from pathlib import Path

import pytest

from s2cl.retrieve.family import registry
from s2cl.scene.reference_doc import allowed, default, render, sections, type_name, undescribed
from s2cl.scene.schema import AnalysisSpec, GridSpec, SceneSpec, SurfaceSpec, SweepSpec

PAGE = Path(__file__).resolve().parent.parent / "docs" / "scenes.md"


def test_every_key_has_a_description() -> None:
    missing = undescribed()
    assert not missing, f"s2cl/scene/schema.py: give these fields a Field(description=...): {', '.join(missing)}"


@pytest.mark.skipif(not PAGE.is_file(), reason="docs/ is not in this checkout")
def test_committed_page_is_current() -> None:
    assert PAGE.read_text(encoding="utf-8") == render() + "\n", (
        "docs/scenes.md is stale: regenerate it with `python -m s2cl.scene.reference_doc > docs/scenes.md`")


def test_every_section_and_key_is_on_the_page() -> None:
    page = render()
    keys = list(sections())
    assert {k for k, _, _ in keys} >= {"scene", "surface", "sweep", "sweep.ranges.KEY", "sweep.add", "study.window2"}
    for key, model, _ in keys:
        assert f"## `[{key}]`" in page
        table = page.split(f"## `[{key}]`", 1)[1].split("\n## ", 1)[0]
        for name in model.model_fields:
            assert f"| `{name}` |" in table, f"[{key}] {name}"
    assert all(f"| `{name}` |" in page for name in SceneSpec.model_fields)


def test_columns_come_from_the_field_declarations() -> None:
    assert allowed(GridSpec.model_fields["step_nm"]) == "> 0; ≤ 50"
    assert allowed(SurfaceSpec.model_fields["copies"]) == "≥ 1; ≤ 1000000"
    assert all(f"`{k}`" in AnalysisSpec.model_fields["kind"].description for k in registry()), "a kind undescribed"
    assert default(AnalysisSpec.model_fields["kind"]) == "required"
    assert default(GridSpec.model_fields["start_nm"]) == "`400.0`"
    assert default(SweepSpec.model_fields["chunk"]) == "—"
    assert default(SweepSpec.model_fields["ranges"]) == "`{}`"
    assert type_name(SweepSpec.model_fields["chunk"].annotation) == "int (optional)"
    assert type_name(SurfaceSpec.model_fields["select"].annotation) == "table of str → list of float"
