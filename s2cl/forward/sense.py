"""Host side of ``kernels/sense.cl.mako``: the chain's per-pixel stages (:mod:`s2cl.forward.stages`) on band
radiance, per band and pixel, for a library or an image."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from s2cl.atmos.correction import BandAtmosphere
from s2cl.cl.device_memory import DeviceBuffer
from s2cl.cl.kernel_args import Arg, bind, buffers, signature
from s2cl.cl.runtime import Runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import VecTypes
from s2cl.errors import InputError
from s2cl.forward.radiometry import Radiometry
from s2cl.forward.stages import ALL_OUTPUTS, Stage, Value, chain, compute, inputs, segments
from s2cl.scene.effects import EffectSet
from s2cl.status import PixelFlag

__all__ = ["MAX_PIXELS", "Radiometry", "SenseResult", "Sensing", "clipped_counts", "launch_pixels", "sense_args"]

TEMPLATE = "sense.cl.mako"
MAX_PIXELS = 2**32 - 1
_OUTPUT_NAMES = tuple(dict.fromkeys(o.name for o in ALL_OUTPUTS))


@dataclass
class SenseResult:
    """Outputs of the chain's per-pixel stages: ``outputs`` by name, each ``(n_bands, n_pixels)`` (an output of a
    stage that is off is absent; ``result.noisy``, ``result.dn``, ...: None then).

    :param clipped: ``(2, n_bands)`` counts of pixels below Lmin (NaN included) / above Lmax (where the chain
        writes pixel flags).
    """

    outputs: dict[str, np.ndarray] = field(default_factory=dict)
    clipped: np.ndarray | None = None

    def __getattr__(self, name: str) -> np.ndarray | None:
        if name in _OUTPUT_NAMES:
            return self.__dict__.get("outputs", {}).get(name)
        raise AttributeError(name)


def clipped_counts(flags: np.ndarray) -> np.ndarray:
    """``(2, n_bands)`` counts below Lmin (NaN radiance included) and above Lmax from pixel flags
    ``(n_bands, n_pixels)``."""
    low = (flags & (PixelFlag.LOW | PixelFlag.NODATA)) != 0
    high = (flags & PixelFlag.HIGH) != 0
    return np.stack([low.sum(axis=1), high.sum(axis=1)]).astype(np.int64)


_CASTS = {"ushort": "(ushort)", "uchar": "(uchar)"}


@dataclass(frozen=True)
class SenseSite:
    """Where band ``k``'s steps run in the sense kernel: values are per-band buffers (``NAME[k]``), scalars
    arguments, outputs written at ``at`` (see ``kernels/common/stages.mako``)."""

    T: VecTypes
    k: int
    band_id: int
    values: dict[str, Value]
    outputs: dict[str, str]

    def has(self, name: str) -> bool:
        return name in self.values

    def value(self, name: str) -> str:
        v = self.values[name]
        if v.varies == "scalar":
            return f"({self.T.R}){name}"
        return f"{name}[{self.k}]"

    def store(self, name: str, expr: str) -> str:
        if name not in self.outputs:
            return ""
        return f"{name}[at] = {_CASTS.get(self.outputs[name], '')}{expr};"

    def deviate(self) -> str:
        return f"z{self.band_id >> 2}.s{self.band_id & 3}"


@dataclass(frozen=True)
class SenseAcross:
    """Where a stage across bands runs in the sense kernel: on ``X[0 … n-1]``, its ``pairs`` values as literals."""

    T: VecTypes
    n: int
    pair_values: dict[str, np.ndarray]
    outputs: dict[str, str]

    def pairs(self, name: str) -> list[list[float]]:
        return [[float(x) for x in row] for row in self.pair_values[name]]

    def store(self, name: str, k: int, expr: str) -> str:
        if name not in self.outputs:
            return ""
        return f"{name}[(size_t){k}u * n_pixels + i] = {_CASTS.get(self.outputs[name], '')}{expr};"


def sense_args(stages: list[Stage]) -> list[Arg]:
    """The sense kernel's arguments for ``stages`` (in the chain's order): their outputs, the radiance, their
    per-band values, the deviates' keys, the pixel offset, their scalars, the pixel count."""
    outs = {o.name: o for s in stages for o in s.outputs}
    values = inputs(stages, "sense")
    args = [Arg(o.name, "out", o.ctype, ("bands", "pixels")) for o in outs.values()]
    args.append(Arg("radiance", "in", "real", ("bands", "pixels")))
    args += [Arg(v.name, "in", v.ctype, ("bands",)) for v in values if v.varies in ("band", "variant")]
    if any(s.deviates for s in stages):
        args += [Arg("seed", "scalar", "uint"), Arg("frame", "scalar", "uint")]
    args.append(Arg("pixel_offset", "scalar", "uint"))
    args += [Arg(v.name, "scalar", v.ctype) for v in values if v.varies == "scalar"]
    return [*args, Arg("n_pixels", "scalar", "uint")]


def launch_pixels(n_bands: int) -> int:
    """Pixels per launch of the sense kernel at most (before the device's own limit): 64 MiB of float64 per band."""
    return max(1, (64 * 2**20) // (n_bands * 8))


def sense_buffers(stages: list[Stage], n_bands: int, real_bytes: int) -> list[DeviceBuffer]:
    """The sense kernel's device buffers for ``stages``, from its argument declarations: fixed bytes and bytes per
    pixel of a launch."""
    return buffers(sense_args(stages), {"bands": n_bands}, real_bytes, "pixels")


class Sensing:
    """The chain's per-pixel stages compiled for a band set, an effect set and a precision.

    :param correction: band-effective terms of the state assumed by the atmospheric correction (its stage needs
        them; also taken from ``radiometry.correction``).
    """

    def __init__(self, rt: Runtime, radiometry: Radiometry, effects: EffectSet, real_t: str = "float32",
                 correction: BandAtmosphere | None = None):
        if not 1 <= radiometry.bits <= 16:
            raise InputError(f"bits must be in 1–16, got {radiometry.bits}", key="effects.bits")
        if correction is not None:
            radiometry = replace(radiometry, correction=correction)
        if radiometry.correction is not None and radiometry.correction.n_bands != radiometry.n_bands:
            raise InputError("the correct effect needs band-effective atmospheric terms for every band")
        self.rt, self.radiometry, self.effects, self.real_t = rt, radiometry, effects, real_t
        self.T = rt.types(real_t, vector=False)
        self.dtype = self.T.dtype.type
        self.stages = chain(effects)
        self.args = sense_args(self.stages)
        self.values = compute(self.stages, radiometry)
        wanted = inputs(self.stages, "sense")
        missing = [(s.name, v.name) for s in self.stages for v in s.values if v.sense and v.name not in self.values]
        if missing:
            name, value = missing[0]
            raise InputError(f"the {name} effect needs its per-band value {value!r} for every band (none was given "
                             "for this band set)", key=f"effects.{name}")
        self.outputs = {o.name: o for s in self.stages for o in s.outputs}
        kinds = {v.name: v for v in wanted}
        ctypes = {n: o.ctype for n, o in self.outputs.items()}
        n = radiometry.n_bands
        ids = list(radiometry.band_ids)
        pairs = {v.name: np.asarray(self.values[v.name]) for v in wanted if v.varies == "pairs"}
        self.source = render(
            TEMPLATE, args=self.args, signature=signature, n_bands=n, band_ids=ids, T=self.T, stages=self.stages,
            segments=segments(self.stages), deviates=any(s.deviates for s in self.stages),
            site=lambda k: SenseSite(self.T, k, ids[k], kinds, ctypes), across=SenseAcross(self.T, n, pairs, ctypes))
        program = rt.build(self.source, template=TEMPLATE)
        self.kernel = rt.kernel(program, "sense_bands")
        self.local_size = rt.work_group(self.kernel)
        self.scalars = {v.name: self.values[v.name] for v in wanted if v.varies == "scalar"}
        self.constants_dev = {v.name: rt.to_device(np.asarray(self.values[v.name]).astype(self.dtype))
                              for v in wanted if v.varies in ("band", "variant")}

    def __call__(self, radiance: np.ndarray, *, seed: int = 0, frame: int = 0, pixel_offset: int = 0,
                 chunk_pixels: int | None = None, local_size: int | None = None) -> SenseResult:
        """Run on ``radiance`` ``(n_bands, n_pixels)`` (W m⁻² sr⁻¹ µm⁻¹); pixel ``j`` keys its
        deviates as global pixel ``pixel_offset + j``."""
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
        result = SenseResult({name: np.empty((nb, n), o.dtype or self.dtype) for name, o in self.outputs.items()})
        chunk = chunk_pixels or self.default_chunk()
        for lo in range(0, n, chunk):
            hi = min(n, lo + chunk)
            self._chunk(radiance[:, lo:hi], lo, hi, result, seed, frame, pixel_offset, local_size)
        if "flags" in result.outputs:
            result.clipped = clipped_counts(result.outputs["flags"])
        return result

    def device_buffers(self) -> list[DeviceBuffer]:
        """The kernel's buffers (:func:`sense_buffers`): fixed bytes and bytes per pixel of a launch."""
        return sense_buffers(self.stages, self.radiometry.n_bands, self.T.dtype.itemsize)

    def default_chunk(self) -> int:
        """Pixels per launch: 64 MiB of float64 per band at most, and no more than the device's memory holds
        (:meth:`device_buffers`); a one-line :class:`~s2cl.errors.ResourceError` when not even one pixel fits."""
        device, own = self.rt.memory, self.device_buffers()
        fit = device.units_fitting(own, launch_pixels(self.radiometry.n_bands))
        if not fit:
            device.require(own, 1, what=f"sensing {self.radiometry.n_bands} bands", key="compute.device", source=None,
                           fits="choose a device with more memory")
        return fit

    def _chunk(self, radiance: np.ndarray, lo: int, hi: int, result: SenseResult, seed: int, frame: int,
               pixel_offset: int, local_size: int | None) -> None:
        rt, nb, m = self.rt, self.radiometry.n_bands, hi - lo
        values: dict[str, Any] = {**self.constants_dev, **self.scalars}
        values["radiance"] = rt.to_device(np.ascontiguousarray(radiance, dtype=self.dtype))
        outs = {name: rt.empty(nb * m * (o.dtype or np.dtype(self.dtype)).itemsize)
                for name, o in self.outputs.items()}
        if any(s.deviates for s in self.stages):
            values.update(seed=seed, frame=frame)
        values.update(outs, pixel_offset=pixel_offset + lo, n_pixels=m)
        local = local_size or self.local_size
        global_size = -(-m // local) * local
        self.kernel(rt.queue, (global_size,), (local,), *bind(self.args, values, self.T))
        for name, buf in outs.items():
            result.outputs[name][:, lo:hi] = rt.fetch(buf, (nb, m), self.outputs[name].dtype or self.dtype)
