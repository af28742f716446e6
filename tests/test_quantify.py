"""Polynomial quantification and the library-level retrieval score."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.retrieve.igrm import BoundFlag, FitStatus
from s2cl.retrieve.quantify import RegressionStatus, fit_polynomial, score_retrieval, trimmed_rms


def test_quadratic_recovered_exactly():
    x = np.linspace(690.0, 740.0, 200)
    y = 3.0 - 0.02 * (x - 700.0) + 0.004 * (x - 700.0) ** 2
    fit = fit_polynomial(x, y)
    assert fit.status == RegressionStatus.OK and fit.n == 200
    assert fit.rms < 1e-10 and fit.r2 == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(fit.predict(x), y, rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(fit.coefficients_in_index(), np.polynomial.polynomial.polyfit(x, y, 2), rtol=1e-6)


def test_conditioning_beats_raw_powers():
    """lp ~ 700 nm, spread 0.01 nm: the centred/scaled fit stays exact where raw powers of x
    in a normal-equation solve lose all digits (the failure the conditioning prevents)."""
    x = 700.0 + np.linspace(-0.005, 0.005, 101)
    y = 2.0 + 300.0 * (x - 700.0) + 1e5 * (x - 700.0) ** 2
    fit = fit_polynomial(x, y)
    assert fit.status == RegressionStatus.OK
    np.testing.assert_allclose(fit.predict(x), y, rtol=1e-9)
    v = np.vander(x, 3, increasing=True)
    with np.errstate(all="ignore"):
        raw = np.linalg.solve(v.T @ v, v.T @ y) if np.linalg.cond(v.T @ v) < 1e300 else np.zeros(3)
    assert np.max(np.abs(v @ raw - y)) > 1e3 * np.max(np.abs(fit.predict(x) - y))


def test_constant_index_gives_clear_finite_result():
    y = np.arange(10.0)
    fit = fit_polynomial(np.full(10, 712.5), y)
    assert fit.status == RegressionStatus.CONSTANT_INDEX
    assert fit.r2 == 0.0 and fit.rms == pytest.approx(np.std(y))
    np.testing.assert_allclose(fit.predict([700.0, 712.5]), 4.5)
    score = score_retrieval(np.full(10, 712.5), y)
    assert "constant_index" in score.summary()


@pytest.mark.parametrize("x, status", [
    (np.full(5, np.nan), RegressionStatus.TOO_FEW_POINTS),
    (np.array([1.0, 1.0, 2.0, 2.0, 2.0]), RegressionStatus.RANK_DEFICIENT),
])
def test_degenerate_inputs_stay_finite(x, status):
    fit = fit_polynomial(x, np.arange(5.0))
    assert fit.status == status
    assert np.all(np.isfinite(fit.coef)) and np.isfinite(fit.rms) and np.isfinite(fit.r2)


def test_constant_target():
    fit = fit_polynomial(np.arange(6.0), np.full(6, 3.0))
    assert fit.status == RegressionStatus.CONSTANT_TARGET and fit.r2 == 0.0 and fit.rms < 1e-12


def test_input_checks():
    with pytest.raises(InputError, match="degree"):
        fit_polynomial(np.arange(3.0), np.arange(3.0), degree=7)
    with pytest.raises(InputError, match="index has 3 values, target 4"):
        fit_polynomial(np.arange(3.0), np.arange(4.0))
    with pytest.raises(InputError, match="trim"):
        score_retrieval(np.arange(3.0), np.arange(3.0), trim=0.7)


def _population(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    cab = rng.uniform(5.0, 100.0, n)
    lp = 695.0 + 0.45 * cab - 0.0012 * cab**2 + rng.normal(0.0, 0.4, n)
    return lp, cab


def test_one_runaway_among_1e4_is_visible():
    """One fit on a bound among 10^4 doubles the RMS; the score shows what happened."""
    lp, cab = _population(10_000)
    status = np.zeros(lp.size, dtype=np.uint8)
    bounds = np.zeros(lp.size, dtype=np.uint8)
    clean = score_retrieval(lp, cab, status=status, bounds=bounds)
    lp_bad = lp.copy()
    lp_bad[1234] = 780.0                     # s ran to s_max = 80 nm: lp = 700 + 80
    bounds[1234] = BoundFlag.L0_HIGH | BoundFlag.S_HIGH
    bad = score_retrieval(lp_bad, cab, status=status, bounds=bounds)
    assert bad.rms >= 2.0 * clean.rms
    assert bad.rms_clean == pytest.approx(clean.rms, rel=1e-3)
    assert clean.rms_clean == clean.rms
    # the outlier also bends the calibration curve: robust errors move, but much less than the RMS
    assert bad.median_abs_error < 0.5 * bad.rms and bad.trimmed_rms < 0.7 * bad.rms
    assert bad.frac_on_bound == pytest.approx(1e-4)
    assert bad.outlier_dominated and not clean.outlier_dominated
    assert "dominated by a few outliers" in bad.summary("ug/cm2")


def test_statuses_exclude_and_count():
    lp, cab = _population(1000)
    status = np.zeros(1000, dtype=np.uint8)
    status[:10] = FitStatus.DEGENERATE
    status[10:15] = FitStatus.INVALID_INPUT
    status[15:20] = FitStatus.ITERATION_LIMIT
    lp[0] = np.nan
    s = score_retrieval(lp, cab, status=status)
    assert s.n_used == 985 and s.frac_excluded == pytest.approx(0.015)
    assert s.frac_failed == pytest.approx(0.02)
    assert s.status_counts["degenerate"] == 10 and s.status_counts["iteration_limit"] == 5
    assert 0.9 < s.r2 <= 1.0


def test_trimmed_rms():
    e = np.array([1.0] * 99 + [100.0])
    assert trimmed_rms(e, 0.01) == pytest.approx(1.0)
    assert trimmed_rms(e, 0.0) == pytest.approx(np.sqrt(np.mean(e**2)))
    assert trimmed_rms(np.array([]), 0.01) == 0.0
