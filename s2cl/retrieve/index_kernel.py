"""Normalised-difference indices on the device (:mod:`s2cl.retrieve.indices`): GVMI and the others.

``index = ((ρ_a + o_a) - (ρ_b + o_b)) / ((ρ_a + o_a) + (ρ_b + o_b))`` per pixel, from band reflectances
``(n_bands, n_pixels)``. Pixels with NaN/inf, |ρ| > ``max_abs``, or an offset term that is not
positive get :attr:`s2cl.status.Status.INVALID` and index 0 (so a valid index lies in (-1, 1)); the
rule is the one the sweep kernel runs (``kernels/common/stages.mako``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.cl.kernel_args import Arg, bind, signature
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import pad_pixels
from s2cl.errors import InputError
from s2cl.retrieve.indices import index_of
from s2cl.status import MAX_ABS_REFLECTANCE


@dataclass
class IndexResult:
    """``index`` (n_pixels,) in the working precision and ``status`` (uint8: 0 valid, 3 invalid)."""

    index: np.ndarray
    status: np.ndarray


#: the kernel's arguments (kernels/index.cl.mako), in order
ARGS = (Arg("index", "out", "real"), Arg("status", "out", "uchar"), Arg("refl", "in", "real"),
        Arg("band_a", "scalar", "int"), Arg("band_b", "scalar", "int"), Arg("pitch", "scalar", "int"))


class IndexKernel:
    """Compiled normalised-difference index ``kind`` for one device, precision and lane count.

    :param rt: the OpenCL runtime to run on.
    :param kind: a key of :data:`s2cl.retrieve.indices.INDICES` (``"gvmi"``, ...).
    :param real_t: ``"float32"`` or ``"float64"``.
    :param lanes: pixels per work-item (default: :meth:`Runtime.lanes`).
    :param max_abs: |reflectance| above which a pixel is invalid.
    """

    def __init__(self, rt: Runtime, kind: str = "gvmi", *, real_t: str = "float32", lanes: int | None = None,
                 max_abs: float = MAX_ABS_REFLECTANCE):
        self.rt, self.nd = rt, index_of(kind)
        self.types = rt.types(real_t, lanes)
        source = render("index.cl.mako", T=self.types, nd=self.nd, max_abs=float(max_abs), args=ARGS,
                        signature=signature)
        self.kernel = rt.kernel(rt.build(source, template="index.cl.mako"), "normalised_difference")

    def __call__(self, refl: np.ndarray, band_a: int, band_b: int) -> IndexResult:
        """The index of rows ``band_a`` and ``band_b`` of ``refl`` (n_bands, n_pixels)."""
        refl = np.asarray(refl)
        if refl.ndim != 2:
            raise InputError(f"must have shape (n_bands, n_pixels), got {refl.shape}", key="reflectance")
        for key, row in zip(self.nd.roles, (band_a, band_b), strict=True):
            if not 0 <= int(row) < refl.shape[0]:
                raise InputError(f"band row must be in 0..{refl.shape[0] - 1}, got {row}", key=key)
        n = refl.shape[1]
        T, rt = self.types, self.rt
        host, pitch = pad_pixels(refl[[int(band_a), int(band_b)]], T.lanes, T.dtype)
        (index, index_d), (status, status_d) = rt.output((pitch,), T.dtype), rt.output((pitch,), np.uint8)
        values = {"index": index_d, "status": status_d, "refl": rt.upload_new(host), "band_a": 0, "band_b": 1,
                  "pitch": pitch}
        self.kernel(rt.queue, (pitch // T.lanes,), rt.local_size(self.kernel, pitch // T.lanes), *bind(ARGS, values, T))
        return IndexResult(rt.result(index_d, index)[:n], rt.result(status_d, status)[:n])


def normalised_difference(refl: np.ndarray, kind: str, band_a: int, band_b: int, *, real_t: str = "float32",
                          device: str | None = None, **kwargs) -> IndexResult:
    """One-shot :class:`IndexKernel` on ``device`` (default: :func:`s2cl.cl.runtime.get_runtime`'s choice)."""
    return IndexKernel(get_runtime(device), kind, real_t=real_t, **kwargs)(refl, band_a, band_b)
