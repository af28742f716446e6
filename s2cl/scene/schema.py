"""The scene file's schema (pydantic models of every TOML section and key, with their ranges and
descriptions) and the one-line errors made from its validation problems: file, dotted key, what is
allowed (``scenes/default.toml`` documents every key).
"""

from __future__ import annotations

import difflib
import math
import re
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from s2cl.errors import InputError, key_token, token
from s2cl.retrieve.indices import INDICES, ROLE_KEYS
from s2cl.sensor.names import BAND_NAME, BAND_NAME_RULE
from s2cl.sensor.srf import DEFAULT_SUPPORT

UINT32_MAX = 2**32 - 1
#: stability study: largest band-centre shift (nm) and width factor a [study] may ask for
MAX_SHIFT_NM, MAX_WIDTH_FACTOR = 100.0, 5.0
#: cellulose study: largest factor on a fixed gas's column a [study] may ask for
MAX_GAS_FACTOR = 3.0
#: a scene name is a folder name: no separators, no leading dot
SCENE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


class SceneMeta(_Section):
    name: str = Field(min_length=1, description="short name, used for the output folder")
    description: str = ""

    @field_validator("name")
    @classmethod
    def _folder_name(cls, value: str) -> str:
        if not SCENE_NAME.fullmatch(value):
            raise ValueError("must be 1-100 letters, digits, '.', '_' or '-', starting with a letter or digit "
                             "(it names the output folder s2cl-out/NAME)")
        return value


class SurfaceSpec(_Section):
    library: str | None = Field(None, description="'builtin:NAME' or a CSV / ENVI (.sli/.hdr) / s2cl .npz library file")
    cube: str | None = Field(None, description="image cube file: NetCDF (.nc) or ENVI (.hdr)")
    variable: str | None = Field(None, description="NetCDF variable of the cube (default: the only 3-D one)")
    gsd_m: float | None = Field(None, gt=0, le=10000, description="ground sampling distance of the cube (m)")
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


class SensorSpec(_Section):
    name: Literal["sentinel2"] | None = Field("sentinel2", description="built-in sensor (Table 1 of the paper)")
    file: str | None = Field(None, description="sensor table CSV with the columns of the built-in one")
    bands: list[str] | None = Field(None, min_length=1, description="subset of bands, in order")
    srf: str = Field("model", description="'model' (paper eq. 1), 'measured-S2A', 'measured-S2B' or 'table:FILE.csv'")
    support: float = Field(DEFAULT_SUPPORT, gt=0, le=5, description="model SRF support, ± this many FWHM")


class GridSpec(_Section):
    start_nm: float = Field(400.0, ge=200, le=3000)
    stop_nm: float = Field(2500.0, ge=200, le=3000)
    step_nm: float = Field(1.0, gt=0, le=50)


class EffectsSpec(_Section):
    atmosphere: bool = False
    resample: bool = True
    noise: bool = True
    seed: int = Field(0, ge=0, le=UINT32_MAX)
    frame: int = Field(0, ge=0, le=UINT32_MAX)
    quantise: bool = True
    bits: int | None = Field(None, ge=1, le=16, description="radiometric resolution (default: the sensor's, 12)")
    calibrate: bool = True
    correct: bool = False


class AtmosphereSpec(_Section):
    """Atmospheric state (ranges are checked against the LUT's axes when it is read)."""

    profile: Literal["midlatitude_summer", "midlatitude_winter"] = "midlatitude_summer"
    water_vapour: float = Field(1.5, gt=0, description="water vapour column, g/cm2")
    aot550: float | None = Field(None, ge=0, description="aerosol optical thickness at 550 nm (or visibility_km)")
    visibility_km: float | None = Field(None, gt=0, description="horizontal visibility (default 23 km if no aot550)")
    ozone: float = Field(330.0, gt=0, description="ozone column, DU")
    solar_zenith: float = Field(40.0, ge=0, lt=90, description="degrees")
    lut: str | None = Field(None, description="LUT file (default: the one shipped with s2cl)")
    interpolation: Literal["linear", "nearest"] = "linear"


class CorrectionSpec(_Section):
    """The state the atmospheric correction assumes; keys not given are taken from [atmosphere]."""

    profile: Literal["midlatitude_summer", "midlatitude_winter"] | None = None
    water_vapour: float | None = Field(None, gt=0)
    aot550: float | None = Field(None, ge=0)
    visibility_km: float | None = Field(None, gt=0)
    ozone: float | None = Field(None, gt=0)
    solar_zenith: float | None = Field(None, ge=0, lt=90)
    calibration_gain: float = Field(1.0, gt=0, le=10, description="factor applied to calibrated radiance "
                                                                  "(1.05: a +5 % calibration error)")


class RangeSpec(_Section):
    """Where a band may move (nm), one of: a window with a width range (left, right, min_width,
    max_width: the paper's Table 2); a grid of centres × widths (centres, widths: lists, or
    [first, last, step] with grid_step); or a fixed band (centre, width)."""

    left: float | None = None
    right: float | None = None
    min_width: float | None = Field(None, gt=0)
    max_width: float | None = Field(None, gt=0)
    centres: list[float] | None = Field(None, min_length=1)
    widths: list[float] | None = Field(None, min_length=1)
    centre: float | None = None
    width: float | None = Field(None, gt=0)


class AddSpec(RangeSpec):
    """A band-addition sweep's one added band (not a band of the sensor): its name, the sensor band whose
    radiometry (Lmin, Lmax, SNR table at that band's own width) it takes, and where it moves (any form of
    :class:`RangeSpec`); the [sweep] bands are then the fixed base set (s2cl.sweep.addition)."""

    name: str = Field(min_length=1, description="name of the added band (1-32 letters, digits, '_' or '-'; "
                      "not a band of the sensor), e.g. 'N2300'")
    like: str = Field(min_length=1, description="sensor band whose radiometry the added band takes (noise "
                      "rescaled to each width as for any swept band)")


class SweepSpec(_Section):
    bands: list[str] = Field(min_length=1, description="swept bands, in fit order (with [sweep.add]: the fixed base "
                             "set; the added band is analysed after them)")
    preset: Literal["none", "table2"] = Field("none", description="take unlisted ranges from the paper's Table 2")
    step_nm: float = Field(5.0, gt=0, le=100)
    ranges: dict[str, RangeSpec] = Field(default_factory=dict)
    chunk: int | None = Field(None, ge=1, le=1_000_000, description="configurations per chunk (default: auto)")
    underdetermined: Literal["exclude", "keep"] = Field(
        "exclude", description="designs the analysis cannot fit (e.g. two IGRM bands on one centre, "
        "s2cl.retrieve.design): left out of the ranking, or kept in it, flagged; results.parquet flags them either way")
    add: AddSpec | None = Field(None, description="band-addition sweep: the one added band; every configuration is "
                                "scored by its gain over the fixed base set alone (s2cl.sweep.addition)")


#: every [analysis] kind: the IGRM fit, each normalised-difference index (s2cl.retrieve.indices), SAM
ANALYSIS_KINDS = ("igrm", *INDICES, "sam")


class AnalysisSpec(_Section):
    kind: Literal[ANALYSIS_KINDS]  # type: ignore[valid-type]
    bands: list[str] | None = Field(None, min_length=2, description="bands analysed by `s2cl simulate` (default: the "
                                    "swept bands, else B4 B5 B6 B7 for igrm, an index's role bands, all for sam)")
    parameter: str | None = Field(None, description="library parameter regressed on the index (igrm: cab, gvmi: ewt)")
    roles: dict[str, str] = Field(default_factory=dict, description="an index's band of each role, written as keys of "
                                  "[analysis] (gvmi: nir = 'B8', swir = 'B11'; s2cl.retrieve.indices)")
    classes: list[str] | None = Field(None, description="sam: library groups to tell apart (default: all)")
    angle_threshold_deg: float | None = Field(None, gt=0, le=90, description="sam: larger angles are unclassified")
    igrm: dict[str, Any] = Field(default_factory=dict, description="IGRM fit settings (see s2cl.retrieve.igrm)")
    regress: list[Literal["converged", "stalled", "iteration_limit"]] = Field(
        ["converged", "stalled", "iteration_limit"], min_length=1,
        description="IGRM fit statuses whose lp enters the regression (degenerate and invalid fits never do; "
        "the summary counts the pixels left out)")

    @model_validator(mode="before")
    @classmethod
    def _gather_roles(cls, data: Any) -> Any:
        """Band-role keys (``nir = "B8"``) of any registered index go into :attr:`roles`."""
        if isinstance(data, dict) and any(k in data for k in ROLE_KEYS):
            data = dict(data)
            data["roles"] = {k: data.pop(k) for k in ROLE_KEYS if k in data}
        return data


class SpatialSpec(_Section):
    psf: Literal["none", "gaussian"] = "none"
    psf_fwhm: float = Field(1.0, gt=0, le=10, description="Gaussian PSF FWHM in units of the band's GSD")


class OutputSpec(_Section):
    directory: str | None = Field(None, description="output folder (default: s2cl-out/<scene name>)")
    precision: Literal["float32", "float64"] | None = Field(
        None, description="deprecated: use compute.precision (still read, with a warning)")


class ComputeSpec(_Section):
    """How the scene is computed: settings that change numbers or where they run, not what is simulated."""

    precision: Literal["float32", "float64"] = Field(
        "float32", description="working precision of every kernel (float64 for reference runs)")
    lanes: int | None = Field(None, description="pixels per work-item of the per-pixel fits and the sweep "
                              "(1, 2, 4, 8 or 16; "
                              "default: the device's native vector width)")
    device: str | None = Field(None, description="OpenCL device (PLATFORM:DEVICE or part of its name; the CLI's "
                               "--device wins; default: $PYOPENCL_CTX, else the first PoCL CPU device)")


class WindowSpec(_Section):
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


class StudySpec(_Section):
    """A study (``s2cl study NAME``): the paper's atmospheric-band studies vary the bands of the [sweep] section;
    ``stability`` drifts the bands of each scene in ``applications``."""

    kind: Literal["cirrus", "water-vapour", "water-vapour-1020", "aerosol", "ozone", "methane", "stability",
                  "cellulose"]
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


class SceneSpec(_Section):
    scene: SceneMeta
    surface: SurfaceSpec
    sensor: SensorSpec = SensorSpec()
    grid: GridSpec = GridSpec()
    atmosphere: AtmosphereSpec = AtmosphereSpec()
    correction: CorrectionSpec = CorrectionSpec()
    effects: EffectsSpec = EffectsSpec()
    spatial: SpatialSpec = SpatialSpec()
    analysis: AnalysisSpec | None = None
    sweep: SweepSpec | None = None
    study: StudySpec | None = None
    compute: ComputeSpec = ComputeSpec()
    output: OutputSpec = OutputSpec()


def input_error(err: ValidationError, source: str) -> InputError:
    """The first validation problem as one line: file, dotted key, what is allowed."""
    e = err.errors()[0]
    loc = [str(x) for x in e["loc"]]
    if loc[:2] == ["analysis", "roles"]:  # role keys are written as keys of [analysis]
        loc = ["analysis", *loc[2:]]
    key = ".".join(key_token(x) for x in loc)
    if e["type"] == "extra_forbidden":
        allowed = _allowed_keys(loc[:-1])
        near = difflib.get_close_matches(loc[-1], allowed, n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        return InputError(f"unknown key{hint}; allowed keys here: {', '.join(allowed)}", source=source, key=key)
    if e["type"] == "missing":
        return InputError("required key is missing", source=source, key=key)
    if e["type"] == "value_error":
        return InputError(str((e.get("ctx") or {}).get("error", e["msg"])), source=source, key=key)
    return InputError(f"{_allowed_text(e, loc)}, got {token(e.get('input'))}", source=source, key=key)


_BOUNDS = (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"))


def _allowed_text(e: dict[str, Any], loc: list[str]) -> str:
    """'must be >= 1 and <= 16' from the field's declared range (not only the violated side)."""
    info = _field(loc)
    declared = []
    for meta in getattr(info, "metadata", []):
        for attr, sym in _BOUNDS:
            if getattr(meta, attr, None) is not None:
                declared.append(f"{sym} {getattr(meta, attr)}")
    ctx = e.get("ctx") or {}
    if declared and any(k in ctx for k, _ in _BOUNDS):
        return "must be " + " and ".join(declared)
    if "expected" in ctx:
        return f"must be one of {ctx['expected']}"
    return e["msg"].replace("Input should be", "must be")


def _field(loc: list[str]) -> Any:
    """The pydantic FieldInfo at a dotted location, or None."""
    info, _ = _walk(loc)
    return info


def _walk(loc: list[str]) -> tuple[Any, Any]:
    """(FieldInfo, type) at a dotted location; the type of an entry of a ``dict[str, Model]`` field (such as
    ``sweep.ranges.B4``) is the model, with no FieldInfo. (None, None) where the location leaves the schema."""
    model: Any = SceneSpec
    info = None
    for part in loc:
        model = _unwrap_optional(model)
        if getattr(model, "__origin__", None) is dict:  # an entry of a dict field: its key is the user's
            info, model = None, model.__args__[1]
            continue
        fields = getattr(model, "model_fields", None)
        if not fields or part not in fields:
            return None, None
        info = fields[part]
        model = info.annotation
    return info, model


def _allowed_keys(loc: list[str]) -> list[str]:
    if not loc:
        return list(SceneSpec.model_fields)
    if loc == ["analysis"]:
        return [k for k in AnalysisSpec.model_fields if k != "roles"] + list(ROLE_KEYS)
    _, model = _walk(loc)
    fields = getattr(_unwrap_optional(model), "model_fields", None)
    return list(fields) if fields else []


def _unwrap_optional(annotation: Any) -> Any:
    """``X | None`` → ``X`` (for walking nested sections)."""
    args = getattr(annotation, "__args__", None)
    if args and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        if len(rest) == 1:
            return rest[0]
    return annotation
