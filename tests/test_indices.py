"""Normalised-difference index kernels (GVMI: paper eq. 3) against their float64 oracle."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.reference import stages as ref
from s2cl.retrieve.index_kernel import IndexKernel, normalised_difference
from s2cl.retrieve.indices import INDICES


@pytest.mark.parametrize("n", [1, 13, 10007])
def test_gvmi_matches_oracle(rt, real_t, lanes, n):
    rng = np.random.default_rng(n)
    refl = np.vstack([rng.uniform(0.0, 0.6, n), rng.uniform(0.2, 0.7, n), rng.uniform(0.05, 0.5, n)])
    out = IndexKernel(rt, "gvmi", real_t=real_t, lanes=lanes)(refl, 1, 2)
    expect, status = ref.normalised_difference(refl[1], refl[2], INDICES["gvmi"].offsets)
    np.testing.assert_array_equal(out.status, status)
    tol = 1e-6 if real_t == "float32" else 1e-14
    np.testing.assert_allclose(out.index, expect, rtol=0, atol=tol)


def test_gvmi_paper_range_for_dense_vegetation(rt):
    """Dense green canopy: NIR 0.45, SWIR (1.6 um) 0.2 -> GVMI 0.43 (paper: 0.3-0.8); wetter is higher."""
    out = normalised_difference(np.array([[0.45, 0.45], [0.20, 0.10]]), "gvmi", 0, 1)
    assert 0.2 < out.index[0] < out.index[1] < 0.8


def test_gvmi_hard_cases(rt, real_t):
    """NaN/inf, |rho| > 10 and a non-positive offset term (NIR + 0.1 or SWIR + 0.02) are INVALID; the
    last two pixels are the "GVMI of 199" case (denominator 1e-4, SWIR + 0.02 < 0) and a valid one
    whose SWIR is slightly negative: kernel and numpy twin agree on every pixel."""
    refl = np.array([
        [0.4, np.nan, 0.4, np.inf, -0.07, 0.0, 4000.0, 0.4, 0.01 - 0.1, 0.3],
        [0.2, 0.2, np.nan, 0.2, -0.05, 0.0, 0.2, 0.2, -0.0099 - 0.02, -0.01],
    ])
    out = normalised_difference(refl, "gvmi", 0, 1, real_t=real_t)
    assert np.all(np.isfinite(out.index))
    np.testing.assert_array_equal(out.status, [0, 3, 3, 3, 3, 0, 3, 0, 3, 0])
    expect, status = ref.normalised_difference(refl[0], refl[1], INDICES["gvmi"].offsets)
    np.testing.assert_array_equal(out.status, status)
    np.testing.assert_allclose(out.index, expect, atol=1e-6)
    assert np.all(np.abs(out.index) < 1.0)
    assert np.all(out.index[out.status == 3] == 0.0)
    assert out.index[0] == out.index[7]  # neighbours unaffected
    np.testing.assert_allclose(out.index[5], 0.08 / 0.12, rtol=1e-6)


def test_gvmi_input_errors(rt):
    with pytest.raises(InputError, match=r"swir: band row must be in 0\.\.1"):
        normalised_difference(np.zeros((2, 4)), "gvmi", 0, 2)
    with pytest.raises(InputError, match=r"\(n_bands, n_pixels\)"):
        normalised_difference(np.zeros(4), "gvmi", 0, 1)
    with pytest.raises(InputError, match="unknown index 'evi'; known: gvmi"):
        normalised_difference(np.zeros((2, 4)), "evi", 0, 1)


@pytest.mark.parametrize("group", [2, 8, 64])
def test_work_group_size_changes_no_bits(rt, monkeypatch, group: int) -> None:
    rng = np.random.default_rng(3)
    refl = np.vstack([rng.uniform(0.2, 0.7, 1037), rng.uniform(0.05, 0.5, 1037)])
    base = IndexKernel(rt, "gvmi")(refl, 0, 1)
    with monkeypatch.context() as m:
        m.setattr(type(rt), "work_group", lambda self, kernel: group)
        for n in (1024, 1037):
            other = IndexKernel(rt, "gvmi")(refl[:, :n], 0, 1)
            assert np.array_equal(other.index, base.index[:n]) and np.array_equal(other.status, base.status[:n])
