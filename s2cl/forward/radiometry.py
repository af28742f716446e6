"""What the stages of the forward chain compute their per-band values from (:mod:`s2cl.forward.stages`): a set of
bands (a sensor's, a band group's, or every variant of one swept band) with their radiometry, names, centres, the
correction's band-effective terms, the scene's stage settings and seed, and (in a sweep) their noise-free radiance.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from s2cl.atmos.correction import BandAtmosphere
from s2cl.sensor.sensor import Band


@dataclass(frozen=True, eq=False)
class Radiometry:
    """Per-band constants, float64 arrays of length ``n_bands``.

    :param lmin, lmax: quantisation range, W m⁻² sr⁻¹ µm⁻¹.
    :param noise_a, noise_b: σ² = a + b·max(L, 0) at each band's actual width.
    :param band_ids: global index of each band (keys its noise stream).
    :param bits: radiometric resolution.
    :param names: band names (per-band scene settings name them); ``centres``: band centres, nm.
    :param correction: band-effective terms of the state the atmospheric correction assumes (None: none).
    :param settings: the scene's ``[effects]`` (its stages' settings; None: each stage's defaults).
    :param seed: the scene's seed (a stage that draws per-band values draws them from it).
    :param radiance: noise-free band radiance ``(n_bands, n_spectra)`` where the values are tabulated per spectrum
        (a sweep's variants of one band); None elsewhere.
    :param extras: the sensor table's optional numeric columns by name, per band (NaN where a band has none).
    """

    lmin: np.ndarray
    lmax: np.ndarray
    noise_a: np.ndarray
    noise_b: np.ndarray
    band_ids: tuple[int, ...]
    bits: int
    names: tuple[str, ...] = ()
    centres: np.ndarray | None = None
    correction: BandAtmosphere | None = None
    settings: Any = None
    seed: int = 0
    radiance: np.ndarray | None = None
    extras: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def of(cls, bands: list[Band] | tuple[Band, ...], bits: int, band_ids: list[int] | None = None, *,
           correction: BandAtmosphere | None = None, settings: Any = None, seed: int = 0,
           radiance: np.ndarray | None = None) -> Radiometry:
        coeffs = np.array([b.noise_coefficients() for b in bands], dtype=np.float64).reshape(-1, 2)
        return cls(
            lmin=np.array([b.lmin for b in bands], dtype=np.float64),
            lmax=np.array([b.lmax for b in bands], dtype=np.float64),
            noise_a=coeffs[:, 0],
            noise_b=coeffs[:, 1],
            band_ids=tuple(band_ids if band_ids is not None else range(len(bands))),
            bits=bits,
            names=tuple(b.name for b in bands),
            centres=np.array([b.centre_nm for b in bands], dtype=np.float64),
            correction=correction, settings=settings, seed=seed, radiance=radiance,
            extras={c: np.array([dict(b.extra).get(c, np.nan) for b in bands], dtype=np.float64)
                    for c in dict.fromkeys(c for b in bands for c, _ in b.extra)},
        )

    @property
    def n_bands(self) -> int:
        return int(self.lmin.size)

    @property
    def maxdn(self) -> int:
        return 2**self.bits - 1

    @property
    def scale(self) -> np.ndarray:
        """DN per unit radiance."""
        return self.maxdn / (self.lmax - self.lmin)

    @property
    def gain(self) -> np.ndarray:
        """Radiance per DN."""
        return (self.lmax - self.lmin) / self.maxdn

    def setting(self, name: str) -> Any:
        """The scene's setting of stage ``name`` (``[effects] NAME``), None where there is none."""
        return getattr(self.settings, name, None) if self.settings is not None else None
