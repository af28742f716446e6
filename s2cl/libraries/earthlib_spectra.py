"""Measured soils and non-photosynthetic vegetation (NPV) from earthlib, shipped with s2cl
(``s2cl/data/earthlib_soils_npv.npz``, made by ``tools/extract_earthlib.py``; earthlib is not needed at run time).

* :func:`soil_library` — the 4,168 ICRAF-ISRIC soil spectra (group ``soil``), with two iron indices as
  parameters computed on the measured 10 nm samples: ``fe_band_depth`` (:func:`fe_band_depth`) and
  ``redness_index`` (:func:`redness_index`), and ``site`` (1, 2, … per distinct location in earthlib's
  metadata, shared by the horizons of one profile; 0 = no usable location);
* :func:`npv_library` — the measured litter, bark, wood and other NPV spectra (groups ``npv:litter``,
  ``npv:bark``, ``npv:wood``, ``npv:npv``).

How the spectra reach a grid (the data hold 400–1350, 1460–1790 and 1960–2450 nm at 10 nm):

* inside 400–2450 nm, linear interpolation between the measured samples;
* across the two water-vapour gaps (:data:`WATER_GAPS_NM`, where earthlib has no data) the same linear
  interpolation between the samples either side FILLS the grid: such values are not measured. The library's
  ``source`` says so with the number of filled grid points, and :func:`filled_mask` names them. Of
  Sentinel-2's bands only B10 (1375 nm, cirrus) lies inside a gap;
* a grid reaching below 400 or above 2450 nm is refused (:class:`InputError`): s2cl does not extrapolate.
  A scene using these libraries sets ``[grid] stop_nm = 2450`` (B12 at 2190/180 nm stays inside).
"""

from __future__ import annotations

import importlib.resources
import logging
from functools import cache
from pathlib import Path

import numpy as np

from s2cl.errors import InputError
from s2cl.grid import SpectralGrid
from s2cl.libraries.library import SpectralLibrary
from s2cl.libraries.npz import LibraryFile, read_library_file

LOG = logging.getLogger("s2cl.libraries")
DATA_FILE = "earthlib_soils_npv.npz"
EARTHLIB_VERSION = "1.1.0"
EARTHLIB_URL = "https://github.com/earth-chris/earthlib"
CITATION = (
    "Anderson, C. (2023) earthlib: a global spectral library for satellite land cover mapping, "
    f"version {EARTHLIB_VERSION}, {EARTHLIB_URL} (MIT licence); soils from the ICRAF-ISRIC soil spectral library "
    "(World Agroforestry Centre (ICRAF) and ISRIC - World Soil Information), as earthlib's metadata names them"
)
SOIL_SOURCE = "icraf-isric-soil-database"
SOIL_GROUP = "soil"
NPV_GROUP_PREFIX = "npv:"
#: wavelengths (nm) the data measure, end to end
MEASURED_RANGE_NM = (400.0, 2450.0)
#: open intervals (nm) between measured samples where earthlib left the water-vapour bands out
WATER_GAPS_NM = ((1350.0, 1460.0), (1790.0, 1960.0))
#: Fe3+ crystal-field band (Hunt 1977; hematite ~860-880 nm, goethite ~900-930 nm): continuum shoulders (nm)
FE_SHOULDERS_NM = (760.0, 1000.0)
#: Landsat TM blue, green, red band ranges (nm) of the redness index (Mathieu et al. 1998)
REDNESS_BANDS_NM = ((450.0, 520.0), (520.0, 600.0), (630.0, 690.0))


def data_path() -> Path:
    """Path of the shipped earthlib data file (inside the installed package)."""
    return Path(str(importlib.resources.files("s2cl") / "data" / DATA_FILE))


@cache
def _file() -> LibraryFile:
    return read_library_file(data_path())


def provenance() -> dict:
    """Metadata of the shipped file: source, citation, licence, wheel sha256, selection."""
    return dict(_file().metadata)


def fe_band_depth(wavelength_nm: np.ndarray, spectra: np.ndarray) -> np.ndarray:
    """Depth of the Fe3+ crystal-field band near 900 nm by continuum removal, one value per spectrum (float64).

    The continuum is the straight line through the reflectance at the shoulders :data:`FE_SHOULDERS_NM`
    (linearly interpolated there); the band depth is ``max(1 - R/Rc)`` over the samples strictly between them
    (Clark & Roush 1984, J. Geophys. Res. 89:6329, band depth of a continuum-removed spectrum). Larger =
    more ferric iron (hematite, goethite); 0 or below = no band.

    :param wavelength_nm: increasing wavelengths (nm) of the columns of ``spectra``; must cover the shoulders.
    :param spectra: reflectance, ``(n, m)`` or ``(m,)``.
    """
    w = np.asarray(wavelength_nm, dtype=np.float64)
    r = np.atleast_2d(np.asarray(spectra, dtype=np.float64))
    lo, hi = FE_SHOULDERS_NM
    if w[0] > lo or w[-1] < hi:
        raise InputError(f"the Fe band depth needs {lo:g}–{hi:g} nm, the wavelengths cover {w[0]:g}–{w[-1]:g} nm")
    r_lo = np.array([np.interp(lo, w, row) for row in r])
    r_hi = np.array([np.interp(hi, w, row) for row in r])
    inside = (w > lo) & (w < hi)
    frac = (w[inside] - lo) / (hi - lo)
    continuum = r_lo[:, None] + (r_hi - r_lo)[:, None] * frac[None, :]
    return np.max(1.0 - r[:, inside] / continuum, axis=1)


def redness_index(wavelength_nm: np.ndarray, spectra: np.ndarray) -> np.ndarray:
    """Soil redness index ``RI = R² / (B · G³)`` of band-mean reflectances (Mathieu, Pouget, Cervelle &
    Escadafal 1998, Remote Sens. Environ. 66:17-28), bands :data:`REDNESS_BANDS_NM`; float64 per spectrum."""
    w = np.asarray(wavelength_nm, dtype=np.float64)
    r = np.atleast_2d(np.asarray(spectra, dtype=np.float64))
    means = []
    for lo, hi in REDNESS_BANDS_NM:
        cols = (w >= lo) & (w <= hi)
        if not cols.any():
            raise InputError(f"the redness index needs samples in {lo:g}–{hi:g} nm")
        means.append(r[:, cols].mean(axis=1))
    blue, green, red = means
    return red**2 / (blue * green**3)


def filled_mask(grid: SpectralGrid) -> np.ndarray:
    """True at the grid wavelengths inside a water-vapour gap (values filled by interpolation, not measured)."""
    w = grid.wavelengths
    return np.any([(w > a) & (w < b) for a, b in WATER_GAPS_NM], axis=0)


def _check_grid(grid: SpectralGrid, name: str) -> None:
    lo, hi = MEASURED_RANGE_NM
    if grid.start_nm < lo - 1e-9 or grid.stop_nm > hi + 1e-9:
        raise InputError(
            f"library {name} is measured over {lo:g}–{hi:g} nm but the grid is {grid.describe()}; s2cl does not "
            f"extrapolate: set grid.start_nm >= {lo:g} and grid.stop_nm <= {hi:g}", key="grid")


def _load(grid: SpectralGrid, name: str, rows: list[int]) -> SpectralLibrary:
    _check_grid(grid, name)
    f = _file()
    lib = f.to_library(grid, rows)
    filled = int(filled_mask(grid).sum())
    note = (f"; {filled} grid wavelengths inside the unmeasured water-vapour bands "
            f"{', '.join(f'{a:g}-{b:g}' for a, b in WATER_GAPS_NM)} nm are linearly interpolated, not measured"
            if filled else "")
    lib.source = f"{name}: {f.metadata['source']}; {CITATION}{note}"
    if filled:
        LOG.info("%s: %d grid wavelengths filled by linear interpolation across water-vapour gaps", name, filled)
    return lib


@cache
def _soil_rows() -> tuple[int, ...]:
    return tuple(i for i, g in enumerate(_file().groups) if g == SOIL_GROUP)


@cache
def soil_indices() -> dict[str, np.ndarray]:
    """``fe_band_depth`` and ``redness_index`` of every shipped soil, on the measured samples (float64)."""
    f = _file()
    rows = list(_soil_rows())
    return {"fe_band_depth": fe_band_depth(f.wavelength_nm, f.spectra[rows]),
            "redness_index": redness_index(f.wavelength_nm, f.spectra[rows])}


def soil_library(grid: SpectralGrid) -> SpectralLibrary:
    """The 4,168 ICRAF-ISRIC soils on ``grid`` (inside 400–2450 nm); names are the ICRAF sample ids, params
    ``fe_band_depth`` and ``redness_index`` (unitless, from the measured samples) and ``site``."""
    lib = _load(grid, "earthlib-soils", list(_soil_rows()))
    lib.params = {**{k: v.copy() for k, v in soil_indices().items()}, "site": lib.params["site"]}
    return lib


def npv_library(grid: SpectralGrid) -> SpectralLibrary:
    """The measured non-photosynthetic vegetation (litter, bark, wood, npv) on ``grid`` (inside 400–2450 nm)."""
    rows = [i for i, g in enumerate(_file().groups) if g.startswith(NPV_GROUP_PREFIX)]
    lib = _load(grid, "earthlib-npv", rows)
    lib.params = {}
    return lib


def is_soil(name: str) -> bool:
    """Whether ``name`` is the ICRAF sample id of a shipped soil."""
    return name in _soil_names()


@cache
def _soil_names() -> frozenset[str]:
    f = _file()
    return frozenset(f.names[i] for i in _soil_rows())


def soil_spectrum(name: str, grid: SpectralGrid) -> np.ndarray:
    """One soil by its ICRAF sample id (e.g. ``FS15R_FS4275``), on ``grid`` (float64)."""
    f = _file()
    rows = [i for i in _soil_rows() if f.names[i] == name]
    if not rows:
        raise InputError(f"unknown earthlib soil {name!r} (names are ICRAF sample ids such as "
                         f"{f.names[_soil_rows()[0]]!r})", key="background")
    return _load(grid, "earthlib-soils", rows).spectra[0]
