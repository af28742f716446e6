"""Batched IGRM fitting on the OpenCL device (Segl et al. 2012, eq. 2).

Model, per pixel, with band centre wavelengths ``l`` in nm::

    rho(l) = rmax - (rmax - rmin) * exp(-(l - l0)**2 / (2 s**2)),   lp = l0 + s

fitted by a bounded Levenberg-Marquardt (``kernels/common/igrm_lm.mako``) with
``s_min <= s <= s_max``, ``l0_min <= l0 <= l0_max``, ``rmax >= rmin >= rmin_min``. Every pixel reports a
:class:`FitStatus`, its iteration count and which bounds it ended on (:class:`BoundFlag`).

The defaults of :class:`IgrmSettings` and why:

* ``l0`` window 650-700 nm: the paper's l0 is the wavelength of the reflectance minimum, the
  in-vivo chlorophyll-a red absorption (670-690 nm). Hyperspectral fits of PROSAIL canopies
  (Cab 5-100 ug/cm2, LAI 3-4) put it at 670-688 nm; the window leaves 20 nm below and 10 nm
  above so that noise does not pin good fits, while a fit that runs into it is flagged.
* ``s`` 10-80 nm: the same fits give s = 22-52 nm (inflection lp = 696-734 nm). Narrower than
  10 nm is a notch no canopy makes (and falls between four broad bands, unconstrained); wider
  than 80 nm no longer describes a red edge (lp beyond 780 nm, the NIR plateau).
* ``rmin_min`` -0.05: rmin is the model's minimum, an extrapolation between bands that
  noise-free PROSAIL fits put as low as -0.02; without a floor, noisy four-band fits with a
  narrow dip run away to rmin ~ -1 with s at its minimum (the fit then crawls for hundreds
  of iterations). The floor stops them there, flagged.
* ``depth_min`` 0.01: with rmax - rmin below one reflectance percent the red edge is not
  resolved (flat targets, bare minerals, noise): the fit is reported DEGENERATE.
* initial guess ``"data"``: l0 at the darkest band (clipped into the window), rmin/rmax the
  extreme band values, s from the half-depth crossing; ``"grid"`` scans a grid of (l0, s)
  with the optimal (rmax, rmin) of each (variable projection) and starts from the best.
* ``tol`` 1e-5 (relative step, cost change and scaled gradient: when to stop), ``max_iter`` 50,
  loss ``"linear"`` (the paper's least squares); ``"soft_l1"`` is the robust alternative.
* ``lp_tol_nm`` 1e-3: the status is decided after stopping, from the undamped Gauss-Newton step
  at the result: CONVERGED when it moves lp by at most this, else STALLED (stopped where the
  precision ran out) or ITERATION_LIMIT. On float32 sweep pixels of Lib1 and Lib2, 99.99 % of
  CONVERGED fits lie within 1e-3 nm of the float64 optimum (``kernels/common/igrm_lm.mako``).
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from s2cl.cl.kernel_args import Arg, bind, signature
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.cl.templates import render
from s2cl.cl.vecmath import EXP_DEGREE, exp_template_vars
from s2cl.cl.vectypes import VecTypes, pad_pixels
from s2cl.errors import InputError
from s2cl.retrieve.design import check_design
from s2cl.retrieve.igrm_settings import IgrmSettings, kernel_config
from s2cl.status import Status

PARAM_NAMES = ("rmax", "rmin", "l0", "s", "lp", "rms")


class FitStatus(enum.IntEnum):
    """Per-pixel outcome of a fit (the ``status`` array, uint8): the shared codes of
    :class:`s2cl.status.Status` (``kernels/common/s2_status.clh``)."""

    CONVERGED = Status.OK  #: exact fit, or the scaled gradient below ``tol`` at the returned point
    ITERATION_LIMIT = Status.ITERATION_LIMIT
    DEGENERATE = Status.DEGENERATE  #: rmax - rmin <= depth_min: no red edge, l0 and s are undetermined
    INVALID_INPUT = Status.INVALID  #: a band value was NaN, inf or |rho| > max_abs_reflectance; outputs are 0
    #: no step makes progress at the working precision while the gradient test still fails
    STALLED = Status.STALLED


class BoundFlag(enum.IntFlag):
    """Bits of the per-pixel ``bounds`` mask: which bounds a fit ended on."""

    NONE = 0
    L0_LOW = 1
    L0_HIGH = 2
    S_LOW = 4
    S_HIGH = 8
    DEPTH_ZERO = 16  #: rmax == rmin
    RMIN_LOW = 32  #: rmin at rmin_min


@dataclass
class IgrmResult:
    """Per-pixel IGRM fit results, arrays of shape ``(n_pixels,)``.

    ``rmax``, ``rmin``, ``rms`` are reflectances; ``l0``, ``s``, ``lp`` nm; ``rms`` is the RMS of
    the band residuals of the plain least-squares cost. All finite; 0 for INVALID_INPUT pixels.
    ``log10_condition``: log10 of the condition estimate of the column-scaled Jacobian at the
    solution (``kernels/common/igrm_lm.mako``), capped at 12; large when the bands cannot pin the
    four parameters.
    """

    rmax: np.ndarray
    rmin: np.ndarray
    l0: np.ndarray
    s: np.ndarray
    lp: np.ndarray
    rms: np.ndarray
    status: np.ndarray
    iterations: np.ndarray
    bounds: np.ndarray
    log10_condition: np.ndarray | None = None

    @property
    def n_pixels(self) -> int:
        return int(self.status.size)

    def fitted(self) -> np.ndarray:
        """Mask of fits with meaningful parameters: converged, stalled, or stopped at the iteration limit."""
        return np.isin(self.status, (FitStatus.CONVERGED, FitStatus.STALLED, FitStatus.ITERATION_LIMIT))

    def on_bound(self) -> np.ndarray:
        """Mask of fitted pixels that ended on an l0, s or rmin bound."""
        edge = BoundFlag.L0_LOW | BoundFlag.L0_HIGH | BoundFlag.S_LOW | BoundFlag.S_HIGH | BoundFlag.RMIN_LOW
        return self.fitted() & ((self.bounds & int(edge)) != 0)

    def counts(self) -> dict[str, int]:
        """Number of pixels per status and on a bound."""
        out = {s.name.lower(): int(np.count_nonzero(self.status == s)) for s in FitStatus}
        out["on_bound"] = int(np.count_nonzero(self.on_bound()))
        return out

    def params(self) -> np.ndarray:
        """The six parameter arrays stacked, shape ``(6, n_pixels)`` (order of ``PARAM_NAMES``)."""
        return np.stack([getattr(self, k) for k in PARAM_NAMES])

    def take(self, idx: Any) -> IgrmResult:
        """The results of the pixels ``idx`` (an index array, a mask or a slice), every field alike."""
        return IgrmResult(*(None if getattr(self, f.name) is None else getattr(self, f.name)[idx]
                            for f in dataclasses.fields(self)))


Exp = Literal["poly", "builtin"]


class IgrmFitter:
    """A compiled IGRM fit for one (device, settings, band count, precision, lanes): build once, fit often.

    :param rt: the OpenCL runtime to run on.
    :param n_bands: number of bands (>= 4).
    :param settings: fit design; defaults to :class:`IgrmSettings` ().
    :param real_t: ``"float32"`` (default) or ``"float64"``.
    :param lanes: pixels per work-item; default :meth:`Runtime.lanes` (the device's native vector
        width on CPUs: 16 floats with AVX-512, 8 with AVX2; 1 on GPUs).
    :param exp: ``"poly"`` (own polynomial, fast on PoCL) or ``"builtin"`` (OpenCL ``exp``: the
        plain, obviously-correct variant that the fast one is checked against).
    :param exp_degree: polynomial degree (default 5 for float32, 12 for float64).
    """

    def __init__(self, rt: Runtime, n_bands: int, settings: IgrmSettings | None = None, *, real_t: str = "float32",
                 lanes: int | None = None, exp: Exp = "poly", exp_degree: int | None = None):
        if isinstance(n_bands, bool) or not isinstance(n_bands, int | np.integer) or n_bands < 4:
            raise InputError(f"the IGRM fit needs at least 4 bands, got {n_bands}", key="n_bands")
        if exp not in ("poly", "builtin"):
            raise InputError(f"must be 'poly' or 'builtin', got {exp!r}", key="exp")
        self.rt = rt
        self.settings = settings or IgrmSettings()
        self.n_bands = int(n_bands)
        self.types = rt.types(real_t, lanes)
        self.config = kernel_config(self.settings, self.n_bands, real_t, exp)
        self.exp_degree = EXP_DEGREE[real_t] if exp_degree is None else exp_degree
        self.iter_dtype = np.dtype(np.uint8 if self.settings.max_iter <= 255 else np.uint16)
        self.args = (Arg("params", "out", "real"), Arg("status", "out", "uchar"),
                     Arg("iterations", "out", "uchar" if self.iter_dtype == np.uint8 else "ushort"),
                     Arg("bounds", "out", "uchar"), Arg("refl", "in", "real"), Arg("wavelength", "in", "real"),
                     Arg("pitch", "scalar", "int"))
        self.source = self._render()
        self.kernel = rt.kernel(rt.build(self.source, template="igrm.cl.mako"), "igrm_fit")

    def _render(self) -> str:
        return render(
            "igrm.cl.mako",
            T=self.types,
            T1=VecTypes(self.types.real_t, 1),
            c=self.config,
            iter_t="uchar" if self.iter_dtype == np.uint8 else "ushort",
            args=self.args,
            signature=signature,
            **exp_template_vars(self.types.real_t, self.exp_degree),
        )

    def check(self, refl: np.ndarray, wavelengths_nm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Validate inputs: ``refl`` (n_bands, n_pixels), wavelengths (n_bands,) increasing, nm."""
        refl = np.asarray(refl)
        if refl.ndim != 2 or refl.shape[0] != self.n_bands:
            raise InputError(f"must have shape ({self.n_bands}, n_pixels), got {refl.shape}", key="reflectance")
        if not np.issubdtype(refl.dtype, np.floating):
            raise InputError(f"must be floating point reflectance, got dtype {refl.dtype}", key="reflectance")
        wl = np.asarray(wavelengths_nm, dtype=np.float64)
        if wl.shape != (self.n_bands,):
            raise InputError(f"must have shape ({self.n_bands},), got {wl.shape}", key="wavelengths_nm")
        if not np.all(np.isfinite(wl)):
            raise InputError(f"must be finite, got {wl.tolist()}", key="wavelengths_nm")
        check_design("igrm", [f"band {k + 1}" for k in range(wl.size)], wl, np.zeros_like(wl), key="wavelengths_nm")
        if np.any(np.diff(wl) <= 0):
            raise InputError(f"must be strictly increasing (sort the bands by centre), got {wl.tolist()}",
                             key="wavelengths_nm")
        if wl[0] < 300.0 or wl[-1] > 2600.0:
            raise InputError(f"must be band centres in nm within 300-2600, got {wl.tolist()}", key="wavelengths_nm")
        return refl, wl

    def fit(self, refl: np.ndarray, wavelengths_nm: np.ndarray, *, chunk: int = 1 << 22) -> IgrmResult:
        """Fit every pixel of ``refl`` (n_bands, n_pixels); see :class:`IgrmResult`."""
        refl, wl = self.check(refl, wavelengths_nm)
        n = refl.shape[1]
        parts = [self._fit_chunk(refl[:, i:i + chunk], wl) for i in range(0, max(n, 1), chunk)]
        if len(parts) == 1:
            return parts[0]
        return IgrmResult(*(np.concatenate([getattr(p, f.name) for p in parts])
                            for f in dataclasses.fields(IgrmResult)))

    def buffers(self, refl: np.ndarray, wl: np.ndarray) -> dict[str, Any]:
        """One launch's arguments, named as :attr:`args`: ``refl`` (n_bands, n_pixels) padded to whole lanes
        and uploaded with the centres ``wl`` (nm), the outputs allocated (7 parameter rows: the six
        parameters and the condition estimate), ``pitch`` the padded pixel count."""
        return self._buffers(refl, wl)[0]

    def _buffers(self, refl: np.ndarray, wl: np.ndarray) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """:meth:`buffers` and the host arrays the outputs land in (:meth:`Runtime.output`)."""
        T, rt = self.types, self.rt
        host, pitch = pad_pixels(refl, T.lanes, T.dtype)
        shapes = {"params": ((7, pitch), T.dtype), "status": ((pitch,), np.uint8),
                  "iterations": ((pitch,), self.iter_dtype), "bounds": ((pitch,), np.uint8)}
        arrays, v = {}, {}
        for name, (shape, dtype) in shapes.items():
            arrays[name], v[name] = rt.output(shape, dtype)
        # read in place on host-memory devices (the kernel loads it with vloadN: any alignment), else copied
        v["refl"] = rt.to_device(host, zero_copy=True) if rt.host_memory else rt.upload_new(host)
        v["wavelength"], v["pitch"] = rt.upload_new(wl.astype(T.dtype)), pitch
        return v, arrays

    def enqueue(self, v: dict[str, Any]) -> None:
        """Queue the fit on the arguments ``v`` (:meth:`buffers`); returns at once."""
        items = v["pitch"] // self.types.lanes
        self.kernel(self.rt.queue, (items,), self.rt.local_size(self.kernel, items), *bind(self.args, v, self.types))

    def _fit_chunk(self, refl: np.ndarray, wl: np.ndarray) -> IgrmResult:
        n, rt = refl.shape[1], self.rt
        v, arrays = self._buffers(refl, wl)
        self.enqueue(v)
        out = {name: rt.result(v[name], array) for name, array in arrays.items()}
        params = out["params"][:, :n]
        return IgrmResult(*params[:6], status=out["status"][:n], iterations=out["iterations"][:n],
                          bounds=out["bounds"][:n], log10_condition=params[6])


def fit_igrm(refl: np.ndarray, wavelengths_nm: np.ndarray, settings: IgrmSettings | None = None, *,
             real_t: str = "float32", device: str | None = None, **kwargs: Any) -> IgrmResult:
    """One-shot :class:`IgrmFitter` on ``device`` (builds are cached, so repeated calls are cheap)."""
    refl = np.asarray(refl)
    n_bands = refl.shape[0] if refl.ndim == 2 else -1
    if refl.ndim != 2:
        raise InputError(f"must have shape (n_bands, n_pixels), got {refl.shape}", key="reflectance")
    return IgrmFitter(get_runtime(device), n_bands, settings, real_t=real_t, **kwargs).fit(refl, wavelengths_nm)
