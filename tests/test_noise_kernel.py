"""Counter-based noise: Philox bit-exact, uniforms strictly inside (0, 1), normals against the
float64 reference, statistics, and determinism under chunking, work-group size and pixel order.

Tolerances for normals: float32 log/sqrt/cospi have a few ulp of error (OpenCL 1.2 allows 3–4 ulp),
so |z_dev − z_ref| <= 2e-6 · (1 + |z|); float64: 1e-12 · (1 + |z|).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from s2cl.cl.templates import render_def
from s2cl.forward.noise import TAG_SENSOR_NOISE, normal4, philox4x32, sensor_noise, uniform
from s2cl.forward.sense import Radiometry, Sensing
from s2cl.reference import forward as ref
from s2cl.scene.effects import EffectSet
from s2cl.sensor.sensor import Sensor

TEST_KERNELS = r"""
__kernel void words(__global uint4 *out, const uint seed, const uint tag)
{
    const uint i = get_global_id(0);
    out[i] = s2_philox_words(seed, tag, i, 7u, 3u, 1u);
}
__kernel void normals(__global R *out, const uint seed, const uint group)
{
    const uint i = get_global_id(0);
    const R4 z = s2_normal4_SFX(seed, S2_TAG_SENSOR_NOISE, i, group, 0u, 0u);
    vstore4(z, i, out);
}
__kernel void uniform_extremes(__global R *out)
{
    out[0] = s2_uniform_SFX(0u);
    out[1] = s2_uniform_SFX(0xffffffffu);
    out[2] = log(out[0]);
    out[3] = log(out[1]);
}
"""

NORMAL_TOL = {"float32": 2e-6, "float64": 1e-12}


def _program(rt, real_t: str):
    """The noise stage (common/random.mako) alone, with test kernels around it."""
    T = rt.types(real_t, vector=False)
    pragma = "#pragma OPENCL EXTENSION cl_khr_fp64 : enable\n" if T.double else ""
    kernels = TEST_KERNELS.replace("R4", f"{T.R}4").replace("R ", f"{T.R} ").replace("SFX", T.suffix)
    return rt.build(pragma + render_def("common/random.mako", "random", T=T) + kernels, template="tests/noise")


def test_philox_known_answers() -> None:
    cases = [((0, 0, 0, 0), (0, 0), "6627e8d5 e169c58d bc57ac4c 9b00dbd8"),
             ((0xFFFFFFFF,) * 4, (0xFFFFFFFF,) * 2, "408f276d 41c83b0e a20bc7c6 6d5451fd"),
             ((0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344), (0xA4093822, 0x299F31D0),
              "d16cfe09 94fdcceb 5001e420 24126ea1")]
    for ctr, key, expected in cases:
        got = philox4x32(np.array(ctr, dtype=np.uint64), key)
        assert " ".join(f"{w:08x}" for w in got) == expected


def test_device_philox_is_bit_exact(rt) -> None:
    import pyopencl as cl

    n = 4099
    out = np.empty((n, 4), np.uint32)
    buf = rt.empty(out.nbytes)
    rt.kernel(_program(rt, "float32"), "words")(rt.queue, (n,), None, buf, np.uint32(1234), np.uint32(0xBEEF))
    cl.enqueue_copy(rt.queue, out, buf)
    ctr = np.stack([np.arange(n), np.full(n, 7), np.full(n, 3), np.full(n, 1)], axis=1).astype(np.uint64)
    assert np.array_equal(out, philox4x32(ctr, (1234, 0xBEEF)))


def test_uniforms_strictly_inside_unit_interval(rt, real_t: str) -> None:
    import pyopencl as cl

    dtype = np.dtype(real_t)
    out = np.empty(4, dtype)
    buf = rt.empty(out.nbytes)
    rt.kernel(_program(rt, real_t), "uniform_extremes")(rt.queue, (1,), None, buf)
    cl.enqueue_copy(rt.queue, out, buf)
    assert 0 < out[0] < out[1] < 1
    assert np.all(np.isfinite(out))
    assert out[0] == uniform(np.array([0]))[0] and out[1] == uniform(np.array([0xFFFFFFFF]))[0]


def test_normals_match_reference(rt, real_t: str) -> None:
    import pyopencl as cl

    n = 20000
    dtype = np.dtype(real_t)
    out = np.empty((n, 4), dtype)
    buf = rt.empty(out.nbytes)
    rt.kernel(_program(rt, real_t), "normals")(rt.queue, (n,), None, buf, np.uint32(99), np.uint32(2))
    cl.enqueue_copy(rt.queue, out, buf)
    expected = normal4(99, TAG_SENSOR_NOISE, np.arange(n), np.full(n, 2))
    err = np.abs(out - expected) / (1 + np.abs(expected))
    assert err.max() <= NORMAL_TOL[real_t], f"max error {err.max():.3g}"


def _radiometry(n_bands: int = 13) -> Radiometry:
    bands = Sensor.sentinel2().bands[:n_bands]
    return Radiometry.of(bands, 12)


def test_sense_noise_matches_reference(rt, real_t: str) -> None:
    r = _radiometry()
    rng = np.random.default_rng(0)
    L = rng.uniform(0, 200, (13, 5003))
    out = Sensing(rt, r, EffectSet(quantise=False, calibrate=False), real_t)(L, seed=7, pixel_offset=11)
    expected = ref.add_noise(L.astype(np.dtype(real_t)), r, seed=7, pixel_offset=11)
    sigma = np.sqrt(r.noise_a[:, None] + r.noise_b[:, None] * L)
    assert np.max(np.abs(out.noisy - expected) / (sigma * 10 + np.abs(L) * 1e-6)) <= 1.0
    if real_t == "float64":
        assert np.allclose(out.noisy, expected, rtol=1e-12, atol=1e-12)


def test_noise_statistics(rt) -> None:
    """Mean 0 and variance 1 within 5 standard errors, normal (KS), uncorrelated across bands and pixels."""
    r = _radiometry()
    r = Radiometry(lmin=r.lmin, lmax=r.lmax, noise_a=np.ones(13), noise_b=np.zeros(13), band_ids=r.band_ids, bits=12)
    n = 200_000
    z = Sensing(rt, r, EffectSet(quantise=False, calibrate=False), "float64")(np.zeros((13, n)), seed=2024).noisy
    se = 1 / np.sqrt(n)
    assert np.all(np.abs(z.mean(axis=1)) < 5 * se)
    assert np.all(np.abs(z.var(axis=1) - 1) < 5 * np.sqrt(2) * se)
    assert stats.kstest(z[4], "norm").pvalue > 1e-4
    corr = np.corrcoef(z)
    off_diagonal = corr[~np.eye(13, dtype=bool)]
    assert np.abs(off_diagonal).max() < 5 * se
    lag = np.array([np.corrcoef(z[k, :-1], z[k, 1:])[0, 1] for k in range(13)])
    assert np.abs(lag).max() < 5 * se


def test_noise_is_deterministic_under_chunking_and_work_groups(rt) -> None:
    r = _radiometry()
    L = np.random.default_rng(1).uniform(0, 300, (13, 3001))
    sensing = Sensing(rt, r, EffectSet())
    base = sensing(L, seed=5)
    for chunk, local in ((1000, None), (97, 1), (3001, 16), (64, 64)):
        other = sensing(L, seed=5, chunk_pixels=chunk, local_size=local)
        assert np.array_equal(other.noisy, base.noisy)
        assert np.array_equal(other.dn, base.dn)
        assert np.array_equal(other.clipped, base.clipped)
    # pixel order: a slice with its offset reproduces the same pixels
    part = sensing(L[:, 1200:1700], seed=5, pixel_offset=1200)
    assert np.array_equal(part.noisy, base.noisy[:, 1200:1700])
    # another seed and another frame change everything
    # (float32 values may coincide by chance: a few in 39,000)
    assert np.mean(sensing(L, seed=6).noisy == base.noisy) < 1e-3
    assert np.mean(sensing(L, seed=5, frame=1).noisy == base.noisy) < 1e-3


def test_band_noise_does_not_depend_on_band_subset(rt) -> None:
    bands = Sensor.sentinel2().bands
    full = Radiometry.of(bands, 12)
    sub = Radiometry.of([bands[5], bands[9]], 12, band_ids=[5, 9])
    L = np.full((13, 100), 50.0)
    a = Sensing(rt, full, EffectSet(quantise=False, calibrate=False))(L, seed=3).noisy
    b = Sensing(rt, sub, EffectSet(quantise=False, calibrate=False))(L[[5, 9]], seed=3).noisy
    assert np.array_equal(a[[5, 9]], b)


def test_reference_noise_layout() -> None:
    z = sensor_noise(1, np.arange(10), [0, 1, 2, 3, 4])
    quad = normal4(1, TAG_SENSOR_NOISE, np.arange(10), np.zeros(10, dtype=np.uint64))
    assert np.array_equal(z[:4].T, quad)


@pytest.mark.parametrize("seed", [0, 2**32 - 1])
def test_seed_range(rt, seed: int) -> None:
    out = Sensing(rt, _radiometry(2), EffectSet(quantise=False, calibrate=False))(np.ones((2, 3)), seed=seed)
    assert np.all(np.isfinite(out.noisy))
