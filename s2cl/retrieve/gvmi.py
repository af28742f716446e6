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

from s2cl.cl.kernel_args import Arg, bind, signature
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import pad_pixels
from s2cl.errors import InputError
from s2cl.status import MAX_ABS_REFLECTANCE


@dataclass
class GvmiResult:
    """``gvmi`` (n_pixels,) in the working precision and ``status`` (uint8: 0 valid, 3 invalid)."""

    gvmi: np.ndarray
    status: np.ndarray


#: the kernel's arguments (kernels/gvmi.cl.mako), in order
ARGS = (Arg("gvmi", "out", "real"), Arg("status", "out", "uchar"), Arg("refl", "in", "real"),
        Arg("nir", "scalar", "int"), Arg("swir", "scalar", "int"), Arg("pitch", "scalar", "int"))


class GvmiKernel:
    """Compiled GVMI for one device, precision and lane count.

    :param rt: the OpenCL runtime to run on.
    :param real_t: ``"float32"`` or ``"float64"``.
    :param lanes: pixels per work-item (default: :meth:`Runtime.lanes`).
    :param max_abs: |reflectance| above which a pixel is invalid.
    """

    def __init__(self, rt: Runtime, *, real_t: str = "float32", lanes: int | None = None,
                 max_abs: float = MAX_ABS_REFLECTANCE):
        self.rt = rt
        self.types = rt.types(real_t, lanes)
        source = render("gvmi.cl.mako", T=self.types, max_abs=float(max_abs), args=ARGS, signature=signature)
        self.kernel = rt.kernel(rt.build(source, template="gvmi.cl.mako"), "gvmi")

    def __call__(self, refl: np.ndarray, nir: int, swir: int) -> GvmiResult:
        """GVMI from rows ``nir`` and ``swir`` of ``refl`` (n_bands, n_pixels)."""
        refl = np.asarray(refl)
        if refl.ndim != 2:
            raise InputError(f"must have shape (n_bands, n_pixels), got {refl.shape}", key="reflectance")
        for key, row in (("nir", nir), ("swir", swir)):
            if not 0 <= int(row) < refl.shape[0]:
                raise InputError(f"band row must be in 0..{refl.shape[0] - 1}, got {row}", key=key)
        n = refl.shape[1]
        T, rt = self.types, self.rt
        host, pitch = pad_pixels(refl[[int(nir), int(swir)]], T.lanes, T.dtype)
        values = {"gvmi": rt.alloc(pitch * T.dtype.itemsize), "status": rt.alloc(pitch),
                  "refl": rt.upload_new(host), "nir": 0, "swir": 1, "pitch": pitch}
        self.kernel(rt.queue, (pitch // T.lanes,), None, *bind(ARGS, values, T))
        return GvmiResult(rt.fetch(values["gvmi"], (pitch,), T.dtype)[:n],
                          rt.fetch(values["status"], (pitch,), np.uint8)[:n])


def gvmi(refl: np.ndarray, nir: int, swir: int, *, real_t: str = "float32", device: str | None = None,
         **kwargs) -> GvmiResult:
    """One-shot :class:`GvmiKernel` on ``device`` (default: :func:`s2cl.cl.runtime.get_runtime`'s choice)."""
    return GvmiKernel(get_runtime(device), real_t=real_t, **kwargs)(refl, nir, swir)
