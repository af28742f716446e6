"""Resampling kernel against the float64 oracle, including hard shapes and the atmosphere effect.

Tolerances: float32 sums of up to ~400 products of normalised weights (each < 1) and values
of order 1–100: the rounding error bound is ~n·eps·max ≈ 400 · 6e-8 ≈ 2.4e-5 relative to the
largest value; we require 2e-6 relative to each band's value scale (observed ~3e-7), and 1e-12
for float64.
"""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.forward.resample import ResamplePlan, Resampler
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.reference import forward as ref
from s2cl.sensor.sensor import Sensor
from s2cl.sensor.srf import band_weights, point_weights

RTOL = {"float32": 2e-6, "float64": 1e-12}


def _plan(grid: SpectralGrid = DEFAULT_GRID, bands=None) -> ResamplePlan:
    s = Sensor.sentinel2()
    weights = bands or [b.weights(grid) for b in s.bands]
    names = tuple(f"b{k}" for k in range(len(weights)))
    return ResamplePlan(names, tuple(weights), grid.size)


def _spectra(n: int, grid: SpectralGrid = DEFAULT_GRID, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    smooth = np.cumsum(rng.normal(size=(n, grid.size)), axis=1) * 0.5
    return 50.0 + smooth + rng.random((n, grid.size)) * 10


def _check(out: np.ndarray, expected: np.ndarray, real_t: str) -> None:
    scale = np.abs(expected).max(axis=1, keepdims=True) + 1e-300
    err = np.abs(out.astype(np.float64) - expected) / scale
    assert err.max() <= RTOL[real_t], f"max relative error {err.max():.3g}"


@pytest.mark.parametrize("width", [4, 8, 16])
def test_vector_width_matches_oracle(rt, real_t: str, width: int) -> None:
    """Every vector-load width (the device picks one) gives the oracle's result (with the atmosphere
    effect: below)."""
    plan = _plan()
    spectra = _spectra(33)
    out = Resampler(rt, plan, real_t, vector_width=width)(spectra)
    _check(out, ref.resample(spectra.astype(np.dtype(real_t)), plan.weights), real_t)


@pytest.mark.parametrize("rows", [1, 2, 4, 8, 16])
def test_rows_per_work_item_give_identical_bits(rt, rows: int) -> None:
    """Every rows-per-work-item setting (CPUs read 8 spectra interleaved) gives the same bits, whatever
    the pixel count's remainder; with the atmosphere effect too."""
    plan = _plan()
    spectra = _spectra(37, seed=4)
    base = Resampler(rt, plan, rows_per_item=1)(spectra)
    for n in (1, 5, 17, 37):
        assert np.array_equal(Resampler(rt, plan, rows_per_item=rows)(spectra[:n]), base[:, :n])
    rng = np.random.default_rng(6)
    terms = _Terms(DEFAULT_GRID.size, rng)
    rho = rng.uniform(0.0, 0.9, (19, DEFAULT_GRID.size))
    one = Resampler(rt, plan, atmosphere=terms, rows_per_item=1)(rho)
    assert np.array_equal(Resampler(rt, plan, atmosphere=terms, rows_per_item=rows)(rho), one)
    with pytest.raises(InputError, match="rows_per_item"):
        Resampler(rt, plan, rows_per_item=3)


@pytest.mark.parametrize("width", [4, 8, 16])
def test_rows_reduced_in_groups_give_identical_bits(rt, width: int) -> None:
    """Rows are reduced in groups of min(rows, width) lanes (the transposed tree per group, each accumulator first
    halved to the group's width): at every width and rows setting, the same bits as one row per work-item, with
    tails that cut through a group; also on a 14-sample grid, where capped supports keep scalar tails."""
    short = SpectralGrid(2000, 2390, 30)  # 14 samples: B12's support, capped there, keeps 8- and 16-wide scalar tails
    b12 = Sensor.sentinel2().bands[-1].weights(short)
    for grid, plan in ((DEFAULT_GRID, _plan()), (short, _plan(short, bands=[b12, b12]))):
        spectra = _spectra(23, grid, seed=5)
        one = Resampler(rt, plan, vector_width=width, rows_per_item=1)(spectra)
        for rows in (2, 4, 8, 16):
            many = Resampler(rt, plan, vector_width=width, rows_per_item=rows)
            for n in (3, 6, 23):
                assert np.array_equal(many(spectra[:n]), one[:, :n]), (rows, n)


@pytest.mark.parametrize("n", [1, 7, 301, 10007])
def test_resample_matches_oracle(rt, real_t: str, n: int) -> None:
    plan = _plan()
    spectra = _spectra(n)
    out = Resampler(rt, plan, real_t)(spectra)
    expected = ref.resample(spectra.astype(np.dtype(real_t)), plan.weights)
    _check(out, expected, real_t)


def test_chunks_and_work_groups_give_identical_bits(rt) -> None:
    plan = _plan()
    spectra = _spectra(1000, seed=3)
    r = Resampler(rt, plan)
    base = r(spectra)
    for chunk, local in ((37, None), (1000, 1), (256, 64)):
        assert np.array_equal(r(spectra, chunk_pixels=chunk, local_size=local), base)


@pytest.mark.parametrize(("centre", "fwhm"), [(1000.0, 1.0), (1000.0, 0.3), (1450.0, 1000.0), (401.0, 1.0),
                                              (2499.0, 1.0), (2490.0, 7.0)])
def test_extreme_band_widths(rt, real_t: str, centre: float, fwhm: float) -> None:
    w = band_weights(DEFAULT_GRID, name="x", centre_nm=centre, fwhm_nm=fwhm)
    plan = _plan(bands=[w])
    spectra = _spectra(50)
    _check(Resampler(rt, plan, real_t)(spectra), ref.resample(spectra, plan.weights), real_t)


def test_flat_spectrum_gives_its_value(rt, real_t: str) -> None:
    plan = _plan()
    out = Resampler(rt, plan, real_t)(np.full((5, DEFAULT_GRID.size), 0.3))
    assert np.allclose(out, 0.3, rtol=RTOL[real_t] * 10, atol=0)


def test_point_sampling_when_resampling_is_off(rt) -> None:
    plan = _plan(bands=[point_weights(DEFAULT_GRID, c) for c in (443.0, 665.5, 2190.0)])
    spectra = np.tile(DEFAULT_GRID.wavelengths, (4, 1))
    assert np.allclose(Resampler(rt, plan, "float64")(spectra), [[443.0], [665.5], [2190.0]])


def test_coarse_grid(rt) -> None:
    grid = SpectralGrid(400, 2500, 5)
    plan = _plan(grid)
    spectra = _spectra(20, grid)
    _check(Resampler(rt, plan, "float64")(spectra), ref.resample(spectra, plan.weights), "float64")


class _Terms:
    def __init__(self, n: int, rng: np.random.Generator):
        self.path_radiance = rng.uniform(1, 60, n)
        self.ground_term = rng.uniform(10, 150, n)
        self.spherical_albedo = rng.uniform(0.02, 0.3, n)


@pytest.mark.parametrize("width", [None, 4, 8, 16])
def test_atmosphere_effect_matches_oracle(rt, real_t: str, width: int | None) -> None:
    rng = np.random.default_rng(5)
    terms = _Terms(DEFAULT_GRID.size, rng)
    plan = _plan()
    rho = rng.uniform(0.0, 0.9, (300, DEFAULT_GRID.size))
    out = Resampler(rt, plan, real_t, atmosphere=terms, vector_width=width)(rho)
    cast = np.dtype(real_t).type
    toa = ref.toa_radiance(rho.astype(cast), terms.path_radiance.astype(cast), terms.ground_term.astype(cast),
                           terms.spherical_albedo.astype(cast))
    _check(out, ref.resample(toa, plan.weights), real_t)


@pytest.mark.parametrize("rows", [1, 4])
@pytest.mark.parametrize("width", [4, 8, 16])
def test_scalar_tail_applies_the_atmosphere(rt, real_t: str, width: int, rows: int) -> None:
    """A band whose support, padded to whole vectors, would be wider than the grid keeps a scalar tail; it turns
    reflectance into radiance as the vector part does, with one row per work-item (the GPU default) or several."""
    grid = SpectralGrid(400, 460, 5)  # 13 samples: the support of a 30 nm wide band at 430 nm covers them all
    plan = _plan(grid, [band_weights(grid, name="wide", centre_nm=430.0, fwhm_nm=30.0)])
    bands, _ = plan.packed(width)
    assert bands[0]["length"] % width, "no scalar tail: the test would not reach it"
    rng = np.random.default_rng(11)
    terms = _Terms(grid.size, rng)
    rho = rng.uniform(0.0, 0.9, (37, grid.size))
    r = Resampler(rt, plan, real_t, atmosphere=terms, vector_width=width, rows_per_item=rows)
    if r.vw != width:
        pytest.skip(f"{width} lanes do not build cleanly on this device")
    toa = ref.toa_radiance(rho, terms.path_radiance, terms.ground_term, terms.spherical_albedo)
    _check(r(rho), ref.resample(toa, plan.weights), real_t)


def test_launches_name_their_work_group(rt) -> None:
    """Launches name the work-group size the device prefers, never the driver's divisor of the global
    size; any other size gives the same bits (above)."""
    import pyopencl as cl

    r = Resampler(rt, _plan())
    info = cl.kernel_work_group_info
    multiple = r.kernel.get_work_group_info(info.PREFERRED_WORK_GROUP_SIZE_MULTIPLE, rt.device)
    assert r.local_size == rt.work_group(r.kernel)
    assert 1 <= r.local_size <= rt.max_work_group_size(r.kernel)
    assert r.local_size % multiple == 0 or r.local_size == rt.max_work_group_size(r.kernel)
    spectra = _spectra(3993 * 8, seed=4)  # 3,993 work-items of 8 rows: a size PoCL would split badly
    assert np.array_equal(r(spectra), r(spectra, local_size=1))


@pytest.mark.parametrize("multiple", [4, 8, 16])
def test_supports_padded_to_whole_vectors_keep_the_weights(multiple: int) -> None:
    """The kernel reads whole vectors only: each support is padded with zero weights, inside the grid."""
    plan = _plan()
    exact, _ = plan.packed(1)
    bands, weights = plan.packed(multiple)
    dense = np.zeros((plan.n_bands, plan.n_wavelengths))
    for k, b in enumerate(bands):
        assert b["length"] % multiple == 0 or b["length"] == plan.n_wavelengths
        assert 0 <= b["start"] and b["start"] + b["length"] <= plan.n_wavelengths
        dense[k, b["start"]:b["start"] + b["length"]] = weights[b["offset"]:b["offset"] + b["length"]]
    assert np.array_equal(dense, plan.dense())
    assert sum(b["length"] for b in exact) == sum(w.weights.size for w in plan.weights)


def test_results_stay_valid_after_later_calls(rt) -> None:
    """One launch writes its result in place on host-memory devices: a later call must not reuse that memory."""
    plan = _plan()
    r = Resampler(rt, plan)
    a, b = _spectra(40, seed=8), _spectra(40, seed=9)
    first = r(a)
    kept = first.copy()
    second = r(b)
    assert np.array_equal(first, kept)
    assert not np.array_equal(first, second)
    assert np.array_equal(r(a), kept)
