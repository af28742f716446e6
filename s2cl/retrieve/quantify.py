"""Quantification: regress a parameter (chlorophyll, EWT) on an index (lp, GVMI) over all pixels
of a library, and score how well the index predicts it.

The paper (Segl et al. 2012, section 4) fits a second-order polynomial and reports its RMS and
R^2. A single run-away fit can dominate an RMS, so :class:`RetrievalScore` also carries the
fraction of failed and bound-limited fits and two robust errors (median absolute, trimmed RMS).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from s2cl.errors import InputError
from s2cl.retrieve.igrm import BoundFlag, FitStatus, IgrmResult
from s2cl.status import FITTED


class RegressionStatus(enum.IntEnum):
    """Outcome of :func:`fit_polynomial`; every outcome comes with finite numbers."""

    OK = 0
    CONSTANT_INDEX = 1  #: the index does not vary: the prediction is the target mean, R^2 = 0
    RANK_DEFICIENT = 2  #: fewer distinct index values than coefficients: minimum-norm solution
    TOO_FEW_POINTS = 3  #: no usable point: coefficients 0, errors NaN-free zeros
    CONSTANT_TARGET = 4  #: the target does not vary: R^2 is reported as 0


@dataclass(frozen=True)
class PolyFit:
    """A polynomial ``target ~ sum coef[k] z**k`` in the conditioned index ``z = (x - centre) / scale``.

    ``rms`` (target units) and ``r2`` are in-sample over the ``n`` points used.
    """

    degree: int
    coef: np.ndarray
    centre: float
    scale: float
    n: int
    rms: float
    r2: float
    status: RegressionStatus

    def predict(self, index: np.ndarray) -> np.ndarray:
        """Predicted target for ``index`` (any shape), float64."""
        z = (np.asarray(index, dtype=np.float64) - self.centre) / self.scale
        return np.polynomial.polynomial.polyval(z, self.coef)

    def coefficients_in_index(self) -> np.ndarray:
        """Ascending coefficients in the raw index x (ill-conditioned for lp ~ 700 nm: for display)."""
        p = np.polynomial.Polynomial(self.coef, domain=[self.centre - self.scale, self.centre + self.scale],
                                     window=[-1.0, 1.0])
        return p.convert().coef


def fit_polynomial(index: np.ndarray, target: np.ndarray, *, degree: int = 2,
                   mask: np.ndarray | None = None) -> PolyFit:
    """Least-squares polynomial of ``target`` on ``index`` over the finite points (and ``mask``).

    The index is centred on its mean and scaled by its standard deviation before the fit
    (lp ~ 700 nm squared would otherwise lose about 6 digits), and the system is solved by SVD
    (``numpy.linalg.lstsq``). Degenerate inputs give a finite result and a
    :class:`RegressionStatus`, never an exception from linear algebra.
    """
    if isinstance(degree, bool) or not isinstance(degree, int) or not 0 <= degree <= 5:
        raise InputError(f"must be an integer in 0..5, got {degree!r}", key="degree")
    x = np.asarray(index, dtype=np.float64).ravel()
    y = np.asarray(target, dtype=np.float64).ravel()
    if x.shape != y.shape:
        raise InputError(f"index has {x.size} values, target {y.size}", key="target")
    use = np.isfinite(x) & np.isfinite(y)
    if mask is not None:
        use &= np.asarray(mask, dtype=bool).ravel()
    x, y = x[use], y[use]
    n = int(x.size)
    if n == 0:
        return PolyFit(degree, np.zeros(degree + 1), 0.0, 1.0, 0, 0.0, 0.0, RegressionStatus.TOO_FEW_POINTS)
    centre = float(x.mean())
    spread = float(x.std())
    if not spread > 1e-12 * max(abs(centre), 1.0):
        coef = np.zeros(degree + 1)
        coef[0] = y.mean()
        return PolyFit(degree, coef, centre, 1.0, n, float(y.std()), 0.0, RegressionStatus.CONSTANT_INDEX)
    z = (x - centre) / spread
    vander = np.polynomial.polynomial.polyvander(z, degree)
    coef, _, rank, _ = np.linalg.lstsq(vander, y, rcond=None)
    resid = vander @ coef - y
    ss_res = float(resid @ resid)
    ss_tot = float(((y - y.mean()) ** 2).sum())
    status = RegressionStatus.OK if rank == degree + 1 else RegressionStatus.RANK_DEFICIENT
    if ss_tot > 0.0:
        r2 = 1.0 - ss_res / ss_tot
    else:
        r2, status = 0.0, RegressionStatus.CONSTANT_TARGET
    return PolyFit(degree, coef, centre, spread, n, float(np.sqrt(ss_res / n)), r2, status)


@dataclass(frozen=True)
class RetrievalScore:
    """How well an index predicts a parameter over a library, with the numbers that expose when
    a few bad fits drive the RMS.

    :param rms: RMS of the regression residuals (target units) over the pixels used: the paper's metric.
    :param median_abs_error: median |residual|: unmoved by a few run-away fits.
    :param trimmed_rms: RMS over the (1 - trim) best residuals.
    :param frac_failed: pixels whose fit did not converge (iteration limit, degenerate, invalid).
    :param frac_on_bound: pixels whose fit ended on an l0, s or rmin bound.
    :param frac_excluded: pixels left out of the regression (degenerate, invalid, non-finite).
    :param rms_clean: RMS of the same regression refitted on the clean pixels only (converged,
        on no bound): what the number would be without the flagged fits.
    """

    n_pixels: int
    n_used: int
    rms: float
    r2: float
    median_abs_error: float
    trimmed_rms: float
    trim: float
    frac_failed: float
    frac_on_bound: float
    frac_excluded: float
    rms_clean: float
    fit: PolyFit
    status_counts: dict[str, int] = field(default_factory=dict)

    @property
    def outlier_dominated(self) -> bool:
        """True when a few pixels make the RMS: it exceeds 1.5x the clean-pixel RMS or 2x the
        trimmed RMS."""
        return self.rms > 1.5 * self.rms_clean or self.rms > 2.0 * self.trimmed_rms

    def summary(self, unit: str = "") -> str:
        """One line for reports."""
        u = f" {unit}" if unit else ""
        text = (f"RMS {self.rms:.3g}{u}, R2 {self.r2:.3f}, median |err| {self.median_abs_error:.3g}{u}, "
                f"trimmed RMS ({self.trim:.0%}) {self.trimmed_rms:.3g}{u}, RMS of clean fits {self.rms_clean:.3g}{u}; "
                f"failed {self.frac_failed:.2%}, "
                f"on bound {self.frac_on_bound:.2%}, excluded {self.frac_excluded:.2%} of {self.n_pixels}")
        if self.outlier_dominated:
            text += " -- RMS dominated by a few outliers"
        if self.fit.status != RegressionStatus.OK:
            text += f" -- regression {self.fit.status.name.lower()}"
        return text


def trimmed_rms(errors: np.ndarray, trim: float) -> float:
    """RMS of the ``ceil((1 - trim) n)`` smallest |errors| (0 for no errors)."""
    a = np.sort(np.abs(np.asarray(errors, dtype=np.float64)))
    if a.size == 0:
        return 0.0
    keep = max(1, int(np.ceil((1.0 - trim) * a.size)))
    return float(np.sqrt(np.mean(a[:keep] ** 2)))


def score_retrieval(index: np.ndarray, target: np.ndarray, *, status: np.ndarray | None = None,
                    bounds: np.ndarray | None = None, degree: int = 2, trim: float = 0.01) -> RetrievalScore:
    """Regress ``target`` on ``index`` and score it (see :class:`RetrievalScore`).

    :param status: per-pixel :class:`s2cl.status.Status` (converged, stalled and iteration-limit fits
        have an index; degenerate, invalid and unclassified ones are excluded).
    :param bounds: per-pixel :class:`~s2cl.retrieve.igrm.BoundFlag` bits.
    :param trim: fraction of largest residuals left out of ``trimmed_rms``.
    """
    if not 0.0 <= trim < 0.5:
        raise InputError(f"must be in [0, 0.5), got {trim}", key="trim")
    x = np.asarray(index, dtype=np.float64).ravel()
    y = np.asarray(target, dtype=np.float64).ravel()
    n = int(x.size)
    st = np.zeros(n, dtype=np.uint8) if status is None else np.asarray(status).ravel()
    bd = np.zeros(n, dtype=np.uint8) if bounds is None else np.asarray(bounds).ravel()
    if st.size != n or bd.size != n or y.size != n:
        raise InputError(f"index, target, status and bounds must have the same length ({n})", key="status")
    fitted = np.isin(st, FITTED)
    use = fitted & np.isfinite(x) & np.isfinite(y)
    fit = fit_polynomial(x, y, degree=degree, mask=use)
    err = fit.predict(x[use]) - y[use]
    edge = int(BoundFlag.L0_LOW | BoundFlag.L0_HIGH | BoundFlag.S_LOW | BoundFlag.S_HIGH | BoundFlag.RMIN_LOW)
    clean = use & (st == FitStatus.CONVERGED) & ((bd & edge) == 0)
    rms_clean = fit.rms if clean.sum() == use.sum() else fit_polynomial(x, y, degree=degree, mask=clean).rms
    counts = {s.name.lower(): int(np.count_nonzero(st == s)) for s in FitStatus}
    return RetrievalScore(
        n_pixels=n,
        n_used=int(use.sum()),
        rms=fit.rms,
        r2=fit.r2,
        median_abs_error=float(np.median(np.abs(err))) if err.size else 0.0,
        trimmed_rms=trimmed_rms(err, trim),
        trim=trim,
        frac_failed=float(np.mean(st != FitStatus.CONVERGED)) if n else 0.0,
        frac_on_bound=float(np.mean(fitted & ((bd & edge) != 0))) if n else 0.0,
        frac_excluded=float(np.mean(~use)) if n else 0.0,
        rms_clean=rms_clean,
        fit=fit,
        status_counts=counts,
    )


def score_igrm(result: IgrmResult, target: np.ndarray, *, index: str = "lp", degree: int = 2,
               trim: float = 0.01) -> RetrievalScore:
    """:func:`score_retrieval` of ``target`` (e.g. Cab in ug/cm2) on an IGRM output (default lp)."""
    if index not in ("lp", "l0", "s", "rmax", "rmin"):
        raise InputError(f"must be one of lp, l0, s, rmax, rmin, got {index!r}", key="index")
    return score_retrieval(getattr(result, index), target, status=result.status, bounds=result.bounds,
                           degree=degree, trim=trim)
