"""Sensor scorecards (``s2cl scorecard``): each of a scene's applications scored on several sensors' own bands.

A cell (application × sensor) is the application's score (its metric's score column, e.g. Cab RMS) of the sensor's
own bands, computed exactly as a sweep computes its reference row (:func:`s2cl.app.plan.reference_row`): the
application's single-application scene (:func:`s2cl.scene.applications.application_scene`) with

- its sensor swapped: the scene's sensor with each band the application uses (a *role*: ``B4`` at 665 nm) replaced
  by the sensor's band that plays it (:func:`s2cl.sensor.roles.map_roles`), keeping the role's name and position,
  so that the analysis, a formula's band names and the noise deviates (keyed by band position) stay the scene's;
  the scene's radiometric resolution (``bits``) for every sensor;
- its [sweep] fixed at those bands (one configuration), checked by :func:`s2cl.app.checks.check_sweep` and planned by
  :func:`s2cl.app.plan.plan_sweep`, as any sweep.

So the scene's own sensor scores exactly the reference row ``s2cl optimise`` reports (tested), and every sensor is
scored on the same pixels and noise deviates. A sensor without a band for a role, or whose bands the scene cannot
simulate (an SRF outside the grid, a design the retrieval cannot fit), gets "n/a" with the reason, not an error.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from s2cl.app.analysis import analysis_bands
from s2cl.app.applications import application_bands
from s2cl.app.checks import Checked, check_sweep
from s2cl.app.plan import plan_sweep, reference_row
from s2cl.errors import InputError
from s2cl.io.inputs import input_file
from s2cl.retrieve.family import family_of
from s2cl.scene.applications import Application, application_scene, is_multi_application, scene_applications
from s2cl.scene.scene import Scene
from s2cl.scene.schema import RangeSpec, SweepSpec
from s2cl.sensor.catalogue import (
    MODEL_SRF,
    CatalogueSensor,
    canonical_name,
    catalogue_sensor,
    known_sensors,
)
from s2cl.sensor.roles import DEFAULT_TOLERANCE_NM, RoleMapping, map_roles
from s2cl.sensor.sensor import Sensor
from s2cl.sweep.report import read_summary

#: the sensors scored when none is named
DEFAULT_SENSORS = ("sentinel2", "S2A", "S2B", "OLI", "OLI-2", "landsat-next")
RESULTS_PREFIX = "results:"
#: the designs ``results:FOLDER:WHICH`` may take from a finished sweep
DESIGN_SELECTORS = ("best", "balanced")


@dataclass(frozen=True)
class Cell:
    """One application on one sensor: ``score`` (the metric's score column; None where ``na`` says why), the
    sensor bands that played each role (``bands``: role → band, label, centre, width) and the whole metrics
    ``row`` (as a sweep's reference row)."""

    application: str
    sensor: str
    score: float | None
    na: str | None
    bands: dict[str, dict[str, Any]] = field(default_factory=dict)
    row: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class AppInfo:
    """What an application is scored by: its name, analysis kind and parameter, metric (score column) and units."""

    name: str
    kind: str
    parameter: str | None
    metric: str
    units: str


@dataclass(frozen=True)
class Scorecard:
    """Every cell of a scorecard, with its applications and sensors (their cards) and the role tolerance."""

    scene: str
    tolerance_nm: float
    applications: list[AppInfo]
    sensors: list[CatalogueSensor]
    cells: list[Cell]

    def cell(self, application: str, sensor: str) -> Cell:
        return next(c for c in self.cells if c.application == application and c.sensor == sensor)

    def best(self, application: str) -> float | None:
        """The lowest finite score of ``application`` over the sensors (lower is better), or None."""
        scores = [c.score for c in self.cells if c.application == application and c.score is not None]
        return min(scores) if scores else None

    def relative(self, cell: Cell) -> float | None:
        """``cell``'s score over the best sensor's for its application (1 = the best; 1.25: 25 % worse); None for an
        n/a cell, and for a non-zero score where the best is 0 (a ratio to 0 has no value)."""
        best = self.best(cell.application)
        if cell.score is None or best is None:
            return None
        if best == 0.0:
            return 1.0 if cell.score == 0.0 else None
        return cell.score / best


def resolve_sensor(text: str, scene: Scene) -> CatalogueSensor:
    """A ``--sensor`` value: a catalogue name (:mod:`s2cl.sensor.catalogue`), ``results:FOLDER`` (a finished sweep's
    #1 design on the scene's sensor), ``results:FOLDER:balanced`` (the best design of its Pareto front by relative
    sum) or a sensor table (``FILE.csv``, the columns of ``[sensor] file``).

    :raises InputError: an unknown name (listing the known ones), an unreadable table, a folder without a readable
        summary.json, without a ranked design or (``:balanced``) without a ``pareto`` record.
    """
    if text.startswith(RESULTS_PREFIX):
        folder, which = results_selector(text)
        return results_sensor(folder, scene, which)
    if canonical_name(text) is None and (text.lower().endswith(".csv") or Path(text).exists()):
        path = input_file(Path(text), what="sensor table", key="--sensor")
        sensor = Sensor.from_csv(path)
        return CatalogueSensor(path.stem, f"sensor table {path.name}", path.name, MODEL_SRF,
                               "the table's own (Lmin, Lref, Lmax, SNR)", sensor)
    return catalogue_sensor(text)


def results_selector(text: str) -> tuple[Path, str]:
    """``results:FOLDER[:best|:balanced]`` as (FOLDER, the design to take: ``best`` when none is named)."""
    rest = text[len(RESULTS_PREFIX):]
    head, sep, tail = rest.rpartition(":")
    if sep and head and tail in DESIGN_SELECTORS:
        return Path(head), tail
    return Path(rest), "best"


def summary_design(summary: dict[str, Any], which: str, source: Path) -> tuple[dict[str, Any], str]:
    """The design ``which`` of a finished sweep's ``summary`` (read from ``source``) as (its bands, band → [centre,
    width] nm; a one-line description): ``best``, the #1 design of the ranking; ``balanced``, the best design of the
    Pareto front by relative sum (``pareto.front.designs[0]``, the front being listed by relative sum).

    :raises InputError: one line naming ``source``: no ranked design, no ``pareto`` record, a front not ranked by
        relative sum.
    """
    if which == "balanced":
        pareto = summary.get("pareto")
        if not isinstance(pareto, dict) or not isinstance(pareto.get("front"), dict):
            raise InputError("has no pareto record (written by s2cl optimise of a scene with several "
                             "applications): results:FOLDER:balanced needs one; results:FOLDER takes the #1 design",
                             source=source, key="--sensor")
        front = pareto["front"]
        designs = front.get("designs") or []
        if front.get("order") != "relative sum" or not designs or not isinstance(designs[0].get("bands"), dict):
            missing = ", ".join((pareto.get("relative_sum") or {}).get("missing") or []) or "none listed"
            raise InputError(f"its Pareto front is not ranked by relative sum (applications without an own-bands "
                             f"score: {missing}): no balanced design", source=source, key="--sensor")
        d = designs[0]
        rel = d.get("relative_sum")  # null where not finite (s2cl.sweep.pareto)
        return d["bands"], (f"balanced design (best of the Pareto front by relative sum, "
                            f"{'n/a' if rel is None else format(rel, '.4g')})")
    best = summary.get("best") or next(iter(summary.get("top") or []), None)
    if not isinstance(best, dict) or not isinstance(best.get("bands"), dict):
        raise InputError("has no ranked design (best) to score: is it a finished sweep's summary.json?",
                         source=source, key="--sensor")
    metric = summary.get("metric", "score")
    return best["bands"], f"#1 design ({metric} {best.get(metric, float('nan')):.4g})"


def results_sensor(folder: Path, scene: Scene, which: str = "best") -> CatalogueSensor:
    """The scene's sensor with the design ``which`` (:func:`summary_design`: ``best`` or ``balanced``) of the finished
    sweep in ``folder`` (its ``summary.json``: model SRFs, the scene's radiometry with the SNR scaled to each band's
    width, as the sweep scored it)."""
    path = folder / "summary.json" if folder.is_dir() else folder
    if path.name != "summary.json" or not path.is_file():
        raise InputError(f"no summary.json in {folder}: name a finished sweep's output folder", key="--sensor")
    summary = read_summary(path)
    bands, what = summary_design(summary, which, path)
    sensor = scene.sensor
    for band, shape in bands.items():
        if band.lower() not in (n.lower() for n in sensor.band_names):
            raise InputError(f"the design's band {band} is not a band of the scene's sensor "
                             f"({', '.join(sensor.band_names)})", source=path, key="--sensor")
        sensor = sensor.replace_band(sensor.band(band).with_shape(*shape))
    swept = " ".join(f"{b} {c:g}/{w:g}" for b, (c, w) in bands.items())
    name = f"{which}:{path.parent.name or 'results'}"
    return CatalogueSensor(name, f"{what} of {summary.get('scene') or path.parent.name}: {swept}", str(path),
                           "model (eq. 1) at the design's centres and widths; the scene's for the other bands",
                           "the scene's sensor, SNR scaled by sqrt(width / its width)", sensor, by_name=True)


def application_roles(scene: Scene, app: Application | None = None) -> dict[str, float]:
    """The bands a single-application scene's analysis reads, each with its centre (nm) on the scene's sensor: the
    roles another sensor's bands must play. ``app``: the application of a scene with ``[[application]]`` tables
    that ``scene`` stands for, which reads the bands a multi-application sweep gives it
    (:func:`s2cl.app.applications.application_bands`). Otherwise a family that reads every band it is given (IGRM,
    SAM) reads the [sweep] bands, as the sweep's reference row does (else the analysis bands); one that reads the
    bands it names (an index, a formula) those bands only, so a sensor is not refused for a band the application
    never reads (its score is the same: each band's noise is keyed by its place in the sensor, not in the design)."""
    a = scene.spec.analysis
    assert a is not None
    family = family_of(a.kind, scene.source)
    if app is not None:
        bands = application_bands(scene, app)
    elif not family.uses_every_band:
        bands = family.default_bands(a, scene.sensor.band_names)
    else:
        bands = list(scene.spec.sweep.bands) if scene.spec.sweep is not None else analysis_bands(scene)
    return {scene.sensor.band(b).name: scene.sensor.band(b).centre_nm for b in bands}


def mapped_sensor(base: Sensor, other: Sensor, mapping: RoleMapping) -> Sensor:
    """``base`` (the scene's sensor) with each role's band replaced by ``other``'s band that plays it, under the
    role's name; its bits are ``base``'s."""
    for role, band in mapping.bands.items():
        base = base.replace_band(dataclasses.replace(other.band(band), name=base.band(role).name))
    return base


def fixed_scene(scene: Scene, sensor: Sensor, roles: list[str]) -> Scene:
    """``scene`` on ``sensor`` with its [sweep] fixed at the sensor's bands ``roles`` (one configuration; no
    [sweep.add], no search, no within-noise test)."""
    ranges = {b: RangeSpec(centre=sensor.band(b).centre_nm, width=sensor.band(b).fwhm_nm) for b in roles}
    update = {"bands": roles, "ranges": ranges, "preset": "none", "add": None, "search": "exhaustive",
              "chunk": None, "within_noise_top": 0}
    sweep = (scene.spec.sweep or SweepSpec(bands=roles)).model_copy(update=update)
    return dataclasses.replace(scene, spec=scene.spec.model_copy(update={"sweep": sweep}), sensor=sensor)


def own_check(scene: Scene, app: Application | None = None) -> Checked:
    """The application's scene fixed at its own sensor's bands, checked: the scene's own errors (its library,
    atmosphere, analysis) are errors here, once, before any sensor is scored (``app``: as
    :func:`application_roles`)."""
    roles = list(application_roles(scene, app))
    return check_sweep(fixed_scene(scene, scene.sensor, roles))


def score_cell(scene: Scene, app: Application, sensor: CatalogueSensor, tolerance_nm: float = DEFAULT_TOLERANCE_NM,
               device: str | None = None, own: Checked | None = None) -> Cell:
    """``app`` (of ``scene``) on ``sensor``'s own bands: the reference-row path of a sweep on the application's scene
    with the sensor swapped in (module docstring); n/a with the reason where the sensor cannot run it. ``own``: the
    application's :func:`own_check`, whose library and atmosphere terms the cell reuses (a sensor changes neither)."""
    if sensor.sensor is None:
        return Cell(app.name, sensor.name, None, sensor.unavailable or "unavailable")
    one = application_scene(scene, app)
    roles = application_roles(one, app if is_multi_application(scene) else None)
    mapping = map_roles(roles, sensor.sensor, tolerance_nm, by_name=sensor.by_name)
    bands = {m.role: _band_record(sensor, m.band) for m in mapping.matches if m.band is not None}
    if mapping.missing:
        return Cell(app.name, sensor.name, None, mapping.missing, bands)
    try:
        fixed = fixed_scene(one, mapped_sensor(one.sensor, sensor.sensor, mapping), list(roles))
        reuse = {} if own is None else {"library": own.library, "terms": (own.truth, own.assumed)}
        checked = check_sweep(fixed, **reuse)
        row = reference_row(checked, plan_sweep(fixed, checked=checked, device=device), device)
    except InputError as err:  # this sensor's bands on this scene (an SRF outside the grid, an unfittable design)
        return Cell(app.name, sensor.name, None, err.detail, bands)
    assert checked.analysis is not None
    score = row.get(checked.analysis.family.score_column)
    if score is None or not math.isfinite(score):
        return Cell(app.name, sensor.name, None, f"no score (failed_fraction {row.get('failed_fraction')})", bands,
                    row)
    return Cell(app.name, sensor.name, float(score), None, bands, row)


def _band_record(sensor: CatalogueSensor, band: str) -> dict[str, Any]:
    assert sensor.sensor is not None
    b = sensor.sensor.band(band)
    return {"band": b.name, "label": sensor.labels.get(b.name, ""), "centre_nm": b.centre_nm, "width_nm": b.fwhm_nm}


def app_info(app: Application, checked: Checked) -> AppInfo:
    """What ``app`` is scored by, from its checked (own-sensor) scene."""
    assert checked.analysis is not None
    metric = checked.analysis.family.metric
    parameter = checked.analysis.parameter
    return AppInfo(app.name, app.analysis.kind, parameter, metric.score_column, metric.unit(parameter))


def default_sensors(scene: Scene) -> list[str]:
    """The sensors a scorecard scores when none is named: :data:`DEFAULT_SENSORS` and, where the scene's output
    folder holds its finished sweep (``summary.json`` of this scene), that sweep's #1 design and, with a Pareto
    record, its balanced design (``results:FOLDER``, ``results:FOLDER:balanced``)."""
    folder = scene.output_dir
    path = folder / "summary.json"
    if not path.is_file():
        return list(DEFAULT_SENSORS)
    try:
        summary = read_summary(path)
    except InputError:
        return list(DEFAULT_SENSORS)
    if summary.get("scene") != scene.name or not summary.get("top"):
        return list(DEFAULT_SENSORS)
    found = [f"{RESULTS_PREFIX}{folder}"]
    if isinstance(summary.get("pareto"), dict):
        found.append(f"{RESULTS_PREFIX}{folder}:balanced")
    return [*DEFAULT_SENSORS, *found]


def scorecard(scene: str | Path | Scene, sensors: list[str] | None = None, *,
              tolerance_nm: float = DEFAULT_TOLERANCE_NM, device: str | None = None,
              progress: Callable[[Cell], None] | None = None) -> Scorecard:
    """Score every application of ``scene`` on every sensor of ``sensors`` (names as ``--sensor`` takes them;
    default :data:`DEFAULT_SENSORS`). Everything is checked first (the names, the tables, each application's own
    scene); ``progress(cell)`` is called after each cell.

    :raises InputError: a bad sensor name or file, a scene without an application, a tolerance outside 0-100 nm.
    """
    sc = scene if isinstance(scene, Scene) else Scene.load(str(scene))
    if not 0 <= tolerance_nm <= 100:
        raise InputError(f"must be 0 to 100 nm, got {tolerance_nm:g}", key="--tolerance")
    apps = scene_applications(sc)
    if not apps:
        raise InputError("the scene has no [analysis] or [[application]]: nothing to score", source=sc.source,
                         key="analysis")
    cards = [resolve_sensor(s, sc) for s in (sensors or default_sensors(sc))]
    names = [c.name for c in cards]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"sensor {twice[0]} is named twice; known: {', '.join(known_sensors())}", key="--sensor")
    multi = is_multi_application(sc)
    owns = [own_check(application_scene(sc, app), app if multi else None) for app in apps]
    infos = [app_info(app, own) for app, own in zip(apps, owns, strict=True)]
    cells = []
    for app, own in zip(apps, owns, strict=True):
        for card in cards:  # each cell on the library and atmosphere terms its application's checks loaded
            cells.append(score_cell(sc, app, card, tolerance_nm, device, own=own))
            if progress is not None:
                progress(cells[-1])
    return Scorecard(sc.name, tolerance_nm, infos, cards, cells)
