"""A scene resolved into the parts the forward chain takes (:class:`~s2cl.forward.parts.ChainParts`): each band's
resampling weights, the true atmosphere's terms and the correction's band terms, computed once here; the engines
(:class:`~s2cl.forward.simulate.Simulator`, :func:`~s2cl.forward.cube.simulate_cube`, the instrument's effects) take
the parts, never the scene. Errors the engines raise name the key; the application layer runs them inside
:func:`s2cl.errors.errors_in` with the scene's file."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from s2cl.atmos.correction import BandAtmosphere
from s2cl.cl.runtime import Runtime
from s2cl.forward.grid_interpolation import GridInterpolation
from s2cl.forward.instrument import Instrument
from s2cl.forward.parts import ChainParts
from s2cl.forward.simulate import Simulator
from s2cl.scene.scene import Scene
from s2cl.scene.terms import correction_terms, scene_atmosphere
from s2cl.sensor.srf import point_weights

if TYPE_CHECKING:
    from s2cl.app.checks import Checked

#: :func:`chain_parts`'s default: the true atmosphere's terms when the scene's atmosphere is on
SCENE_ATMOSPHERE: Any = object()


def chain_parts(scene: Scene, *, atmosphere: Any = SCENE_ATMOSPHERE, assumed: Any = None) -> ChainParts:
    """The chain's parts of ``scene`` (resolved: a cube scene's grid is its product's, :mod:`s2cl.app.product_scene`):
    each band's weights on its grid (its SRF, or a point band without resampling), the correction's band terms (when
    the correction is on), and the true atmosphere's TOA terms (``atmosphere``: the scene's by default, or the terms
    given, None for none); ``assumed``: the correction's per-wavelength terms where they were computed already (the
    checks': :func:`checked_parts`)."""
    weights = tuple(
        b.weights(scene.grid, scene.run.support, scene.source)
        if scene.effects.resample else point_weights(scene.grid, b.centre_nm, b.name, scene.source)
        for b in scene.sensor.bands
    )
    correction = None
    if scene.effects.correct:
        correction = BandAtmosphere.of(correction_terms(scene) if assumed is None else assumed, weights)
    terms = scene_atmosphere(scene) if atmosphere is SCENE_ATMOSPHERE else atmosphere
    return ChainParts(scene.name, str(scene.path or ""), scene.sensor, scene.grid, weights, scene.effects,
                      scene.spec.effects, scene.run, terms, correction)


def checked_parts(checked: Checked) -> ChainParts:
    """The chain's parts of a checked scene, with the atmosphere terms the checks computed (never computed again)."""
    scene = checked.scene
    truth = checked.truth if scene.effects.atmosphere else None
    if (scene.effects.atmosphere and truth is None) or (scene.effects.correct and checked.assumed is None):
        raise AssertionError("the checks computed no terms for an effect that is on")  # check_simulate does
    return chain_parts(scene, atmosphere=truth, assumed=checked.assumed)


def scene_simulator(rt: Runtime, scene: Scene, *, atmosphere: Any = None,
                    interpolation: GridInterpolation | None = None) -> Simulator:
    """The scene's compiled chain on ``rt`` (:meth:`Simulator.of`); ``atmosphere``: the TOA terms the spectra go
    through (None: the spectra are radiance, as given); ``interpolation``: a cube's native wavelengths put on the
    grid by the resampling kernel."""
    return Simulator.of(rt, chain_parts(scene, atmosphere=atmosphere), interpolation=interpolation)


def scene_instrument(scene: Scene) -> Instrument:
    """The scene's image effects (``[effects]`` psf, coregistration, smile, nonuniformity) on its bands."""
    return Instrument.of(scene.spec.effects, scene.run.seed, scene.sensor.bands)
