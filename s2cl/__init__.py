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

import s2cl.logs  # noqa: F401  (the s2cl logger is silent until an application configures it)
from s2cl.app.optimise import OptimiseResult, optimise
from s2cl.atmos.atmosphere import AtmosphereLUT
from s2cl.atmos.state import AtmosphereState
from s2cl.errors import BuildError, DeviceError, InputError, S2CLError
from s2cl.forward.simulate import LibrarySimulation, Simulator, simulate
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.libraries.library import SpectralLibrary
from s2cl.libraries.registry import available_libraries, load_library
from s2cl.scene.effects import EffectSet
from s2cl.scene.scene import Scene
from s2cl.sensor.sensor import Band, Sensor
from s2cl.version import __version__

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
