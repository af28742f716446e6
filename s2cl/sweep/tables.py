"""What a sweep computes once: per (band variant, library spectrum) tables.

The sweep is separable: resampling is linear and each band depends
only on its own (centre, width). So the spectral integral runs once per band variant and
spectrum, here, in float64; every configuration is then a gather from these tables:

- ``radiance[k][v, s]``: noise-free TOA band radiance of spectrum ``s`` in variant ``v`` of band
  slot ``k`` (W m⁻² sr⁻¹ µm⁻¹), under the true atmosphere;
- ``values``: what the chain's per-pixel stages that are on (:mod:`s2cl.forward.stages`) read, by name, as each
  declares it: one per band slot (a literal of the kernel: every variant takes its band's), one per variant (such
  as the band-effective correction terms of the atmosphere the correction assumes), one per variant and spectrum
  (such as the noise σ of the band at that width, of its noise-free radiance), or one per pair of slots;
- ``z[k, p]``: the standard normal deviate of pixel ``p`` in slot ``k``, the same for every
  configuration (common random numbers: configurations differ by their bands, not by their
  luck). ``z`` is the sensor-noise stream of s2cl's Philox generator keyed by (seed, pixel, the
  slot's band index in the sensor): the deviate ``s2cl simulate`` adds to that band.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from s2cl.atmos.correction import BandAtmosphere
from s2cl.errors import InputError
from s2cl.forward.noise import sensor_noise
from s2cl.forward.radiometry import Radiometry
from s2cl.forward.resample import AtmosphereArrays
from s2cl.forward.stages import Value, chain, compute, inputs, stage
from s2cl.grid import SpectralGrid
from s2cl.libraries.library import SpectralLibrary
from s2cl.scene.config import RunConfig
from s2cl.sensor.sensor import Sensor
from s2cl.sensor.variants import SweepSpace

__all__ = ["SweepTables", "build_tables"]


@dataclass(frozen=True, eq=False)
class SweepTables:
    """Everything a configuration needs, as plain arrays (picklable: Dask ships it to workers)."""

    bands: tuple[str, ...]
    counts: tuple[int, ...]
    centre: tuple[np.ndarray, ...]
    width: tuple[np.ndarray, ...]
    radiance: tuple[np.ndarray, ...]
    bits: int
    copies: int
    z: np.ndarray
    target: np.ndarray
    class_names: tuple[str, ...] = ()
    references: tuple[np.ndarray, ...] = ()
    #: the chain's per-pixel stages the configurations run, in order (:func:`s2cl.forward.stages.chain`)
    stages: tuple[str, ...] = ()
    #: their values by name (:class:`s2cl.forward.stages.Value`): ``band`` an array over the slots, ``scalar`` a
    #: number, ``pairs`` ``[n_slots, n_slots]``; ``variant`` per slot an array over its variants, ``pixel`` per slot
    #: ``[variants, spectra]``
    values: dict[str, Any] = field(default_factory=dict)
    #: a design list rather than a product space: configuration ``c`` takes variant ``c`` of every slot (the
    #: tables hold each design's variants row by row: :func:`s2cl.sweep.design_tables.design_tables`)
    diagonal: bool = False

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
        return int(self.counts[0]) if self.diagonal else int(np.prod(self.counts))

    @property
    def maxdn(self) -> int:
        return 2**self.bits - 1

    def inputs(self) -> list[Value]:
        """The values the stages read in the sweep kernel, each once, in order."""
        return inputs([stage(n) for n in self.stages], "sweep")

    def per_row(self) -> list[str]:
        """Names of the values held per variant (a table row per variant: what a design list gathers)."""
        return [v.name for v in self.inputs() if v.varies in ("variant", "pixel")]

    def fingerprint(self) -> str:
        """sha256 of every table: two sweeps with the same fingerprint compute the same numbers."""
        h = hashlib.sha256()
        for name in ("bands", "counts", "bits", "copies", "class_names", "stages", "diagonal"):
            h.update(repr(getattr(self, name)).encode())
        for name in ("centre", "width", "radiance", "references"):
            for a in getattr(self, name):
                h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        for name in sorted(self.values):
            h.update(name.encode())
            value = self.values[name]
            for a in (value if isinstance(value, tuple) else (value,)):
                h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        for a in (self.z, self.target):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()


def build_tables(space: SweepSpace, library: SpectralLibrary, truth: AtmosphereArrays, assumed: AtmosphereArrays,
                 sensor: Sensor, grid: SpectralGrid, run: RunConfig, settings: Any, *,
                 target: np.ndarray | None = None, class_names: tuple[str, ...] = (),
                 shared: dict[Any, Any] | None = None) -> SweepTables:
    """Tables for a sweep of ``space`` over ``library`` (surface reflectance) seen through ``truth`` and corrected
    with ``assumed`` (per-wavelength terms on ``grid``), by ``sensor``'s bands (a band-addition sweep's sensor holds
    the added band) and the chain of ``run`` (its stages, seed, SRF support, copies); ``settings``: the scene's
    [effects] section, which the stages read. Errors name the key (the caller adds the file).

    ``shared``: band tables already built for other sweeps of the same scene (a multi-application sweep's
    applications, :mod:`s2cl.app.applications`), filled here: a band slot whose variants, library, atmosphere terms,
    sensor band, grid and chain are those of a slot built before takes that slot's arrays (the resampled radiance,
    the per-variant values of the stages, the centres and widths) instead of computing them again; the same numbers,
    since they are computed from the same inputs alone (the target, copies and noise deviates are each sweep's)."""
    if library.quantity != "reflectance":
        raise InputError("a sweep needs a reflectance library (it runs the atmosphere and its correction)",
                         key="surface.quantity")
    support, e = run.support, run
    rho = library.spectra
    toa: np.ndarray | None = None  # the library's TOA radiance on the grid: computed when a band is resampled here
    stages = chain(run.effects)
    bands = [sensor.band(r.band) for r in space.ranges]
    # keyed by each band's index in the sensor, as `s2cl simulate` keys it: pixel p of band B gets the
    # same deviate on both paths (and in every configuration: common random numbers)
    band_ids = [sensor.band_names.index(b.name) for b in bands]
    chain_settings = dict(settings=settings, seed=e.seed)
    base = compute(stages, Radiometry.of(bands, sensor.bits, band_ids, **chain_settings))
    wanted = inputs(stages, "sweep")
    values: dict[str, Any] = {v.name: base[v.name] for v in wanted if v.varies in ("band", "scalar", "pairs")}
    per_variant: dict[str, list[np.ndarray]] = {v.name: [] for v in wanted if v.varies in ("variant", "pixel")}
    per_slot: dict[str, list[np.ndarray]] = {k: [] for k in ("centre", "width", "radiance", "refs")}
    for variants, band, band_id in zip(space.per_band, bands, band_ids, strict=True):
        key = _band_key(variants, band, band_id, library, truth, assumed, sensor, grid, run, settings, stages,
                        class_names)
        built = shared.get(key) if shared is not None else None
        if built is None:
            if toa is None:
                toa = truth.path_radiance + truth.ground_term * rho / (1.0 - truth.spherical_albedo * rho)
            built = _band_tables(variants, band, band_id, toa, library, assumed, sensor, grid, support, stages,
                                 chain_settings, class_names)
            if shared is not None:  # the inputs the key names by identity are held with the arrays
                shared[key] = (*built, (library, truth, assumed, sensor, grid))
        radiance, of_variants, refs = built[:3]
        for name, rows in per_variant.items():
            rows.append(np.asarray(of_variants[name]))
        per_slot["centre"].append(variants[:, 0].copy())
        per_slot["width"].append(variants[:, 1].copy())
        per_slot["radiance"].append(radiance)
        if class_names:
            per_slot["refs"].append(refs)
    copies = e.copies
    n_pixels = library.size * copies
    z = sensor_noise(e.seed, np.arange(n_pixels), band_ids, e.frame)
    values.update({name: tuple(rows) for name, rows in per_variant.items()})
    return SweepTables(
        bands=tuple(r.band for r in space.ranges), counts=tuple(space.counts),
        centre=tuple(per_slot["centre"]), width=tuple(per_slot["width"]), radiance=tuple(per_slot["radiance"]),
        bits=sensor.bits, copies=copies, z=z,
        target=np.zeros(n_pixels) if target is None else np.repeat(np.asarray(target), copies),
        class_names=tuple(class_names), references=tuple(per_slot["refs"]),
        stages=tuple(s.name for s in stages), values=values,
    )


def _band_key(variants: np.ndarray, band: Any, band_id: int, library: SpectralLibrary, truth: AtmosphereArrays,
              assumed: AtmosphereArrays, sensor: Sensor, grid: SpectralGrid, run: RunConfig, settings: Any,
              stages: list[Any], class_names: tuple[str, ...]) -> tuple[Any, ...]:
    """What one band slot's tables are computed from (:func:`_band_tables`): its variants (centre, width in nm), the
    sensor band (its name and index), and by identity the library, the atmosphere terms, the sensor and the grid
    (held beside the tables in ``build_tables``' ``shared``, so an identity is never reused), the SRF support, the
    chain's stages, seed and frame, the [effects] settings and the SAM classes."""
    return (np.ascontiguousarray(variants, dtype=np.float64).tobytes(), variants.shape, band.name, band_id,
            id(library), id(truth), id(assumed), id(sensor), id(grid), sensor.bits, run.support, run.seed, run.frame,
            tuple(s.name for s in stages), repr(settings), class_names)


def _band_tables(variants: np.ndarray, band: Any, band_id: int, toa: np.ndarray, library: SpectralLibrary,
                 assumed: AtmosphereArrays, sensor: Sensor, grid: SpectralGrid, support: Any, stages: list[Any],
                 chain_settings: dict[str, Any], class_names: tuple[str, ...]
                 ) -> tuple[np.ndarray, dict[str, Any], np.ndarray | None]:
    """One band slot's tables: the TOA radiance of every spectrum in every variant ``[variants, spectra]`` (the
    library's TOA radiance ``toa`` resampled by the variant's SRF), the stages' values of the variants (by name)
    and, with SAM classes, each class's mean surface reflectance per variant ``[variants, classes]`` (else None)."""
    shaped, radiance, weights_all, surface = [], [], [], []
    rho = library.spectra
    for c, w in variants:
        shaped.append(band.with_shape(c, w))
        weights = shaped[-1].weights(grid, support)
        sl = slice(weights.start, weights.stop)
        radiance.append(toa[:, sl] @ weights.weights)
        weights_all.append(weights)
        if class_names:
            surface.append(rho[:, sl] @ weights.weights)
    corr = BandAtmosphere.of(assumed, weights_all)
    table = np.array(radiance)
    of_variants = compute(stages, Radiometry.of(shaped, sensor.bits, [band_id] * len(shaped), correction=corr,
                                                radiance=table, **chain_settings))
    refs = None
    if class_names:
        groups = np.array(library.groups)
        surf = np.array(surface)  # (n_v, n_spectra)
        refs = np.stack([surf[:, groups == c].mean(axis=1) for c in class_names], axis=1)
    return table, of_variants, refs
