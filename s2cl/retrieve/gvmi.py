"""Global Vegetation Moisture Index on the device (Segl et al. 2012, eq. 3).

``GVMI = ((NIR + 0.1) - (SWIR + 0.02)) / ((NIR + 0.1) + (SWIR + 0.02))`` per pixel, from band
reflectances ``(n_bands, n_pixels)``. Pixels with NaN/inf, |rho| > ``max_abs``, or an offset
reflectance (NIR + 0.1, SWIR + 0.02) that is not positive get :attr:`s2cl.status.Status.INVALID` and
index 0 (so the index lies in (-1, 1) whenever it is valid); the rule is the one the sweep kernel
runs (``kernels/common/stages.mako``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.cl.bufferpool import BufferPool
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import VecTypes, pad_pixels
from s2cl.errors import InputError
from s2cl.status import MAX_ABS_REFLECTANCE


@dataclass
class GvmiResult:
    """``gvmi`` (n_pixels,) in the working precision and ``status`` (uint8: 0 valid, 3 invalid)."""

    gvmi: np.ndarray
    status: np.ndarray


class GvmiKernel:
    """Compiled GVMI for one precision and lane count.

    :param real_t: ``"float32"`` or ``"float64"``.
    :param lanes: pixels per work-item (default: :meth:`Runtime.lanes`).
    :param max_abs: |reflectance| above which a pixel is invalid.
    """

    def __init__(self, *, real_t: str = "float32", lanes: int | None = None, max_abs: float = MAX_ABS_REFLECTANCE,
                 rt: Runtime | None = None):
        self.rt = rt or get_runtime()
        if real_t == "float64" and not self.rt.has_fp64:
            raise InputError(f"device {self.rt.name} has no float64 support", key="real_t")
        self.types = VecTypes(real_t, self.rt.lanes(real_t, lanes))
        source = render("gvmi.cl.mako", T=self.types, max_abs=float(max_abs))
        self.kernel = self.rt.kernel(self.rt.build(source, template="gvmi.cl.mako"), "gvmi")
        self.buffers = BufferPool(self.rt)

    def __call__(self, refl: np.ndarray, nir: int, swir: int) -> GvmiResult:
        """GVMI from rows ``nir`` and ``swir`` of ``refl`` (n_bands, n_pixels)."""
        refl = np.asarray(refl)
        if refl.ndim != 2:
            raise InputError(f"must have shape (n_bands, n_pixels), got {refl.shape}", key="reflectance")
        for key, row in (("nir", nir), ("swir", swir)):
            if not 0 <= int(row) < refl.shape[0]:
                raise InputError(f"band row must be in 0..{refl.shape[0] - 1}, got {row}", key=key)
        n = refl.shape[1]
        rows = refl[[int(nir), int(swir)]]
        host, pitch = pad_pixels(rows, self.types.lanes, self.types.dtype)
        rt, pool = self.rt, self.buffers
        out_d, st_d = pool.get("gvmi", pitch * self.types.dtype.itemsize), pool.get("status", pitch)
        self.kernel(rt.queue, (pitch // self.types.lanes,), None, out_d, st_d, pool.upload("refl", host),
                    np.int32(0), np.int32(1), np.int32(pitch))
        return GvmiResult(rt.fetch(out_d, (pitch,), self.types.dtype)[:n], rt.fetch(st_d, (pitch,), np.uint8)[:n])


def gvmi(refl: np.ndarray, nir: int, swir: int, *, real_t: str = "float32", **kwargs) -> GvmiResult:
    """One-shot :class:`GvmiKernel` (the build is cached)."""
    return GvmiKernel(real_t=real_t, **kwargs)(refl, nir, swir)
