"""One entry point for every spectral library: ``load_library("builtin:lib1", grid)`` or a file path.

Builtin names are listed by :func:`available_libraries`; a path ending in ``.csv`` is read by
:func:`s2cl.libraries.files.load_csv_library`, one ending in ``.sli`` or ``.hdr`` by
:func:`s2cl.libraries.files.load_envi_library`, one ending in ``.npz`` (s2cl's own library file) by
:func:`s2cl.libraries.npz.load_npz_library`. Each carries its per-spectrum parameters
(:mod:`s2cl.libraries.params`). A relative path is resolved against the directory of ``source`` (the scene
file that named it) when one is given.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from s2cl.errors import InputError, token
from s2cl.grid import SpectralGrid
from s2cl.io.budget import Budget
from s2cl.io.inputs import input_file, parse_number
from s2cl.libraries.earthlib_spectra import npv_library, soil_library
from s2cl.libraries.files import load_csv_library, load_envi_library
from s2cl.libraries.library import DEFAULT_FLAT_VALUES, Quantity, SpectralLibrary, flat_targets
from s2cl.libraries.minerals import iron_backgrounds, mineral_library, mineral_library_swir
from s2cl.libraries.npz import load_npz_library
from s2cl.libraries.vegetation import load_vegetation

BUILTIN_PREFIX = "builtin:"

_BUILTINS: dict[str, tuple[str, Callable[[SpectralGrid], SpectralLibrary]]] = {
    "flat": (
        "flat reflectance targets 0.1 and 0.2 (builtin:flat:V1,V2,... for other values in [0, 1])",
        lambda grid: flat_targets(grid, DEFAULT_FLAT_VALUES),
    ),
    "lib1": (
        "PROSAIL Lib1: Cab 5-100 ug/cm2 step 5, LAI 3 and 4, over 3 iron-bearing backgrounds (120 spectra)",
        lambda grid: load_vegetation("lib1", grid),
    ),
    "lib2": (
        "PROSAIL Lib2: Cab 5-100 ug/cm2 step 5, LAI 0.5, 1 and 2, over 3 iron-bearing backgrounds (180 spectra)",
        lambda grid: load_vegetation("lib2", grid),
    ),
    "leaf-water": (
        "PROSAIL leaf water: EWT 100-500 um step 10, LAI 3 and 4, Cab 40, over 3 iron-bearing backgrounds (246)",
        lambda grid: load_vegetation("leaf-water", grid),
    ),
    "minerals": (
        "USGS splib07 Al-OH and Mg-OH/C-O minerals measured over all of 400-2500 nm",
        mineral_library,
    ),
    "minerals-swir": (
        "USGS splib07 Al-OH and Mg-OH/C-O minerals incl. SWIR-only spectra; grid must lie inside 1500-2500 nm",
        mineral_library_swir,
    ),
    "iron-backgrounds": (
        "USGS splib07 iron-bearing spectra used as PROSAIL backgrounds (stand-ins for goethite/hematite)",
        iron_backgrounds,
    ),
    "earthlib-soils": (
        "earthlib 1.1.0: 4168 measured ICRAF-ISRIC soils, params fe_band_depth, redness_index, site; grid inside "
        "400-2450 nm (water-vapour bands interpolated)",
        soil_library,
    ),
    "earthlib-npv": (
        "earthlib 1.1.0: 104 measured litter, bark, wood (non-photosynthetic vegetation); grid inside 400-2450 nm "
        "(water-vapour bands interpolated)",
        npv_library,
    ),
}


def available_libraries() -> dict[str, str]:
    """Builtin library names (use as ``builtin:NAME``) with a one-line description each."""
    return {name: desc for name, (desc, _) in _BUILTINS.items()}


def load_library(
    spec: str, grid: SpectralGrid, *, source: str | Path | None = None, key: str = "library",
    quantity: Quantity = "reflectance", base_dir: str | Path | None = None, budget: Budget | None = None,
) -> SpectralLibrary:
    """Load the library named by ``spec`` onto ``grid``.

    :param spec: ``builtin:NAME`` (see :func:`available_libraries`), ``builtin:flat:0.05,0.3``,
        or a path to a ``.csv`` / ``.sli`` / ``.hdr`` / ``.npz`` file.
    :param source: the file ``spec`` came from (a scene), used in error messages (a file that is missing,
        or not a regular file, is reported as ``source: key``) and to resolve relative paths.
    :param key: the key inside ``source`` that held ``spec``.
    :param base_dir: the folder relative paths are resolved against (default: the folder of ``source``,
        else the working folder); a scene passes its own (:attr:`s2cl.scene.scene.Scene.base_dir`).
    :param quantity: what a CSV or ENVI file holds (``surface.quantity``); built-in libraries are reflectance,
        an ``.npz`` file says what it holds (its metadata).
    :param budget: the memory a file may take once read onto ``grid``, sized from its metadata (header line,
        file size, ENVI header) before it is read; default :meth:`Budget.of`.
    :raises InputError: unknown builtin (the message lists the available ones), unknown file type,
        or any problem of the file itself.
    """
    text = str(spec).strip()
    if text.startswith(BUILTIN_PREFIX):
        return _load_builtin(text[len(BUILTIN_PREFIX) :], grid, source=source, key=key)
    path = Path(text).expanduser()
    if not path.is_absolute():
        if base_dir is not None:
            path = Path(base_dir) / path
        elif source is not None:
            path = Path(source).parent / path
    suffix = path.suffix.lower()
    if suffix in {".csv", ".sli", ".hdr", ".npz"}:
        input_file(path, what="spectral library file", source=source, key=key)
        if suffix == ".csv":
            return load_csv_library(path, grid, quantity=quantity, budget=budget)
        if suffix == ".npz":
            return load_npz_library(path, grid, budget=budget)
        return load_envi_library(path, grid, quantity=quantity, budget=budget)
    raise InputError(
        f"{token(text)} is neither builtin:NAME ({', '.join(_BUILTINS)}) nor a .csv/.sli/.hdr/.npz file",
        source=source,
        key=key,
    )


def _load_builtin(name: str, grid: SpectralGrid, *, source: str | Path | None, key: str) -> SpectralLibrary:
    name = name.strip().lower()
    if name.startswith("flat:"):
        try:
            values = [parse_number(v.strip()) for v in name[len("flat:") :].split(",") if v.strip()]
        except ValueError as err:
            raise InputError(f"builtin:{name}: flat values must be numbers, e.g. builtin:flat:0.05,0.3",
                             source=source, key=key) from err  # fmt: skip
        try:
            return flat_targets(grid, values)
        except InputError as err:
            raise InputError(f"builtin:flat: {err.detail}, e.g. builtin:flat:0.05,0.3", source=source,
                             key=key) from None
    if name not in _BUILTINS:
        listing = "; ".join(f"{n} ({d})" for n, (d, _) in _BUILTINS.items())
        raise InputError(f"unknown builtin library {token(name)}; available: {listing}", source=source, key=key)
    return _BUILTINS[name][1](grid)
