"""Sensor-definition tool: the paper's configuration counts and bad ranges."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.sensor.variants import MAX_CONFIGS, BandRange, SweepSpace, table2_space


@pytest.mark.parametrize(("bands", "count"), [(["B4", "B5", "B6", "B7"], 43_056), (["B4", "B5", "B6", "B8"], 3_312),
                                               (["B4", "B5", "B6", "B8a"], 82_800)])
def test_paper_counts(bands: list[str], count: int) -> None:
    assert table2_space(bands).size == count


def test_per_band_counts_and_edges() -> None:
    space = table2_space(["B4", "B5", "B6", "B7", "B8", "B8a"])
    assert space.counts == [23, 18, 8, 13, 1, 25]
    for r, v in zip(space.ranges, space.per_band, strict=True):
        assert np.all(v[:, 0] - v[:, 1] / 2 >= r.left_nm - 1e-9)
        assert np.all(v[:, 0] + v[:, 1] / 2 <= r.right_nm + 1e-9)
    assert space.per_band[4].tolist() == [[832.5, 115.0]]  # B8 fills its window


def test_mixed_radix_round_trip() -> None:
    space = table2_space(["B4", "B5", "B6", "B7"])
    idx = space.indices(0, space.size)
    assert idx.shape == (43_056, 4)
    assert len({tuple(r) for r in idx[::97]}) == idx[::97].shape[0]
    for i in (0, 1, 12_345, space.size - 1):
        assert space.index_of(list(idx[i])) == i
    esa = space.find([(665, 30), (705, 15), (740, 15), (783, 20)])
    assert esa is None  # 783 nm is off the 5 nm grid: the ESA B7 is not a variant
    best = space.find([(675, 30), (710, 20), (735, 30), (785, 30)])  # paper's best for Lib1
    assert best is not None and np.allclose(space.shapes(best, best + 1)[0], [[675, 30], [710, 20], [735, 30],
                                                                              [785, 30]])


def test_fixed_band() -> None:
    space = SweepSpace((BandRange.fixed("B11", 1610, 90), BandRange("B12", 2100, 2280, 30, 180, 10))).validate()
    assert space.counts[0] == 1 and space.per_band[0].tolist() == [[1610, 90]]


@pytest.mark.parametrize(
    ("rng", "message"),
    [(BandRange("B4", 630, 640, 30, 50), "admits no variant"), (BandRange("B4", 690, 630, 30, 50), "right"),
     (BandRange("B4", 630, 690, 50, 30), "max_width"), (BandRange("B4", 630, 690, 0, 30), "min_width"),
     (BandRange("B4", 630, float("nan"), 30, 50), "finite")],
)
def test_bad_ranges(rng: BandRange, message: str) -> None:
    with pytest.raises(InputError, match=message) as err:
        SweepSpace((rng,)).validate("sweep.toml")
    assert "sweep.ranges.B4" in str(err.value) and "sweep.toml" in str(err.value)


def test_duplicate_band() -> None:
    with pytest.raises(InputError, match="twice"):
        SweepSpace((BandRange("B4", 630, 690, 30, 50), BandRange("B4", 630, 690, 30, 50))).validate()


def test_space_beyond_64_bit_configuration_numbers_is_refused() -> None:
    """Six bands of 2,346 variants (1.7·10²⁰ designs) cannot be numbered; 1,251 each (3.8·10¹⁸) can."""
    wide = SweepSpace(tuple(BandRange(f"B{k}", 0, 80, 10, 60, step_nm=1) for k in range(6)))
    assert wide.size > MAX_CONFIGS
    wide.validate()  # it can be counted
    with pytest.raises(InputError, match="64-bit"):
        wide.check_numbered()
    narrow = SweepSpace(tuple(BandRange(f"B{k}", 0, 60, 10, 50, step_nm=1) for k in range(6))).validate()
    narrow.check_numbered()
    assert narrow.size <= MAX_CONFIGS


def test_grid_band() -> None:
    from s2cl.sensor.variants import BandGrid

    g = BandGrid("B4", tuple(range(660, 706, 5)), (15, 20, 25, 30, 35, 40, 50))
    space = SweepSpace((g,)).validate()
    assert space.size == 70
    assert space.per_band[0][0].tolist() == [660, 15] and space.per_band[0][-1].tolist() == [705, 50]
    with pytest.raises(InputError, match="duplicates"):
        BandGrid("B4", (660, 660), (15,)).validate()
    with pytest.raises(InputError, match="> 0"):
        BandGrid("B4", (660,), (0,)).validate()
