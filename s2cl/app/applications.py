"""A scene with several applications (``[[application]]``), checked once: the shared [sweep] space, the atmosphere
terms, each distinct library, and per application its single-application scene restricted to its bands.

A design of the scene is one position of every swept band (the joint space). An application reads the bands its
analysis needs (its ``analysis.bands``, else its family's default: an index's role bands, IGRM's four red-edge
bands, ...); a band it reads that the [sweep] does not move stays at the sensor's own position. Each application is
scored over its own sub-space (the shared ranges restricted to its bands) by the single-application machinery on
:func:`application_sweep_scene`; a joint configuration number maps to the application's configuration number by
mixed radix (:meth:`s2cl.sweep.joint.JointApplication.configs_of`), so each application's score of a design is by
construction what its own scene gives for that design and seed. Errors are one line naming the scene file and the
application's key (``application[i].library``, ``application[i].analysis.nir``, ...).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from s2cl.app.checks import Checked, atmosphere_terms, check_sweep
from s2cl.errors import InputError, errors_in, token
from s2cl.forward.resample import AtmosphereArrays
from s2cl.grid import SpectralGrid
from s2cl.io.budget import Budget
from s2cl.libraries.library import SpectralLibrary
from s2cl.retrieve.family import family_of
from s2cl.retrieve.metric import Metric
from s2cl.scene.applications import Application, application_scene, scene_applications, target_value
from s2cl.scene.caveats import Caveat
from s2cl.scene.library import scene_library
from s2cl.scene.scene import Scene
from s2cl.scene.schema import RangeSpec
from s2cl.sensor.variants import SweepSpace
from s2cl.sweep.space import sweep_space

#: most designs of a joint space (its configuration numbers are int64)
MAX_JOINT = 2**62


@dataclass(frozen=True, eq=False)
class ApplicationPart:
    """One application of a multi-application sweep: the application as written, its single-application scene over
    its own sub-space (:func:`application_sweep_scene`) checked with the shared parts, its ``bands`` (its slots, the
    sensor's names, in its order), its ``metric`` and ``target`` (in the metric's units, or None), and per slot the
    joint space's slot it reads (``slots``; None: a band the [sweep] does not move, at the sensor's own position)."""

    app: Application
    scene: Scene
    checked: Checked
    bands: tuple[str, ...]
    metric: Metric
    target: float | None
    slots: tuple[int | None, ...]

    @property
    def name(self) -> str:
        return self.app.name

    @property
    def column(self) -> str:
        """Its score's column in the joint results (``chlorophyll_rms``)."""
        return f"{self.app.name}_{self.metric.score_column}"

    @property
    def space(self) -> SweepSpace:
        assert self.checked.space is not None
        return self.checked.space


@dataclass(frozen=True, eq=False)
class CheckedApplications:
    """A multi-application scene that passed every check: the joint ``space`` (the [sweep], shared), the
    applications in the order written, the atmosphere terms (computed once) and the caveats of them all."""

    scene: Scene
    space: SweepSpace
    parts: tuple[ApplicationPart, ...]
    caveats: list[Caveat]
    truth: AtmosphereArrays | None
    assumed: AtmosphereArrays | None

    @property
    def source(self) -> str:
        return self.scene.source


def check_applications(scene: Scene, *, budget: Budget | None = None) -> CheckedApplications:
    """Everything a sweep of a scene with ``[[application]]`` tables needs, checked before any work: the [sweep]
    (shared; resolved once), the atmosphere terms (once), each distinct (library, surface.select) loaded once, and
    every application as its own single-application sweep (its library, parameter, bands and design rule, its
    ``target`` in its metric's units). One-line errors name the scene file and the key."""
    spec = scene.spec
    _check_sections(scene)
    assert spec.sweep is not None
    with errors_in(scene.source):
        space = sweep_space(spec.sweep, scene.sensor, scene.grid, scene.run.support)
    terms = atmosphere_terms(scene)
    grids: dict[SpectralGrid, tuple[Any, Any]] = {scene.grid: terms}  # terms once per grid
    libraries: dict[tuple[str | None, str, SpectralGrid], SpectralLibrary] = {}
    shared: dict[Any, Any] = {}  # the band tables the applications' sweeps share (s2cl.sweep.tables.build_tables)
    parts, caveats = [], []
    joint = [r.band for r in space.ranges]
    for app in scene_applications(scene):
        with application_errors(scene, app):
            bands = application_bands(scene, app)
            one = application_sweep_scene(scene, app, bands)
            off = [b for b in bands if b not in one.sensor.band_names]  # its own grid cannot hold a band it reads
            if off:
                raise InputError(f"{', '.join(off)} (which the application reads) {'does' if len(off) == 1 else 'do'}"
                                 f" not lie on its grid {one.grid.describe()}: widen the grid",
                                 source=scene.source, key=f"{app.key}.grid")
            key = (app.library, repr(sorted(scene.spec.surface.select.items())), one.grid)
            if key not in libraries:
                libraries[key] = scene_library(one, budget=budget)
            if one.grid not in grids:  # an application's own grid ([[application]] grid)
                grids[one.grid] = atmosphere_terms(one)
            checked = check_sweep(one, budget=budget, library=libraries[key], terms=grids[one.grid])
            checked = dataclasses.replace(checked, shared_tables=shared)  # each band resampled once per library
            assert checked.analysis is not None
            metric = checked.analysis.family.metric
            with errors_in(scene.source):
                target = target_value(app, metric)
        slots = tuple(joint.index(b) if b in joint else None for b in bands)
        part = ApplicationPart(app, one, checked, tuple(bands), metric, target, slots)
        for k, slot in enumerate(slots):  # the sub-space's variants are the joint space's, in the same order
            assert slot is None or part.space.counts[k] == space.counts[slot]
        parts.append(part)
        caveats += [c for c in checked.caveats if c not in caveats]
    _check_joint(scene, space, parts)
    return CheckedApplications(scene, space, tuple(parts), caveats, *terms)


def _check_sections(scene: Scene) -> None:
    spec = scene.spec
    if spec.sweep is None:
        raise InputError("the scene has no [sweep] section: it cannot be optimised (s2cl simulate runs it)",
                         source=scene.source, key="sweep")
    if spec.surface.cube is not None:
        raise InputError("a [sweep] runs over spectral libraries (surface.library, application.library), not an "
                         "image cube", source=scene.source, key="surface.cube")
    if not (scene.effects.atmosphere and scene.effects.correct):
        raise InputError("a sweep runs the whole chain: set effects.atmosphere = true and effects.correct = true",
                         source=scene.source, key="effects")
    if spec.sweep.add is not None:
        raise InputError("a band-addition sweep of a scene with several applications is not yet supported: remove "
                         "[sweep.add], or sweep one [analysis]", source=scene.source, key="sweep.add")


def _check_joint(scene: Scene, space: SweepSpace, parts: list[ApplicationPart]) -> None:
    """Every swept band is read by some application; the joint space's size is countable; no application's score
    column is a column of the first application's results."""
    read = {b for p in parts for b in p.bands}
    idle = [r.band for r in space.ranges if r.band not in read]
    if idle:
        raise InputError(f"{', '.join(idle)} {'is' if len(idle) == 1 else 'are'} swept but no application reads "
                         f"{'it' if len(idle) == 1 else 'them'} (their bands: "
                         f"{'; '.join(f'{p.name}: ' + ' '.join(p.bands) for p in parts)}); remove "
                         f"{'it' if len(idle) == 1 else 'them'} from sweep.bands or add to an application's "
                         "analysis.bands", source=scene.source, key="sweep.bands")
    size = 1
    for n in space.counts:
        size *= int(n)
    if size >= MAX_JOINT:
        raise InputError(f"the joint space has {size:.3g} designs, more than the {MAX_JOINT:.3g} a results table can "
                         "number; sweep fewer bands or coarser steps", source=scene.source, key="sweep")
    first = parts[0]
    taken = set(first.metric.columns) | {"config", "underdetermined", "host"} | \
        {f"{r.band}_{s}" for r in space.ranges for s in ("centre_nm", "width_nm")}
    for p in parts:
        if p.column in taken:
            raise InputError(f"its score column {p.column} is a column of the results already; choose another name",
                             source=scene.source, key=f"{p.app.key}.name")


def application_bands(scene: Scene, app: Application) -> list[str]:
    """The bands the application's analysis reads, as the sensor names them, in its order: ``analysis.bands``,
    else its family's default (:meth:`s2cl.retrieve.family.Family.default_bands`: an index's role bands, IGRM's
    B4-B7, SAM's every band). A band the sensor does not have is refused, naming the key that asks for it."""
    a = app.analysis
    names = list(a.bands) if a.bands else family_of(a.kind).default_bands(a, scene.sensor.band_names)
    known = {n.lower(): n for n in scene.sensor.band_names}
    for b in names:
        if b.lower() not in known:
            role = next((r for r, v in a.roles.items() if v.lower() == b.lower()), None)
            key = "analysis.bands" if a.bands else f"analysis.{role}" if role else "analysis"
            raise InputError(f"the analysis needs band {token(b)}, which no swept or fixed band provides: the sensor "
                             f"has no such band (its bands: {', '.join(scene.sensor.band_names)})", key=key)
    return list(dict.fromkeys(known[b.lower()] for b in names))


def application_sweep_scene(scene: Scene, app: Application, bands: list[str]) -> Scene:
    """The application's single-application scene (:func:`s2cl.scene.applications.application_scene`) with its
    [sweep] restricted to ``bands``: a band the scene sweeps keeps its range (or the preset's), any other is fixed
    at the sensor's own centre and width. Its sweep of a design equals the scene's for the same bands and seed."""
    sweep = scene.spec.sweep
    assert sweep is not None
    swept = {b.lower() for b in sweep.bands}
    ranges: dict[str, RangeSpec] = {}
    for b in bands:
        if b.lower() in swept:
            written = next((v for k, v in sweep.ranges.items() if k.lower() == b.lower()), None)
            if written is not None:
                ranges[b] = written
        else:
            band = scene.sensor.band(b)
            ranges[b] = RangeSpec(centre=band.centre_nm, width=band.fwhm_nm)
    one = application_scene(scene, app)
    sub = sweep.model_copy(update={"bands": list(bands), "ranges": ranges})
    return dataclasses.replace(one, spec=one.spec.model_copy(update={"sweep": sub}))


#: keys of the single-application scene that the application writes under its own key
_OWN_KEYS = {"surface.library": "library", "surface.copies": "copies", "analysis": "analysis", "grid": "grid"}


@contextmanager
def application_errors(scene: Scene, app: Application) -> Iterator[None]:
    """Errors of an application's checks as one line naming the scene file and the application's key: its
    single-application scene's ``surface.library`` is ``application[i].library``, ``analysis.X`` is
    ``application[i].analysis.X``; another key keeps its name, the message says which application."""
    try:
        yield
    except InputError as err:
        key = err.key or ""
        for own, mine in _OWN_KEYS.items():
            if key == own or key.startswith(own + "."):
                raise InputError(err.detail, source=scene.source, key=app.key + "." + mine + key[len(own):]) \
                    from None
        if key.startswith(app.key):
            raise InputError(err.detail, source=err.source or scene.source, key=key) from None
        raise InputError(f"application {app.name}: {err.detail}", source=err.source or scene.source,
                         key=err.key) from None
