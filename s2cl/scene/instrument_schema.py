"""The scene's [instrument] section: the instrument's own artefacts on an image cube, each off unless asked for.

Split from :mod:`s2cl.scene.schema` by subject; the scene model there holds an :class:`InstrumentSpec`. Default
magnitudes and their sources are listed in :data:`SOURCES` (the effect-cost table prints them); the model is
:mod:`s2cl.forward.instrument`.
"""

from __future__ import annotations

import math

from pydantic import Field, field_validator

from s2cl.errors import InputError, token
from s2cl.scene.section import Section

#: system MTF of the box aggregation alone at the band's Nyquist frequency, sinc(1/2) = 2/π: a Gaussian PSF
#: can only lower it, so an MTF at Nyquist must lie below
BOX_MTF_NYQUIST = 2.0 / math.pi

#: the default magnitude of each effect and where it comes from (an assumption is said to be one)
SOURCES: dict[str, str] = {
    "mtf": "MTF at Nyquist 0.15 for every band: the lower end of the 0.15-0.30 range the Sentinel-2 MSI "
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


class InstrumentSpec(Section):
    """Instrument artefacts applied to an image cube (``[surface] cube``), each off unless switched on here."""

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


def check_instrument(spec: InstrumentSpec, band_names: list[str], *, psf: str, cube: bool, resample: bool,
                     source: str) -> None:
    """The [instrument] section against the rest of the scene: named bands exist, the smile keeps every width
    positive, the per-band MTF does not meet a [spatial] PSF, and an effect needs an image cube.

    :raises InputError: naming the file, key and what is allowed."""
    if spec.any and not cube:
        raise InputError("instrument effects act on an image cube: give surface.cube or switch them off",
                         source=source, key="instrument")
    if spec.mtf and psf != "none":
        raise InputError("instrument.mtf sets each band's PSF: remove spatial.psf (one PSF model at a time)",
                         source=source, key="spatial.psf")
    if spec.smile and not resample:
        raise InputError("instrument.smile moves each band's SRF: it needs effects.resample = true",
                         source=source, key="instrument.smile")
    known = {b.lower() for b in band_names}
    for key in ("mtf_nyquist_bands", "coregistration_shifts"):
        unknown = [b for b in getattr(spec, key) if b.lower() not in known]
        if unknown:
            raise InputError(f"unknown band(s) {', '.join(map(token, unknown))}; the sensor has "
                             f"{', '.join(band_names)}", source=source, key=f"instrument.{key}")
    if spec.smile:
        x = [-1.0 + 2.0 * i / 200 for i in range(201)]
        worst = min(sum(c * xi**n for n, c in enumerate(spec.smile_width_pct)) for xi in x)
        if worst <= -90.0:
            raise InputError(f"the width change reaches {worst:.4g} % across the swath; it must stay above -90 %",
                             source=source, key="instrument.smile_width_pct")
