"""float64 numpy oracles of the forward chain: resampling, the atmosphere, and the per-pixel stages of a band set
(:func:`chain`, each stage's twin of :mod:`s2cl.reference.stages` in the chain's order)."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

import numpy as np

from s2cl.atmos.correction import toa
from s2cl.forward.noise import add_noise as host_noise
from s2cl.forward.noise import sensor_noise
from s2cl.forward.radiometry import Radiometry
from s2cl.forward.stages import Stage, compute, inputs
from s2cl.forward.stages import chain as stages_on
from s2cl.scene.effects import EffectSet
from s2cl.sensor.srf import BandWeights


def resample(spectra: np.ndarray, weights: list[BandWeights] | tuple[BandWeights, ...]) -> np.ndarray:
    """Band values ``(n_bands, n_pixels)``: Σ w·spectrum over each band's support, float64."""
    return np.stack([w.apply(spectra) for w in weights])


def toa_radiance(rho: np.ndarray, path_radiance: np.ndarray, ground_term: np.ndarray,
                 spherical_albedo: np.ndarray) -> np.ndarray:
    """L = Lp + G·ρ / (1 − S·ρ) per wavelength (W m⁻² sr⁻¹ µm⁻¹), float64 (the product's host formula)."""
    return toa(rho, path_radiance, ground_term, spherical_albedo)


def add_noise(radiance: np.ndarray, r: Radiometry, seed: int, pixel_offset: int = 0, frame: int = 0) -> np.ndarray:
    """Radiance plus σ(L)·z with the kernel's counter-based normals (the product's host noise)."""
    return host_noise(radiance, r.noise_a, r.noise_b, r.band_ids, seed, pixel_offset, frame)


def twin(stage: Stage) -> Callable[[np.ndarray, Any, dict[str, np.ndarray]], np.ndarray]:
    """The float64 step of ``stage`` (its declared twin)."""
    module, name = str(stage.twin).split(":")
    return getattr(importlib.import_module(module), name)


def run_steps(stages: list[Stage], L: np.ndarray, v: dict[str, Any]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``L`` (band axis first) through the twins of ``stages`` in order: (the last L, every output)."""
    out: dict[str, np.ndarray] = {}
    for s in stages:
        L = twin(s)(L, v, out)
    return L, out


def chain(radiance: np.ndarray, r: Radiometry, effects: EffectSet, *, seed: int = 0, frame: int = 0,
          pixel_offset: int = 0) -> dict[str, np.ndarray]:
    """The per-pixel stages ``effects`` switches on, on noise-free band radiance ``(n_bands, n_pixels)`` of the bands
    of ``r``, in float64: every stage's outputs (``noisy``, ``dn`` (float64), ``flags``, ``calibrated``,
    ``reflectance``, ...), pixel ``j`` keyed as global pixel ``pixel_offset + j`` (the sense kernel's deviates)."""
    stages = stages_on(effects)
    L = np.asarray(radiance, dtype=np.float64)
    values = compute(stages, r)
    v: dict[str, Any] = {}
    for val in inputs(stages, "sense"):
        x = values[val.name]
        v[val.name] = np.asarray(x, dtype=np.float64)[:, None] if val.varies in ("band", "variant") else x
    if any(s.deviates for s in stages):
        v["z"] = sensor_noise(seed, np.arange(L.shape[1]) + pixel_offset, list(r.band_ids), frame)
    return run_steps(stages, L, v)[1]
