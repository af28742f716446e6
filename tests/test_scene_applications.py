"""A scene's applications (``[[application]]``): the schema's rules, each refusal one line, and the
single-application scene each application stands for."""

from __future__ import annotations

import tomllib

import pytest

from s2cl.errors import InputError
from s2cl.scene.applications import application_scene, is_multi_application, scene_applications
from s2cl.scene.scene import Scene

TWO = """
[scene]
name = "two"
[surface]
library = "builtin:lib1"
quantity = "reflectance"
copies = 7
[effects]
atmosphere = true
correct = true
[[application]]
name = "chlorophyll"
target = 5.0
[application.analysis]
kind = "igrm"
parameter = "cab"
[[application]]
name = "leaf_water"
library = "builtin:leaf-water"
copies = 3
analysis = { kind = "gvmi", parameter = "ewt" }
"""


def _scene(text: str) -> Scene:
    return Scene.from_dict(tomllib.loads(text))


def test_two_applications_in_order_with_their_libraries_and_copies() -> None:
    sc = _scene(TWO)
    apps = scene_applications(sc)
    assert [a.name for a in apps] == ["chlorophyll", "leaf_water"]
    assert [a.library for a in apps] == ["builtin:lib1", "builtin:leaf-water"]  # the first one inherits
    assert [a.copies for a in apps] == [7, 3]
    assert [a.target for a in apps] == [5.0, None]
    assert [a.key for a in apps] == ["application[0]", "application[1]"]
    assert [a.analysis.kind for a in apps] == ["igrm", "gvmi"]
    assert is_multi_application(sc)


def test_application_scene_is_the_single_application_scene() -> None:
    sc = _scene(TWO)
    one = application_scene(sc, scene_applications(sc)[1])
    assert one.spec.application is None and one.spec.analysis.kind == "gvmi"
    assert one.spec.surface.library == "builtin:leaf-water" and one.spec.surface.copies == 3
    assert one.run.copies == 3 and sc.run.copies == 7  # what the engines read (the resolved run), not only the spec
    assert one.sensor is sc.sensor and one.grid is sc.grid and one.name == "two"
    assert scene_applications(one)[0].name == "ewt"  # an [analysis] scene: one application, named by its parameter
    assert not is_multi_application(one)


def test_an_analysis_scene_is_one_application() -> None:
    sc = Scene.load("default")
    [app] = scene_applications(sc)
    assert (app.name, app.library, app.copies, app.key) == ("cab", "builtin:lib1", 100, "analysis")


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace('name = "leaf_water"', 'name = "chlorophyll"'), "two applications are named 'chlorophyll'"),
    (lambda t: t + '\n[analysis]\nkind = "igrm"\nparameter = "cab"\n', "not both"),
    (lambda t: t.replace('name = "leaf_water"', 'name = "Leaf water"'), "lower-case letters"),
    (lambda t: t.split("[[application]]")[0] + "application = []\n", "the list is empty"),
])
def test_bad_application_lists_are_one_line(edit, words) -> None:  # type: ignore[no-untyped-def]
    text = edit(TWO)
    if "application = []" in text:  # a key of the top level: before every table
        text = "application = []\n" + text.replace("application = []\n", "")
    with pytest.raises(InputError) as err:
        _scene(text)
    message = str(err.value)
    assert words in message and "\n" not in message
