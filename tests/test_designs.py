"""One evaluator of given designs (s2cl.sweep.designs): configuration numbers in any order, repeated or not, score as
the exhaustive sweep scores them, bit for bit, on the device and with the numpy twin, in one kernel launch per
batch; a number past the kernel's 32-bit configuration numbers is no special case; one function says where the
metrics run."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from sweep_fixtures import gvmi_job, numpy_evaluator

from s2cl.sweep import designs
from s2cl.sweep.designs import design_pixels, score_designs
from s2cl.sweep.engine import evaluate_chunk, kernel_evaluator
from s2cl.sweep.kernel import KERNEL_CONFIGS, SweepKernel
from s2cl.sweep.metrics_kernel import metrics_on_device
from s2cl.sweep.tables import SweepTables

CONFIGS = [5, 0, 3, 3, 7, 1]  # any order, a repeat


def _launches(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts SweepKernel launches (one entry per launch: its configurations)."""
    seen: list[int] = []
    real = SweepKernel._launch

    def launch(self: SweepKernel, start: int, stop: int, extra: dict | None = None) -> dict:
        seen.append(stop - start)
        return real(self, start, stop, extra)

    monkeypatch.setattr(SweepKernel, "_launch", launch)
    return seen


def _assert_rows_equal(got: dict, want: dict, rows: list[int]) -> None:
    assert list(got) == list(want)
    for k in want:
        np.testing.assert_array_equal(got[k], np.asarray(want[k])[rows], err_msg=k)


def test_given_designs_score_as_in_the_sweep_in_one_launch_per_batch(monkeypatch: pytest.MonkeyPatch) -> None:
    job = gvmi_job(chunk=4, copies=3)
    assert job.n_configs > max(CONFIGS)
    full = evaluate_chunk(job, 0, job.n_configs)
    pixels = kernel_evaluator(job)(0, job.n_configs)
    monkeypatch.setattr(designs, "_KERNELS", {})
    seen = _launches(monkeypatch)
    got = score_designs(job, np.array(CONFIGS))  # batches of the job's chunk (4): two launches
    assert seen == [4, 2]
    _assert_rows_equal(got, full, CONFIGS)
    seen.clear()
    raw = design_pixels(job, np.array(CONFIGS))
    assert seen == [4, 2]
    for name in ("index", "status", "bounds", "condition"):
        np.testing.assert_array_equal(getattr(raw, name), getattr(pixels, name)[CONFIGS], err_msg=name)
    seen.clear()
    monkeypatch.setattr(designs, "DESIGN_BATCH", 2)
    _assert_rows_equal(score_designs(job, np.array(CONFIGS)), full, CONFIGS)
    assert seen == [2, 2, 2]


def test_the_numpy_twin_scores_given_designs_as_in_the_sweep() -> None:
    job = gvmi_job(chunk=4, copies=3)
    full = evaluate_chunk(job, 0, job.n_configs, evaluator=numpy_evaluator(job))
    _assert_rows_equal(score_designs(job, np.array(CONFIGS), evaluator_of=numpy_evaluator), full, CONFIGS)


def _tiled(t: SweepTables, reps: tuple[int, ...]) -> SweepTables:
    """``t`` with slot ``k``'s variants repeated ``reps[k]`` times over (variant ``i`` is variant ``i % count``)."""
    def tile(arrays: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
        return tuple(np.tile(a, (r,) + (1,) * (a.ndim - 1)) for a, r in zip(arrays, reps, strict=True))

    return replace(t, counts=tuple(c * r for c, r in zip(t.counts, reps, strict=True)), centre=tile(t.centre),
                   width=tile(t.width), radiance=tile(t.radiance),
                   values={**t.values, **{n: tile(t.values[n]) for n in t.per_row()}})


def test_a_design_numbered_past_32_bits_scores_as_its_twin_within_them() -> None:
    """In a space of more designs than 32-bit numbers (each slot's variants repeated), design ``2³² + x`` has the
    variants of a design of the small space (by hand, the mixed radix), and its row and pixels are that design's."""
    job = gvmi_job(chunk=4, copies=3)
    t = job.tables
    reps = tuple(math.ceil(70_000 / c) for c in t.counts)
    big = replace(job, tables=_tiled(t, reps))
    assert big.n_configs > KERNEL_CONFIGS
    number = KERNEL_CONFIGS + 1 + 12_345
    variants = []
    rest = number
    for c in reversed(big.tables.counts):  # the mixed radix, last slot fastest
        rest, v = divmod(rest, c)
        variants.insert(0, v)
    small = 0
    for v, c in zip(variants, t.counts, strict=True):  # variant v of a repeated slot is variant v % count
        small = small * c + v % c
    row = score_designs(big, np.array([number]))
    want = evaluate_chunk(job, small, small + 1)
    assert int(row["config"][0]) == number
    for k in want:
        if k != "config":
            np.testing.assert_array_equal(row[k], want[k], err_msg=k)
    np.testing.assert_array_equal(design_pixels(big, np.array([number])).index,
                                  kernel_evaluator(job)(small, small + 1).index)


def test_one_function_says_where_the_metrics_run() -> None:
    class Device:
        def __init__(self, fp64: bool) -> None:
            self.has_fp64 = fp64

    assert metrics_on_device(Device(True)) is True
    assert metrics_on_device(Device(False)) is False
    assert metrics_on_device(Device(True), distributed=True) is False
