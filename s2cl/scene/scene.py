"""Scenes: TOML files that say what to simulate and which effects run.

A scene names its surface (a spectral library or an image cube), its sensor, the spectral grid,
the effects of the chain (each can be switched off, and then costs nothing: it is not in the
compiled kernel), and where the output goes. ``scenes/default.toml`` documents every key.
Paths inside a scene are relative to the scene file. Unknown keys, wrong types and values out of
range are errors that name the file, the key and the allowed range.
"""

from __future__ import annotations

import logging
import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from s2cl.errors import InputError, token
from s2cl.grid import SpectralGrid
from s2cl.io.inputs import input_file
from s2cl.libraries.fields import fields_shape, is_builtin_cube
from s2cl.resources import scene_dir
from s2cl.scene.config import RunConfig, resolve_run
from s2cl.scene.effects import EffectSet
from s2cl.scene.instrument_schema import check_image_effects, moved_effects
from s2cl.scene.schema import GridSpec, SceneSpec
from s2cl.scene.schema_errors import input_error
from s2cl.sensor.sensor import Sensor
from s2cl.sensor.srf import load_srf_csv, measured_sentinel2_srf

_log = logging.getLogger(__name__)

#: largest scene file read (bytes): scenes are a few kB; this refuses a wrong file before parsing it
MAX_SCENE_BYTES = 1_000_000

@dataclass(frozen=True, eq=False)
class Scene:
    """A validated scene, ready to simulate."""

    spec: SceneSpec
    path: Path | None
    grid: SpectralGrid
    sensor: Sensor
    effects: EffectSet
    run: RunConfig
    base_dir: Path = field(default_factory=Path.cwd)

    @property
    def name(self) -> str:
        return self.spec.scene.name

    @property
    def source(self) -> str:
        return str(self.path) if self.path else f"scene {self.name!r}"

    @property
    def portable_source(self) -> str:
        """The scene as a result file should name it, without this machine's folders: ``scenes/NAME.toml``
        for a built-in scene, the path relative to the working folder where it lies below it, else the
        file's name."""
        if not self.path:
            return self.source
        path = self.path.resolve()
        for base, prefix in ((scene_dir().resolve(), "scenes"), (Path.cwd().resolve(), "")):
            if path.is_relative_to(base):
                return str(Path(prefix) / path.relative_to(base)) if prefix else str(path.relative_to(base))
        return path.name

    @property
    def output_dir(self) -> Path:
        d = self.spec.output.directory
        return self.resolve(d) if d else Path("s2cl-out") / self.name

    def resolve(self, relative: str) -> Path:
        """A path from the scene, relative to the scene file's folder."""
        p = Path(relative).expanduser()
        return p if p.is_absolute() else self.base_dir / p

    @classmethod
    def load(cls, scene: str | Path) -> Scene:
        """Load a scene file, or a built-in scene by name (``default``; see :func:`builtin_scenes`)."""
        path = find_scene(scene)
        return cls.from_dict(read_toml(path), path=path)

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, path: Path | None = None, base_dir: Path | None = None) -> Scene:
        """Validate a scene given as a dict (the parsed TOML)."""
        source = str(path) if path else "scene"
        try:
            spec = SceneSpec.model_validate(data)
        except ValidationError as err:
            raise input_error(err, source) from None
        spec = _moved_keys(spec, source)
        base = base_dir or (path.parent if path else Path.cwd())
        grid = _grid(spec.grid, source)
        sensor = _sensor(spec, base, source)
        effects = _effects(spec, source)
        _check_surface(spec, source)
        check_image_effects(spec.effects, sensor.band_names, resample=effects.resample, source=source)
        _check_atmosphere(spec, source)
        if effects.resample:
            for band in sensor.bands:
                band.weights(grid, spec.sensor.support, source)
        run = resolve_run(spec, effects, source)
        return cls(spec=spec, path=path, grid=grid, sensor=sensor, effects=effects, run=run, base_dir=base)


def read_toml(path: Path) -> dict[str, Any]:
    """A scene file's TOML as a dict; every failure (not a regular file, too large, not UTF-8, not TOML,
    nested too deeply) is an :class:`InputError` naming the file."""
    try:
        if not path.is_file():
            raise InputError("is not a regular file", source=path)
        if path.stat().st_size > MAX_SCENE_BYTES:
            raise InputError(f"is larger than {MAX_SCENE_BYTES:,} bytes: not a scene file", source=path)
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"not valid TOML: {err}", source=path) from None
    except RecursionError:
        raise InputError("not a usable scene: arrays or tables nested too deeply", source=path) from None
    except UnicodeDecodeError:
        raise InputError("cannot read scene: not UTF-8 text", source=path) from None
    except OSError as err:
        raise InputError(f"cannot read scene ({err.strerror or type(err).__name__})", source=path) from None


def builtin_scenes() -> dict[str, Path]:
    """Built-in scenes by name."""
    return {p.stem: p for p in sorted(scene_dir().glob("*.toml"))}


def find_scene(scene: str | Path) -> Path:
    """A scene file path, or the built-in scene of that name."""
    p = Path(scene)
    if p.suffix == ".toml" or p.exists():
        return input_file(p, what="scene file")
    builtins = builtin_scenes()
    if str(scene) in builtins:
        return builtins[str(scene)]
    raise InputError(
        f"no scene file {str(scene)!r} and no built-in scene of that name; built-in: {', '.join(builtins)}"
    )


def _grid(g: GridSpec, source: str) -> SpectralGrid:
    try:
        return SpectralGrid(g.start_nm, g.stop_nm, g.step_nm)
    except InputError as err:
        raise InputError(str(err), source=source) from None


def _sensor(spec: SceneSpec, base: Path, source: str) -> Sensor:
    s = spec.sensor
    if s.file:
        sensor = Sensor.from_csv(input_file(_relative(base, s.file), what="sensor table", source=source,
                                            key="sensor.file"))
    else:
        sensor = Sensor.sentinel2()
    if s.bands:
        seen = [b.lower() for b in s.bands]
        twice = sorted({b for b in s.bands if seen.count(b.lower()) > 1})
        if twice:
            raise InputError(f"lists band(s) {', '.join(map(token, twice))} more than once", source=source,
                             key="sensor.bands")
        unknown = [b for b in s.bands if b.lower() not in {n.lower() for n in sensor.band_names}]
        if unknown:
            raise InputError(
                f"unknown band(s) {', '.join(map(token, unknown))}; the sensor has {', '.join(sensor.band_names)}",
                source=source, key="sensor.bands",
            )
        sensor = sensor.select(s.bands)
    if spec.effects.bits is not None:
        sensor = sensor.with_bits(spec.effects.bits)
    return _with_srf(sensor, s.srf, base, source)


def _with_srf(sensor: Sensor, srf: str, base: Path, source: str) -> Sensor:
    if srf == "model":
        return sensor
    if srf.startswith("measured-"):
        platform = srf.split("-", 1)[1]
        bands = tuple(replace(b, tabulated=measured_sentinel2_srf(platform, b.name)) for b in sensor.bands)
        return replace(sensor, bands=bands)
    if srf.startswith("table:"):
        path = input_file(_relative(base, srf.split(":", 1)[1]), what="SRF table", source=source, key="sensor.srf")
        table = load_srf_csv(str(path))
        missing = [b.name for b in sensor.bands if b.name not in table]
        if missing:
            raise InputError(f"SRF table lacks band(s) {', '.join(missing)}", source=source, key="sensor.srf")
        return replace(sensor, bands=tuple(replace(b, tabulated=table[b.name]) for b in sensor.bands))
    raise InputError(
        f"unknown SRF {srf!r}; allowed: 'model', 'measured-S2A', 'measured-S2B', 'table:FILE.csv'",
        source=source, key="sensor.srf",
    )


def _effects(spec: SceneSpec, source: str) -> EffectSet:
    e = spec.effects
    effects = EffectSet.of(e).validate(source)
    if e.atmosphere and spec.surface.quantity != "reflectance":
        raise InputError("atmosphere = true needs surface.quantity = 'reflectance'", source=source,
                         key="effects.atmosphere")
    if not e.atmosphere and spec.surface.quantity == "reflectance":
        raise InputError(
            "surface.quantity = 'reflectance' needs effects.atmosphere = true (the sensor sees TOA radiance)",
            source=source, key="surface.quantity",
        )
    return effects


def _moved_keys(spec: SceneSpec, source: str) -> SceneSpec:
    """The deprecated [instrument] and [spatial] keys moved into [effects], one WARNING line per key given."""
    if spec.instrument is None and spec.spatial is None:
        return spec
    try:
        moved, notes = moved_effects(spec.instrument, spec.spatial)
    except ValueError as err:
        raise InputError(str(err), source=source, key="spatial.psf") from None
    for name in moved:
        if name in spec.effects.model_fields_set:
            raise InputError(f"effects.{name} and the deprecated [instrument] or [spatial] keys both set it: keep "
                             f"effects.{name} only", source=source, key=f"effects.{name}")
    for note in notes:
        _log.warning("%s: %s", source, note)
    return spec.model_copy(update={"effects": spec.effects.model_copy(update=moved), "instrument": None,
                                   "spatial": None})


def _check_surface(spec: SceneSpec, source: str) -> None:
    s = spec.surface
    if (s.library is None) == (s.cube is None):
        raise InputError("give exactly one of surface.library or surface.cube", source=source, key="surface")
    if s.layout == "blocks" and math.isqrt(s.copies) ** 2 != s.copies:
        root = math.isqrt(s.copies)
        raise InputError(f"layout 'blocks' lays each spectrum's copies out as a square tile: copies must be a square "
                         f"number (such as {root * root} or {(root + 1) ** 2}), got {s.copies}", source=source,
                         key="surface.copies")
    if s.cube is not None and s.select:
        raise InputError("surface.select picks library spectra by parameter; an image cube has none",
                         source=source, key="surface.select")
    if s.cube is not None and is_builtin_cube(s.cube):
        fields_shape(s.cube, source=source)
    if s.cube is not None and is_builtin_cube(s.cube) and s.gsd_m is None:
        raise InputError("an image cube needs surface.gsd_m (its ground sampling distance in m)",
                         source=source, key="surface.gsd_m")


def _check_atmosphere(spec: SceneSpec, source: str) -> None:
    for section in ("atmosphere", "correction"):
        a = getattr(spec, section)
        if a.aot550 is not None and a.visibility_km is not None:
            raise InputError("give aot550 or visibility_km, not both", source=source, key=f"{section}.aot550")


def _relative(base: Path, name: str) -> Path:
    p = Path(name).expanduser()
    return p if p.is_absolute() else base / p


