"""s2cl: end-to-end optical sensor simulation for spectral band selection, with OpenCL kernels.

Python API (mirrors the CLI)::

    import s2cl
    scene = s2cl.Scene.load("default")          # a built-in scene, or a path to a .toml file
    best = s2cl.optimise("default")              # the main job: .ranking (DataFrame), .reference, .summary
    result = s2cl.simulate(scene)                # LibrarySimulation
    result.summary()                             # per-band radiance, SNR, clipping
    result.to_dataset().to_netcdf("out.nc")      # xarray Dataset
    s2cl.Sensor.sentinel2().band("B4")           # the paper's Table 1
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

import s2cl.logs  # noqa: F401  (the s2cl logger is silent until an application configures it)
from s2cl.errors import BuildError, DeviceError, InputError, S2CLError
from s2cl.version import __version__

if TYPE_CHECKING:  # what the names below are, for type checkers and readers; imported on first use
    from s2cl.app.library_simulation import simulate
    from s2cl.app.optimise import OptimiseResult, optimise
    from s2cl.atmos.atmosphere import AtmosphereLUT
    from s2cl.atmos.state import AtmosphereState
    from s2cl.forward.simulate import LibrarySimulation, Simulator
    from s2cl.grid import DEFAULT_GRID, SpectralGrid
    from s2cl.libraries.library import SpectralLibrary
    from s2cl.libraries.registry import available_libraries, load_library
    from s2cl.scene.effects import EffectSet
    from s2cl.scene.scene import Scene
    from s2cl.sensor.sensor import Band, Sensor

#: each public name imported on first use (``s2cl.Scene`` imports :mod:`s2cl.scene.scene`), and the module it
#: comes from: ``import s2cl`` imports only the errors, the version and the logger
LAZY: dict[str, str] = {
    "AtmosphereLUT": "s2cl.atmos.atmosphere",
    "AtmosphereState": "s2cl.atmos.state",
    "Band": "s2cl.sensor.sensor",
    "DEFAULT_GRID": "s2cl.grid",
    "EffectSet": "s2cl.scene.effects",
    "LibrarySimulation": "s2cl.forward.simulate",
    "OptimiseResult": "s2cl.app.optimise",
    "Scene": "s2cl.scene.scene",
    "Sensor": "s2cl.sensor.sensor",
    "Simulator": "s2cl.forward.simulate",
    "SpectralGrid": "s2cl.grid",
    "SpectralLibrary": "s2cl.libraries.library",
    "available_libraries": "s2cl.libraries.registry",
    "load_library": "s2cl.libraries.registry",
    "optimise": "s2cl.app.optimise",
    "simulate": "s2cl.app.library_simulation",
}


def __getattr__(name: str) -> Any:
    """The public name ``name`` from its module (imported now, then kept in this module's namespace)."""
    if name not in LAZY:
        raise AttributeError(f"module 's2cl' has no attribute {name!r}")
    value = getattr(importlib.import_module(LAZY[name]), name)
    globals()[name] = value  # the next look-up finds it without calling __getattr__
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *LAZY})


__all__ = [
    "DEFAULT_GRID",
    "AtmosphereLUT",
    "AtmosphereState",
    "Band",
    "BuildError",
    "DeviceError",
    "EffectSet",
    "InputError",
    "LibrarySimulation",
    "OptimiseResult",
    "S2CLError",
    "Scene",
    "Sensor",
    "Simulator",
    "SpectralGrid",
    "SpectralLibrary",
    "__version__",
    "available_libraries",
    "load_library",
    "optimise",
    "simulate",
]
