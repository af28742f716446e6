"""Settings of the IGRM fit (scene table ``[analysis] igrm``) and the render-time constants of its kernel.

Defaults and why: :mod:`s2cl.retrieve.igrm` and docs/retrieve.md. Wavelengths in nm, reflectances
unitless; the kernel works in normalised units (:class:`KernelConfig`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from s2cl.errors import InputError

Loss = Literal["linear", "soft_l1"]
Solver = Literal["auto", "varpro", "lm"]
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
    #: "varpro": Levenberg-Marquardt on (l0, s) with (rmin, depth) solved exactly at every step
    #: (common/igrm_varpro.mako; linear loss only); "lm": the four-parameter LM (common/igrm_lm.mako);
    #: "auto": varpro for the linear loss, lm for soft_l1
    solver: Solver = "auto"
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
        if self.solver not in ("auto", "varpro", "lm"):
            raise bad("solver", "'auto', 'varpro' or 'lm'")
        if self.solver == "varpro" and self.loss != "linear":
            raise bad("solver", "'lm' or 'auto' with loss = 'soft_l1' (variable projection solves the linear loss)")
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

    def resolved_solver(self) -> str:
        """The solver that runs: ``solver``, with "auto" resolved by the loss."""
        if self.solver != "auto":
            return self.solver
        return "varpro" if self.loss == "linear" else "lm"

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
    solver: str
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
        solver=settings.resolved_solver(),
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
