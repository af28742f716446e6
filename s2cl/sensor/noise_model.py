"""Sensor noise from the SNR table: noise-equivalent radiance NER(L) = L / SNR(L).

Shot-noise model (as the paper assumes): the noise variance is affine in the signal,
``σ²(L) = a + b·L`` (W m⁻² sr⁻¹ µm⁻¹)², with ``a`` the signal-independent (dark/read) part and
``b·L`` the photon shot noise. ``a`` and ``b`` are fitted to the given (L, SNR) points of a band:

- three points (B1–B9): non-negative least squares on σ², each point weighted by 1/σ²ᵢ so that
  every point's relative error counts equally (Table 1's points lie on such a line to < 1 %), solved exactly
  for its two unknowns by :func:`nnls_two` (no iterative solver: the unconstrained fit when both are
  non-negative, else the better of the two one-coefficient fits);
- two points (B11, B12): the line through both (still non-negative);
- one point (B10: SNR 50 at Lref only): pure shot noise, ``a = 0``, ``b = σ²/L`` — the paper's
  "dominating shot noise" assumption, so SNR ∝ √L around the one given value.

A band whose width changes from its reference width ``w_ref`` to ``w`` collects ``w/w_ref`` times the
photons, so its SNR scales by √(w / w_ref) and its variance by ``w_ref / w``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.errors import InputError


def noise_sigma(radiance: np.ndarray | float, a: np.ndarray | float, b: np.ndarray | float) -> np.ndarray:
    """σ(L) = sqrt(a + b·max(L, 0)), float64: the noise stage's standard deviation (the kernels compute the
    same; ``a``, ``b`` are a band's coefficients at its width, broadcast against ``radiance``)."""
    return np.sqrt(a + b * np.maximum(np.asarray(radiance, dtype=np.float64), 0.0))


@dataclass(frozen=True)
class NoiseModel:
    """σ²(L) = (a + b·max(L, 0)) · w_ref / w, radiance in W m⁻² sr⁻¹ µm⁻¹.

    :param a: signal-independent variance, (W m⁻² sr⁻¹ µm⁻¹)².
    :param b: shot-noise variance per unit radiance, W m⁻² sr⁻¹ µm⁻¹.
    :param fwhm_ref_nm: the band width the SNR table refers to.
    """

    a: float
    b: float
    fwhm_ref_nm: float

    def coefficients(self, fwhm_nm: float) -> tuple[float, float]:
        """(a, b) for a band of width ``fwhm_nm`` (variance scaled by w_ref / w)."""
        scale = self.fwhm_ref_nm / fwhm_nm
        return self.a * scale, self.b * scale

    def sigma(self, radiance: np.ndarray | float, fwhm_nm: float | None = None) -> np.ndarray:
        """Noise standard deviation (NER) at ``radiance`` for a band of width ``fwhm_nm``."""
        return noise_sigma(radiance, *self.coefficients(fwhm_nm or self.fwhm_ref_nm))

    def snr(self, radiance: np.ndarray | float, fwhm_nm: float | None = None) -> np.ndarray:
        """SNR = L / NER(L)."""
        return np.asarray(radiance, dtype=np.float64) / self.sigma(radiance, fwhm_nm)


def fit_noise_model(points: list[tuple[float, float]], fwhm_ref_nm: float, *, band: str = "") -> NoiseModel:
    """Fit σ² = a + b·L to (L, SNR) points (see module doc for 1, 2 and 3 points)."""
    pts = [(float(L), float(s)) for L, s in points]
    if not pts:
        raise InputError("needs at least one (radiance, SNR) point", key=f"{band}.snr")
    for L, s in pts:
        if not (L > 0 and s > 0):
            raise InputError(f"SNR point (L={L}, SNR={s}) needs L > 0 and SNR > 0", key=f"{band}.snr")
    L = np.array([p[0] for p in pts])
    var = (L / np.array([p[1] for p in pts])) ** 2
    if len(pts) == 1:
        return NoiseModel(a=0.0, b=float(var[0] / L[0]), fwhm_ref_nm=fwhm_ref_nm)
    weight = 1.0 / var
    design = np.stack([np.ones_like(L), L], axis=1) * weight[:, None]
    a, b = nnls_two(design, var * weight)
    return NoiseModel(a=a, b=b, fwhm_ref_nm=fwhm_ref_nm)


def nnls_two(design: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """The non-negative least-squares solution ``(x₀, x₁) ≥ 0`` minimising ``‖design · x − target‖₂`` for a design
    ``(m, 2)`` (float64), exactly: the least-squares solution (:func:`numpy.linalg.lstsq`) when it has full rank and
    both coefficients are non-negative; otherwise the minimum lies on a boundary of the quadrant (the problem is
    convex), so it is the better of the two one-coefficient fits ``(0, x₁ ≥ 0)`` and ``(x₀ ≥ 0, 0)``, the first on a
    tie, and the first alone when the two columns are parallel and it fits at all (rank 1: every split of the fit is
    as good; for the noise model, pure shot noise, as with one point; the second where the first is zero or points
    away from the target)."""
    D = np.asarray(design, dtype=np.float64)
    y = np.asarray(target, dtype=np.float64)
    x, _, rank, _ = np.linalg.lstsq(D, y, rcond=None)
    if rank == 2 and x[0] >= 0 and x[1] >= 0:
        return float(x[0]), float(x[1])
    best: tuple[float, float] = (0.0, 0.0)
    best_norm = float(np.linalg.norm(y))
    for k in (1, 0):  # (0, x₁) first: it wins a tie
        col = D[:, k]
        norm2 = float(col @ col)
        if norm2 == 0.0:
            continue
        c = max(0.0, float(col @ y) / norm2)
        norm = float(np.linalg.norm(col * c - y))
        if norm < best_norm:
            best = (0.0, c) if k == 1 else (c, 0.0)
            best_norm = norm
            if rank < 2:  # parallel columns: a fit by the second one is as good; the first alone decides
                break
    return best
