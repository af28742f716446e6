"""s2cl: end-to-end optical sensor simulation for spectral band selection, with OpenCL kernels.

Python API (mirrors the CLI)::

    import s2cl
    scene = s2cl.Scene.load("default")          # a built-in scene, or a path to a .toml file
    result = s2cl.simulate(scene)                # LibrarySimulation
    result.summary()                             # per-band radiance, SNR, clipping
    result.to_dataset().to_netcdf("out.nc")      # xarray Dataset
    s2cl.Sensor.sentinel2().band("B4")           # the paper's Table 1
"""

__version__ = "0.1.0"

from .atmosphere import AtmosphereLUT, AtmosphereState
from .effects import EffectSet
from .errors import BuildError, DeviceError, InputError, S2CLError
from .grid import DEFAULT_GRID, SpectralGrid
from .libraries import available_libraries, load_library
from .library import SpectralLibrary
from .scene import Scene
from .sensor import Band, Sensor
from .simulate import LibrarySimulation, Simulator, simulate

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
    "S2CLError",
    "Scene",
    "Sensor",
    "Simulator",
    "SpectralGrid",
    "SpectralLibrary",
    "__version__",
    "available_libraries",
    "load_library",
    "simulate",
]
