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
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from s2cl.cl.bufferpool import BufferPool
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.cl.templates import render
from s2cl.cl.vecmath import EXP_DEGREE, exp_template_vars
from s2cl.cl.vectypes import VecTypes, pad_pixels
from s2cl.errors import InputError
from s2cl.retrieve.design import check_design
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


Loss = Literal["linear", "soft_l1"]
Init = Literal["data", "grid"]


@dataclass(frozen=True)
class IgrmSettings:
    """Design of the IGRM fit: bounds, initial guess, loss, stopping rules (see module doc).

    Wavelengths in nm, reflectances unitless. All fields are scene parameters (``[igrm]``).
    """

    l0_min_nm: float = 650.0
    l0_max_nm: float = 700.0
    s_min_nm: float = 10.0
    s_max_nm: float = 80.0
    #: lower bound of rmin (reflectance): a little below 0 because the inverted Gaussian's
    #: minimum is an extrapolation between bands (noise-free PROSAIL fits reach -0.02)
    rmin_min: float = -0.05
    #: s of the initial guess when the data have no half-depth crossing after their minimum
    s_guess_nm: float = 35.0
    init: Init = "data"
    #: grid initial guess: number of l0 and of s values (even spacing in l0, geometric in s)
    grid_l0: int = 6
    grid_s: int = 6
    loss: Loss = "linear"
    #: soft-L1 residual scale (reflectance): residuals much larger than it count linearly
    f_scale: float = 0.01
    max_iter: int = 50
    #: relative tolerance on steps, cost decrease and the scaled gradient
    tol: float = 1e-5
    #: RMS residual (reflectance) at which a fit is exact and stops
    residual_floor: float = 1e-7
    #: a fit is CONVERGED when the Gauss-Newton step from its result moves lp by at most this (nm)
    lp_tol_nm: float = 1e-3
    #: rmax - rmin at or below which a pixel is DEGENERATE
    depth_min: float = 0.01
    #: |rho| above this marks a pixel INVALID_INPUT (reflectance, not DN, is expected)
    max_abs_reflectance: float = 10.0

    def __post_init__(self) -> None:
        def bad(key: str, allowed: str) -> InputError:
            return InputError(f"must be {allowed}, got {getattr(self, key)!r}", key=f"igrm.{key}")

        for key in ("l0_min_nm", "l0_max_nm", "s_min_nm", "s_max_nm", "rmin_min", "s_guess_nm", "f_scale", "tol",
                    "residual_floor", "lp_tol_nm", "depth_min", "max_abs_reflectance"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise bad(key, "a finite number")
        if not 300.0 <= self.l0_min_nm < self.l0_max_nm <= 2600.0:
            raise bad("l0_max_nm", f"> igrm.l0_min_nm = {self.l0_min_nm} and both within 300-2600 nm")
        if not 0.0 < self.s_min_nm < self.s_max_nm <= 1000.0:
            raise bad("s_max_nm", f"> igrm.s_min_nm = {self.s_min_nm} > 0 and <= 1000 nm")
        if not self.s_min_nm <= self.s_guess_nm <= self.s_max_nm:
            raise bad("s_guess_nm", f"within [igrm.s_min_nm, igrm.s_max_nm] = [{self.s_min_nm}, {self.s_max_nm}]")
        if not -1.0 <= self.rmin_min <= 0.5:
            raise bad("rmin_min", "in [-1, 0.5] (reflectance)")
        if self.init not in ("data", "grid"):
            raise bad("init", "'data' or 'grid'")
        if self.loss not in ("linear", "soft_l1"):
            raise bad("loss", "'linear' or 'soft_l1'")
        for key in ("grid_l0", "grid_s"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or not 2 <= value <= 32:
                raise bad(key, "an integer in 2..32")
        if isinstance(self.max_iter, bool) or not isinstance(self.max_iter, int) or not 1 <= self.max_iter <= 65535:
            raise bad("max_iter", "an integer in 1..65535")
        if not 0.0 < self.f_scale <= 1.0:
            raise bad("f_scale", "in (0, 1] (reflectance)")
        if not 1e-15 <= self.tol <= 1e-1:
            raise bad("tol", "in [1e-15, 0.1]")
        if not 0.0 <= self.residual_floor <= 1e-2:
            raise bad("residual_floor", "in [0, 0.01] (reflectance)")
        if not 1e-9 <= self.lp_tol_nm <= 10.0:
            raise bad("lp_tol_nm", "in [1e-9, 10] (nm)")
        if not 0.0 <= self.depth_min < 1.0:
            raise bad("depth_min", "in [0, 1) (reflectance)")
        if not 1.0 <= self.max_abs_reflectance <= 1e6:
            raise bad("max_abs_reflectance", "in [1, 1e6]")

    @classmethod
    def from_mapping(cls, values: dict[str, Any], *, source: str | None = None) -> IgrmSettings:
        """Settings from a scene's ``[igrm]`` table; unknown keys raise :class:`InputError`."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise InputError(f"unknown key(s) {unknown}; allowed: {sorted(known)}", source=source, key="igrm")
        try:
            return cls(**values)
        except InputError as err:
            raise InputError(str(err), source=source) from None

    def l0_grid(self) -> np.ndarray:
        """l0 values (nm) of the grid initial guess: evenly spaced over the window."""
        return np.linspace(self.l0_min_nm, self.l0_max_nm, self.grid_l0)

    def s_grid(self) -> np.ndarray:
        """s values (nm) of the grid initial guess: geometric over [s_min, s_max]."""
        return np.geomspace(self.s_min_nm, self.s_max_nm, self.grid_s)


#: Levenberg-Marquardt internals (not scene parameters): damping start, factors and limits,
#: the damping floor added to the diagonal, and the relative pivot threshold of the LDL^T solve.
LM_CONSTANTS = {"lam0": 1e-3, "lam_down": 0.1, "lam_up": 10.0, "lam_min": 1e-9, "lam_max": 1e10,
                "diag_eps": 1e-6}
PIVOT_REL = {"float32": 1e-6, "float64": 1e-13}


@dataclass(frozen=True)
class KernelConfig:
    """Render-time constants of ``common/igrm_lm.mako`` in normalised units.

    Wavelengths enter as ``(l - xc) / xw``; ``lo_l``/``hi_l`` bound that for l0, ``lo_s``/``hi_s``
    bound ``s / xw``. ``f_abs`` is the exact-fit cost ``n_bands * residual_floor**2``.
    """

    n_bands: int
    xc: float
    xw: float
    rmin_lo: float
    lo_l: float
    hi_l: float
    lo_s: float
    hi_s: float
    s_guess: float
    init: str
    grid_l: tuple[float, ...]
    grid_s: tuple[float, ...]
    loss: str
    f_scale: float
    max_iter: int
    xtol: float
    ftol: float
    gtol: float
    f_abs: float
    lp_tol: float
    depth_min: float
    max_abs: float
    exp: str
    pivot_rel: float
    lam0: float = LM_CONSTANTS["lam0"]
    lam_down: float = LM_CONSTANTS["lam_down"]
    lam_up: float = LM_CONSTANTS["lam_up"]
    lam_min: float = LM_CONSTANTS["lam_min"]
    lam_max: float = LM_CONSTANTS["lam_max"]
    diag_eps: float = LM_CONSTANTS["diag_eps"]


def kernel_config(settings: IgrmSettings, n_bands: int, real_t: str = "float32", exp: str = "poly") -> KernelConfig:
    """The :class:`KernelConfig` for ``settings`` and ``n_bands`` bands."""
    xc = 0.5 * (settings.l0_min_nm + settings.l0_max_nm)
    xw = 0.5 * (settings.s_min_nm + settings.s_max_nm)
    return KernelConfig(
        n_bands=n_bands,
        xc=xc,
        xw=xw,
        rmin_lo=settings.rmin_min,
        lo_l=(settings.l0_min_nm - xc) / xw,
        hi_l=(settings.l0_max_nm - xc) / xw,
        lo_s=settings.s_min_nm / xw,
        hi_s=settings.s_max_nm / xw,
        s_guess=settings.s_guess_nm / xw,
        init=settings.init,
        grid_l=tuple(float((v - xc) / xw) for v in settings.l0_grid()),
        grid_s=tuple(float(v / xw) for v in settings.s_grid()),
        loss=settings.loss,
        f_scale=settings.f_scale,
        max_iter=settings.max_iter,
        xtol=settings.tol,
        ftol=settings.tol,
        gtol=settings.tol,
        f_abs=n_bands * settings.residual_floor**2,
        lp_tol=settings.lp_tol_nm / xw,
        depth_min=settings.depth_min,
        max_abs=settings.max_abs_reflectance,
        exp=exp,
        pivot_rel=PIVOT_REL[real_t],
    )


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
    """A compiled IGRM fit for one (settings, band count, precision, lanes): build once, fit often.

    :param n_bands: number of bands (>= 4).
    :param settings: fit design; defaults to :class:`IgrmSettings` ().
    :param real_t: ``"float32"`` (default) or ``"float64"``.
    :param lanes: pixels per work-item; default :meth:`Runtime.lanes` (the device's native vector
        width on CPUs: 16 floats with AVX-512, 8 with AVX2; 1 on GPUs).
    :param exp: ``"poly"`` (own polynomial, fast on PoCL) or ``"builtin"`` (OpenCL ``exp``: the
        plain, obviously-correct variant that the fast one is checked against).
    :param exp_degree: polynomial degree (default 5 for float32, 12 for float64).
    """

    def __init__(self, n_bands: int, settings: IgrmSettings | None = None, *, real_t: str = "float32",
                 lanes: int | None = None, exp: Exp = "poly", exp_degree: int | None = None,
                 rt: Runtime | None = None):
        if isinstance(n_bands, bool) or not isinstance(n_bands, int | np.integer) or n_bands < 4:
            raise InputError(f"the IGRM fit needs at least 4 bands, got {n_bands}", key="n_bands")
        if exp not in ("poly", "builtin"):
            raise InputError(f"must be 'poly' or 'builtin', got {exp!r}", key="exp")
        self.rt = rt or get_runtime()
        self.settings = settings or IgrmSettings()
        self.n_bands = int(n_bands)
        if real_t == "float64" and not self.rt.has_fp64:
            raise InputError(f"device {self.rt.name} has no float64 support", key="real_t")
        self.types = VecTypes(real_t, self.rt.lanes(real_t, lanes))
        self.config = kernel_config(self.settings, self.n_bands, real_t, exp)
        self.exp_degree = EXP_DEGREE[real_t] if exp_degree is None else exp_degree
        self.iter_dtype = np.dtype(np.uint8 if self.settings.max_iter <= 255 else np.uint16)
        self.source = self._render()
        program = self.rt.build(self.source, template="igrm.cl.mako")
        self.kernel = self.rt.kernel(program, "igrm_fit")
        self.buffers = BufferPool(self.rt)

    def _render(self) -> str:
        return render(
            "igrm.cl.mako",
            T=self.types,
            T1=VecTypes(self.types.real_t, 1),
            c=self.config,
            iter_t="uchar" if self.iter_dtype == np.uint8 else "ushort",
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

    def _fit_chunk(self, refl: np.ndarray, wl: np.ndarray) -> IgrmResult:
        n = refl.shape[1]
        lanes = self.types.lanes
        host, pitch = pad_pixels(refl, lanes, self.types.dtype)
        rt, pool = self.rt, self.buffers
        params_d = pool.get("params", 7 * pitch * self.types.dtype.itemsize)
        status_d = pool.get("status", pitch)
        iter_d = pool.get("iterations", pitch * self.iter_dtype.itemsize)
        bounds_d = pool.get("bounds", pitch)
        refl_d = pool.upload("refl", host)
        wl_d = pool.upload("wavelength", wl.astype(self.types.dtype))
        self.kernel(rt.queue, (pitch // lanes,), None, params_d, status_d, iter_d, bounds_d, refl_d, wl_d,
                    np.int32(pitch))
        params = rt.fetch(params_d, (7, pitch), self.types.dtype)[:, :n]
        return IgrmResult(
            *params[:6],
            status=rt.fetch(status_d, (pitch,), np.uint8)[:n],
            iterations=rt.fetch(iter_d, (pitch,), self.iter_dtype)[:n],
            bounds=rt.fetch(bounds_d, (pitch,), np.uint8)[:n],
            log10_condition=params[6],
        )


def fit_igrm(refl: np.ndarray, wavelengths_nm: np.ndarray, settings: IgrmSettings | None = None, *,
             real_t: str = "float32", **kwargs: Any) -> IgrmResult:
    """One-shot :class:`IgrmFitter` (builds are cached, so repeated calls are cheap)."""
    refl = np.asarray(refl)
    n_bands = refl.shape[0] if refl.ndim == 2 else -1
    if refl.ndim != 2:
        raise InputError(f"must have shape (n_bands, n_pixels), got {refl.shape}", key="reflectance")
    return IgrmFitter(n_bands, settings, real_t=real_t, **kwargs).fit(refl, wavelengths_nm)
