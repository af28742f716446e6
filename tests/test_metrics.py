"""Per-configuration metrics: regression conditioning, robust error, constant index, SAM confusion."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.reference import stages
from s2cl.retrieve.metrics import classification_metrics, regression_metrics
from s2cl.status import Status

DEGENERATE, INVALID, OK = Status.DEGENERATE, Status.INVALID, Status.OK


def test_regression_matches_polyfit() -> None:
    rng = np.random.default_rng(0)
    x = rng.uniform(700, 730, (3, 500))
    y = 0.02 * (x[0] - 715) ** 2 + 3 * (x[0] - 715) + 40 + rng.normal(0, 2, 500)
    m = regression_metrics(x[:1], np.zeros((1, 500), np.uint8), np.zeros((1, 500), np.uint8), y)
    fit = np.polyval(np.polyfit(x[0], y, 2), x[0])
    assert m["rms"][0] == pytest.approx(np.sqrt(np.mean((y - fit) ** 2)), rel=1e-9)
    r2 = 1 - np.sum((y - fit) ** 2) / np.sum((y - y.mean()) ** 2)
    assert m["r2"][0] == pytest.approx(r2, rel=1e-9)
    assert m["robust_rms"][0] == pytest.approx(2.0, rel=0.15)  # Gaussian residuals: robust ≈ RMS


def test_conditioning_with_large_offsets() -> None:
    """An index near 1e6 with a spread of 1e-2 would make the raw normal equations singular."""
    x = 1e6 + np.linspace(0, 0.01, 200)[None]
    y = 5 + 300 * (x[0] - 1e6)
    m = regression_metrics(x, np.zeros_like(x, np.uint8), np.zeros_like(x, np.uint8), y)
    assert m["rms"][0] < 1e-6 and m["r2"][0] == pytest.approx(1.0)


def test_one_runaway_fit_shows_in_the_metrics() -> None:
    """One fit in 10^4 at a bound doubles the RMS; rms_unbounded and bound_fraction say so."""
    rng = np.random.default_rng(1)
    x = rng.uniform(700, 730, (1, 10_000))
    y = 3 * (x[0] - 715) + 40 + rng.normal(0, 1, 10_000)
    zero = np.zeros_like(x, np.uint8)
    clean = regression_metrics(x, zero, zero, y)
    x2 = x.copy()
    x2[0, 17] = 800.0  # a runaway fit at the upper bound of its window
    bounds = zero.copy()
    bounds[0, 17] = 2
    bad = regression_metrics(x2, zero, bounds, y)
    assert bad["rms"][0] > 2 * clean["rms"][0]
    assert bad["rms_unbounded"][0] == pytest.approx(clean["rms"][0], rel=1e-3)
    assert bad["bound_fraction"][0] == pytest.approx(1e-4)
    # a large residual without leverage barely moves the robust error
    y3 = y.copy()
    y3[17] += 200.0
    assert regression_metrics(x, zero, zero, y3)["robust_rms"][0] == pytest.approx(clean["robust_rms"][0], rel=0.02)


def test_constant_index_is_reported_not_singular() -> None:
    x = np.full((1, 50), 710.0)
    y = np.arange(50.0)
    m = regression_metrics(x, np.zeros_like(x, np.uint8), np.zeros_like(x, np.uint8), y)
    assert m["constant_index"][0] and m["r2"][0] == 0.0
    assert m["rms"][0] == pytest.approx(np.std(y))


def test_failed_pixels_are_excluded_and_counted() -> None:
    x = np.tile(np.linspace(0, 1, 10), (2, 1))
    y = 2 * x[0] + 1
    status = np.zeros_like(x, np.uint8)
    status[1, :3] = INVALID
    x[1, :3] = np.nan
    m = regression_metrics(x, status, np.zeros_like(status), y)
    assert m["n_valid"].tolist() == [10, 7]
    assert m["failed_fraction"][1] == pytest.approx(0.3)
    assert np.all(m["rms"] < 1e-12)
    all_bad = regression_metrics(x[:1], np.full((1, 10), INVALID, np.uint8), status[:1], y)
    assert np.isnan(all_bad["rms"][0]) and all_bad["failed_fraction"][0] == 1.0


def test_confusion_and_omission() -> None:
    truth = np.array([0, 0, 0, 0, 1, 1])
    pred = np.array([[0, 0, 0, 1, 1, 1], [0, 0, 0, 0, 1, 1]])
    status = np.zeros_like(pred, np.uint8)
    status[1, 5] = DEGENERATE  # unclassified
    m = classification_metrics(pred, status, truth, 2)
    assert m["confusion"][0].tolist() == [[3, 1, 0], [0, 2, 0]]
    assert m["omission_error_pct"][0] == pytest.approx(12.5)
    assert m["omission_error_pct"][1] == pytest.approx(25.0)
    assert m["unclassified_fraction"][1] == pytest.approx(1 / 6)


def test_gvmi_and_sam_twins_hard_cases() -> None:
    """The numpy twins' rules (the kernels' rules, kernels/common/stages.mako)."""
    index, status = stages.normalised_difference(np.array([0.4, np.nan, -0.2, 0.01 - 0.1]),
                                                 np.array([0.2, 0.1, -0.1, -0.0099 - 0.02]))
    assert index[0] == pytest.approx((0.5 - 0.22) / (0.5 + 0.22))
    assert status.tolist() == [Status.OK, Status.INVALID, Status.INVALID, Status.INVALID]  # last: "GVMI 199"
    refs = np.array([[1.0, 0.0], [0.0, 1.0]])
    cls, angle, status = stages.sam_classify(np.array([[2.0, 0.1], [0.0, 0.0], [np.nan, 1.0], [1.0, 1.0]]).T, refs)
    assert cls.tolist()[:3] == [0, -1, -1]
    assert status.tolist()[:3] == [Status.OK, Status.DEGENERATE, Status.INVALID]
    assert np.all(np.isfinite(angle))
    same = np.array([[1.0, 1.0], [1.0, 1.0]])  # identical references: first wins, deterministically
    cls, _, status = stages.sam_classify(np.array([[0.3, 0.2]]).T, same)
    assert cls.tolist() == [0] and status.tolist() == [Status.OK]
    cls, _, status = stages.sam_classify(np.array([[1.0, 1.0]]).T, refs, np.deg2rad(10.0))  # 45 degrees
    assert status.tolist() == [Status.UNCLASSIFIED] and cls.tolist() == [-1]


def test_batched_metrics_agree_with_single_population_fit() -> None:
    """s2cl.retrieve.metrics (per configuration, for sweeps) and s2cl.retrieve.quantify (one population, with
    coefficients for plots) must give the same regression."""
    from s2cl.retrieve.quantify import fit_polynomial

    rng = np.random.default_rng(3)
    x = rng.uniform(690, 735, (4, 3000))
    y = 0.05 * (x[0] - 700) ** 2 + 2 * (x[0] - 700) + rng.normal(0, 3, 3000)
    status = np.zeros_like(x, np.uint8)
    status[2, ::7] = INVALID
    m = regression_metrics(x, status, np.zeros_like(status), y)
    for row in range(4):
        single = fit_polynomial(x[row], y, mask=status[row] == OK)
        assert m["rms"][row] == pytest.approx(single.rms, rel=1e-10)
        assert m["r2"][row] == pytest.approx(single.r2, rel=1e-10)


def test_regression_of_too_few_pixels_is_finite() -> None:
    """analysis.regress = ["converged"] can leave two pixels in a row (found on table3-lib2-b4568): a
    singular 3 x 3 system must give finite numbers, in the plain and in the bound-free refit, and leave
    the other rows of the block exact."""
    x = np.array([[700.0, 701.0, 702.0, 703.0], [700.0, 701.0, 702.0, 703.0]])
    y = np.array([10.0, 20.0, 35.0, 55.0])
    status = np.array([[OK, OK, 1, 1], [OK, OK, OK, OK]], dtype=np.uint8)
    bounds = np.array([[0, 0, 0, 0], [0, 0, 1, 0]], dtype=np.uint8)  # row 2's refit keeps 3 pixels
    m = regression_metrics(x, status, bounds, y, regress=(OK,))
    assert np.all(np.isfinite(m["rms"])) and np.all(np.isfinite(m["rms_unbounded"]))
    assert m["rms"][0] == pytest.approx(0.0, abs=1e-9)  # two points: a line through both
    exact = regression_metrics(x[1:], status[1:], bounds[1:], y, regress=(OK,))
    assert m["rms"][1] == pytest.approx(exact["rms"][0], rel=1e-12)
