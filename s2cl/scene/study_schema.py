"""The scene's [study] section: what a study (`s2cl study`) sweeps and scores, checked on load.

Split from :mod:`s2cl.scene.schema` by subject; the scene model there holds a :class:`StudySpec`.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from s2cl.errors import token
from s2cl.scene.section import Section
from s2cl.sensor.names import BAND_NAME, BAND_NAME_RULE

#: stability study: largest band-centre shift (nm) and width factor a [study] may ask for
MAX_SHIFT_NM, MAX_WIDTH_FACTOR = 100.0, 5.0
#: cellulose study: largest factor on a fixed gas's column a [study] may ask for
MAX_GAS_FACTOR = 3.0


class WindowSpec(Section):
    """A second window (reference) channel for the three-channel water-vapour retrieval
    (``s2cl study water-vapour-1020``): a band that is not in the sensor, swept over ``centres`` × ``widths``
    (nm), with the noise model of the sensor band ``noise_band`` at each width; ``centre``/``width`` is the
    headline variant the tables report (one of the grid's)."""

    name: str = Field("N1020", description="the channel's name (not a sensor band's)")
    noise_band: str = Field("B9", description="sensor band whose SNR model (scaled with width) the channel uses")
    centres: list[float] = Field(min_length=1, description="centres, nm")
    widths: list[float] = Field(min_length=1, description="widths (FWHM), nm")
    centre: float = Field(1020.0, description="headline centre, nm")
    width: float = Field(20.0, gt=0, description="headline width, nm")

    @field_validator("name")
    @classmethod
    def _name(cls, value: str) -> str:
        if not BAND_NAME.fullmatch(value):
            raise ValueError(f"band name {token(value)} is not allowed: a band name is {BAND_NAME_RULE}")
        return value

    @field_validator("centres", "widths")
    @classmethod
    def _shapes(cls, values: list[float]) -> list[float]:
        bad = [v for v in values if not (math.isfinite(v) and v > 0)]
        if bad:
            raise ValueError(f"values must be finite and > 0 nm, got {bad[0]}")
        if len(set(values)) != len(values):
            raise ValueError("values hold duplicates")
        return values

    @model_validator(mode="after")
    def _headline_in_grid(self) -> WindowSpec:
        if self.centre not in self.centres or self.width not in self.widths:
            raise ValueError(f"the headline channel {self.centre:g}/{self.width:g} nm (centre, width) must be one "
                             "of the grid's centres × widths")
        return self


class StudySpec(Section):
    """A study (``s2cl study NAME``): the paper's atmospheric-band studies vary the bands of the [sweep] section;
    ``stability`` drifts the bands of each scene in ``applications``."""

    kind: Literal["cirrus", "water-vapour", "water-vapour-1020", "aerosol", "ozone", "methane", "stability",
                  "cellulose", "instrument"] = Field(description="which study runs")
    reflectance: list[float] = Field([0.3], min_length=1, description="flat target reflectances, unitless")
    targets: dict[str, str] = Field(default_factory=dict, description="target class -> library ('builtin:NAME')")
    spectra: int = Field(0, ge=0, le=10_000, description="spectra taken from each target library (0: all)")
    water_vapour: list[float] = Field(default_factory=list, description="true water-vapour columns, g/cm2")
    ozone: list[float] = Field(default_factory=list, description="true ozone columns, DU")
    aot550: list[float] = Field(default_factory=list, description="true AOT550 values")
    factor_errors: list[float] = Field(default_factory=list, description="relative errors of a correlation factor")
    pixels: int = Field(100, ge=1, le=100_000, description="noisy pixels per target and state (stability: noisy "
                        "copies per library spectrum)")
    applications: dict[str, str] = Field(default_factory=dict, description="stability: label -> scene (built-in "
                                         "name, or a .toml file relative to this scene) with [analysis] and [sweep]")
    shifts_nm: list[float] = Field(default_factory=list, description="stability: band-centre shifts, nm")
    width_factors: list[float] = Field(default_factory=list, description="stability: band-width factors, unitless")
    growth: float = Field(0.1, gt=0, le=10, description="stability: error growth over the nominal that sets a "
                          "requirement (0.1: +10 %)")
    window2: WindowSpec | None = Field(None, description="water-vapour-1020: the second window channel "
                                       "(name, noise_band, centres, widths, centre, width)")
    npv_fractions: list[float] = Field(default_factory=list, description="cellulose: fractions of non-photosynthetic "
                                       "vegetation in the soil + NPV (+ green) mixtures, each in [0, 1]")
    green_fractions: list[float] = Field([0.0], min_length=1, description="cellulose: fractions of green vegetation "
                                         "(targets.green), each in [0, 1]; the soil takes the rest")
    shoulders: list[list[float]] = Field(default_factory=list, description="cellulose: the CAI's two fixed shoulder "
                                         "bands [[centre, width], [centre, width]] (nm), below and above 2.1 um")
    co2_factors: list[float] = Field([1.0], min_length=1, description="cellulose: true CO2 columns as factors of the "
                                     "LUT's (6S's fixed profile); the correction assumes 1")
    image_px: int = Field(0, ge=0, le=2000, description="instrument: side of a builtin:fields image, input pixels "
                          "(0: the scene's cube as given)")
    quick: dict[str, Any] = Field(default_factory=dict, description="[study] keys replaced under --quick")

    @field_validator("reflectance")
    @classmethod
    def _reflectance(cls, values: list[float]) -> list[float]:
        bad = [v for v in values if not (math.isfinite(v) and 0 < v <= 1)]
        if bad:
            raise ValueError(f"reflectances must be > 0 and <= 1, got {bad[0]}")
        return values

    @field_validator("water_vapour", "ozone", "aot550", "factor_errors")
    @classmethod
    def _finite(cls, values: list[float]) -> list[float]:
        bad = [v for v in values if not math.isfinite(v)]
        if bad:
            raise ValueError(f"values must be finite numbers, got {bad[0]}")
        return values

    @field_validator("npv_fractions", "green_fractions")
    @classmethod
    def _fractions(cls, values: list[float]) -> list[float]:
        return _each_within(values, 0.0, 1.0, "fractions")

    @field_validator("co2_factors")
    @classmethod
    def _co2(cls, values: list[float]) -> list[float]:
        return _each_within(values, 0.0, MAX_GAS_FACTOR, "CO2 column factors")

    @field_validator("shoulders")
    @classmethod
    def _shoulders(cls, values: list[list[float]]) -> list[list[float]]:
        if not values:
            return values
        if len(values) != 2 or any(len(v) != 2 for v in values):
            raise ValueError("give two shoulder bands as [[centre, width], [centre, width]] (nm)")
        for centre, width in values:
            if not (math.isfinite(centre) and math.isfinite(width) and width > 0):
                raise ValueError(f"a shoulder needs a finite centre and a width > 0 nm, got [{centre}, {width}]")
        if not values[0][0] < values[1][0]:
            raise ValueError(f"the first shoulder must lie below the second, got centres {values[0][0]:g} and "
                             f"{values[1][0]:g} nm")
        return values

    @field_validator("shifts_nm")
    @classmethod
    def _shifts(cls, values: list[float]) -> list[float]:
        bad = [v for v in values if not (math.isfinite(v) and abs(v) <= MAX_SHIFT_NM)]
        if bad:
            raise ValueError(f"shifts must be finite and within ±{MAX_SHIFT_NM:g} nm, got {bad[0]}")
        return values

    @field_validator("width_factors")
    @classmethod
    def _factors(cls, values: list[float]) -> list[float]:
        bad = [v for v in values if not (math.isfinite(v) and 0 < v <= MAX_WIDTH_FACTOR)]
        if bad:
            raise ValueError(f"width factors must be > 0 and <= {MAX_WIDTH_FACTOR:g}, got {bad[0]}")
        return values

    @field_validator("applications")
    @classmethod
    def _applications(cls, values: dict[str, str]) -> dict[str, str]:
        for label, scene in values.items():
            if not 1 <= len(label) <= 40 or not label.isprintable():
                raise ValueError(f"application labels are 1-40 printable characters, got {token(label)}")
            if not scene:
                raise ValueError(f"application {token(label)} names no scene")
        return values


def _each_within(values: list[float], lo: float, hi: float, what: str) -> list[float]:
    """``values`` if each is finite and in [lo, hi]; else a ValueError naming the first that is not."""
    bad = [v for v in values if not (math.isfinite(v) and lo <= v <= hi)]
    if bad:
        raise ValueError(f"{what} must be in [{lo:g}, {hi:g}], got {bad[0]}")
    return values
