"""Validity before work: everything a scene asks for is checked here, once, by the same function for
every command, before anything is allocated, computed or written.

:func:`check_simulate` (``s2cl simulate``) and :func:`check_sweep` (``s2cl optimise``, ``sweep run``,
``sweep count``) load the surface library, resolve the [sweep] section when there is one (counts
computed, never enumerated), validate the [analysis] section against the library and the bands
(parameter, classes, IGRM settings with their full keys), put the atmosphere states through the
LUT's ranges, and collect the caveats (:mod:`s2cl.scene.caveats`). Errors name the scene file and the full
key; a scene with a broken [sweep] section is refused by ``simulate`` too (it is one scene).

What the checks compute they keep: :class:`Checked` is the scene resolved once (library, sweep space, analysis,
atmosphere terms, the sweep's sensor), and the engines take its parts, never the scene (docs/architecture.md).
The engines' errors name the key; the checks run them inside :func:`s2cl.errors.errors_in`, which adds the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from s2cl.app.analysis import analysis_bands, analysis_design, check_image_analysis
from s2cl.app.product_scene import resolve_cube
from s2cl.errors import InputError, errors_in, token
from s2cl.forward.parts import ResolvedCube
from s2cl.forward.resample import AtmosphereArrays
from s2cl.forward.stages import caveats as stage_caveats
from s2cl.grid import SpectralGrid
from s2cl.io.budget import Budget
from s2cl.io.inputs import input_file
from s2cl.libraries.fields import is_builtin_cube
from s2cl.libraries.library import SpectralLibrary
from s2cl.retrieve.analysis import AnalysisSettings, analysis_targets
from s2cl.retrieve.design import check_design, count_underdetermined
from s2cl.retrieve.family import registry
from s2cl.scene.caveats import Caveat, grid_caveats, srf_caveats
from s2cl.scene.config import RunConfig
from s2cl.scene.library import scene_library
from s2cl.scene.scene import Scene
from s2cl.scene.terms import correction_terms, scene_terms
from s2cl.sensor.sensor import Sensor
from s2cl.sensor.variants import SweepSpace
from s2cl.sweep.addition import AdditionBase, check_base
from s2cl.sweep.space import sweep_space, with_added_band


@dataclass(frozen=True, eq=False)
class Checked:
    """A scene that passed every check, resolved once: what the checks loaded and computed, which the run reuses
    (the engines take these parts, not the scene)."""

    scene: Scene
    library: SpectralLibrary | None
    space: SweepSpace | None
    analysis: AnalysisSettings | None
    analysis_bands: list[str] = field(default_factory=list)
    caveats: list[Caveat] = field(default_factory=list)
    #: a band-addition sweep's base set and the analysis that scores it alone (s2cl.sweep.addition)
    base: AdditionBase | None = None
    #: per-wavelength terms of the true atmosphere on the scene's grid (None where nothing needs them)
    truth: AtmosphereArrays | None = None
    #: per-wavelength terms of the atmosphere the correction assumes (None where nothing needs them)
    assumed: AtmosphereArrays | None = None
    #: the sensor a sweep's tables see: the scene's, with a band-addition sweep's added band appended
    #: (:func:`s2cl.sweep.space.with_added_band`); the scene's own for ``simulate``
    sensor: Sensor | None = None
    #: an image scene's cube, its file's metadata opened once (``scene`` is completed from it: GSD, grid)
    cube: ResolvedCube | None = None
    #: band tables shared with the other applications of a multi-application scene (``build_tables``' ``shared``:
    #: each band's resampling done once per library); None: the sweep's own
    shared_tables: dict[Any, Any] | None = field(default=None, repr=False)

    @property
    def source(self) -> str:
        """The scene file, which the application layer adds to the engines' errors."""
        return self.scene.source

    @property
    def grid(self) -> SpectralGrid:
        return self.scene.grid

    @property
    def run(self) -> RunConfig:
        return self.scene.run


def check_simulate(scene: Scene, *, budget: Budget | None = None) -> Checked:
    """Everything ``s2cl simulate`` needs, checked (its analysis runs on ``analysis_bands``); a library file is
    sized from its metadata against ``budget`` before it is read; a cube file's metadata is opened once, and the scene
    completed from it (:func:`s2cl.app.product_scene.resolve_cube`)."""
    scene, cube = resolve_cube(scene)
    library, space = _surface(scene, budget), _space(scene)
    analysis, bands = None, []
    if scene.spec.analysis is not None:
        bands = _known_bands(scene, analysis_bands(scene), "analysis.bands")
        analysis = _analysis(scene, bands, library)
        analysis_design(scene, bands, analysis)  # the design rule, as simulate's analysis applies it
        if scene.spec.surface.cube is not None:
            check_image_analysis(scene, analysis)
        if not scene.effects.correct:
            raise InputError("the analysis needs band reflectance: set effects.atmosphere and effects.correct "
                             "(or remove [analysis])", source=scene.source, key="effects.correct")
    truth, assumed = atmosphere_terms(scene)
    caveats = [*(cube.caveats if cube else ()), *_caveats(scene, space, list(scene.sensor.band_names))]
    return Checked(scene, library, space, analysis, bands, caveats, truth=truth, assumed=assumed, sensor=scene.sensor,
                   cube=cube)


def check_sweep(scene: Scene, *, budget: Budget | None = None, library: SpectralLibrary | None = None,
                terms: tuple[AtmosphereArrays | None, AtmosphereArrays | None] | None = None) -> Checked:
    """Everything a sweep of ``scene`` needs, checked (the same for optimise, sweep run and sweep count); a
    library file is sized from its metadata against ``budget`` before it is read. ``library`` and ``terms`` (the
    true and the assumed atmosphere's): what the caller already loaded and computed for this scene (an application
    of a scene with several: :mod:`s2cl.app.applications`), used instead of loading and computing them again."""
    check_sweep_sections(scene)
    library, space = library if library is not None else _surface(scene, budget), _space(scene)
    assert space is not None
    _known_bands(scene, scene.spec.analysis.bands or [], "analysis.bands")  # simulate's analysis bands
    analysis = _analysis(scene, space.bands, library)
    check_fittable(scene, space, analysis)

    with errors_in(scene.source):  # an addition sweep: its base set scorable alone
        base = check_base(scene.spec.sweep.add, scene.spec.analysis, space, library)
        sensor = with_added_band(scene.sensor, scene.spec.sweep)
    truth, assumed = terms if terms is not None else atmosphere_terms(scene)
    known = [b for b in space.bands if base is None or b != base.added]  # the added band has the model SRF
    caveats = _caveats(scene, space, known) + srf_caveats(scene, known)
    return Checked(scene, library, space, analysis, list(space.bands), caveats, base, truth, assumed, sensor)


def check_fittable(scene: Scene, space: SweepSpace, analysis: AnalysisSettings) -> None:
    """Refuse a sweep in which no configuration can be fitted (:mod:`s2cl.retrieve.design`; e.g. a fixed design
    with two IGRM bands on one centre), in one line naming the bands."""
    bad = count_underdetermined(analysis, space)
    if bad is not None and bad == space.size:
        first = space.shapes(0, 1)[0]
        check_design(analysis, space.bands, first[:, 0], first[:, 1], source=scene.source, key="sweep")


def _surface(scene: Scene, budget: Budget | None) -> SpectralLibrary | None:
    if scene.spec.surface.library is None:
        cube = scene.spec.surface.cube
        assert cube is not None  # the scene has one of them (s2cl.scene.scene)
        if is_builtin_cube(cube):  # generated: its name was checked with the scene
            return None
        if not scene.resolve(cube).is_dir():  # a folder is a product (EnMAP), checked by its reader
            input_file(scene.resolve(cube), what="image cube", source=scene.source, key="surface.cube")
        return None

    return scene_library(scene, budget=budget)


def _space(scene: Scene) -> SweepSpace | None:
    if scene.spec.sweep is None:
        return None
    if scene.spec.surface.cube is not None:
        raise InputError("a [sweep] runs over a spectral library (surface.library), not an image cube: remove "
                         "[sweep] to simulate the cube, or sweep a library", source=scene.source, key="sweep")

    with errors_in(scene.source):
        return sweep_space(scene.spec.sweep, scene.sensor, scene.grid, scene.run.support)


def _known_bands(scene: Scene, bands: list[str], key: str) -> list[str]:
    names = {n.lower(): n for n in scene.sensor.band_names}
    unknown = [b for b in bands if b.lower() not in names]
    if unknown:
        raise InputError(f"unknown band(s) {', '.join(token(b) for b in unknown)}; the sensor's bands here: "
                         f"{', '.join(scene.sensor.band_names)}", source=scene.source, key=key)
    return bands


def _analysis(scene: Scene, bands: list[str], library: SpectralLibrary | None) -> AnalysisSettings:
    with errors_in(scene.source):
        settings = AnalysisSettings.from_spec(scene.spec.analysis, bands)
        if library is not None:
            analysis_targets(library, settings, scene.spec.analysis.classes)
    return settings


def atmosphere_terms(scene: Scene) -> tuple[AtmosphereArrays | None, AtmosphereArrays | None]:
    """The terms of the true atmosphere and of the one the correction assumes, each where the scene needs it (the
    effect is on, or the scene has a sweep): both states inside the LUT's ranges, checked by computing them once."""
    sweep = scene.spec.sweep is not None
    truth = scene_terms(scene) if scene.effects.atmosphere or sweep else None
    assumed = correction_terms(scene) if scene.effects.correct or sweep else None
    return truth, assumed


def _caveats(scene: Scene, space: SweepSpace | None, bands: list[str]) -> list[Caveat]:
    widths = {b.name: b.fwhm_nm for b in scene.sensor.bands}
    if space is not None:
        for r in space.ranges:
            widths[r.band] = min(widths.get(r.band, float("inf")), r.extent()[2])
    return grid_caveats(scene, widths) + stage_caveats(scene.sensor, scene.effects, bands,
                                                       image=scene.spec.surface.cube is not None,
                                                       sweep=scene.spec.sweep is not None)


def check_sweep_sections(scene: Scene) -> None:
    """The sections a sweep needs are there: [sweep], [analysis], and the whole chain's effects."""
    if scene.spec.sweep is None:
        raise InputError("the scene has no [sweep] section: it cannot be optimised (s2cl simulate runs it)",
                         source=scene.source, key="sweep")
    if scene.spec.analysis is None and scene.spec.application is not None:
        raise InputError("a scene with [[application]] tables runs with s2cl optimise, sweep run or sweep count; "
                         "this command takes one [analysis]", source=scene.source, key="application")
    if scene.spec.analysis is None:
        raise InputError(f"a sweep needs an [analysis] section (kind: {', '.join(registry())})",
                         source=scene.source, key="analysis")
    if not (scene.effects.atmosphere and scene.effects.correct):
        raise InputError("a sweep runs the whole chain: set effects.atmosphere = true and effects.correct = true",
                         source=scene.source, key="effects")
