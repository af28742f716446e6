"""s2cl: end-to-end optical sensor simulation for spectral band selection, with OpenCL kernels."""

from .errors import BuildError, DeviceError, InputError, S2CLError
from .grid import DEFAULT_GRID, SpectralGrid
from .library import SpectralLibrary

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_GRID",
    "BuildError",
    "DeviceError",
    "InputError",
    "S2CLError",
    "SpectralGrid",
    "SpectralLibrary",
    "__version__",
]
