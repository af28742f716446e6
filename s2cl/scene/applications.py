"""A scene's applications: what its designs are scored for.

A scene with an [analysis] has one application; a scene with ``[[application]]`` tables has several, each with its
own name, surface library (and copies), analysis and, optionally, a requirement (``target``). Everything else (the
sensor, grid, atmosphere, effects and the [sweep] space) is shared. :func:`application_scene` is the
single-application scene an application stands for: scoring the application is scoring that scene, so a design's
score for one application equals what the application's own scene gives for the same design and seed.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Protocol

from s2cl.errors import InputError, token
from s2cl.grid import SpectralGrid
from s2cl.scene.scene import Scene
from s2cl.scene.schema import AnalysisSpec, GridSpec
from s2cl.sensor.sensor import Band


@dataclass(frozen=True)
class Application:
    """One application of a scene: ``name`` (it names results columns), the ``analysis`` section, the surface
    ``library`` (a ``builtin:NAME`` or file, as ``surface.library``) with its ``copies``, the requirement as
    written (``target``: None, a number or a number with a unit; checked against the metric by the checks), and
    ``key``: where the application is written in the scene (``analysis`` or ``application[i]``), for errors; its own
    ``grid`` where it has one."""

    name: str
    analysis: AnalysisSpec
    library: str | None
    copies: int
    target: float | str | None
    key: str
    #: its own spectral grid (None: the scene's [grid])
    grid: GridSpec | None = None


def scene_applications(scene: Scene) -> list[Application]:
    """The scene's applications, in the order written: its ``[[application]]`` tables, or its [analysis] as one
    application named after the analysis's parameter (else its kind); empty for a scene without either."""
    spec, surface = scene.spec, scene.spec.surface
    if spec.application is not None:
        return [Application(a.name, a.analysis, a.library or surface.library, a.copies or surface.copies, a.target,
                            f"application[{i}]", a.grid) for i, a in enumerate(spec.application)]
    if spec.analysis is None:
        return []
    name = (spec.analysis.parameter or spec.analysis.kind).lower()
    return [Application(name, spec.analysis, surface.library, surface.copies, None, "analysis")]


def is_multi_application(scene: Scene) -> bool:
    """The scene is written with ``[[application]]`` tables (even one), not an [analysis]."""
    return scene.spec.application is not None


def application_scene(scene: Scene, app: Application) -> Scene:
    """The single-application scene ``app`` stands for: ``scene`` with the application's analysis as its
    [analysis], its library and copies as ``surface.library`` and ``surface.copies`` (and ``run.copies``: what the
    engines read), its own grid as [grid] where it has one (and then the sensor's bands that lie on it, in the
    sensor's order, as ``sensor.bands``: the single-application scene of a library on part of the spectrum, as
    ``scenes/table6-b12.toml`` writes it), and no ``[[application]]`` (the sensor, atmosphere, effects, [sweep] and
    output are the scene's).

    :raises InputError: the application's grid is not a grid, naming ``application[i].grid``.
    """
    spec = scene.spec
    surface = spec.surface.model_copy(update={"library": app.library, "copies": app.copies})
    update = {"analysis": app.analysis, "application": None, "surface": surface}
    grid, sensor = scene.grid, scene.sensor
    if app.grid is not None:
        try:
            grid = SpectralGrid(app.grid.start_nm, app.grid.stop_nm, app.grid.step_nm)
        except InputError as err:
            raise InputError(err.detail, source=scene.source, key=f"{app.key}.grid") from None
        kept = [b.name for b in sensor.bands if _on_grid(b, grid, spec.sensor.support)]
        if not kept:
            raise InputError(f"no band of the sensor lies on the grid {grid.describe()}", source=scene.source,
                             key=f"{app.key}.grid")
        sensor = sensor.select(kept)
        update["grid"] = app.grid
        update["sensor"] = spec.sensor.model_copy(update={"bands": kept})
    one = spec.model_copy(update=update)
    return dataclasses.replace(scene, spec=one, grid=grid, sensor=sensor,
                               run=dataclasses.replace(scene.run, copies=app.copies))


def _on_grid(band: Band, grid: SpectralGrid, support: float) -> bool:
    """The band's SRF lies on ``grid`` (as a scene's check of its bands on its [grid] requires)."""
    try:
        band.weights(grid, support, "")
    except InputError:
        return False
    return True


#: a requirement written with its unit: a number, then the unit (``5 ug/cm2``, ``5 µg/cm²``, ``10 %``, ``5``)
_TARGET = re.compile(r"\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*")


def _unit_key(unit: str) -> str:
    """A unit spelled for comparison: ``µ``/``μ`` as ``u``, superscripts as digits, no spaces, lower case."""
    table = str.maketrans({"µ": "u", "μ": "u", "²": "2", "³": "3", " ": None})
    return unit.translate(table).lower()


class Metric(Protocol):
    """What :func:`target_value` asks of a metric (:class:`s2cl.retrieve.metric.Metric`, a layer above scenes)."""

    def unit(self, parameter: str | None) -> str: ...

    def score_label(self, parameter: str | None) -> str: ...


def target_value(app: Application, metric: Metric) -> float | None:
    """The application's requirement (``target``) as a number in the units of its ``metric`` (the score to meet,
    lower is better), or None when it has none. ``target`` is a number in those units, or a string of a number and
    a unit that must be the metric's (``"5 ug/cm2"`` and ``"5 µg/cm²"`` for an RMS of cab, ``"10 %"`` for an
    omission error); anything else is a one-line :class:`InputError` naming ``<key>.target`` and the unit expected
    (the caller adds the scene's file: :func:`s2cl.errors.errors_in`)."""
    if app.target is None:
        return None
    key = f"{app.key}.target"
    unit = metric.unit(app.analysis.parameter)
    expected = f"a number in {unit} (e.g. 5 or '5 {unit}')" if unit else "a number (the metric has no known unit)"
    if isinstance(app.target, str):
        m = _TARGET.fullmatch(app.target)
        if m is None:
            raise InputError(f"{token(app.target)} is not a requirement: give {expected}", key=key)
        value, written = float(m[1]), m[2]
        if written and _unit_key(written) != _unit_key(unit):
            label = metric.score_label(app.analysis.parameter)
            raise InputError(f"{token(app.target)} is in {token(written)}, but the {label} is in "
                             f"{unit or 'no known unit'}: give {expected}", key=key)
    else:
        value = float(app.target)
    if not math.isfinite(value) or value < 0:
        raise InputError(f"must be a finite score ≥ 0 (lower is better), got {token(app.target)}: give {expected}",
                         key=key)
    return value
