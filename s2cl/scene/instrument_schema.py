"""The instrument's own artefacts on an image cube, each off unless asked for: their settings, as ``[effects]`` keys
(one PSF, co-registration, smile, non-uniformity), and the deprecated sections they were given in before
(``[instrument]``, ``[spatial]``), still read (:func:`moved_effects`).

Split from :mod:`s2cl.scene.schema` by subject; the scene model's ``[effects]`` holds a :class:`PsfSpec`,
:class:`CoregistrationSpec`, :class:`SmileSpec` and :class:`NonUniformitySpec` (or ``true``/``false``). Default
magnitudes and their sources are listed in :data:`SOURCES` (the effect-cost table prints them); the model is
:mod:`s2cl.forward.instrument`.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from s2cl.errors import InputError, token
from s2cl.scene.section import Section

#: system MTF of the box aggregation alone at the band's Nyquist frequency, sinc(1/2) = 2/π: a Gaussian PSF
#: can only lower it, so an MTF at Nyquist must lie below
BOX_MTF_NYQUIST = 2.0 / math.pi

#: the default magnitude of each effect and where it comes from (an assumption is said to be one)
SOURCES: dict[str, str] = {
    "psf": "MTF at Nyquist 0.15 for every band: the lower end of the 0.15-0.30 range the Sentinel-2 MSI "
           "requirements set (ESA Sentinel-2 Mission Requirements Document, EOP-SM/1163/MR-dr, 2010); taken as "
           "the system MTF (optics × detector footprint)",
    "coregistration": "each band shifted by 0.15 band pixels in a direction drawn from the seed, so that no two "
                      "bands are more than 0.3 pixels apart: the multispectral registration requirement for any "
                      "couple of bands (3 m / 6 m / 18 m for the 10 / 20 / 60 m bands; GSC Sentinel-2 PDGS "
                      "Operations Concept Document, GMES-GSEG-EOPG-TN-09-0008, Table 4-6)",
    "smile": "assumption: band centre +1 nm at the swath edges, 0 at its centre (Δλ = x², x = -1…1 across the "
             "image), width unchanged; an order of magnitude, not a Sentinel-2 figure (MSI's filters sit on "
             "12 staggered detectors, so its across-track SRF variation is per detector, not a spectrometer smile)",
    "nonuniformity": "assumption: raw per-column gain 2 % and offset 0.5 % of Lref (rms), equalised by a relative "
                     "calibration that leaves 0.2 % gain and 0.05 % of Lref offset (rms) per column; orders of "
                     "magnitude, not Sentinel-2 figures",
}


def _finite(values: list[float], what: str) -> list[float]:
    bad = [v for v in values if not math.isfinite(v)]
    if bad:
        raise ValueError(f"{what} must be finite, got {bad[0]}")
    return values


class EffectSpec(Section):
    """The settings of one effect of ``[effects]`` given as a table (``on = false`` keeps them, switched off)."""

    on: bool = Field(True, description="whether the effect runs (false: off, its settings kept, e.g. for the "
                     "instrument study)")


class PsfSpec(EffectSpec):
    """Each band's Gaussian PSF before the box average to its GSD, by the system MTF at the band's Nyquist
    frequency (with the box average) or by its FWHM in band pixels; one filter (with the co-registration shift)
    and one reach (s2cl.forward.reach)."""

    mtf_nyquist: float | None = Field(None, gt=0, lt=BOX_MTF_NYQUIST, description="system MTF at Nyquist of every "
                                      "band (below 2/π, the box average's own), unitless; 0.15 when neither it nor "
                                      "fwhm is given")
    fwhm: float | None = Field(None, gt=0, le=10, description="Gaussian PSF FWHM in band pixels (instead of "
                               "mtf_nyquist)")
    bands: dict[str, float] = Field(default_factory=dict, description="per band, in the unit given (MTF at Nyquist, "
                                    "or FWHM in band pixels), e.g. {B2 = 0.25}; other bands take the common value")

    @model_validator(mode="after")
    def _one_unit(self) -> PsfSpec:
        if self.mtf_nyquist is not None and self.fwhm is not None:
            raise ValueError("give the PSF as mtf_nyquist or as fwhm, not both")
        for band, v in self.bands.items():
            if self.fwhm is not None and not 0 < v <= 10:
                raise ValueError(f"bands.{band}: a FWHM must be > 0 and <= 10 band pixels, got {v}")
            if self.fwhm is None and not 0 < v < BOX_MTF_NYQUIST:
                raise ValueError(f"bands.{band}: MTF at Nyquist must be > 0 and < {BOX_MTF_NYQUIST:.4f} (2/π, the "
                                 f"box average's own), got {v}")
        return self

    @property
    def unit(self) -> Literal["fwhm", "mtf_nyquist"]:
        return "fwhm" if self.fwhm is not None else "mtf_nyquist"

    def value(self, band: str) -> float:
        """The band's FWHM (band pixels) or MTF at Nyquist, in :attr:`unit`."""
        given = next((v for b, v in self.bands.items() if b.lower() == band.lower()), None)
        if given is not None:
            return float(given)
        return float(self.fwhm if self.fwhm is not None else (self.mtf_nyquist or 0.15))


class CoregistrationSpec(EffectSpec):
    """Band-to-band co-registration error: each band shifted by a sub-pixel amount (a band-limited shift, in the
    PSF's filter on the input grid)."""

    px: float = Field(0.15, ge=0, le=2, description="each band's shift, band pixels, in a direction drawn from the "
                      "seed (0.15: half the 0.3-pixel band-to-band requirement)")
    shifts: dict[str, list[float]] = Field(default_factory=dict, description="per-band shift [dx, dy] in band "
                                           "pixels (x across, y along the image), e.g. {B5 = [0.1, -0.2]}; other "
                                           "bands take px")

    @field_validator("shifts")
    @classmethod
    def _shifts(cls, value: dict[str, list[float]]) -> dict[str, list[float]]:
        for band, d in value.items():
            if len(d) != 2 or not all(math.isfinite(v) and abs(v) <= 2 for v in d):
                raise ValueError(f"{band}: a shift is [dx, dy] with |dx|, |dy| <= 2 band pixels, got {d}")
        return value


class SmileSpec(EffectSpec):
    """Spectral smile: band centre (and width) vary across the swath, polynomial in the column position
    x = -1 … 1 across the image."""

    centre_nm: list[float] = Field([0.0, 0.0, 1.0], min_length=1, max_length=6, description="centre shift "
                                   "Δλ(x) = c0 + c1·x + c2·x² + …, coefficients in nm")
    width_pct: list[float] = Field([0.0], min_length=1, max_length=6, description="width change ΔFWHM(x)/FWHM, "
                                   "coefficients in %")

    @field_validator("centre_nm", "width_pct")
    @classmethod
    def _coefficients(cls, value: list[float]) -> list[float]:
        return _finite(value, "polynomial coefficients")


class NonUniformitySpec(EffectSpec):
    """Detector non-uniformity: per-column gain and offset of each band, drawn from the seed."""

    gain_pct: float = Field(2.0, ge=0, le=50, description="raw per-column gain spread (rms), %")
    offset_pct: float = Field(0.5, ge=0, le=50, description="raw per-column offset spread (rms), % of the band's Lref")
    equalised: bool = Field(True, description="a relative calibration equalises the columns, leaving the residuals "
                            "below (false: the raw non-uniformity stays in the product)")
    residual_gain_pct: float = Field(0.2, ge=0, le=50, description="per-column gain error of the relative "
                                     "calibration (rms), %: the striping left in the product")
    residual_offset_pct: float = Field(0.05, ge=0, le=50, description="per-column offset error of the relative "
                                       "calibration (rms), % of the band's Lref")


#: the image effects of [effects] and their settings' models
IMAGE_EFFECTS: dict[str, type[EffectSpec]] = {"psf": PsfSpec, "coregistration": CoregistrationSpec,
                                              "smile": SmileSpec, "nonuniformity": NonUniformitySpec}


def setting(value: Any, model: type[EffectSpec]) -> EffectSpec | None:
    """An ``[effects]`` key's settings: its table, ``model()`` for ``true``, None when off."""
    if value is True:
        return model()
    if isinstance(value, EffectSpec):
        return value if value.on else None
    return None


def magnitudes(value: Any, model: type[EffectSpec]) -> EffectSpec:
    """An ``[effects]`` key's settings whether it is on or off (the defaults where none are given)."""
    return value if isinstance(value, EffectSpec) else model()


class SpatialSpec(Section):
    """Deprecated: the [spatial] PSF is ``effects.psf = {fwhm = ...}``."""

    psf: Literal["none", "gaussian"] = Field("none", description="deprecated: write effects.psf = {fwhm = F}")
    psf_fwhm: float = Field(1.0, gt=0, le=10, description="deprecated: Gaussian PSF FWHM in band pixels "
                            "(effects.psf.fwhm)")


class InstrumentSpec(Section):
    """Deprecated: the [instrument] keys are ``[effects]`` keys now (:func:`moved_effects`)."""

    mtf: bool = Field(False, description="per-band spatial response: a Gaussian PSF per band whose system MTF "
                      "(with the box average to the band's GSD) at the band's Nyquist frequency is mtf_nyquist; "
                      "replaces [spatial] psf")
    mtf_nyquist: float = Field(0.15, gt=0, lt=BOX_MTF_NYQUIST, description="system MTF at Nyquist of every band "
                               "(below 2/π, the box average's own), unitless")
    mtf_nyquist_bands: dict[str, float] = Field(default_factory=dict, description="per-band MTF at Nyquist, "
                                                "e.g. {B2 = 0.25}; other bands take mtf_nyquist")
    coregistration: bool = Field(False, description="band-to-band co-registration error: each band shifted by a "
                                 "sub-pixel amount (band-limited shift by a finite filter on the input grid)")
    coregistration_px: float = Field(0.15, ge=0, le=2, description="each band's shift, band pixels, in a direction "
                                     "drawn from the seed (0.15: half the 0.3-pixel band-to-band requirement)")
    coregistration_shifts: dict[str, list[float]] = Field(
        default_factory=dict, description="per-band shift [dx, dy] in band pixels (x across, y along the image), "
        "e.g. {B5 = [0.1, -0.2]}; other bands take coregistration_px")
    smile: bool = Field(False, description="spectral smile: band centre (and width) vary across the swath, "
                        "polynomial in the column position x = -1 … 1 across the image")
    smile_centre_nm: list[float] = Field([0.0, 0.0, 1.0], min_length=1, max_length=6, description="centre shift "
                                         "Δλ(x) = c0 + c1·x + c2·x² + …, coefficients in nm")
    smile_width_pct: list[float] = Field([0.0], min_length=1, max_length=6, description="width change "
                                         "ΔFWHM(x)/FWHM, coefficients in %")
    nonuniformity: bool = Field(False, description="detector non-uniformity: per-column gain and offset of each "
                                "band, drawn from the seed")
    gain_pct: float = Field(2.0, ge=0, le=50, description="raw per-column gain spread (rms), %")
    offset_pct: float = Field(0.5, ge=0, le=50, description="raw per-column offset spread (rms), % of the band's Lref")
    equalised: bool = Field(True, description="a relative calibration equalises the columns, leaving the residuals "
                            "below (false: the raw non-uniformity stays in the product)")
    residual_gain_pct: float = Field(0.2, ge=0, le=50, description="per-column gain error of the relative "
                                     "calibration (rms), %: the striping left in the product")
    residual_offset_pct: float = Field(0.05, ge=0, le=50, description="per-column offset error of the relative "
                                       "calibration (rms), % of the band's Lref")

    @field_validator("mtf_nyquist_bands")
    @classmethod
    def _mtf_range(cls, value: dict[str, float]) -> dict[str, float]:
        for band, m in value.items():
            if not (0 < m < BOX_MTF_NYQUIST):
                raise ValueError(f"{band}: MTF at Nyquist must be > 0 and < {BOX_MTF_NYQUIST:.4f} (2/π, the box "
                                 f"average's own), got {m}")
        return value

    @field_validator("coregistration_shifts")
    @classmethod
    def _shifts(cls, value: dict[str, list[float]]) -> dict[str, list[float]]:
        for band, d in value.items():
            if len(d) != 2 or not all(math.isfinite(v) and abs(v) <= 2 for v in d):
                raise ValueError(f"{band}: a shift is [dx, dy] with |dx|, |dy| <= 2 band pixels, got {d}")
        return value

    @field_validator("smile_centre_nm", "smile_width_pct")
    @classmethod
    def _coefficients(cls, value: list[float]) -> list[float]:
        return _finite(value, "polynomial coefficients")

    @property
    def any(self) -> bool:
        """Whether any instrument effect is on."""
        return self.mtf or self.coregistration or self.smile or self.nonuniformity

    def describe(self) -> str:
        on = [k for k in ("mtf", "coregistration", "smile", "nonuniformity") if getattr(self, k)]
        return ", ".join(on) if on else "ideal"


def moved_effects(instrument: InstrumentSpec | None, spatial: SpatialSpec | None) -> tuple[dict[str, Any], list[str]]:
    """The ``[effects]`` keys that the deprecated [instrument] and [spatial] sections give, and a one-line note per
    key given there (``instrument.mtf_nyquist is deprecated: write it as effects.psf = {mtf_nyquist = 0.2}``)."""
    out: dict[str, Any] = {}
    notes: list[str] = []
    given = instrument.model_fields_set if instrument is not None else set()
    table = {
        "psf": ("mtf", {"mtf_nyquist": "mtf_nyquist", "mtf_nyquist_bands": "bands"}),
        "coregistration": ("coregistration", {"coregistration_px": "px", "coregistration_shifts": "shifts"}),
        "smile": ("smile", {"smile_centre_nm": "centre_nm", "smile_width_pct": "width_pct"}),
        "nonuniformity": ("nonuniformity", {k: k for k in ("gain_pct", "offset_pct", "equalised",
                                                              "residual_gain_pct", "residual_offset_pct")}),
    }
    if instrument is not None:
        for effect, (switch, keys) in table.items():
            on = getattr(instrument, switch)
            settings = {new: getattr(instrument, old) for old, new in keys.items() if old in given}
            if not on and not settings and switch not in given:
                continue
            model = IMAGE_EFFECTS[effect](**settings, on=on)
            out[effect] = model
            dumped = model.model_dump(exclude_defaults=True)
            shown = _toml(dumped) if dumped else ("true" if on else "false")
            for old in [switch, *keys]:
                if old in given:
                    notes.append(f"instrument.{old} is deprecated: write it as effects.{effect} = {shown}")
    if spatial is not None:
        if "psf" in out and spatial.psf != "none" and out["psf"].on:
            raise ValueError("instrument.mtf and spatial.psf both set a PSF: keep one, effects.psf")
        if spatial.psf != "none":
            out["psf"] = PsfSpec(fwhm=spatial.psf_fwhm)
        off = " (off: spatial.psf is 'none')" if spatial.psf == "none" else ""
        for key in sorted(spatial.model_fields_set):
            notes.append(f"spatial.{key} is deprecated: write it as effects.psf = {_toml({'fwhm': spatial.psf_fwhm})}"
                         + off)
    return out, notes


def _toml(d: dict[str, Any]) -> str:
    def one(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, dict):
            return _toml(v)
        if isinstance(v, list):
            return "[" + ", ".join(one(x) for x in v) + "]"
        return f"{v:g}" if isinstance(v, float) else repr(v) if isinstance(v, str) else str(v)
    return "{" + ", ".join(f"{k} = {one(v)}" for k, v in d.items()) + "}"


def check_image_effects(effects: Any, band_names: list[str], *, resample: bool, source: str) -> None:
    """The image effects of ``[effects]`` against the rest of the scene: named bands exist, the smile keeps every
    width positive and needs the SRF integral.

    :raises InputError: naming the file, key and what is allowed."""
    psf, coreg = magnitudes(effects.psf, PsfSpec), magnitudes(effects.coregistration, CoregistrationSpec)
    smile = setting(effects.smile, SmileSpec)
    if smile is not None and not resample:
        raise InputError("effects.smile moves each band's SRF: it needs effects.resample = true",
                         source=source, key="effects.smile")
    known = {b.lower() for b in band_names}
    for key, spec, field in (("psf", psf, "bands"), ("coregistration", coreg, "shifts")):
        unknown = [b for b in getattr(spec, field, {}) if b.lower() not in known]
        if unknown:
            raise InputError(f"unknown band(s) {', '.join(map(token, unknown))}; the sensor has "
                             f"{', '.join(band_names)}", source=source, key=f"effects.{key}.{field}")
    if isinstance(smile, SmileSpec):
        x = [-1.0 + 2.0 * i / 200 for i in range(201)]
        worst = min(sum(c * xi**n for n, c in enumerate(smile.width_pct)) for xi in x)
        if worst <= -90.0:
            raise InputError(f"the width change reaches {worst:.4g} % across the swath; it must stay above -90 %",
                             source=source, key="effects.smile.width_pct")
