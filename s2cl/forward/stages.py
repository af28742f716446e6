"""The forward chain as declared stages: the one place that says which stages there are and in which order.

Each :class:`Stage` is declared once, in :data:`STAGES` (the chain's order): its name, its scene key, what it acts
on, its kernel inputs (:class:`Value`: what the sweep tables tabulate per variant) and outputs, its device function
(a ``<%def>`` of ``kernels/common/stages.mako`` and its ``<def>_step``, which ``sense.cl.mako`` and
``sweep.cl.mako`` splice in this order), its float64 twin (a function of :mod:`s2cl.reference.stages` with the
same step signature, which :mod:`s2cl.reference.forward` and :mod:`s2cl.reference.sweep` run in this order) and
the attributes it writes on each band's output variable. The kernels' argument lists are built from it
(:func:`s2cl.forward.sense.sense_args`, :func:`s2cl.sweep.kernel.kernel_args`).

What a stage acts on (``acts``):

- ``spectrum``: per wavelength or at the spectral integral (atmosphere, resampling; the smile on image cubes);
- ``image``: on a band's image (image cubes only; a library or sweep scene names it in a caveat, see
  :func:`image_only`);
- ``bands``: across the bands of one pixel (a step over all of them at once);
- ``band``: per band and pixel: a library pixel, an image pixel and every configuration of a sweep.

Adding a per-band effect: a key in ``s2cl/scene/schema.py`` (``[effects]``), an entry here, its device function and
step in ``kernels/common/stages.mako``, its twin in ``s2cl/reference/stages.py`` — four files
(``tests/test_stages.py`` counts them).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from s2cl.forward.radiometry import Radiometry
from s2cl.scene.caveats import Caveat
from s2cl.scene.effects import EffectSet
from s2cl.scene.schema import CalibrationErrorSpec, CrosstalkSpec
from s2cl.sensor.noise_model import noise_sigma
from s2cl.sensor.sensor import Sensor

Acts = Literal["spectrum", "image", "bands", "band"]
Varies = Literal["band", "variant", "pixel", "scalar", "pairs"]
RADIANCE_UNITS = "W m-2 sr-1 um-1"


@dataclass(frozen=True)
class Value:
    """A per-band input of a stage's device step.

    :param varies: ``band``: one per band (a sweep: a literal per band slot, each variant taking its band's);
        ``variant``: one per band (a sweep: one per variant, a table gathered by variant); ``pixel``: a sweep's
        table per variant and spectrum (computed on the host; the sense kernel computes it itself); ``scalar``: one
        for every band; ``pairs``: one per pair of bands ``[k][j]`` (literals).
    :param ctype: ``real`` (the working precision) or an OpenCL scalar type.
    :param sense, sweep: whether the sense kernel (libraries, images) and the sweep kernel read it.
    """

    name: str
    varies: Varies
    ctype: str = "real"
    sense: bool = True
    sweep: bool = True


@dataclass(frozen=True)
class Output:
    """A per-pixel output of a stage: ``[n_bands × n_pixels]`` of ``ctype`` (``real``, ``ushort``, ``uchar``)."""

    name: str
    ctype: str
    units: str
    long_name: str

    @property
    def dtype(self) -> np.dtype | None:
        """The host dtype (None: the working precision's)."""
        return {"ushort": np.dtype(np.uint16), "uchar": np.dtype(np.uint8)}.get(self.ctype)

    def itemsize(self, precision: str) -> int:
        return (self.dtype or np.dtype(precision)).itemsize


@dataclass(frozen=True)
class Stage:
    """One stage of the forward chain (see the module doc)."""

    name: str
    key: str
    acts: Acts
    summary: str
    values: tuple[Value, ...] = ()
    outputs: tuple[Output, ...] = ()
    #: the ``<%def>`` of ``kernels/common/stages.mako`` with its device functions; ``<device>_step`` splices it
    device: str | None = None
    #: its float64 twin, ``module:function``
    twin: str | None = None
    #: its values for a set of bands: name -> array over the bands (``pairs``: ``[n, n]``; ``scalar``: a number)
    compute: Callable[[Radiometry], dict[str, Any]] | None = None
    #: what it did to band ``k`` of a set, as attributes of that band's output variables
    attrs: Callable[[Radiometry, int], dict[str, Any]] | None = None
    #: it takes a standard normal deviate per band and pixel (the kernels' common random numbers)
    deviates: bool = False
    #: it degrades the signal: an ideal instrument leaves it out (:mod:`s2cl.studies.instrument_costs`)
    degrades: bool = False
    #: warnings about a sensor's bands with this stage on (sensor, band names) -> caveats
    caveats: Callable[[Sensor, list[str]], list[Caveat]] | None = None

    @property
    def per_pixel(self) -> bool:
        """Whether the sense and sweep kernels run it (per band, or across the bands of a pixel)."""
        return self.acts in ("band", "bands")

    def computed(self, ctx: Radiometry) -> dict[str, Any]:
        return self.compute(ctx) if self.compute is not None else {}


# -- the stages' values --------------------------------------------------------------------------------------------

def _noise(ctx: Radiometry) -> dict[str, Any]:
    out: dict[str, Any] = {"noise_a": ctx.noise_a, "noise_b": ctx.noise_b}
    if ctx.radiance is not None:  # σ of each variant's noise-free radiance, per spectrum (the sweep's table)
        out["sigma"] = noise_sigma(ctx.radiance, ctx.noise_a[:, None], ctx.noise_b[:, None])
    return out


def _quantise(ctx: Radiometry) -> dict[str, Any]:
    return {"lmin": ctx.lmin, "lmax": ctx.lmax, "scale": ctx.scale, "maxdn": ctx.maxdn}


def _calibrate(ctx: Radiometry) -> dict[str, Any]:
    return {"lmin": ctx.lmin, "gain": ctx.gain}


def _correct(ctx: Radiometry) -> dict[str, Any]:
    c = ctx.correction
    if c is None:
        return {}
    return {"lp": c.path_radiance, "g": c.ground_term, "s": c.spherical_albedo}


#: a relative calibration error's deviate: the second word of its generator's seed
_CAL_TAG = 0x63616C65
#: crosstalk coefficient where neither the scene nor the sensor table gives one (an assumption)
DEFAULT_CROSSTALK = 0.002


def _of(table: dict[str, Any], name: str) -> Any:
    """``table``'s entry for band ``name`` (case-insensitive), None where it has none."""
    return next((v for b, v in table.items() if b.lower() == name.lower()), None)


def _calibration_errors(ctx: Radiometry) -> np.ndarray:
    """e per band: its own where the scene gives it, else error + uncertainty z, z a standard normal deviate drawn
    once per band from the seed and the band's name (the same band gets the same error in any band set)."""
    spec = ctx.setting("calibration_error")
    spec = spec if isinstance(spec, CalibrationErrorSpec) else CalibrationErrorSpec()
    errors = []
    for name in ctx.names:
        given = _of(spec.bands, name)
        if given is None:
            z = np.random.default_rng([ctx.seed, _CAL_TAG, zlib.crc32(name.encode())]).standard_normal()
            given = spec.error + spec.uncertainty * z
        errors.append(given)
    return np.array(errors, dtype=np.float64)


def _calibration_error(ctx: Radiometry) -> dict[str, Any]:
    return {"cal_error_gain": 1.0 + _calibration_errors(ctx)}


def _calibration_error_attrs(ctx: Radiometry, k: int) -> dict[str, Any]:
    return {"calibration_error": float(_calibration_errors(ctx)[k])}


def _crosstalk(ctx: Radiometry) -> dict[str, Any]:
    """c[k][j]: what band k gains of band j's radiance (0 across focal planes and on the diagonal)."""
    spec = ctx.setting("crosstalk")
    spec = spec if isinstance(spec, CrosstalkSpec) else CrosstalkSpec()
    n = len(ctx.names)
    centres = ctx.centres if ctx.centres is not None else np.zeros(n)
    swir = centres >= spec.swir_from_nm
    column = ctx.extras.get("crosstalk")
    c = np.zeros((n, n))
    for k, name in enumerate(ctx.names):
        row = _of(spec.pairs, name) or {}
        for j, other in enumerate(ctx.names):
            if j == k or swir[j] != swir[k]:
                continue
            given = _of(row, other)
            if given is None:
                given = spec.coefficient
            if given is None and column is not None and np.isfinite(column[k]):
                given = column[k]
            c[k, j] = DEFAULT_CROSSTALK if given is None else given
    return {"crosstalk": c}


def _crosstalk_attrs(ctx: Radiometry, k: int) -> dict[str, Any]:
    row = _crosstalk(ctx)["crosstalk"][k]
    return {"crosstalk_from": ", ".join(f"{ctx.names[j]} {c:g}" for j, c in enumerate(row) if c != 0.0) or "none"}


def _quantisation_caveats(sensor: Sensor, bands: list[str]) -> list[Caveat]:
    """Bands of ``bands`` whose quantisation noise (step / √12) exceeds their sensor noise at Lref."""
    bits = sensor.bits
    coarse = []
    for name in bands:
        b = sensor.band(name)
        step = (b.lmax - b.lmin) / (2**bits - 1)
        if step / math.sqrt(12) > b.lref / float(b.noise.snr(b.lref)):
            coarse.append(b.name)
    if not coarse:
        return []
    return [Caveat("effects.bits", f"{bits} bits: quantisation noise exceeds the sensor noise at Lref in band(s) "
                                   f"{', '.join(coarse)}; retrievals degrade or fail (Sentinel-2 has 12 bits)")]


# -- the chain -----------------------------------------------------------------------------------------------------

_REF = "s2cl.reference.stages"

#: the forward chain, in order
STAGES: tuple[Stage, ...] = (
    Stage("atmosphere", "effects.atmosphere", "spectrum",
          "surface reflectance to TOA radiance per wavelength, L = Lp + G ρ / (1 - S ρ) (6S LUT terms; in the "
          "resampling kernel)", twin="s2cl.reference.forward:toa_radiance"),
    Stage("smile", "effects.smile", "image",
          "spectral smile: each band's SRF moved (and widened) across the swath (node SRFs in the resampling kernel, "
          "interpolated per column)", twin="s2cl.forward.instrument:smile_twin"),
    Stage("resample", "effects.resample", "spectrum",
          "SRF integral of each band (off: the spectrum at the band centre)", twin="s2cl.reference.forward:resample"),
    Stage("psf", "effects.psf", "image",
          "each band's Gaussian PSF (from its FWHM, or its system MTF at Nyquist with the box average) before the box "
          "average, one finite filter with the co-registration shift", twin="s2cl.forward.instrument:spatial_twin"),
    Stage("coregistration", "effects.coregistration", "image",
          "each band's sub-pixel shift (band-limited, in the PSF's filter)",
          twin="s2cl.forward.instrument:spatial_twin"),
    Stage("nonuniformity", "effects.nonuniformity", "image",
          "per-column gain and offset of each band (detector non-uniformity, after the box average; float64 on the "
          "host, its own twin)", twin="s2cl.forward.instrument:Instrument.column_response"),
    Stage("noise", "effects.noise", "band", "sigma(L) z added, sigma^2 = a + b max(L, 0) at the band's width",
          values=(Value("noise_a", "variant", sweep=False), Value("noise_b", "variant", sweep=False),
                  Value("sigma", "pixel", sense=False)),
          outputs=(Output("noisy", "real", RADIANCE_UNITS, "band radiance with sensor noise"),),
          device="noise", twin=f"{_REF}:noise_step", compute=_noise, deviates=True, degrades=True),
    Stage("crosstalk", "effects.crosstalk", "bands",
          "each band's radiance gains c_kj L_j from the other bands j of its focal plane (VNIR, SWIR), after the noise",
          values=(Value("crosstalk", "pairs"),), device="crosstalk", twin=f"{_REF}:crosstalk_step",
          compute=_crosstalk, attrs=_crosstalk_attrs, degrades=True),
    Stage("quantise", "effects.quantise", "band",
          "DN = round((L - Lmin) scale), ties up, clipped to [0, 2^bits - 1]; pixel flags",
          values=(Value("lmin", "band"), Value("lmax", "band"), Value("scale", "band"),
                  Value("maxdn", "scalar", ctype="uint")),
          outputs=(Output("dn", "ushort", "1", "digital numbers"),
                   Output("flags", "uchar", "1", "radiometric pixel flags")),
          device="quantise", twin=f"{_REF}:quantise_step", compute=_quantise, degrades=True,
          caveats=_quantisation_caveats),
    Stage("calibrate", "effects.calibrate", "band", "radiance from DN, Lmin + DN gain (NaN where no data)",
          values=(Value("lmin", "band"), Value("gain", "band")),
          outputs=(Output("calibrated", "real", RADIANCE_UNITS, "radiance calibrated from DN"),),
          device="calibrate", twin=f"{_REF}:calibrate_step", compute=_calibrate, degrades=True),
    Stage("calibration_error", "effects.calibration_error", "band",
          "each band's absolute calibration error: its calibrated radiance times (1 + e), e per band",
          values=(Value("cal_error_gain", "band"),), device="calibration_error",
          twin=f"{_REF}:calibration_error_step", compute=_calibration_error, attrs=_calibration_error_attrs,
          degrades=True),
    Stage("correct", "effects.correct", "band",
          "band-effective atmospheric correction to band reflectance (the state of [correction])",
          values=(Value("lp", "variant"), Value("g", "variant"), Value("s", "variant")),
          outputs=(Output("reflectance", "real", "1", "band surface reflectance after atmospheric correction"),),
          device="correct", twin=f"{_REF}:correct_step", compute=_correct),
)

_BY_NAME = {s.name: s for s in STAGES}


def stage(name: str) -> Stage:
    """The stage called ``name``."""
    return _BY_NAME[name]


def chain(effects: EffectSet) -> list[Stage]:
    """The per-pixel stages ``effects`` switches on, in the chain's order: what the sense and sweep kernels run."""
    return [s for s in STAGES if s.per_pixel and effects.on(s.name)]


def senses(effects: EffectSet) -> bool:
    """Whether any per-pixel stage runs (else no sense kernel is built)."""
    return bool(chain(effects))


def segments(stages: list[Stage]) -> list[tuple[str, list[Stage]]]:
    """``stages`` cut where a stage acts across bands: ``("band", [...])`` runs per band, ``("bands", [one])`` on
    every band of the pixel at once; the first segment is always a per-band one (it reads the band radiance)."""
    out: list[tuple[str, list[Stage]]] = [("band", [])]
    for s in stages:
        if s.acts == "bands":
            out.append(("bands", [s]))
            out.append(("band", []))
        else:
            out[-1][1].append(s)
    return out


def outputs(effects: EffectSet) -> list[Output]:
    """The per-pixel outputs of the stages ``effects`` switches on, in order."""
    return [o for s in chain(effects) for o in s.outputs]


#: every per-pixel output a chain can have, in order
ALL_OUTPUTS: tuple[Output, ...] = tuple(o for s in STAGES if s.per_pixel for o in s.outputs)


def inputs(stages: list[Stage], kernel: Literal["sense", "sweep"]) -> list[Value]:
    """The values ``stages`` read in ``kernel``, each name once, in order."""
    seen: dict[str, Value] = {}
    for s in stages:
        for v in s.values:
            if getattr(v, kernel) and v.name not in seen:
                seen[v.name] = v
    return list(seen.values())


def compute(stages: list[Stage], ctx: Radiometry) -> dict[str, Any]:
    """Every value ``stages`` compute for the bands of ``ctx`` (a name two stages share: the first's)."""
    out: dict[str, Any] = {}
    for s in stages:
        for k, v in s.computed(ctx).items():
            out.setdefault(k, v)
    return out


def band_attrs(stages: list[Stage], ctx: Radiometry, k: int) -> dict[str, Any]:
    """What ``stages`` did to band ``k`` of ``ctx``, as attributes."""
    out: dict[str, Any] = {}
    for s in stages:
        if s.attrs is not None:
            out.update(s.attrs(ctx, k))
    return out


def image_stage_names() -> frozenset[str]:
    """The stages that act on images only (PSF, shift, smile, non-uniformity...): a library scene does not run them."""
    return frozenset(s.name for s in STAGES if s.acts == "image")


def image_only(effects: EffectSet, *, image: bool, sweep: bool) -> list[Caveat]:
    """One line naming the image-only stages of ``effects`` that a scene without an image cube (``image`` False: a
    library, with a sweep or not) switches on: they do not run there, and are never dropped silently."""
    if image:
        return []
    on = [s.key for s in STAGES if s.acts == "image" and effects.on(s.name)]
    if not on:
        return []
    where = "this library scene or its sweep" if sweep else "this library scene"
    return [Caveat(", ".join(on), f"image-only stage{'s' if len(on) > 1 else ''}, not run on {where} (they act on "
                                  "image cubes: surface.cube)")]


def caveats(sensor: Sensor, effects: EffectSet, bands: list[str], *, image: bool, sweep: bool) -> list[Caveat]:
    """The caveats of the stages ``effects`` switches on, for ``bands`` of ``sensor``: image-only stages without an
    image (:func:`image_only`), and each per-pixel stage's own."""
    own = [c for s in chain(effects) if s.caveats is not None for c in s.caveats(sensor, bands)]
    return image_only(effects, image=image, sweep=sweep) + own
