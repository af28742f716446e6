"""PROSAIL vegetation libraries (PROSPECT-D + 4SAIL through the PyPI package ``prosail``).

The paper's libraries (Segl et al. 2012, sections 4.1 and 4.2.1):

* **Lib1** — chlorophyll a+b 5–100 µg/cm² step 5 at LAI 3 and 4 (dense canopies);
* **Lib2** — the same chlorophyll at LAI 0.5, 1 and 2 (sparse canopies);
* **leaf-water** — equivalent water thickness 100–500 µm step 10 at LAI 3 and 4;

each over the measured iron-bearing USGS backgrounds of :mod:`s2cl.libraries.minerals` (stand-ins for
the paper's goethite/hematite). A spec may name measured soils of :mod:`s2cl.libraries.earthlib_spectra`
instead (``earthlib:<ICRAF id>``): those are measured to 2450 nm only, so such a library covers
400–2450 nm (PROSAIL is run per wavelength; the soil value held from 2450 to 2500 nm to fill PROSAIL's fixed
axis reaches no kept wavelength, the canopy spectra are cut at 2450 nm).
The three default libraries ship as package data (``s2cl/data/prosail_*.npz``, float32) so a simulation
needs neither prosail nor numba.
Any other :class:`VegetationSpec` is generated with prosail (``pip install "s2cl[prosail]"``)
and cached under :func:`s2cl.io.cache.cache_dir` keyed by spec, backgrounds and prosail version.

Per-spectrum metadata: ``params["cab"]`` (µg/cm²), ``params["lai"]`` (m²/m²),
``params["ewt"]`` (µm), and the background key in ``groups``.
"""

from __future__ import annotations

import importlib.metadata
import importlib.resources
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.errors import DependencyError, InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.io.cache import cache_dir, digest
from s2cl.libraries import earthlib_spectra
from s2cl.libraries.library import SpectralLibrary
from s2cl.libraries.minerals import BACKGROUND_KEYS, iron_backgrounds
from s2cl.libraries.npz import LibraryFile, read_library_file, write_library_file

#: PROSAIL's fixed spectral axis: 400–2500 nm at 1 nm.
PROSAIL_GRID = SpectralGrid(400.0, 2500.0, 1.0)
PROSAIL_HINT = 'PROSAIL libraries other than the shipped ones need prosail: pip install "s2cl[prosail]"'
DEFAULT_BACKGROUNDS = ("jarosite-muscovite", "siderite", "chlorite")
#: background key prefix of a measured earthlib soil: ``earthlib:FS15R_FS4275``
EARTHLIB_PREFIX = "earthlib:"
CACHE_FORMAT = 1


@dataclass(frozen=True)
class ProsailConstants:
    """PROSAIL inputs held fixed in a library ("representative mean values", paper sec. 4.1/4.2.1).

    Leaf (PROSPECT-D): ``n`` structure parameter; ``car`` carotenoids µg/cm²; ``cbrown`` brown
    pigments (0 = green leaves); ``cm`` dry matter g/cm²; ``ant`` anthocyanins µg/cm².
    The nominal leaf values N = 1.5, Car = 8, Cbrown = 0, Cm = 0.009 are those of the PROSAIL
    review (Jacquemoud et al. 2009, Remote Sens. Environ. 113:S56–S66) and of the prosail
    package's examples; Ant = 0 is prosail's default (mature green leaves, Féret et al. 2017).
    Canopy (4SAIL): spherical leaf inclination (``typelidf`` 1, a = −0.35, b = −0.15, Verhoef
    1998), hot-spot 0.01. Geometry: sun zenith 40°, nadir view, relative azimuth 0°.
    ``factor`` ``"SDR"`` is the sun-canopy-sensor (bidirectional) reflectance factor.
    """

    n: float = 1.5
    car: float = 8.0
    cbrown: float = 0.0
    cm: float = 0.009
    ant: float = 0.0
    typelidf: int = 1
    lidfa: float = -0.35
    lidfb: float = -0.15
    hspot: float = 0.01
    sza: float = 40.0
    vza: float = 0.0
    raa: float = 0.0
    prospect_version: str = "D"
    factor: str = "SDR"

    def validate(self, *, source: str | None = None, key: str = "prosail.constants") -> None:
        """Raise :class:`InputError` for a value prosail would reject or misread."""
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("prospect_version", "factor", "typelidf"):
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
                raise InputError(f"must be a finite number, got {value!r}", source=source, key=f"{key}.{f.name}")
        checks = {
            "prospect_version": (self.prospect_version in ("D", "5"), "'D' or '5'"),
            "factor": (self.factor in ("SDR", "BHR", "DHR", "HDR"), "one of SDR, BHR, DHR, HDR"),
            "typelidf": (self.typelidf in (1, 2), "1 (Verhoef bimodal) or 2 (ellipsoidal)"),
            "n": (1.0 <= self.n <= 3.5, "in [1, 3.5]"),
            "sza": (0.0 <= self.sza < 90.0, "in [0, 90) degrees"),
            "vza": (0.0 <= self.vza < 90.0, "in [0, 90) degrees"),
        }
        for name, (ok, allowed) in checks.items():
            if not ok:
                raise InputError(f"must be {allowed}, got {getattr(self, name)!r}", source=source, key=f"{key}.{name}")
        for name in ("car", "cbrown", "cm", "ant", "hspot"):
            if getattr(self, name) < 0:
                raise InputError(f"must be >= 0, got {getattr(self, name)}", source=source, key=f"{key}.{name}")


# Allowed ranges (inclusive) for the varied parameters: PROSPECT/SAIL validity, not guesses of use.
RANGES = {"cab": (0.0, 300.0), "lai": (0.0, 15.0), "ewt": (1.0, 2000.0)}


def _steps(lo: float, hi: float, step: float) -> tuple[float, ...]:
    n = round((hi - lo) / step)
    return tuple(round(lo + i * step, 9) for i in range(n + 1))


@dataclass(frozen=True)
class VegetationSpec:
    """A PROSAIL library: the full grid ``backgrounds × lai × ewt × cab`` (cab varies fastest).

    :param cab: leaf chlorophyll a+b values, µg/cm².
    :param lai: leaf area index values, m²/m².
    :param ewt: leaf equivalent water thickness values, µm (prosail's ``cw`` is in cm = µm·1e-4).
    :param backgrounds: keys of :data:`s2cl.libraries.minerals.BACKGROUND_KEYS` values, or
        ``earthlib:<ICRAF sample id>`` (a measured soil of :func:`s2cl.libraries.earthlib_spectra.soil_library`).
    """

    name: str
    cab: tuple[float, ...]
    lai: tuple[float, ...]
    ewt: tuple[float, ...] = (100.0,)
    backgrounds: tuple[str, ...] = DEFAULT_BACKGROUNDS
    constants: ProsailConstants = field(default_factory=ProsailConstants)

    @property
    def size(self) -> int:
        return len(self.cab) * len(self.lai) * len(self.ewt) * len(self.backgrounds)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        for key in ("cab", "lai", "ewt", "backgrounds"):
            d[key] = list(d[key])
        return d

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str | None = None, key: str = "prosail") -> VegetationSpec:
        """Build and validate a spec from a TOML/JSON-like mapping; errors name ``source`` and key."""
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise InputError(f"unknown keys {sorted(unknown)}; allowed: {sorted(known)}", source=source, key=key)
        args: dict[str, Any] = {"name": str(data.get("name", "custom"))}
        for pname in ("cab", "lai", "ewt"):
            if pname in data:
                args[pname] = _values(data[pname], pname, source=source, key=f"{key}.{pname}")
        if "backgrounds" in data:
            args["backgrounds"] = tuple(str(b) for b in data["backgrounds"])
        if "constants" in data:
            cnames = {f.name for f in fields(ProsailConstants)}
            bad = set(data["constants"]) - cnames
            if bad:
                raise InputError(f"unknown keys {sorted(bad)}; allowed: {sorted(cnames)}", source=source, key=key)
            args["constants"] = ProsailConstants(**data["constants"])
            args["constants"].validate(source=source, key=f"{key}.constants")
        if "cab" not in args or "lai" not in args:
            raise InputError("needs at least 'cab' and 'lai' value lists", source=source, key=key)
        spec = cls(**args)
        spec.validate(source=source, key=key)
        return spec

    def validate(self, *, source: str | None = None, key: str = "prosail") -> None:
        """Raise :class:`InputError` for values outside :data:`RANGES`, bad constants or unknown backgrounds."""
        self.constants.validate(source=source, key=f"{key}.constants")
        for pname, (lo, hi) in RANGES.items():
            vals = np.asarray(getattr(self, pname), dtype=np.float64)
            if vals.size == 0 or not np.all(np.isfinite(vals)) or vals.min() < lo or vals.max() > hi:
                raise InputError(
                    f"values must lie in [{lo:g}, {hi:g}], got {list(vals)}", source=source, key=f"{key}.{pname}"
                )
        allowed = sorted(BACKGROUND_KEYS.values())
        for bg in self.backgrounds:
            if bg.startswith(EARTHLIB_PREFIX):
                if not earthlib_spectra.is_soil(bg[len(EARTHLIB_PREFIX):]):
                    raise InputError(f"unknown earthlib soil {bg!r}; names are ICRAF sample ids of "
                                     "builtin:earthlib-soils, e.g. 'earthlib:FS15R_FS4275'", source=source,
                                     key=f"{key}.backgrounds")
            elif bg not in allowed:
                raise InputError(
                    f"unknown background {bg!r}; available: {', '.join(allowed)} or earthlib:<ICRAF soil id>",
                    source=source,
                    key=f"{key}.backgrounds",
                )

    @property
    def grid(self) -> SpectralGrid:
        """The library's own axis: :data:`PROSAIL_GRID`, cut at 2450 nm when a background is an earthlib soil."""
        if any(bg.startswith(EARTHLIB_PREFIX) for bg in self.backgrounds):
            return SpectralGrid(PROSAIL_GRID.start_nm, earthlib_spectra.MEASURED_RANGE_NM[1], PROSAIL_GRID.step_nm)
        return PROSAIL_GRID


def _values(raw: Any, pname: str, *, source: str | None, key: str) -> tuple[float, ...]:
    """A value list, or ``{start, stop, step}`` (inclusive) expanded."""
    if isinstance(raw, dict):
        try:
            return _steps(float(raw["start"]), float(raw["stop"]), float(raw["step"]))
        except (KeyError, TypeError, ValueError) as err:
            raise InputError("needs numeric start, stop, step", source=source, key=key) from err
    try:
        return tuple(float(v) for v in (raw if isinstance(raw, (list, tuple)) else [raw]))
    except (TypeError, ValueError) as err:
        raise InputError(f"{pname} values must be numbers", source=source, key=key) from err


CAB_STEPS = _steps(5.0, 100.0, 5.0)
LIB1 = VegetationSpec("lib1", cab=CAB_STEPS, lai=(3.0, 4.0))
LIB2 = VegetationSpec("lib2", cab=CAB_STEPS, lai=(0.5, 1.0, 2.0))
LEAF_WATER = VegetationSpec("leaf-water", cab=(40.0,), lai=(3.0, 4.0), ewt=_steps(100.0, 500.0, 10.0))
SHIPPED = {spec.name: spec for spec in (LIB1, LIB2, LEAF_WATER)}


def shipped_path(name: str) -> Path:
    """Path of the shipped file of library ``name`` (``lib1``, ``lib2``, ``leaf-water``)."""
    return Path(str(importlib.resources.files("s2cl") / "data" / f"prosail_{name.replace('-', '_')}.npz"))


def prosail_version() -> str:
    """Version of the installed prosail package; :class:`DependencyError` when absent."""
    try:
        return importlib.metadata.version("prosail")
    except importlib.metadata.PackageNotFoundError as err:
        raise DependencyError(PROSAIL_HINT) from err


def _run_prosail() -> Any:
    try:
        import prosail
    except ImportError as err:
        raise DependencyError(PROSAIL_HINT) from err
    return prosail.run_prosail


def _background_spectra(keys: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Each background on :data:`PROSAIL_GRID`; an earthlib soil (measured to 2450 nm) holds its 2450 nm value
    beyond, which only reaches canopy wavelengths that :func:`generate` cuts away."""
    bg = iron_backgrounds(PROSAIL_GRID)
    by_key = {BACKGROUND_KEYS[n]: s for n, s in zip(bg.names, bg.spectra, strict=True)}
    out = {}
    for k in keys:
        if k.startswith(EARTHLIB_PREFIX):
            hi = earthlib_spectra.MEASURED_RANGE_NM[1]
            measured = earthlib_spectra.soil_spectrum(k[len(EARTHLIB_PREFIX):], SpectralGrid(400.0, hi, 1.0))
            out[k] = np.concatenate([measured, np.full(PROSAIL_GRID.size - measured.size, measured[-1])])
        else:
            out[k] = by_key[k]
    return out


def simulate(spec: VegetationSpec, *, cab: float, lai: float, ewt: float, background: np.ndarray) -> np.ndarray:
    """One PROSAIL canopy reflectance (float64, 2101 values at 400–2500 nm) for ``spec.constants``."""
    c = spec.constants
    run = _run_prosail()
    rho = run(
        c.n, cab, c.car, c.cbrown, ewt * 1e-4, c.cm, lai, c.lidfa, c.hspot, c.sza, c.vza, c.raa,
        ant=c.ant, prospect_version=c.prospect_version, typelidf=c.typelidf, lidfb=c.lidfb,
        factor=c.factor, rsoil0=np.ascontiguousarray(background, dtype=np.float64),
    )  # fmt: skip
    return np.asarray(rho, dtype=np.float64)


def generate(spec: VegetationSpec) -> SpectralLibrary:
    """Run PROSAIL for every member of ``spec`` on :data:`PROSAIL_GRID` (float64, deterministic)."""
    spec.validate()
    backgrounds = _background_spectra(spec.backgrounds)
    rows, names, groups, params = [], [], [], {"cab": [], "lai": [], "ewt": []}
    for bg in spec.backgrounds:
        for lai in spec.lai:
            for ewt in spec.ewt:
                for cab in spec.cab:
                    rows.append(simulate(spec, cab=cab, lai=lai, ewt=ewt, background=backgrounds[bg]))
                    names.append(f"{spec.name} cab={cab:g} lai={lai:g} ewt={ewt:g} over {bg}")
                    groups.append(bg)
                    for k, v in (("cab", cab), ("lai", lai), ("ewt", ewt)):
                        params[k].append(v)
    spectra = np.asarray(rows)[:, : spec.grid.size]  # spec.grid starts where PROSAIL_GRID does, same step
    if not np.all(np.isfinite(spectra)) or spectra.min() < 0.0 or spectra.max() > 1.0:
        raise InputError(f"PROSAIL produced reflectance outside [0, 1] for library {spec.name}")
    return SpectralLibrary(
        grid=spec.grid,
        spectra=spectra,
        names=names,
        groups=groups,
        params={k: np.asarray(v) for k, v in params.items()},
        source=_source_text(spec, prosail_version()),
    )


def _source_text(spec: VegetationSpec, version: str) -> str:
    over = []
    if any(not bg.startswith(EARTHLIB_PREFIX) for bg in spec.backgrounds):
        over.append("measured USGS splib07 iron-bearing stand-in backgrounds (Kokaly et al. 2017, doi:10.3133/ds1035)")
    if any(bg.startswith(EARTHLIB_PREFIX) for bg in spec.backgrounds):
        over.append(f"measured ICRAF-ISRIC soils from earthlib {earthlib_spectra.EARTHLIB_VERSION} (400-2450 nm)")
    return (f"{spec.name}: PROSAIL (PROSPECT-{spec.constants.prospect_version} + 4SAIL, prosail {version}) over "
            + " and ".join(over))


def cache_key(spec: VegetationSpec, version: str) -> str:
    """Hex key of a generated library: spec, background spectra, prosail version, file format."""
    bgs = _background_spectra(spec.backgrounds)
    return digest({"spec": spec.to_dict(), "prosail": version, "backgrounds": bgs, "format": CACHE_FORMAT})


def write_library(spec: VegetationSpec, lib: SpectralLibrary, path: Path, *, version: str) -> Path:
    """Write a generated library (float32) with its spec, prosail version and cache key."""
    return write_library_file(
        path,
        wavelength_nm=lib.grid.wavelengths,
        spectra=lib.spectra,
        names=lib.names,
        groups=lib.groups,
        params=lib.params,
        metadata={
            "source": lib.source,
            "spec": spec.to_dict(),
            "prosail_version": version,
            "cache_key": cache_key(spec, version),
            "storage": "float32 (max abs rounding error < 3e-8 in reflectance)",
            "param_units": {"cab": "ug/cm2", "lai": "m2/m2", "ewt": "um"},
            "groups": "background key (s2cl.libraries.minerals.BACKGROUND_KEYS, or earthlib:<ICRAF soil id>)",
        },
    )


def _from_file(f: LibraryFile, spec: VegetationSpec, grid: SpectralGrid) -> SpectralLibrary:
    if f.metadata.get("spec") != spec.to_dict():
        raise InputError(
            f"file does not hold library {spec.name} as s2cl defines it (stale data); "
            "regenerate it with tools/make_prosail_libraries.py",
            source=f.path,
        )
    if not spec.grid.covers(grid.start_nm, grid.stop_nm):
        raise InputError(f"PROSAIL library {spec.name} covers {spec.grid.start_nm:g}–{spec.grid.stop_nm:g} nm (its "
                         f"backgrounds are measured there), the grid is {grid.describe()}; set grid.stop_nm <= "
                         f"{spec.grid.stop_nm:g}", key="grid")
    return f.to_library(grid)


def load_vegetation(spec: VegetationSpec | str, grid: SpectralGrid = DEFAULT_GRID) -> SpectralLibrary:
    """A PROSAIL library on ``grid`` (inside 400–2500 nm).

    The shipped libraries (``lib1``, ``lib2``, ``leaf-water``) are read from package data; any
    other spec is read from the user cache or generated with prosail and cached atomically.
    """
    if isinstance(spec, str):
        if spec not in SHIPPED:
            raise InputError(f"unknown PROSAIL library {spec!r}; shipped: {', '.join(SHIPPED)}", key="library")
        spec = SHIPPED[spec]
    if not PROSAIL_GRID.covers(grid.start_nm, grid.stop_nm):
        raise InputError(f"PROSAIL libraries cover 400–2500 nm, the grid is {grid.describe()}", key="grid")
    if SHIPPED.get(spec.name) == spec:
        return _from_file(read_library_file(shipped_path(spec.name)), spec, grid)
    return _from_file(_cached_file(spec), spec, grid)


def library_file(spec: VegetationSpec) -> Path:
    """Path of the s2cl library file (``.npz``) holding ``spec``: the shipped one, else the user-cache entry
    (generated with prosail when missing). A scene can name it: ``[surface] library = "<path>"``."""
    if SHIPPED.get(spec.name) == spec:
        return shipped_path(spec.name)
    return Path(_cached_file(spec).path)


def _cached_file(spec: VegetationSpec) -> LibraryFile:
    spec.validate()
    version = prosail_version()
    key = cache_key(spec, version)
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in spec.name)[:40]
    path = cache_dir("prosail") / f"{safe}-{key[:20]}.npz"
    if path.is_file():
        try:
            f = read_library_file(path)
        except InputError:
            f = None  # unreadable cache entry: regenerate and replace it
        if f is not None and f.metadata.get("cache_key") == key:
            return f
    write_library(spec, generate(spec), path, version=version)
    return read_library_file(path)
