"""The band-averaging residual of the band-effective correction, per band and library.

The correction inverts band radiance with SRF-weighted terms (:mod:`s2cl.atmos.correction`). Even
without noise or quantisation it cannot return the true band reflectance exactly: the atmosphere
acts per wavelength, the sensor sees band averages. This module measures that residual:
reflectance → TOA radiance at every grid wavelength → SRF resampling → band-
effective correction (the host functions of :mod:`s2cl.atmos.correction`, float64), against the
SRF-weighted surface reflectance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.atmos.atmosphere import AtmosphereLUT
from s2cl.atmos.correction import BandAtmosphere, toa
from s2cl.atmos.state import AtmosphereState
from s2cl.grid import DEFAULT_GRID
from s2cl.libraries.registry import load_library
from s2cl.sensor.sensor import Sensor

DEFAULT_LIBRARIES = ("builtin:flat", "builtin:lib1", "builtin:lib2", "builtin:minerals")


@dataclass(frozen=True)
class Residuals:
    """Residuals of one library: ``corrected - true`` band reflectance, shape ``(n_bands, n_spectra)``."""

    library: str
    bands: tuple[str, ...]
    difference: np.ndarray
    true: np.ndarray

    def max_abs(self) -> np.ndarray:
        """Largest |corrected − true| per band (reflectance units)."""
        return np.abs(self.difference).max(axis=1)


def band_averaging_residuals(libraries: tuple[str, ...] = DEFAULT_LIBRARIES,
                             state: AtmosphereState | None = None,
                             sensor: Sensor | None = None) -> list[Residuals]:
    """Noise-free residual of the correction for each library, under ``state`` (paper standard)."""
    sensor = sensor or Sensor.sentinel2()
    state = state or AtmosphereState.paper_standard()
    terms = AtmosphereLUT.load().terms(state, DEFAULT_GRID)
    weights = [b.weights(DEFAULT_GRID) for b in sensor.bands]
    band_terms = BandAtmosphere.of(terms, weights)
    out = []
    for name in libraries:
        rho = load_library(name, DEFAULT_GRID).spectra
        radiance = toa(rho, terms.path_radiance, terms.ground_term, terms.spherical_albedo)
        corrected = band_terms.reflectance(np.stack([w.apply(radiance) for w in weights]))
        true = np.stack([w.apply(rho) for w in weights])
        out.append(Residuals(name, tuple(sensor.band_names), corrected - true, true))
    return out
