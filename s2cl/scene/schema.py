"""The scene file's schema: pydantic models of every TOML section and key, with their ranges and descriptions
(``scenes/default.toml`` documents every key; :mod:`s2cl.scene.schema_errors` makes one-line errors of its
validation problems).
"""

from __future__ import annotations

import math
import re
from typing import Literal

from pydantic import Field, field_validator, model_validator

from s2cl.scene.analysis_schema import AnalysisSpec, ApplicationSpec
from s2cl.scene.grid_schema import GridSpec
from s2cl.scene.instrument_schema import (
    CoregistrationSpec,
    EffectSpec,
    InstrumentSpec,
    NonUniformitySpec,
    PsfSpec,
    SmileSpec,
    SpatialSpec,
)
from s2cl.scene.section import Section
from s2cl.scene.study_schema import (  # noqa: F401  (re-exported: the [study] section's model and limits)
    MAX_GAS_FACTOR,
    MAX_SHIFT_NM,
    MAX_WIDTH_FACTOR,
    StudySpec,
    WindowSpec,
)
from s2cl.sensor.srf import DEFAULT_SUPPORT

UINT32_MAX = 2**32 - 1
#: a scene name is a folder name: no separators, no leading dot
SCENE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


class SceneMeta(Section):
    name: str = Field(min_length=1, description="short name, used for the output folder")
    description: str = Field("", description="one line about the scene (listed by `s2cl scenes`)")

    @field_validator("name")
    @classmethod
    def _folder_name(cls, value: str) -> str:
        if not SCENE_NAME.fullmatch(value):
            raise ValueError("must be 1-100 letters, digits, '.', '_' or '-', starting with a letter or digit "
                             "(it names the output folder s2cl-out/NAME)")
        return value


class SurfaceSpec(Section):
    library: str | None = Field(None, description="'builtin:NAME' or a CSV / ENVI (.sli/.hdr) / s2cl .npz library file")
    cube: str | None = Field(None, description="image cube: a product as shipped (an EnMAP L2A folder, image or "
                             "METADATA.XML; an EMIT L2A or PRISMA L2D file; a GeoTIFF with GDAL wavelength metadata), "
                             "an ENVI file (the .hdr, or the data file beside it; AVIRIS-NG/-3 with map info) or a "
                             "NetCDF cube, whose no-data values, scale factors, bad bands and georeference are "
                             "honoured (pixels with no data are flagged NODATA, never used as data; GeoTIFF needs "
                             "the geo extra); or builtin:fields[:ROWSxCOLS], parcels generated with a known truth "
                             "(cab, lai)")
    variable: str | None = Field(None, description="NetCDF variable of the cube (default: the only 3-D one; EMIT: "
                                 "reflectance)")
    gsd_m: float | None = Field(None, gt=0, le=10000, description="ground sampling distance of the cube (m); default: "
                                "the pixel size of a product georeferenced in metres (a value that differs from it "
                                "simulates the bands as if the pixels were that size, and says so)")
    geometry: Literal["map", "sensor"] = Field("map", description="a product in sensor geometry with a lookup table "
                                               "(EMIT): orthorectified onto its map grid (map), or kept as the sensor "
                                               "saw it, without a georeference (sensor)")
    quantity: Literal["reflectance", "radiance"] = Field(
        "radiance", description="what the spectra hold: TOA radiance (W m-2 sr-1 um-1) or surface reflectance"
    )
    copies: int = Field(100, ge=1, le=1_000_000, description="noisy copies of each library spectrum")
    layout: Literal["rows", "blocks"] = Field("rows", description="image layout of the copies")
    select: dict[str, list[float]] = Field(default_factory=dict, description="keep the library's spectra whose "
                                           "parameter lies in [low, high] (inclusive), e.g. cab = [0, 25]")

    @field_validator("select")
    @classmethod
    def _select(cls, value: dict[str, list[float]]) -> dict[str, list[float]]:
        for name, bounds in value.items():
            if len(bounds) != 2 or not all(math.isfinite(v) for v in bounds) or bounds[0] > bounds[1]:
                raise ValueError(f"select.{name} must be [low, high] with finite low <= high, got {bounds}")
        return value


class SensorSpec(Section):
    name: Literal["sentinel2"] | None = Field("sentinel2", description="built-in sensor (Table 1 of the paper)")
    file: str | None = Field(None, description="sensor table CSV with the columns of the built-in one")
    bands: list[str] | None = Field(None, min_length=1, description="subset of bands, in order")
    srf: str = Field("model", description="'model' (paper eq. 1), 'measured-S2A', 'measured-S2B' or 'table:FILE.csv'")
    support: float = Field(DEFAULT_SUPPORT, gt=0, le=5, description="model SRF support, ± this many FWHM")


_IMAGE_ONLY = " (image cubes only: a library or sweep scene names it in a caveat)"


def _relative(values: dict[str, float], what: str) -> dict[str, float]:
    for band, v in values.items():
        if not (math.isfinite(v) and -0.5 < v < 0.5):
            raise ValueError(f"{band}: a relative {what} must be > -0.5 and < 0.5, got {v}")
    return values


class CalibrationErrorSpec(EffectSpec):
    """Each band's absolute calibration error e: the calibrated radiance is (1 + e) times the true one (the
    product's radiance, and the reflectance corrected from it, carry it); differing between bands, it bends the
    spectrum. A band of bands takes its own; every other band error + uncertainty z, z a standard normal deviate
    drawn once per band (from the seed and the band's name)."""

    error: float = Field(0.0, gt=-0.5, lt=0.5, description="relative error of every band not in bands (0.05: +5 %)")
    uncertainty: float = Field(0.0, ge=0, le=0.5, description="1-sigma relative uncertainty of the bands not in "
                               "bands: each draws its error once from the seed (Sentinel-2 requirement: 0.05)")
    bands: dict[str, float] = Field(default_factory=dict, description="relative error per band, e.g. {B5 = 0.02}")

    @field_validator("bands")
    @classmethod
    def _range(cls, value: dict[str, float]) -> dict[str, float]:
        return _relative(value, "calibration error")


class CrosstalkSpec(EffectSpec):
    """Inter-band crosstalk within one focal plane: band k's radiance gains the sum over the other bands j of its plane
    of c_kj L_j (VNIR: centres below swir_from_nm; SWIR: from there on), after the noise and before the
    quantisation. c_kj: the pairs entry of band k for band j where given, else coefficient, else the sensor table's
    crosstalk column (band k's), else 0.002 (an assumption, not a Sentinel-2 figure). In a sweep the design's bands
    are the plane; on an image cube, the bands of one GSD (the pixels they share)."""

    coefficient: float | None = Field(None, ge=-0.1, le=0.1, description="c of every pair of bands of one plane "
                                      "not in pairs")
    pairs: dict[str, dict[str, float]] = Field(default_factory=dict, description="c per pair: {B5 = {B4 = 0.003, "
                                               "B6 = 0.001}} (B5 gains 0.003 L_B4 + 0.001 L_B6)")
    swir_from_nm: float = Field(1000.0, gt=0, le=3000, description="band centres from here on lie on the SWIR focal "
                                "plane, those below on the VNIR plane")

    @field_validator("pairs")
    @classmethod
    def _range(cls, value: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
        for band, row in value.items():
            for other, c in row.items():
                if not (math.isfinite(c) and -0.1 <= c <= 0.1):
                    raise ValueError(f"{band}.{other}: a crosstalk coefficient must be >= -0.1 and <= 0.1, got {c}")
        return value


class EffectsSpec(Section):
    """The stages of the forward chain, in its order (s2cl.forward.stages), each on or off; an effect with settings
    takes a table of them (which switches it on), e.g. psf = {mtf_nyquist = 0.2}; the one home of every effect."""

    atmosphere: bool = Field(False, description="surface reflectance to TOA radiance at each wavelength (6S LUT)")
    smile: SmileSpec | bool = Field(False, description="spectral smile: each band's SRF moved (and widened) across "
                                    "the swath, {centre_nm = [c0, c1, c2], width_pct = [w0]}" + _IMAGE_ONLY)
    resample: bool = Field(True, description="integrate the spectra over each band's SRF (false: ideal monochromatic "
                           "bands at the centres)")
    psf: PsfSpec | bool = Field(False, description="each band's Gaussian PSF before the box average to its GSD, "
                                "{mtf_nyquist = 0.15} (the system MTF at Nyquist) or {fwhm = 1.0} (band pixels), "
                                "per band in bands = {B2 = 0.25}; true: MTF 0.15" + _IMAGE_ONLY)
    coregistration: CoregistrationSpec | bool = Field(False, description="band-to-band co-registration error: each "
                                                      "band shifted by a sub-pixel amount, {px = 0.15, shifts = "
                                                      "{B5 = [0.1, -0.2]}}" + _IMAGE_ONLY)
    nonuniformity: NonUniformitySpec | bool = Field(False, description="detector non-uniformity: per-column gain and "
                                                    "offset of each band drawn from the seed, {gain_pct = 2, "
                                                    "residual_gain_pct = 0.2, ...}" + _IMAGE_ONLY)
    noise: bool = Field(True, description="add the sensor's noise (SNR model of each band)")
    crosstalk: CrosstalkSpec | bool = Field(False, description="inter-band crosstalk within a focal plane (VNIR, "
                                            "SWIR): each band's radiance gains c L_j from the other bands of its "
                                            "plane, after the noise, e.g. {coefficient = 0.002} or {pairs = {B5 = "
                                            "{B4 = 0.003}}}; true: the sensor table's crosstalk column, else 0.002")
    seed: int = Field(0, ge=0, le=UINT32_MAX, description="noise generator seed (Philox key): same seed, same noise")
    frame: int = Field(0, ge=0, le=UINT32_MAX, description="noise frame (Philox counter word): another frame draws "
                       "independent noise for the same pixels")
    quantise: bool = Field(True, description="quantise radiance to digital numbers between Lmin and Lmax")
    bits: int | None = Field(None, ge=1, le=16, description="radiometric resolution (default: the sensor's, 12)")
    calibrate: bool = Field(True, description="convert digital numbers back to radiance (W m-2 sr-1 um-1)",
                            json_schema_extra={"needs": ["quantise", "calibration turns DN back into radiance"]})
    calibration_error: CalibrationErrorSpec | bool = Field(
        False, description="each band's absolute calibration error: its calibrated radiance is (1 + e) times the "
        "true one, e per band ({bands = {B5 = 0.02}}), common ({error = 0.05}) or drawn once per band from a 1-sigma "
        "uncertainty with the seed ({uncertainty = 0.05}; Sentinel-2: 5 %); correction.calibration_gain g is the "
        "shorthand {error = g - 1}")
    correct: bool = Field(False, description="band-effective atmospheric correction of band radiance back to "
                          "surface reflectance (the state of [correction])",
                          json_schema_extra={"needs": ["atmosphere", "the correction inverts an atmosphere"]})


class AtmosphereSpec(Section):
    """Atmospheric state (ranges are checked against the LUT's axes when it is read)."""

    profile: Literal["midlatitude_summer", "midlatitude_winter"] = Field(
        "midlatitude_summer", description="atmospheric profile (temperature, pressure, gases) of the LUT")
    water_vapour: float = Field(1.5, gt=0, description="water vapour column, g/cm2")
    aot550: float | None = Field(None, ge=0, description="aerosol optical thickness at 550 nm (or visibility_km)")
    visibility_km: float | None = Field(None, gt=0, description="horizontal visibility (default 23 km if no aot550)")
    ozone: float = Field(330.0, gt=0, description="ozone column, DU")
    solar_zenith: float = Field(40.0, ge=0, lt=90, description="degrees")
    lut: str | None = Field(None, description="LUT file (default: the one shipped with s2cl)")
    interpolation: Literal["linear", "nearest"] = Field("linear", description="interpolation in the LUT's axes")


class CorrectionSpec(Section):
    """The state the atmospheric correction assumes; keys not given are taken from [atmosphere]."""

    profile: Literal["midlatitude_summer", "midlatitude_winter"] | None = Field(
        None, description="assumed atmospheric profile (default: [atmosphere]'s)")
    water_vapour: float | None = Field(None, gt=0, description="assumed water vapour column, g/cm2")
    aot550: float | None = Field(None, ge=0, description="assumed aerosol optical thickness at 550 nm")
    visibility_km: float | None = Field(None, gt=0, description="assumed horizontal visibility, km")
    ozone: float | None = Field(None, gt=0, description="assumed ozone column, DU")
    solar_zenith: float | None = Field(None, ge=0, lt=90, description="assumed solar zenith angle, degrees")
    calibration_gain: float = Field(1.0, gt=0.5, lt=1.5, description="factor applied to calibrated radiance "
                                    "(1.05: a +5 % calibration error in every band; the shorthand of "
                                    "effects.calibration_error = {error = 0.05})")


class RangeSpec(Section):
    """Where a band may move (nm), one of: a window with a width range (left, right, min_width,
    max_width: the paper's Table 2); a grid of centres × widths (centres, widths: lists, or
    [first, last, step] with grid_step); or a fixed band (centre, width)."""

    left: float | None = Field(None, description="window: lowest wavelength a band edge may reach, nm")
    right: float | None = Field(None, description="window: highest wavelength a band edge may reach, nm")
    min_width: float | None = Field(None, gt=0, description="window: narrowest band width (FWHM), nm")
    max_width: float | None = Field(None, gt=0, description="window: widest band width (FWHM), nm")
    centres: list[float] | None = Field(None, min_length=1, description="grid: band centres, nm")
    widths: list[float] | None = Field(None, min_length=1, description="grid: band widths (FWHM), nm")
    centre: float | None = Field(None, description="fixed band: centre, nm")
    width: float | None = Field(None, gt=0, description="fixed band: width (FWHM), nm")


class AddSpec(RangeSpec):
    """A band-addition sweep's one added band (not a band of the sensor): its name, the sensor band whose
    radiometry (Lmin, Lmax, SNR table at that band's own width) it takes, and where it moves (any form of
    :class:`RangeSpec`); the [sweep] bands are then the fixed base set (s2cl.sweep.addition)."""

    name: str = Field(min_length=1, description="name of the added band (1-32 letters, digits, '_' or '-'; "
                      "not a band of the sensor), e.g. 'N2300'")
    like: str = Field(min_length=1, description="sensor band whose radiometry the added band takes (noise "
                      "rescaled to each width as for any swept band)")


class SweepSpec(Section):
    bands: list[str] = Field(min_length=1, description="swept bands, in fit order (with [sweep.add]: the fixed base "
                             "set; the added band is analysed after them)")
    preset: Literal["none", "table2"] = Field("none", description="take unlisted ranges from the paper's Table 2")
    step_nm: float = Field(5.0, gt=0, le=100, description="step of centres and widths in a window range, nm")
    ranges: dict[str, RangeSpec] = Field(default_factory=dict, description="where each swept band moves, one "
                                         "table per band (ranges.B4 = {...}): a window, a grid or a fixed band")
    chunk: int | None = Field(None, ge=1, le=1_000_000, description="configurations per chunk (default: auto)")
    underdetermined: Literal["exclude", "keep"] = Field(
        "exclude", description="designs the analysis cannot fit (e.g. two IGRM bands on one centre, "
        "s2cl.retrieve.design): left out of the ranking, or kept in it, flagged; results.parquet flags them either way")
    within_noise_top: int = Field(100, ge=0, le=10_000, description="the best designs re-scored per pixel to find "
                                  "those within noise of #1 (a paired bootstrap over library spectra, "
                                  "s2cl.sweep.within_noise); 0: none")
    add: AddSpec | None = Field(None, description="band-addition sweep: the one added band; every configuration is "
                                "scored by its gain over the fixed base set alone (s2cl.sweep.addition)")
    search: Literal["exhaustive", "halving"] = Field(
        "exhaustive", description="exhaustive: score every design on every pixel; halving: successive halving on "
        "noise copies (every design on one copy, the best search_keep on search_keep⁻¹ times more, ..., the "
        "finalists on every pixel, scored exactly as the exhaustive sweep scores them), from a coarse sub-grid "
        "refined step by step when the space holds more than search_start designs (s2cl.sweep.search)")
    search_keep: float = Field(0.25, gt=0, le=0.5, description="halving: fraction of the designs a rung keeps; the "
                               "next rung scores them on 1 / search_keep times more copies")
    search_finalists: int = Field(16, ge=1, le=100_000, description="halving: designs scored on every pixel at the "
                                  "end of each halving (at least)")
    search_start: int = Field(100_000, ge=100, le=100_000_000, description="halving: most designs of the first rung; "
                              "a larger space starts from a coarse sub-grid of its centres and widths and refines "
                              "around the finalists down to the space's own step")
    search_radius: int = Field(5, ge=1, le=50, description="halving of a refined space: the last stage moves each band "
                               "alone over ± search_radius steps of centre and width, and all bands together over ± "
                               "1 step, on every pixel, until no design there scores better; then each band alone "
                               "over its whole range (halved), back to this stage wherever that finds a better design")
    search_seed: int = Field(0, ge=0, le=2**31 - 1, description="halving: seed of the coarse sub-grid's offset (the "
                             "noise is effects.seed's); the same seed gives the same search")
    search_restarts: int = Field(4, ge=1, le=64, description="halving of a refined space: coarse sub-grids it "
                                 "starts from (offsets moved by stride / search_restarts steps each), each halved "
                                 "and refined to the space's step; their best designs are then crossed band by band, "
                                 "halved and refined again before the local stage")


class OutputSpec(Section):
    directory: str | None = Field(None, description="output folder (default: s2cl-out/<scene name>)")
    format: Literal["netcdf", "cog"] = Field("netcdf", description="image outputs of s2cl simulate: simulation.nc "
                                             "alone (netcdf), or also Cloud-Optimised GeoTIFFs, one per GSD group "
                                             "and one per retrieval map (cog; needs the geo extra; the CLI's --format "
                                             "wins)")
    precision: Literal["float32", "float64"] | None = Field(
        None, description="deprecated: use compute.precision (still read, with a warning)")


class ComputeSpec(Section):
    """How the scene is computed: settings that change numbers or where they run, not what is simulated."""

    precision: Literal["float32", "float64"] = Field(
        "float32", description="working precision of every kernel (float64 for reference runs)")
    lanes: int | None = Field(None, description="pixels per work-item of the per-pixel fits and the sweep "
                              "(1, 2, 4, 8 or 16; "
                              "default: the widest width the device builds cleanly on CPUs, 1 on GPUs)")
    device: str | None = Field(None, description="OpenCL device (PLATFORM:DEVICE or part of its name; the CLI's "
                               "--device wins; default: $PYOPENCL_CTX, else the PoCL CPU device that builds "
                               "the widest vectors)")


class SceneSpec(Section):
    scene: SceneMeta = Field(description="the scene's name and description")
    surface: SurfaceSpec = Field(description="what is seen: a spectral library (with noisy copies) or an image cube")
    sensor: SensorSpec = Field(SensorSpec(), description="the sensor: bands, radiometry and SRFs")
    grid: GridSpec = Field(GridSpec(), description="the spectral grid everything is simulated on")
    atmosphere: AtmosphereSpec = Field(AtmosphereSpec(), description="the true atmospheric state (6S LUT)")
    correction: CorrectionSpec = Field(CorrectionSpec(), description="the state the atmospheric correction assumes")
    effects: EffectsSpec = Field(EffectsSpec(), description="which stages of the chain run, and their settings: the "
                                 "one home of every effect")
    spatial: SpatialSpec | None = Field(None, description="deprecated: its PSF is effects.psf (still read, with a "
                                        "note)")
    instrument: InstrumentSpec | None = Field(None, description="deprecated: its effects are [effects] keys (psf, "
                                              "coregistration, smile, nonuniformity; still read, with a note)")
    analysis: AnalysisSpec | None = Field(None, description="the retrieval scored on the simulated bands")
    application: list[ApplicationSpec] | None = Field(None, description="several applications sharing one band "
                                                      "set, instead of [analysis] (s2cl.scene.applications)")
    sweep: SweepSpec | None = Field(None, description="which bands move, and where (s2cl optimise)")
    study: StudySpec | None = Field(None, description="an atmospheric-band, stability or cellulose study "
                                    "(s2cl study)")
    compute: ComputeSpec = Field(ComputeSpec(), description="precision, vector width and device")
    output: OutputSpec = Field(OutputSpec(), description="where the outputs are written")

    @model_validator(mode="after")
    def _applications(self) -> SceneSpec:
        """[[application]] is a non-empty list of uniquely named applications, and replaces [analysis]."""
        if self.application is None:
            return self
        if self.analysis is not None:
            raise ValueError("application: give [analysis] (one application) or [[application]] (several), not both")
        if not self.application:
            raise ValueError("application: the list is empty; give at least one [[application]] or an [analysis]")
        names = [a.name for a in self.application]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"application: two applications are named {', '.join(repr(n) for n in twice)}; names "
                             "must differ (they name the results columns)")
        return self

    @model_validator(mode="after")
    def _calibration_gain(self) -> SceneSpec:
        """``correction.calibration_gain`` g is the shorthand of ``effects.calibration_error = {error = g - 1}``."""
        gain = self.correction.calibration_gain
        if gain == 1.0:
            return self
        if self.effects.calibration_error is not False:
            raise ValueError("correction.calibration_gain is the shorthand of effects.calibration_error: give one")
        effects = self.effects.model_copy(update={"calibration_error": CalibrationErrorSpec(error=gain - 1.0)})
        return self.model_copy(update={"effects": effects})
