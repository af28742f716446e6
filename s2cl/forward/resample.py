"""Host side of ``kernels/resample.cl.mako``: spectra → band radiance through sparse SRF supports."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from s2cl.cl.device_memory import DeviceBuffer
from s2cl.cl.kernel_args import Arg, bind, buffers, signature
from s2cl.cl.runtime import Runtime
from s2cl.cl.templates import render
from s2cl.errors import InputError
from s2cl.forward.grid_interpolation import GridInterpolation
from s2cl.sensor.srf import BandWeights

if TYPE_CHECKING:
    from s2cl.grid import SpectralGrid
    from s2cl.sensor.sensor import Band

TEMPLATE = "resample.cl.mako"

#: Wavelengths per vector load unless asked otherwise, capped at the device's native width and at
#: least 4 (there is no vload1): 8-wide loads ran 1.08-1.13x as fast as 16-wide on an AVX-512 CPU
#: (``python -m bench.bench_lanes``, bench/results/lanes-*.json); on AVX2 8 is the native width.
DEFAULT_VECTOR_WIDTH = 8
#: Spectra per work-item on CPUs, read interleaved so that that many memory streams are in flight at
#: once: one row at a time waits on the first cache miss of every band support (1.6 M spectra/s against
#: 4-5 M with 8 rows on a 2-core AVX-512 EPYC; ``python -m bench.bench_lanes``). GPUs take one row per
#: work-item (their work-items are the parallelism).
DEFAULT_ROWS_PER_ITEM = 8


class AtmosphereArrays(Protocol):
    """Per-wavelength TOA terms on the resampling grid (see :mod:`s2cl.atmos.atmosphere`):
    L = path_radiance + ground_term · ρ / (1 − spherical_albedo · ρ), radiances in W m⁻² sr⁻¹ µm⁻¹."""

    path_radiance: np.ndarray
    ground_term: np.ndarray
    spherical_albedo: np.ndarray


@dataclass(frozen=True, eq=False)
class ResamplePlan:
    """Band supports on a grid of ``n_wavelengths`` samples, packed for the kernel."""

    names: tuple[str, ...]
    weights: tuple[BandWeights, ...]
    n_wavelengths: int

    @classmethod
    def of(cls, bands: Sequence[Band], grid: SpectralGrid) -> ResamplePlan:
        """The plan of ``bands``' model SRFs on ``grid`` with the default support cut-off."""
        return cls(tuple(b.name for b in bands), tuple(b.weights(grid) for b in bands), grid.size)

    @property
    def n_bands(self) -> int:
        return len(self.weights)

    def packed(self, multiple: int = 1) -> tuple[list[dict], np.ndarray]:
        """Band descriptors for the template and the concatenated weight array (float64); each support
        padded with zero weights to a whole number of ``multiple``-wide vectors (extended to the right, or
        to the left at the grid's end), so the kernel needs no scalar tail."""
        bands, parts, offset = [], [], 0
        for name, w in zip(self.names, self.weights, strict=True):
            n = int(w.weights.size)
            length = min(-(-n // multiple) * multiple, self.n_wavelengths)
            start = min(w.start, self.n_wavelengths - length)
            padded = np.zeros(length)
            padded[w.start - start : w.start - start + n] = w.weights
            bands.append({"name": name, "start": start, "length": length, "offset": offset})
            parts.append(padded)
            offset += length
        return bands, np.concatenate(parts)

    def dense(self) -> np.ndarray:
        """The dense SRF matrix ``(n_bands, n_wavelengths)`` (float64), e.g. for numpy baselines."""
        m = np.zeros((self.n_bands, self.n_wavelengths))
        for k, w in enumerate(self.weights):
            m[k, w.start : w.stop] = w.weights
        return m


def _args(atmosphere: bool, interpolated: bool = False) -> list[Arg]:
    samples = "samples" if interpolated else "wavelengths"
    args = [Arg("out", "out", "real", ("bands", "pixels")), Arg("spectra", "in", "real", ("pixels", samples)),
            Arg("weights", "in", "real", ("weights",))]
    if interpolated:
        args += [Arg("lower", "in", "int", ("wavelengths",)), Arg("upper", "in", "int", ("wavelengths",)),
                 Arg("fraction", "in", "real", ("wavelengths",))]
    if atmosphere:
        args += [Arg(n, "in", "real", ("wavelengths",)) for n in ("path_radiance", "ground_term", "spherical_albedo")]
    return [*args, Arg("n_pixels", "scalar", "uint")]


def resample_buffers(n_bands: int, n_wavelengths: int, real_bytes: int, *, atmosphere: bool,
                     n_weights: int | None = None, n_samples: int | None = None) -> list[DeviceBuffer]:
    """The resampling kernel's device buffers, from its argument declarations: fixed bytes and bytes per spectrum of
    a launch; ``n_weights``: the packed SRF weights (None: every band over the whole grid, an upper bound);
    ``n_samples``: native samples per spectrum that the kernel interpolates onto the grid (None: spectra on the
    grid, :class:`~s2cl.forward.grid_interpolation.GridInterpolation`)."""
    sizes = {"bands": n_bands, "wavelengths": n_wavelengths, "samples": n_samples or 0,
             "weights": n_bands * n_wavelengths if n_weights is None else n_weights}
    return buffers(_args(atmosphere, n_samples is not None), sizes, real_bytes, "pixels")


class Resampler:
    """Compiled resampling kernel for one plan, precision and (optional) atmosphere.

    :param atmosphere: per-wavelength TOA terms; when given, input spectra are surface
        reflectance and are turned into TOA radiance at each wavelength before the SRFs.
    :param vector_width: wavelengths per vector load, 4, 8 or 16 (default :data:`DEFAULT_VECTOR_WIDTH`
        capped at the device's native width; a width the CPU cannot use cleanly falls back, see
        :func:`s2cl.cl.devices.choose_lanes`).
    :param rows_per_item: spectra per work-item, 1, 2, 4, 8 or 16 (default :data:`DEFAULT_ROWS_PER_ITEM`
        on CPUs, 1 on other devices).
    :param interpolation: spectra come at a cube's native wavelengths, ``(n_pixels, interpolation.n_native)``, and
        the kernel puts them on the grid linearly, per grid wavelength, before the atmosphere
        (:class:`~s2cl.forward.grid_interpolation.GridInterpolation`); None: spectra on the grid.
    """

    def __init__(self, rt: Runtime, plan: ResamplePlan, real_t: str = "float32",
                 atmosphere: AtmosphereArrays | None = None, vector_width: int | None = None,
                 rows_per_item: int | None = None, interpolation: GridInterpolation | None = None):
        self.T = rt.types(real_t, vector=False)
        self.rt, self.plan, self.real_t = rt, plan, real_t
        self.dtype = self.T.dtype.type
        if interpolation is not None and interpolation.n_grid != plan.n_wavelengths:
            raise InputError(f"interpolates onto {interpolation.n_grid} wavelengths but the plan's grid has "
                             f"{plan.n_wavelengths}", key="interpolation")
        self.interpolation = interpolation
        #: values per spectrum the kernel reads (native samples, or the grid's wavelengths)
        self.n_samples = interpolation.n_native if interpolation is not None else plan.n_wavelengths
        self.args = _args(atmosphere is not None, interpolation is not None)
        if vector_width not in (None, 4, 8, 16):
            raise InputError(f"must be 4, 8 or 16, got {vector_width!r}", key="vector_width")
        if vector_width is None:
            vector_width = max(4, min(DEFAULT_VECTOR_WIDTH, rt.native_lanes(real_t)))
        self.vw = max(4, rt.lanes(real_t, vector_width))  # a width this CPU cannot use falls back
        bands, weights = plan.packed(self.vw)
        if rows_per_item is not None and rows_per_item not in (1, 2, 4, 8, 16):
            raise InputError(f"must be 1, 2, 4, 8 or 16, got {rows_per_item!r}", key="rows_per_item")
        self.rows = rows_per_item or (DEFAULT_ROWS_PER_ITEM if "CPU" in rt.info.kind else 1)
        self.source = render(TEMPLATE, args=self.args, signature=signature, T=self.T, bands=bands,
                             n_wavelengths=plan.n_wavelengths, stride=self.n_samples, vw=self.vw, rows=self.rows,
                             atmosphere=atmosphere is not None, interpolated=interpolation is not None)
        program = rt.build(self.source, template=TEMPLATE)
        self.kernel = rt.kernel(program, "resample_bands")
        self.local_size = rt.work_group(self.kernel)
        self.n_weights = int(weights.size)
        self.weights_dev = rt.to_device(weights.astype(self.dtype))
        self.table_dev = {}
        if interpolation is not None:
            self.table_dev = {"lower": rt.to_device(interpolation.lower.astype(np.int32)),
                              "upper": rt.to_device(interpolation.upper.astype(np.int32)),
                              "fraction": rt.to_device(interpolation.fraction.astype(self.dtype))}
        self.atmosphere_dev = None
        if atmosphere is not None:
            self.atmosphere_dev = {
                n: rt.to_device(np.asarray(getattr(atmosphere, n), dtype=self.dtype))
                for n in ("path_radiance", "ground_term", "spherical_albedo")
            }

    def enqueue(self, out_dev, spectra_dev, n_pixels: int, local_size: int | None = None) -> None:
        """Resample ``n_pixels`` rows already on the device into ``out_dev`` (bands × n_pixels)."""
        values = {"out": out_dev, "spectra": spectra_dev, "weights": self.weights_dev, "n_pixels": n_pixels,
                  **self.table_dev}
        if self.atmosphere_dev:
            values.update(self.atmosphere_dev)
        local = local_size or self.local_size
        global_size = _round_up(-(-n_pixels // self.rows), local)
        self.kernel(self.rt.queue, (global_size,), (local,), *bind(self.args, values, self.T))

    def __call__(self, spectra: np.ndarray, *, chunk_pixels: int | None = None,
                 local_size: int | None = None) -> np.ndarray:
        """Band radiance ``(n_bands, n_pixels)`` of ``spectra`` ``(n_pixels, n_wavelengths)`` (``(n_pixels,
        n_native)`` with an :attr:`interpolation`)."""
        spectra = np.asarray(spectra)
        if spectra.ndim != 2 or spectra.shape[1] != self.n_samples:
            raise InputError(f"spectra of shape {spectra.shape}; this resampler reads {self.n_samples} values per "
                             "spectrum", key="spectra")
        n = spectra.shape[0]
        chunk = chunk_pixels or self.default_chunk()
        if 0 < n <= chunk:  # one launch: its result is the answer, no copy
            return self._launch(spectra, local_size)
        out = np.empty((self.plan.n_bands, n), dtype=self.dtype)
        for lo in range(0, n, chunk):
            out[:, lo:min(n, lo + chunk)] = self._launch(spectra[lo:lo + chunk], local_size)
        return out

    def _launch(self, block: np.ndarray, local_size: int | None) -> np.ndarray:
        """Band radiance of one chunk ``(n_bands, len(block))``: the device reads ``block`` and, where it works in
        host memory, writes the result in place (:meth:`Runtime.output`)."""
        out, out_dev = self.rt.output((self.plan.n_bands, block.shape[0]), self.dtype)
        spectra_dev = self.rt.to_device(np.ascontiguousarray(block, dtype=self.dtype), zero_copy=True)
        self.enqueue(out_dev, spectra_dev, block.shape[0], local_size)
        return self.rt.result(out_dev, out)  # blocking: spectra_dev stays referenced until the kernel is done

    def device_buffers(self) -> list[DeviceBuffer]:
        """The kernel's buffers (:func:`resample_buffers`): fixed bytes and bytes per spectrum of a launch."""
        return resample_buffers(self.plan.n_bands, self.plan.n_wavelengths, self.T.dtype.itemsize,
                                atmosphere=self.atmosphere_dev is not None, n_weights=self.n_weights,
                                n_samples=self.n_samples if self.interpolation is not None else None)

    def default_chunk(self) -> int:
        """Pixels per chunk: input at most 256 MiB where it is copied to the device (1 GiB where the device reads
        host memory in place: no copy, and fewer, larger launches run faster on PoCL), and no more than the
        device's memory holds (:meth:`device_buffers`, :meth:`s2cl.cl.device_memory.DeviceMemory.units_fitting`);
        a one-line :class:`~s2cl.errors.ResourceError` when not even one spectrum fits."""
        row = self.n_samples * self.dtype().itemsize
        cap = 2**30 if self.rt.host_memory else 256 * 2**20
        device, own = self.rt.memory, self.device_buffers()
        fit = device.units_fitting(own, max(1, cap // row))
        if not fit:
            device.require(own, 1, what=f"resampling {self.plan.n_wavelengths:,} wavelengths to "
                           f"{self.plan.n_bands} bands", key="grid.step_nm", source=None,
                           fits="coarsen the grid or choose a device with more memory (compute.device)")
        return fit


def _round_up(n: int, m: int) -> int:
    return max(m, -(-n // m) * m)
