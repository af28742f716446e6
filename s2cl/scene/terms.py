"""A scene's atmosphere: the true state ([atmosphere]), the state the correction assumes
([correction], defaulting to the true one), and their per-wavelength terms from the 6S LUT."""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import Any

from s2cl.atmos.atmosphere import AtmosphereLUT
from s2cl.atmos.state import PAPER_VISIBILITY_KM, AtmosphereState, visibility_to_aot550
from s2cl.errors import InputError
from s2cl.io.inputs import input_file
from s2cl.scene.scene import Scene

STATE_KEYS = ("profile", "water_vapour", "aot550", "visibility_km", "ozone", "solar_zenith")


@cache
def _lut(path: str | None) -> Any:
    return AtmosphereLUT.load(path)


def scene_lut(scene: Scene) -> Any:
    """The LUT the scene names ([atmosphere] lut), or the shipped one."""
    lut = scene.spec.atmosphere.lut
    if not lut:
        return _lut(None)

    path = input_file(scene.resolve(lut), what="atmosphere LUT", source=scene.source, key="atmosphere.lut")
    return _lut(str(path))


def _state(scene: Scene, values: dict[str, Any], section: str) -> Any:
    v = dict(values)
    try:
        aot = v.pop("aot550")
        visibility = v.pop("visibility_km")
        if aot is None:
            aot = visibility_to_aot550(visibility if visibility is not None else PAPER_VISIBILITY_KM)
        return AtmosphereState(aot550=aot, **v)
    except InputError as err:
        raise err.within(scene.source, section) from None


def true_state(scene: Scene) -> Any:
    """The atmosphere the scene is simulated under."""
    a = scene.spec.atmosphere
    return _state(scene, {k: getattr(a, k) for k in STATE_KEYS}, "atmosphere")


def assumed_state(scene: Scene) -> Any:
    """The atmosphere the correction assumes: [correction] keys over [atmosphere]."""
    a, c = scene.spec.atmosphere, scene.spec.correction
    values = {k: getattr(a, k) for k in STATE_KEYS}
    given = {k: getattr(c, k) for k in STATE_KEYS if getattr(c, k) is not None}
    if "aot550" in given or "visibility_km" in given:
        values["aot550"] = values["visibility_km"] = None
    values.update(given)
    return _state(scene, values, "correction")


def state_terms(scene: Scene, state: Any, section: str) -> Any:
    """Per-wavelength terms of ``state`` from the scene's LUT on its grid; errors name ``section``."""
    table = scene_lut(scene)  # a LUT file at fault is named by its own errors
    try:
        return table.terms(state, scene.grid, scene.spec.atmosphere.interpolation)
    except InputError as err:
        if err.key in STATE_KEYS or err.key == "grid":  # the scene's value is outside the LUT's axes
            key = "grid" if err.key == "grid" else f"{section}.{err.key}"
            lut = f" (LUT {Path(err.source).name})" if err.source else ""
            raise InputError(err.detail + lut, source=scene.source, key=key) from None
        if err.source and Path(err.source).suffix in (".npz", ".nc"):
            raise  # the LUT file itself is at fault
        raise err.within(scene.source, section) from None


def scene_terms(scene: Scene) -> Any:
    """Per-wavelength terms of the true atmosphere on the scene's grid."""
    return state_terms(scene, true_state(scene), "atmosphere")


def correction_terms(scene: Scene) -> Any:
    """Per-wavelength terms of the atmosphere the correction assumes."""
    return state_terms(scene, assumed_state(scene), "correction")


def scene_atmosphere(scene: Scene) -> Any:
    """The per-wavelength TOA terms for the scene's atmosphere, when that effect is on."""
    if not scene.effects.atmosphere:
        return None

    return scene_terms(scene)
