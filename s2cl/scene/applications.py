"""A scene's applications: what its designs are scored for.

A scene with an [analysis] has one application; a scene with ``[[application]]`` tables has several, each with its
own name, surface library (and copies), analysis and, optionally, a requirement (``target``). Everything else (the
sensor, grid, atmosphere, effects and the [sweep] space) is shared. :func:`application_scene` is the
single-application scene an application stands for: scoring the application is scoring that scene, so a design's
score for one application equals what the application's own scene gives for the same design and seed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from s2cl.scene.scene import Scene
from s2cl.scene.schema import AnalysisSpec


@dataclass(frozen=True)
class Application:
    """One application of a scene: ``name`` (it names results columns), the ``analysis`` section, the surface
    ``library`` (a ``builtin:NAME`` or file, as ``surface.library``) with its ``copies``, the requirement as
    written (``target``: None, a number or a number with a unit; checked against the metric by the checks), and
    ``key``: where the application is written in the scene (``analysis`` or ``application[i]``), for errors."""

    name: str
    analysis: AnalysisSpec
    library: str | None
    copies: int
    target: float | str | None
    key: str


def scene_applications(scene: Scene) -> list[Application]:
    """The scene's applications, in the order written: its ``[[application]]`` tables, or its [analysis] as one
    application named after the analysis's parameter (else its kind); empty for a scene without either."""
    spec, surface = scene.spec, scene.spec.surface
    if spec.application is not None:
        return [Application(a.name, a.analysis, a.library or surface.library, a.copies or surface.copies, a.target,
                            f"application[{i}]") for i, a in enumerate(spec.application)]
    if spec.analysis is None:
        return []
    name = (spec.analysis.parameter or spec.analysis.kind).lower()
    return [Application(name, spec.analysis, surface.library, surface.copies, None, "analysis")]


def is_multi_application(scene: Scene) -> bool:
    """The scene is written with ``[[application]]`` tables (even one), not an [analysis]."""
    return scene.spec.application is not None


def application_scene(scene: Scene, app: Application) -> Scene:
    """The single-application scene ``app`` stands for: ``scene`` with the application's analysis as its
    [analysis], its library and copies as ``surface.library`` and ``surface.copies``, and no ``[[application]]``
    (the sensor, grid, atmosphere, effects, [sweep] and output are the scene's)."""
    spec = scene.spec
    surface = spec.surface.model_copy(update={"library": app.library, "copies": app.copies})
    one = spec.model_copy(update={"analysis": app.analysis, "application": None, "surface": surface})
    return dataclasses.replace(scene, spec=one)
