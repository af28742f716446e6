"""What the forward chain takes, resolved from a scene once by the application layer (:mod:`s2cl.app.chain_parts`,
:mod:`s2cl.app.product_scene`): the engines of this package take these parts, never the scene itself.

- :class:`ChainParts`: the sensor, the spectral grid, each band's resampling weights on it, the stages that are on
  and their settings, the run settings (seed, frame, precision, ...), the true atmosphere's terms and the correction's
  band terms, computed once; and the scene's name and file, for the run's attributes.
- :class:`ResolvedCube`: a scene's image cube from its metadata, opened once: the reader of a cube file (or the name
  of a generated cube), its shape, its GSD and the spectral grid (taken from a product's coverage where it does not
  cover the scene's), the caveats that say what was taken, and whether the resampling kernel interpolates the file's
  own wavelengths onto the grid.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from s2cl.atmos.correction import BandAtmosphere
from s2cl.grid import SpectralGrid
from s2cl.io.cube_reader import CubeReader
from s2cl.scene.caveats import Caveat
from s2cl.scene.config import RunConfig
from s2cl.scene.effects import EffectSet
from s2cl.sensor.sensor import Sensor
from s2cl.sensor.srf import BandWeights


@dataclass(frozen=True, eq=False)
class ChainParts:
    """The parts of the forward chain for one scene (band order of ``sensor``).

    :param name: the scene's name; ``scene_file``: its file (``""`` for a scene built in memory).
    :param weights: each band's resampling weights on ``grid`` (its SRF, or a point band without resampling).
    :param settings: the scene's ``[effects]`` section (each stage's settings).
    :param atmosphere: the true atmosphere's per-wavelength TOA terms on ``grid`` (None: the spectra are radiance).
    :param correction: the correction's band terms (None: no correction).
    """

    name: str
    scene_file: str
    sensor: Sensor
    grid: SpectralGrid
    weights: tuple[BandWeights, ...]
    effects: EffectSet
    settings: Any
    run: RunConfig
    atmosphere: Any = None
    correction: BandAtmosphere | None = None


@dataclass(frozen=True, eq=False)
class ResolvedCube:
    """A scene's image cube from its metadata (nothing but metadata is read).

    :param reader: the cube file opened for reading by rows (None: a generated cube, ``builtin``).
    :param builtin: the generated cube's name (``builtin:fields:RxC``), None for a file.
    :param rows, cols: its size in pixels; ``wavelengths``: bands held per pixel in its file (0: generated).
    :param gsd_m: its ground sampling distance (m): the scene's, or the product's pixel size.
    :param grid: the spectral grid the chain runs on (the scene's, or taken from the product's coverage).
    :param interpolates: the resampling kernel puts the file's own wavelengths on ``grid`` (they are not its samples).
    :param source: the cube file as the scene names it (errors about its contents name it), or the scene for a
        generated cube.
    :param quantity: what its values are (``surface.quantity``).
    :param caveats: what was taken from the product (GSD, grid), one line each.
    """

    reader: CubeReader | None
    builtin: str | None
    rows: int
    cols: int
    wavelengths: int
    gsd_m: float
    grid: SpectralGrid
    interpolates: bool
    source: str
    quantity: str
    caveats: tuple[Caveat, ...] = ()

    @property
    def pixels(self) -> int:
        return self.rows * self.cols
