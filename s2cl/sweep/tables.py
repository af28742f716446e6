"""What a sweep computes once: per (band variant, library spectrum) tables.

The sweep is separable (``shared/ARCHITECTURE.md``): resampling is linear and each band depends
only on its own (centre, width). So the spectral integral runs once per band variant and
spectrum, here, in float64; every configuration is then a gather from these tables:

- ``radiance[k][v, s]``: noise-free TOA band radiance of spectrum ``s`` in variant ``v`` of band
  slot ``k`` (W m⁻² sr⁻¹ µm⁻¹), under the true atmosphere;
- ``sigma[k][v, s]``: its noise standard deviation (the band's shot-noise model at that width);
- ``lp, g, s[k][v]``: band-effective correction terms of the atmosphere the correction assumes;
- ``z[k, p]``: the standard normal deviate of pixel ``p`` in slot ``k``, the same for every
  configuration (common random numbers: configurations differ by their bands, not by their
  luck). ``z`` is the sensor-noise stream of s2cl's Philox generator keyed by (seed, pixel, the
  slot's band index in the sensor): the deviate ``s2cl simulate`` adds to that band.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from s2cl.atmos.correction import BandAtmosphere
from s2cl.errors import InputError
from s2cl.forward.noise import sensor_noise
from s2cl.forward.resample import AtmosphereArrays
from s2cl.libraries.library import SpectralLibrary
from s2cl.scene.scene import Scene
from s2cl.sensor.noise_model import noise_sigma
from s2cl.sensor.sensor import Band
from s2cl.sensor.variants import TABLE2, BandGrid, BandRange, SweepSpace


def sweep_space(scene: Scene) -> SweepSpace:
    """The scene's [sweep] section as a :class:`SweepSpace` (bands checked against the sensor)."""
    spec = scene.spec.sweep
    if spec is None:
        raise InputError("the scene has no [sweep] section", source=scene.source, key="sweep")
    ranges = []
    for name in spec.bands:
        band = _sensor_band(scene, name, "sweep.bands")
        r = spec.ranges.get(name) or spec.ranges.get(band.name)
        if r is None:
            if spec.preset == "table2" and band.name in TABLE2:
                ranges.append(BandRange(band.name, *map(float, TABLE2[band.name]), step_nm=spec.step_nm))
                continue
            raise InputError(f"no range for band {name}: give [sweep.ranges.{name}] or preset = 'table2'",
                             source=scene.source, key=f"sweep.ranges.{name}")
        window = [v is not None for v in (r.left, r.right, r.min_width, r.max_width)]
        if r.centres is not None or r.widths is not None:
            if r.centres is None or r.widths is None or any(window) or r.centre is not None or r.width is not None:
                raise InputError("a grid band gives centres and widths only", source=scene.source,
                                 key=f"sweep.ranges.{name}")
            ranges.append(BandGrid(band.name, tuple(r.centres), tuple(r.widths)))
            continue
        if r.centre is not None or r.width is not None:
            if r.centre is None or r.width is None or any(window):
                raise InputError("a fixed band gives centre and width only", source=scene.source,
                                 key=f"sweep.ranges.{name}")
            ranges.append(BandRange.fixed(band.name, r.centre, r.width))
            continue
        missing = [k for k in ("left", "right", "min_width", "max_width") if getattr(r, k) is None]
        if missing:
            raise InputError(f"missing {', '.join(missing)} (or give centres and widths for a grid, or centre and "
                             "width for a fixed band)",
                             source=scene.source, key=f"sweep.ranges.{name}")
        ranges.append(BandRange(band.name, r.left, r.right, r.min_width, r.max_width, step_nm=spec.step_nm))
    unknown = set(spec.ranges) - set(spec.bands)
    if unknown:
        raise InputError(f"ranges for bands not swept: {', '.join(sorted(unknown))}", source=scene.source,
                         key="sweep.ranges")
    space = SweepSpace(tuple(ranges)).validate(scene.source)
    _check_on_grid(scene, space)
    return space


def _check_on_grid(scene: Scene, space: SweepSpace) -> None:
    """Every variant's model SRF (centre ± sensor.support × width) inside the scene's grid: the one check that
    ``sweep count``, ``simulate`` and ``optimise`` share (:func:`s2cl.scene.validate.check_sweep`), before any
    table is built."""
    grid, support = scene.grid, scene.run.support
    for r in space.ranges:
        lo, hi = r.support_extent(support)
        if not grid.covers(lo, hi):
            raise InputError(f"the variants' SRFs (centre ± {support:g} × width, sensor.support) reach {lo:g}–{hi:g} "
                             f"nm, outside the spectral grid {grid.describe()}; move or narrow the band's range, or "
                             "widen the grid", source=scene.source, key=f"sweep.ranges.{r.band}")


def _sensor_band(scene: Scene, name: str, key: str) -> Band:
    try:
        return scene.sensor.band(name)
    except InputError:
        raise InputError(f"sensor has no band {name!r}; bands: {', '.join(scene.sensor.band_names)}",
                         source=scene.source, key=key) from None


@dataclass(frozen=True, eq=False)
class SweepTables:
    """Everything a configuration needs, as plain arrays (picklable: Dask ships it to workers)."""

    bands: tuple[str, ...]
    counts: tuple[int, ...]
    centre: tuple[np.ndarray, ...]
    width: tuple[np.ndarray, ...]
    radiance: tuple[np.ndarray, ...]
    sigma: tuple[np.ndarray, ...]
    lp: tuple[np.ndarray, ...]
    g: tuple[np.ndarray, ...]
    s: tuple[np.ndarray, ...]
    lmin: np.ndarray
    lmax: np.ndarray
    bits: int
    copies: int
    z: np.ndarray
    target: np.ndarray
    calibration_gain: float = 1.0
    class_names: tuple[str, ...] = ()
    references: tuple[np.ndarray, ...] = ()
    noise: bool = True
    quantise: bool = True
    extra: dict[str, str] = field(default_factory=dict)

    @property
    def n_slots(self) -> int:
        return len(self.bands)

    @property
    def n_spectra(self) -> int:
        return int(self.radiance[0].shape[1])

    @property
    def n_pixels(self) -> int:
        return self.n_spectra * self.copies

    @property
    def n_configs(self) -> int:
        return int(np.prod(self.counts))

    @property
    def maxdn(self) -> int:
        return 2**self.bits - 1

    def fingerprint(self) -> str:
        """sha256 of every table: two sweeps with the same fingerprint compute the same numbers."""
        h = hashlib.sha256()
        for name in ("bands", "counts", "bits", "copies", "calibration_gain", "class_names", "noise", "quantise"):
            h.update(repr(getattr(self, name)).encode())
        for name in ("centre", "width", "radiance", "sigma", "lp", "g", "s", "references"):
            for a in getattr(self, name):
                h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        for a in (self.lmin, self.lmax, self.z, self.target):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()


def build_tables(scene: Scene, space: SweepSpace, library: SpectralLibrary, truth: AtmosphereArrays,
                 assumed: AtmosphereArrays, *, target: np.ndarray | None = None,
                 class_names: tuple[str, ...] = ()) -> SweepTables:
    """Tables for a sweep of ``space`` over ``library`` (surface reflectance) seen through ``truth``
    and corrected with ``assumed`` (per-wavelength terms on the scene's grid)."""
    if library.quantity != "reflectance":
        raise InputError("a sweep needs a reflectance library (it runs the atmosphere and its correction)",
                         source=scene.source, key="surface.quantity")
    grid, support = scene.grid, scene.run.support
    rho = library.spectra
    toa = truth.path_radiance + truth.ground_term * rho / (1.0 - truth.spherical_albedo * rho)
    per_slot: dict[str, list[np.ndarray]] = {k: [] for k in
                                             ("centre", "width", "radiance", "sigma", "lp", "g", "s", "refs")}
    for rng, variants in zip(space.ranges, space.per_band, strict=True):
        base = scene.sensor.band(rng.band)
        radiance, sigma, weights_all, surface = [], [], [], []
        for c, w in variants:
            band = base.with_shape(c, w)
            weights = band.weights(grid, support, scene.source)
            sl = slice(weights.start, weights.stop)
            L = toa[:, sl] @ weights.weights
            radiance.append(L)
            sigma.append(noise_sigma(L, *band.noise_coefficients()))
            weights_all.append(weights)
            surface.append(rho[:, sl] @ weights.weights)
        corr = BandAtmosphere.of(assumed, weights_all).with_calibration_gain(scene.run.calibration_gain)
        per_slot["centre"].append(variants[:, 0].copy())
        per_slot["width"].append(variants[:, 1].copy())
        per_slot["radiance"].append(np.array(radiance))
        per_slot["sigma"].append(np.array(sigma))
        per_slot["lp"].append(corr.path_radiance)
        per_slot["g"].append(corr.ground_term)
        per_slot["s"].append(corr.spherical_albedo)
        if class_names:
            groups = np.array(library.groups)
            surf = np.array(surface)  # (n_v, n_spectra)
            per_slot["refs"].append(np.stack([surf[:, groups == c].mean(axis=1) for c in class_names], axis=1))
    copies = scene.run.copies
    n_pixels = library.size * copies
    e = scene.run
    bands = [scene.sensor.band(r.band) for r in space.ranges]
    # keyed by each band's index in the sensor, as `s2cl simulate` keys it: pixel p of band B gets the
    # same deviate on both paths (and in every configuration: common random numbers)
    band_ids = [scene.sensor.band_names.index(b.name) for b in bands]
    z = sensor_noise(e.seed, np.arange(n_pixels), band_ids, e.frame)
    return SweepTables(
        bands=tuple(r.band for r in space.ranges), counts=tuple(space.counts),
        centre=tuple(per_slot["centre"]), width=tuple(per_slot["width"]),
        radiance=tuple(per_slot["radiance"]), sigma=tuple(per_slot["sigma"]),
        lp=tuple(per_slot["lp"]), g=tuple(per_slot["g"]), s=tuple(per_slot["s"]),
        lmin=np.array([b.lmin for b in bands]), lmax=np.array([b.lmax for b in bands]),
        bits=scene.sensor.bits, copies=copies, z=z,
        target=np.zeros(n_pixels) if target is None else np.repeat(np.asarray(target), copies),
        calibration_gain=scene.run.calibration_gain,
        class_names=tuple(class_names), references=tuple(per_slot["refs"]),
        noise=e.effects.noise, quantise=e.effects.quantise,
    )
