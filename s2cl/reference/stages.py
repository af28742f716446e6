"""float64 numpy twins of the stage functions in ``kernels/common/stages.mako``: the chain's stages, GVMI, SAM.
Same rules, same statuses and flags (:mod:`s2cl.status`); simple on purpose. Tests and bench compare every kernel
that splices a stage against these.

Each stage of the chain (:mod:`s2cl.forward.stages`) names its twin here, a *step* with one signature,
``step(L, v, out) -> L``: ``L`` the radiance of a set of bands (band axis first, float64), ``v`` the stage's values
by name broadcastable against it (band axis first; ``z``: the deviates; a ``pairs`` value ``[n, n]``), ``out`` the
outputs so far (a step writes its own and may read an earlier step's). :mod:`s2cl.reference.forward` and
:mod:`s2cl.reference.sweep` run the steps of the stages that are on in the chain's order.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from s2cl.atmos.correction import correct  # the host correction is the twin of s2_correct
from s2cl.status import MAX_ABS_REFLECTANCE, PixelFlag, Status

__all__ = ["calibrate", "calibrate_step", "calibration_error_step", "correct", "correct_step", "crosstalk_step",
           "noise_step", "normalised_difference", "quantise", "quantise_step", "sam", "sam_classify", "spectral_angles"]

Values = Mapping[str, Any]



def quantise(L: np.ndarray, lmin, lmax, maxdn: int) -> tuple[np.ndarray, np.ndarray]:
    """DN (float64) with ties rounding up, clipped into [0, maxdn], and the pixel flags (uint8).

    ``lmin``, ``lmax`` broadcast against ``L`` (e.g. ``(n_bands, 1)``)."""
    L = np.asarray(L, dtype=np.float64)
    lmin, lmax = np.asarray(lmin, dtype=np.float64), np.asarray(lmax, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        x = (L - lmin) * (maxdn / (lmax - lmin))
        xc = np.where(x > 0, np.where(x > maxdn, float(maxdn), x), 0.0)
    f = np.floor(xc)
    dn = np.where(xc - f >= 0.5, f + 1.0, f)
    with np.errstate(invalid="ignore"):
        low, high = ~(L >= lmin), L > lmax
    flags = np.where(np.isnan(L), PixelFlag.NODATA,
                     np.where(low, PixelFlag.LOW, np.where(high, PixelFlag.HIGH, 0))).astype(np.uint8)
    return dn, flags


def calibrate(dn: np.ndarray, flags: np.ndarray, lmin, gain) -> np.ndarray:
    """Radiance from DN, ``lmin + DN gain``; NaN where the pixel has no data."""
    L = np.asarray(lmin, dtype=np.float64) + np.asarray(dn, dtype=np.float64) * np.asarray(gain, dtype=np.float64)
    return np.where((np.asarray(flags) & PixelFlag.NODATA) != 0, np.nan, L)


def noise_step(L: np.ndarray, v: Values, out: dict[str, np.ndarray]) -> np.ndarray:
    """L + σ z, σ from the table ``sigma`` where given (a sweep), else sqrt(a + b max(L, 0)); writes ``noisy``."""
    sigma = v["sigma"] if "sigma" in v else np.sqrt(v["noise_a"] + v["noise_b"] * np.maximum(L, 0.0))
    out["noisy"] = L = L + sigma * v["z"]
    return L


def crosstalk_step(L: np.ndarray, v: Values, out: dict[str, np.ndarray]) -> np.ndarray:
    """L_k + Σ_j c[k][j] L_j over the bands (axis 0), every band from the others' radiance before the step; writes
    ``noisy`` where the chain has it."""
    c = np.asarray(v["crosstalk"], dtype=np.float64)
    L = L + np.tensordot(c, L, axes=(1, 0))
    if "noisy" in out:
        out["noisy"] = L
    return L


def quantise_step(L: np.ndarray, v: Values, out: dict[str, np.ndarray]) -> np.ndarray:
    """Writes ``dn`` (float64) and ``flags``; L unchanged."""
    out["dn"], out["flags"] = quantise(L, v["lmin"], v["lmax"], int(v["maxdn"]))
    return L


def calibrate_step(L: np.ndarray, v: Values, out: dict[str, np.ndarray]) -> np.ndarray:
    """Radiance from the DN of the quantisation step; writes ``calibrated``."""
    out["calibrated"] = L = calibrate(out["dn"], out["flags"], v["lmin"], v["gain"])
    return L


def calibration_error_step(L: np.ndarray, v: Values, out: dict[str, np.ndarray]) -> np.ndarray:
    """L (1 + e), the band's calibration error; writes ``calibrated`` again where the chain has it."""
    L = L * v["cal_error_gain"]
    if "calibrated" in out:
        out["calibrated"] = L
    return L


def correct_step(L: np.ndarray, v: Values, out: dict[str, np.ndarray]) -> np.ndarray:
    """Band reflectance through the band-effective terms ``lp``, ``g``, ``s``; writes ``reflectance``."""
    out["reflectance"] = L = correct(L, v["lp"], v["g"], v["s"])
    return L


def normalised_difference(rho_a: np.ndarray, rho_b: np.ndarray, offsets: tuple[float, float] = (0.1, 0.02),
                          max_abs: float = MAX_ABS_REFLECTANCE) -> tuple[np.ndarray, np.ndarray]:
    """A normalised-difference index (:mod:`s2cl.retrieve.indices`; default offsets: GVMI, Segl et al. 2012
    eq. 3) and status: INVALID (index 0) unless both reflectances are finite, within ``max_abs``, and
    both offset terms ρ + o are positive."""
    rho_a = np.asarray(rho_a, dtype=np.float64)
    rho_b = np.asarray(rho_b, dtype=np.float64)
    a, b = rho_a + offsets[0], rho_b + offsets[1]
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = (np.abs(rho_a) <= max_abs) & (np.abs(rho_b) <= max_abs) & (a > 0) & (b > 0)
        value = np.where(ok, (a - b) / np.where(ok, a + b, 1.0), 0.0)
    return value, np.where(ok, Status.OK, Status.INVALID).astype(np.uint8)


def sam(pixels: np.ndarray, unit_refs: np.ndarray, cos_min: float, max_abs: float = MAX_ABS_REFLECTANCE
        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The SAM stage: (best reference, its dot product, |p|^2, status).

    :param pixels: ``(..., n_bands)`` reflectance.
    :param unit_refs: ``(..., n_refs, n_bands)`` unit-length references (broadcast against pixels).
    :param cos_min: cosine of the angle threshold; below -1: no threshold.
    """
    p = np.asarray(pixels, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        valid = np.all(np.abs(p) <= max_abs, axis=-1)
    norm2 = (p * p).sum(-1)
    dots = (p[..., None, :] * unit_refs).sum(-1)
    best = np.argmax(np.where(np.isnan(dots), -np.inf, dots), axis=-1)  # the first maximum, as the kernel
    top = np.take_along_axis(dots, best[..., None], -1)[..., 0]
    if cos_min < -1.0:
        inside = np.ones_like(valid)
    else:
        lhs, rhs = top * top, cos_min * cos_min * norm2
        inside = np.where(top >= 0, (cos_min <= 0) | (lhs >= rhs), (cos_min < 0) & (lhs <= rhs))
    status = np.where(~valid, Status.INVALID, np.where(~(norm2 > 1e-30), Status.DEGENERATE,
                                                       np.where(inside, Status.OK, Status.UNCLASSIFIED)))
    return best, top, norm2, status.astype(np.uint8)


def sam_classify(refl: np.ndarray, references: np.ndarray, threshold_rad: float | None = None,
                 max_abs: float = MAX_ABS_REFLECTANCE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The standalone SAM kernel's outputs for ``refl`` ``(n_bands, n)`` and ``references``
    ``(n_refs, n_bands)``: (best reference or -1, angle in radians, status)."""
    r = np.asarray(references, dtype=np.float64)
    unit = r / np.linalg.norm(r, axis=1, keepdims=True)
    cos_min = -2.0 if threshold_rad is None else float(np.cos(threshold_rad))
    best, top, norm2, status = sam(np.asarray(refl, dtype=np.float64).T, unit, cos_min, max_abs)
    directed = (status == Status.OK) | (status == Status.UNCLASSIFIED)
    with np.errstate(invalid="ignore", divide="ignore"):
        angle = np.where(directed, np.arccos(np.clip(top / np.sqrt(norm2), -1.0, 1.0)), 0.0)
    return np.where(status == Status.OK, best, -1).astype(np.int32), angle, status


def spectral_angles(refl: np.ndarray, references: np.ndarray) -> np.ndarray:
    """Angles (radians) between every pixel of ``refl`` (n_bands, n) and every reference
    (n_refs, n_bands): shape (n_refs, n); NaN where a pixel has zero norm."""
    p = np.asarray(refl, dtype=np.float64)
    r = np.asarray(references, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = (r @ p) / (np.linalg.norm(r, axis=1)[:, None] * np.linalg.norm(p, axis=0)[None, :])
    return np.arccos(np.clip(cos, -1.0, 1.0))
