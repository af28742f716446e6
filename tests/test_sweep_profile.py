"""bench.sweep_profile's accounting of lock-step lanes, on hand-computed cases (the timings are never asserted;
tests/test_sweep_kernel.py checks the profile builds it times)."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = [pytest.mark.bench, pytest.mark.usefixtures("bench_path")]


def test_iteration_stats_pays_each_groups_slowest_lane() -> None:
    from bench.sweep_profile import iteration_stats

    # two lanes: groups (1, 3) and (2, 2) pay 3 and 2 iterations a fit: 2.5 paid against 2 used
    s = iteration_stats(np.array([[1, 3, 2, 2]]), lanes=2, status=np.array([[0, 0, 4, 0]]))
    assert s["mean"] == 2.0 and s["paid_iterations"] == 2.5 and s["lane_use"] == pytest.approx(0.8)
    assert s["lane_groups"] == 2 and s["histogram"] == [0, 1, 2, 1]
    assert s["status_fractions"] == {0: 0.75, 4: 0.25}


def test_pixel_orders_bound_and_pilot() -> None:
    from bench.sweep_profile import pixel_orders

    # pixel difficulty the same in every design: the pilot's order is as good as each design's own
    it = np.tile(np.array([1, 9, 2, 8, 3, 7, 4, 6]), (4, 1))
    o = pixel_orders(it, lanes=2)
    assert o["rows"] == 2 and o["sorted_by_own_iterations"] == pytest.approx(o["sorted_by_other_designs"])
    assert o["natural"] < o["sorted_by_own_iterations"] <= 1.0


def test_refill_model_reduces_to_lock_step_and_wins_on_spread() -> None:
    from bench.sweep_profile import refill_cost

    rng = np.random.default_rng(1)
    it = rng.integers(0, 30, 64)
    groups = it.reshape(-1, 4).max(axis=1)
    assert refill_cost(it, lanes=4, free=4, fixed=1.5) == pytest.approx(groups.sum() + 1.5 * groups.size)
    # one long fit among short ones: refilled lanes keep fitting while it runs
    it = np.array([20, 1, 1, 1, 1, 1, 1, 1])
    assert refill_cost(it, lanes=4, free=3, fixed=0.0) == 20
    assert refill_cost(it, lanes=4, free=4, fixed=0.0) == 21
