"""A formula retrieval (:mod:`s2cl.retrieve.formula`, e.g. S2REP) on the device, per pixel, from band reflectances
``(n_bands, n_pixels)``: the value and a status (:attr:`s2cl.status.Status.INVALID` with value 0 where the formula's
validity rule fails). The standalone kernel (``kernels/formula.cl.mako``), splicing the same device function as the
sweep kernel.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from s2cl.cl.kernel_args import Arg, bind, signature
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import pad_pixels
from s2cl.errors import InputError
from s2cl.retrieve.formula import Formula
from s2cl.status import MAX_ABS_REFLECTANCE


class FormulaResult(NamedTuple):
    """``value`` (n_pixels,) in the working precision, in the formula's unit, and ``status`` (uint8)."""

    value: np.ndarray
    status: np.ndarray


#: the kernel's arguments (kernels/formula.cl.mako), in order
ARGS = (Arg("value", "out", "real"), Arg("status", "out", "uchar"), Arg("refl", "in", "real"),
        Arg("pitch", "scalar", "int"))


class FormulaKernel:
    """Compiled ``formula`` for one device, precision and lane count.

    :param rt: the OpenCL runtime to run on.
    :param formula: a parsed :class:`~s2cl.retrieve.formula.Formula`.
    :param real_t: ``"float32"`` or ``"float64"``.
    :param lanes: pixels per work-item (default: :meth:`Runtime.lanes`).
    :param max_abs: |reflectance| above which a pixel is invalid.
    """

    def __init__(self, rt: Runtime, formula: Formula, real_t: str = "float32", lanes: int | None = None, *,
                 max_abs: float = MAX_ABS_REFLECTANCE):
        self.rt, self.formula = rt, formula
        self.types = rt.types(real_t, lanes)
        source = render("formula.cl.mako", T=self.types, formula=formula, max_abs=float(max_abs), args=ARGS,
                        signature=signature)
        self.kernel = rt.kernel(rt.build(source, template="formula.cl.mako"), "formula")

    def __call__(self, refl: np.ndarray, rows: Sequence[int] | None = None) -> FormulaResult:
        """The formula per pixel of ``refl`` (n_rows, n_pixels); ``rows[i]`` is the row of ``formula.bands[i]``
        (default: the rows are the formula's bands, in order)."""
        refl = np.asarray(refl)
        n_bands = len(self.formula.bands)
        rows = list(range(n_bands)) if rows is None else [int(r) for r in rows]
        if refl.ndim != 2:
            raise InputError(f"must have shape (n_bands, n_pixels), got {refl.shape}", key="reflectance")
        if len(rows) != n_bands or not all(0 <= r < refl.shape[0] for r in rows):
            raise InputError(f"needs one row in 0..{refl.shape[0] - 1} for each of the bands "
                             f"{', '.join(self.formula.bands)}, got {rows}", key="reflectance")
        n = refl.shape[1]
        T, rt = self.types, self.rt
        host, pitch = pad_pixels(refl[rows], T.lanes, T.dtype)
        (value, value_d), (status, status_d) = rt.output((pitch,), T.dtype), rt.output((pitch,), np.uint8)
        values = {"value": value_d, "status": status_d, "refl": rt.upload_new(host), "pitch": pitch}
        self.kernel(rt.queue, (pitch // T.lanes,), rt.local_size(self.kernel, pitch // T.lanes), *bind(ARGS, values, T))
        return FormulaResult(rt.result(value_d, value)[:n], rt.result(status_d, status)[:n])


def formula_values(refl: np.ndarray, formula: Formula, rows: Sequence[int] | None = None, *, real_t: str = "float32",
                   device: str | None = None, **kwargs) -> FormulaResult:
    """One-shot :class:`FormulaKernel` on ``device`` (default: :func:`s2cl.cl.runtime.get_runtime`'s choice)."""
    return FormulaKernel(get_runtime(device), formula, real_t=real_t, **kwargs)(refl, rows)
