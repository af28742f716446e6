"""What a sweep computes once: per (band variant, library spectrum) tables.

The sweep is separable: resampling is linear and each band depends
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
from dataclasses import dataclass

import numpy as np

from s2cl.atmos.correction import BandAtmosphere
from s2cl.errors import InputError
from s2cl.forward.noise import sensor_noise
from s2cl.forward.resample import AtmosphereArrays
from s2cl.libraries.library import SpectralLibrary
from s2cl.scene.scene import Scene
from s2cl.sensor.noise_model import noise_sigma
from s2cl.sensor.variants import SweepSpace
from s2cl.sweep.space import sweep_space

__all__ = ["SweepTables", "build_tables", "sweep_space"]


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

    def fingerprint(self) -> str:
        """sha256 of every table: two sweeps with the same fingerprint compute the same numbers."""
        h = hashlib.sha256()
        for name in ("bands", "counts", "bits", "copies", "calibration_gain", "class_names", "noise", "quantise",
                     "diagonal"):
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
