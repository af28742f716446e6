"""A generated image scene with a known truth: ``surface.cube = "builtin:fields"`` (or ``builtin:fields:ROWSxCOLS``).

Fields of the built-in libraries laid out as rectangular parcels with sharp edges: PROSAIL canopies of Lib1 and
Lib2 (known chlorophyll ``cab`` µg/cm² and ``lai`` m²/m², :mod:`s2cl.libraries.vegetation`), bare patches of the
USGS iron-bearing backgrounds those canopies stand on and of USGS Al-OH / Mg-OH minerals
(:mod:`s2cl.libraries.minerals`). Parcel sides are drawn at random (7–31 input pixels, so most edges cut
through the coarser bands' pixels) from the scene's seed: the same seed gives the same image.

The image is held as its distinct spectra and a label per pixel (the cube is never materialised), with the
truth per pixel: ``cab`` (NaN on bare parcels, which have none), ``lai`` (0 on bare parcels) and the parcel id.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from s2cl.errors import InputError, token
from s2cl.grid import SpectralGrid
from s2cl.libraries.library import SpectralLibrary
from s2cl.libraries.minerals import iron_backgrounds, mineral_library
from s2cl.libraries.vegetation import load_vegetation

BUILTIN_CUBE_PREFIX = "builtin:"
FIELDS = "fields"
#: rows and columns of ``builtin:fields`` when the name gives none
DEFAULT_SHAPE = (120, 120)
MAX_SIDE = 100_000
#: smallest and largest parcel side, input pixels
PARCEL_SIDES = (7, 31)
#: probability of a vegetated parcel, a bare-soil parcel, a mineral parcel
CLASS_WEIGHTS = (0.7, 0.15, 0.15)
#: class of each parcel kind (``groups`` of the distinct spectra)
CLASSES = ("vegetation", "soil", "mineral")
_SHAPE = re.compile(r"(\d+)x(\d+)")


def is_builtin_cube(spec: str) -> bool:
    return str(spec).strip().lower().startswith(BUILTIN_CUBE_PREFIX)


def fields_shape(spec: str, *, source: str | None = None, key: str = "surface.cube") -> tuple[int, int]:
    """(rows, cols) of a ``builtin:fields[:ROWSxCOLS]`` cube; a one-line error for any other builtin name."""
    name = str(spec).strip().lower()[len(BUILTIN_CUBE_PREFIX):]
    if name == FIELDS:
        return DEFAULT_SHAPE
    m = _SHAPE.fullmatch(name[len(FIELDS) + 1:]) if name.startswith(FIELDS + ":") else None
    if m is None:
        raise InputError(f"{token(spec)}: the built-in image cube is builtin:{FIELDS} or builtin:{FIELDS}:ROWSxCOLS "
                         f"(e.g. builtin:{FIELDS}:240x360)", source=source, key=key)
    rows, cols = int(m[1]), int(m[2])
    if not (1 <= rows <= MAX_SIDE and 1 <= cols <= MAX_SIDE):
        raise InputError(f"{token(spec)}: rows and columns must be in 1-{MAX_SIDE}", source=source, key=key)
    return rows, cols


@dataclass(frozen=True, eq=False)
class FieldsImage:
    """A generated image: ``library`` holds the distinct reflectance spectra (groups: :data:`CLASSES`; params
    ``cab``, ``lai``), ``labels`` ``(rows, cols)`` the spectrum of each pixel, ``parcels`` its parcel id."""

    library: SpectralLibrary
    labels: np.ndarray
    parcels: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.labels.shape[0]), int(self.labels.shape[1])

    def truth(self) -> dict[str, np.ndarray]:
        """The parameter maps ``(rows, cols)``: ``cab`` µg/cm² (NaN where bare), ``lai`` m²/m² (0 where bare)."""
        return {k: self.library.params[k][self.labels] for k in ("cab", "lai")}


def fields_library(grid: SpectralGrid) -> SpectralLibrary:
    """The distinct spectra a fields image draws from: Lib1 and Lib2 canopies, their bare backgrounds, minerals."""
    veg = SpectralLibrary.concat([load_vegetation("lib1", grid), load_vegetation("lib2", grid)])
    veg = SpectralLibrary(grid, veg.spectra, veg.names, groups=["vegetation"] * veg.size,
                          params={"cab": veg.params["cab"], "lai": veg.params["lai"]}, source=veg.source)
    bare = []
    for lib, group in ((iron_backgrounds(grid), "soil"), (mineral_library(grid), "mineral")):
        bare.append(SpectralLibrary(grid, lib.spectra, lib.names, groups=[group] * lib.size,
                                    params={"cab": np.full(lib.size, np.nan), "lai": np.zeros(lib.size)},
                                    source=lib.source))
    return SpectralLibrary.concat([veg, *bare])


def parcel_layout(rows: int, cols: int, rng: np.random.Generator) -> np.ndarray:
    """Parcel id of each pixel ``(rows, cols)``: strips of random height, each cut into parcels of random width."""
    lo, hi = PARCEL_SIDES
    out = np.empty((rows, cols), np.int32)
    parcel, top = 0, 0
    while top < rows:
        height = int(rng.integers(lo, hi + 1))
        left = 0
        while left < cols:
            width = int(rng.integers(lo, hi + 1))
            out[top : top + height, left : left + width] = parcel
            parcel += 1
            left += width
        top += height
    return out


def fields_image(grid: SpectralGrid, rows: int, cols: int, seed: int) -> FieldsImage:
    """The fields image of ``rows × cols`` input pixels on ``grid``, reproducible from ``seed``."""
    rng = np.random.default_rng([seed, rows, cols])
    lib = fields_library(grid)
    parcels = parcel_layout(rows, cols, rng)
    n_parcels = int(parcels.max()) + 1
    groups = np.array(lib.groups)
    members = [np.flatnonzero(groups == c) for c in CLASSES]
    kind = rng.choice(len(CLASSES), size=n_parcels, p=CLASS_WEIGHTS)
    pick = np.array([members[k][rng.integers(members[k].size)] for k in kind], dtype=np.int32)
    return FieldsImage(lib, pick[parcels], parcels)
