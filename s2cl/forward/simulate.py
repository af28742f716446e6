"""Simulate a scene: library spectra (× noisy copies) → band radiance → the chain's per-pixel stages
(:mod:`s2cl.forward.stages`: noise, DN, calibrated radiance, band reflectance, ...)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from s2cl.atmos.correction import BandAtmosphere
from s2cl.cl.runtime import Runtime
from s2cl.errors import InputError
from s2cl.forward.grid_interpolation import GridInterpolation
from s2cl.forward.parts import ChainParts
from s2cl.forward.radiometry import Radiometry
from s2cl.forward.resample import AtmosphereArrays, ResamplePlan, Resampler
from s2cl.forward.sense import SenseResult, Sensing, clipped_counts
from s2cl.forward.stages import ALL_OUTPUTS, band_attrs, senses
from s2cl.libraries.library import SpectralLibrary
from s2cl.scene.effects import EffectSet
from s2cl.sensor.sensor import Sensor
from s2cl.status import PixelFlag

Progress = Callable[[int], None]
OUTPUT_NAMES = tuple(dict.fromkeys(o.name for o in ALL_OUTPUTS))


@dataclass
class LibrarySimulation:
    """Result of simulating a spectral library with ``copies`` noisy copies per spectrum.

    Arrays are ``(n_bands, n_spectra)`` for the noise-free band radiance and
    ``(n_bands, n_spectra, copies)`` for the per-pixel outputs (None when the stage is off).
    Radiance in W m⁻² sr⁻¹ µm⁻¹.
    """

    scene: str
    sensor: Sensor
    library: SpectralLibrary
    copies: int
    effects: EffectSet
    band_radiance: np.ndarray
    #: the per-pixel outputs of the chain's stages by name (:mod:`s2cl.forward.stages`): ``sim.noisy``, ``sim.dn``,
    #: ``sim.flags`` (:class:`s2cl.status.PixelFlag` bits), ``sim.calibrated``, ``sim.reflectance``, ...; None when
    #: the stage is off
    outputs: dict[str, np.ndarray] = field(default_factory=dict)
    clipped: np.ndarray | None = None
    seconds: dict[str, float] = field(default_factory=dict)
    attrs: dict[str, Any] = field(default_factory=dict)
    #: what the chain's stages did to each band (such as its calibration error), per attribute a value per band
    stage_values: dict[str, list[Any]] = field(default_factory=dict)

    def __getattr__(self, name: str) -> np.ndarray | None:
        if name in OUTPUT_NAMES:
            return self.__dict__.get("outputs", {}).get(name)
        raise AttributeError(name)

    @property
    def n_pixels(self) -> int:
        return self.library.size * self.copies

    @property
    def sensed(self) -> np.ndarray:
        """The last radiance of the chain: calibrated, else noisy, else noise-free (per pixel)."""
        for a in (self.calibrated, self.noisy):
            if a is not None:
                return a
        return np.repeat(self.band_radiance[:, :, None], self.copies, axis=2)

    def summary(self) -> list[dict[str, Any]]:
        """Per band: mean radiance, measured and modelled SNR, clipping, calibration error."""
        stats = BandSummary(self.sensor, self.band_radiance, self.copies)
        stats.add(0, self.library.size, self.noisy, self.calibrated, self.clipped, self.flags)
        return stats.rows()

    def to_dataset(self, layout: str = "rows") -> Any:
        """xarray Dataset: per-band images in the scene's layout plus the spectrum table."""
        from s2cl.forward.dataset import library_dataset  # xarray (and pandas): only for the Dataset

        return library_dataset(self, layout)


class BandSummary:
    """The per-band summary of a simulation, accumulated over chunks of whole spectra (each chunk holds
    every copy of its spectra, so per-spectrum statistics are exact whatever the chunking)."""

    def __init__(self, sensor: Sensor, band_radiance: np.ndarray, copies: int):
        self.sensor, self.band_radiance, self.copies = sensor, band_radiance, copies
        nb = band_radiance.shape[0]
        self.n_pixels = band_radiance.shape[1] * copies
        self._snr: list[np.ndarray] = []
        self._sq_error = np.zeros(nb)
        self._clipped: np.ndarray | None = None
        self._nodata: np.ndarray | None = None
        self._calibrated = False

    def add(self, lo: int, hi: int, noisy: np.ndarray | None, calibrated: np.ndarray | None,
            clipped: np.ndarray | None, flags: np.ndarray | None = None) -> None:
        """Spectra ``lo … hi-1``: ``noisy``, ``calibrated`` and ``flags`` ``(n_bands, hi - lo, copies)``,
        ``clipped`` ``(2, n_bands)`` counts (None where the stage is off)."""
        if flags is not None:
            nodata = np.count_nonzero(flags.reshape(flags.shape[0], -1) & PixelFlag.NODATA, axis=1)
            self._nodata = nodata + (0 if self._nodata is None else self._nodata)
        L = self.band_radiance[:, lo:hi].astype(np.float64)
        if noisy is not None and self.copies > 1:
            std = noisy.astype(np.float64).std(axis=2, ddof=1)
            self._snr.append(np.where(std > 0, L / np.where(std > 0, std, 1.0), np.nan))
        if calibrated is not None:
            err = calibrated.astype(np.float64) - L[:, :, None]
            self._sq_error += np.einsum("kij,kij->k", err, err)
            self._calibrated = True
        if clipped is not None:
            self._clipped = clipped.astype(np.int64) + (0 if self._clipped is None else self._clipped)

    @property
    def clipped(self) -> np.ndarray | None:
        """``(2, n_bands)`` pixels below Lmin / above Lmax so far (None without quantisation)."""
        return self._clipped

    def rows(self) -> list[dict[str, Any]]:
        """Per band: mean radiance, measured and modelled SNR, clipping, calibration error."""
        snr = np.concatenate(self._snr, axis=1) if self._snr else None
        rows = []
        for k, band in enumerate(self.sensor.bands):
            L = self.band_radiance[k].astype(np.float64)
            row: dict[str, Any] = {
                "band": band.name, "centre_nm": band.centre_nm, "fwhm_nm": band.fwhm_nm,
                "mean_radiance": float(L.mean()),
            }
            if snr is not None:
                ok = np.isfinite(snr[k])
                row["snr_measured_median"] = float(np.median(snr[k][ok])) if ok.any() else float("nan")
                row["snr_model_median"] = float(np.median(band.noise.snr(L, band.fwhm_nm)))
            if self._clipped is not None:
                row["clipped_low_pct"] = 100.0 * float(self._clipped[0, k]) / self.n_pixels
                row["clipped_high_pct"] = 100.0 * float(self._clipped[1, k]) / self.n_pixels
            if self._calibrated:
                row["rms_error_vs_noise_free"] = float(np.sqrt(self._sq_error[k] / self.n_pixels))
            if self._nodata is not None:
                row["nodata_pct"] = 100.0 * float(self._nodata[k]) / self.n_pixels
            rows.append(row)
        return rows


class Simulator:
    """Compiled chain (a scene's :class:`~s2cl.forward.parts.ChainParts`, or sensor + effects) on ``rt``'s device,
    reusable across inputs."""

    def __init__(self, rt: Runtime, sensor: Sensor, grid_size: int, weights: list, effects: EffectSet, *,
                 precision: str = "float32", atmosphere: AtmosphereArrays | None = None,
                 correction: BandAtmosphere | None = None, settings: Any = None, seed: int = 0,
                 interpolation: GridInterpolation | None = None):
        self.rt = rt
        self.sensor, self.effects, self.precision = sensor, effects, precision
        self.correction = correction
        self.plan = ResamplePlan(tuple(sensor.band_names), tuple(weights), grid_size)
        self.resampler = Resampler(self.rt, self.plan, precision, atmosphere=atmosphere, interpolation=interpolation)
        radiometry = Radiometry.of(sensor.bands, sensor.bits, correction=correction, settings=settings, seed=seed)
        self.sensing = Sensing(self.rt, radiometry, effects, precision) if senses(effects) else None

    @classmethod
    def of(cls, rt: Runtime, parts: ChainParts, *, interpolation: GridInterpolation | None = None) -> Simulator:
        """The chain of ``parts`` (resolved from a scene by :func:`s2cl.app.chain_parts.chain_parts`);
        ``interpolation``: spectra come at a cube's native wavelengths and the resampling kernel puts them on the
        grid (:class:`~s2cl.forward.grid_interpolation.GridInterpolation`)."""
        return cls(rt, parts.sensor, parts.grid.size, list(parts.weights), parts.effects,
                   precision=parts.run.precision, atmosphere=parts.atmosphere, correction=parts.correction,
                   settings=parts.settings, seed=parts.run.seed, interpolation=interpolation)

    def stage_values(self) -> dict[str, list[Any]]:
        """What the per-pixel stages do to each band (:func:`s2cl.forward.stages.band_attrs`): per attribute, a value
        per band (empty without a stage that says)."""
        if self.sensing is None:
            return {}
        per_band = [band_attrs(self.sensing.stages, self.sensing.radiometry, k) for k in range(self.sensor.size)]
        return {key: [a[key] for a in per_band] for key in per_band[0]} if per_band else {}

    def band_radiance(self, spectra: np.ndarray) -> np.ndarray:
        """Noise-free band values ``(n_bands, n)`` of ``spectra`` ``(n, n_wavelengths)`` (or ``(n, n_native)``: the
        native samples of the resampler's :attr:`~s2cl.forward.resample.Resampler.interpolation`)."""
        return self.resampler(spectra)

    def sense(self, radiance: np.ndarray, *, seed: int, frame: int = 0, pixel_offset: int = 0) -> SenseResult | None:
        if self.sensing is None:
            return None
        return self.sensing(radiance, seed=seed, frame=frame, pixel_offset=pixel_offset)

    def run_library(self, library: SpectralLibrary, *, copies: int, seed: int, frame: int = 0,
                    scene_name: str = "", progress: Progress | None = None) -> LibrarySimulation:
        """Simulate every spectrum ``copies`` times. Spectra are resampled once (copies share the
        noise-free band radiance); pixel ``s · copies + c`` keys the noise of copy ``c`` of spectrum ``s``."""
        if copies < 1:
            raise InputError(f"copies must be >= 1, got {copies}", key="surface.copies")
        t0 = time.perf_counter()
        band_radiance = self.band_radiance(library.spectra)
        seconds = {"resample": time.perf_counter() - t0}
        result = LibrarySimulation(scene_name, self.sensor, library, copies, self.effects, band_radiance,
                                   seconds=seconds, stage_values=self.stage_values())
        if progress:
            progress(0)
        if self.sensing is not None:
            t1 = time.perf_counter()
            self._sense_library(result, seed, frame, progress)
            seconds["sense"] = time.perf_counter() - t1
        elif progress:
            progress(result.n_pixels)
        return result

    def _sense_library(self, result: LibrarySimulation, seed: int, frame: int, progress: Progress | None) -> None:
        nb, ns, c = self.sensor.size, result.library.size, result.copies
        assert self.sensing is not None
        dtype = result.band_radiance.dtype
        result.outputs = {name: np.empty((nb, ns, c), o.dtype or dtype) for name, o in self.sensing.outputs.items()}
        per_chunk = max(1, (1 << 20) // c)
        for lo in range(0, ns, per_chunk):
            hi = min(ns, lo + per_chunk)
            expanded = np.repeat(result.band_radiance[:, lo:hi], c, axis=1)
            out = self.sensing(expanded, seed=seed, frame=frame, pixel_offset=lo * c)
            for name, part in out.outputs.items():
                result.outputs[name][:, lo:hi] = part.reshape(nb, hi - lo, c)
            if progress:
                progress((hi - lo) * c)
            expanded = out = None  # let the chunk go before the next is sensed
        if "flags" in result.outputs:
            result.clipped = clipped_counts(result.outputs["flags"].reshape(nb, -1))
