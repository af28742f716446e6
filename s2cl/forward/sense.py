"""Host side of ``kernels/sense.cl.mako``: noise → quantise → calibrate on band radiance."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.atmos.correction import BandAtmosphere
from s2cl.cl.kernel_args import Arg, bind, signature
from s2cl.cl.runtime import Runtime
from s2cl.cl.templates import render
from s2cl.errors import InputError
from s2cl.scene.effects import EffectSet
from s2cl.sensor.sensor import Band
from s2cl.status import PixelFlag

TEMPLATE = "sense.cl.mako"
MAX_PIXELS = 2**32 - 1


@dataclass(frozen=True, eq=False)
class Radiometry:
    """Per-band radiometric constants, float64 arrays of length ``n_bands``.

    :param lmin, lmax: quantisation range, W m⁻² sr⁻¹ µm⁻¹.
    :param noise_a, noise_b: σ² = a + b·max(L, 0) at each band's actual width.
    :param band_ids: global index of each band (keys its noise stream).
    :param bits: radiometric resolution.
    """

    lmin: np.ndarray
    lmax: np.ndarray
    noise_a: np.ndarray
    noise_b: np.ndarray
    band_ids: tuple[int, ...]
    bits: int

    @classmethod
    def of(cls, bands: list[Band] | tuple[Band, ...], bits: int, band_ids: list[int] | None = None) -> Radiometry:
        coeffs = np.array([b.noise_coefficients() for b in bands], dtype=np.float64).reshape(-1, 2)
        return cls(
            lmin=np.array([b.lmin for b in bands], dtype=np.float64),
            lmax=np.array([b.lmax for b in bands], dtype=np.float64),
            noise_a=coeffs[:, 0],
            noise_b=coeffs[:, 1],
            band_ids=tuple(band_ids if band_ids is not None else range(len(bands))),
            bits=bits,
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


@dataclass
class SenseResult:
    """Outputs of the radiometric stage; arrays are ``(n_bands, n_pixels)``, None when the stage is off.

    :param clipped: ``(2, n_bands)`` counts of pixels below Lmin (NaN included) / above Lmax (quantise only).
    :param flags: ``(n_bands, n_pixels)`` uint8 :class:`s2cl.status.PixelFlag` bits (quantise only).
    """

    noisy: np.ndarray | None
    dn: np.ndarray | None
    calibrated: np.ndarray | None
    clipped: np.ndarray | None
    reflectance: np.ndarray | None = None
    flags: np.ndarray | None = None


def clipped_counts(flags: np.ndarray) -> np.ndarray:
    """``(2, n_bands)`` counts below Lmin (NaN radiance included) and above Lmax from pixel flags
    ``(n_bands, n_pixels)``."""
    low = (flags & (PixelFlag.LOW | PixelFlag.NODATA)) != 0
    high = (flags & PixelFlag.HIGH) != 0
    return np.stack([low.sum(axis=1), high.sum(axis=1)]).astype(np.int64)


def _args(effects: EffectSet) -> list[Arg]:
    args: list[Arg] = []
    if effects.noise:
        args.append(Arg("noisy", "out", "real"))
    if effects.quantise:
        args += [Arg("dn", "out", "ushort"), Arg("flags", "out", "uchar")]
    if effects.calibrate:
        args.append(Arg("calibrated", "out", "real"))
    if effects.correct:
        args.append(Arg("reflectance", "out", "real"))
    args.append(Arg("radiance", "in", "real"))
    if effects.noise:
        args += [Arg("noise_a", "in", "real"), Arg("noise_b", "in", "real")]
    if effects.quantise:
        args += [Arg(n, "in", "real") for n in ("lmin", "lmax", "scale")]
    if effects.calibrate:
        args.append(Arg("gain", "in", "real"))
    if effects.correct:
        args += [Arg(n, "in", "real") for n in ("band_lp", "band_g", "band_s")]
    if effects.noise:
        args += [Arg("seed", "scalar", "uint"), Arg("frame", "scalar", "uint")]
    args.append(Arg("pixel_offset", "scalar", "uint"))
    if effects.quantise:
        args.append(Arg("maxdn", "scalar", "uint"))
    return [*args, Arg("n_pixels", "scalar", "uint")]


class Sensing:
    """Compiled radiometric stage for a band count, an effect set and a precision.

    :param correction: band-effective terms of the state assumed by the atmospheric correction
        (needed when ``effects.correct``).
    """

    def __init__(self, rt: Runtime, radiometry: Radiometry, effects: EffectSet, real_t: str = "float32",
                 correction: BandAtmosphere | None = None):
        if not 1 <= radiometry.bits <= 16:
            raise InputError(f"bits must be in 1–16, got {radiometry.bits}", key="effects.bits")
        self.rt, self.radiometry, self.effects, self.real_t = rt, radiometry, effects, real_t
        self.T = rt.types(real_t, vector=False)
        self.dtype = self.T.dtype.type
        self.args = _args(effects)
        if effects.correct and (correction is None or correction.n_bands != radiometry.n_bands):
            raise InputError("the correct effect needs band-effective atmospheric terms for every band")
        self.source = render(TEMPLATE, args=self.args, signature=signature, n_bands=radiometry.n_bands,
                             band_ids=list(radiometry.band_ids), noise=effects.noise, T=self.T,
                             quantise=effects.quantise, calibrate=effects.calibrate, correct=effects.correct)
        program = rt.build(self.source, template=TEMPLATE)
        self.kernel = rt.kernel(program, "sense_bands")
        self.local_size = rt.work_group(self.kernel)
        r = radiometry
        constants = {"noise_a": r.noise_a, "noise_b": r.noise_b, "lmin": r.lmin, "lmax": r.lmax,
                     "scale": r.scale, "gain": r.gain}
        if effects.correct:
            constants.update(band_lp=correction.path_radiance, band_g=correction.ground_term,
                             band_s=correction.spherical_albedo)
        names = {a.name for a in self.args}
        self.constants_dev = {k: rt.to_device(v.astype(self.dtype)) for k, v in constants.items() if k in names}

    def __call__(self, radiance: np.ndarray, *, seed: int = 0, frame: int = 0, pixel_offset: int = 0,
                 chunk_pixels: int | None = None, local_size: int | None = None) -> SenseResult:
        """Run on ``radiance`` ``(n_bands, n_pixels)`` (W m⁻² sr⁻¹ µm⁻¹); pixel ``j`` keys its
        noise as global pixel ``pixel_offset + j``."""
        radiance = np.asarray(radiance)
        nb, n = radiance.shape
        if nb != self.radiometry.n_bands:
            raise InputError(f"radiance has {nb} bands, the sensor {self.radiometry.n_bands}")
        if pixel_offset + n > MAX_PIXELS:
            raise InputError(
                f"at most {MAX_PIXELS} pixels per frame (noise counters are 32-bit), got {pixel_offset + n}")
        for name, v in (("seed", seed), ("frame", frame)):
            if not 0 <= int(v) <= 2**32 - 1:
                raise InputError(f"must be in 0–{2**32 - 1}, got {v}", key=f"effects.{name}")
        e = self.effects
        result = SenseResult(
            noisy=np.empty((nb, n), self.dtype) if e.noise else None,
            dn=np.empty((nb, n), np.uint16) if e.quantise else None,
            calibrated=np.empty((nb, n), self.dtype) if e.calibrate else None,
            clipped=None,
            reflectance=np.empty((nb, n), self.dtype) if e.correct else None,
            flags=np.empty((nb, n), np.uint8) if e.quantise else None,
        )
        chunk = chunk_pixels or max(1, (64 * 2**20) // (nb * 8))
        for lo in range(0, n, chunk):
            hi = min(n, lo + chunk)
            self._chunk(radiance[:, lo:hi], lo, hi, result, seed, frame, pixel_offset, local_size)
        if result.flags is not None:
            result.clipped = clipped_counts(result.flags)
        return result

    def _chunk(self, radiance, lo, hi, result, seed, frame, pixel_offset, local_size) -> None:
        rt, nb, m = self.rt, self.radiometry.n_bands, hi - lo
        item = self.dtype().itemsize
        values = dict(self.constants_dev)
        values["radiance"] = rt.to_device(np.ascontiguousarray(radiance, dtype=self.dtype))
        outs = {}
        if self.effects.noise:
            outs["noisy"] = rt.empty(nb * m * item)
            values.update(seed=seed, frame=frame)
        if self.effects.quantise:
            outs["dn"] = rt.empty(nb * m * 2)
            outs["flags"] = rt.empty(nb * m)
            values["maxdn"] = self.radiometry.maxdn
        if self.effects.calibrate:
            outs["calibrated"] = rt.empty(nb * m * item)
        if self.effects.correct:
            outs["reflectance"] = rt.empty(nb * m * item)
        values.update(outs, pixel_offset=pixel_offset + lo, n_pixels=m)
        local = local_size or self.local_size
        global_size = -(-m // local) * local
        self.kernel(rt.queue, (global_size,), (local,), *bind(self.args, values, self.T))
        if "noisy" in outs:
            result.noisy[:, lo:hi] = rt.fetch(outs["noisy"], (nb, m), self.dtype)
        if "dn" in outs:
            result.dn[:, lo:hi] = rt.fetch(outs["dn"], (nb, m), np.uint16)
            result.flags[:, lo:hi] = rt.fetch(outs["flags"], (nb, m), np.uint8)
        for name in ("calibrated", "reflectance"):
            if name in outs:
                getattr(result, name)[:, lo:hi] = rt.fetch(outs[name], (nb, m), self.dtype)
