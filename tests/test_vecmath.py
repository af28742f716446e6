"""Device math helpers of kernels/common/vecmath.mako against float64 numpy."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.cl.templates import render
from s2cl.cl.vecmath import EXP_DEGREE, EXP_MIN, exp_neg_model, exp_poly_coefficients, exp_template_vars
from s2cl.cl.vectypes import VecTypes

#: Stated accuracy of s2_exp_neg on [EXP_MIN, 0] (relative, against exp of the same input):
#: float32 degree 5: polynomial 1.0e-7 + rounding -> 3e-7 (2.5 ulp); float64 degree 12: 4e-16.
EXP_REL_TOL = {"float32": 3e-7, "float64": 4e-16}


def _program(rt, real_t: str, lanes: int, degree: int | None = None):
    T = VecTypes(real_t, rt.lanes(real_t, lanes))  # a width this CPU cannot use falls back (devices.choose_lanes)
    src = render("vecmath_check.cl.mako", T=T, **exp_template_vars(real_t, degree))
    return T, rt.build(src, template="vecmath_check.cl.mako")


def _run(rt, prog, name, T, out_shape, *arrays):
    n = arrays[0].shape[-1]
    bufs = [rt.to_device(np.ascontiguousarray(a, dtype=T.dtype)) for a in arrays]
    out = rt.empty(int(np.prod(out_shape)) * T.dtype.itemsize)
    rt.kernel(prog, name)(rt.queue, (n // T.lanes,), None, out, *bufs, np.int32(n))
    return rt.fetch(out, out_shape, T.dtype)


def test_exp_neg_accuracy(rt, real_t, lanes):
    T, prog = _program(rt, real_t, lanes)
    emin = EXP_MIN[real_t]
    a = np.concatenate([-np.geomspace(1e-12, -emin, 200_000), -np.linspace(0, 30, 200_000), [0.0, emin]])
    a = a.astype(T.dtype)[: (a.size // 16) * 16]
    out = _run(rt, prog, "check_exp_neg", T, a.shape, a)
    rel = np.abs(out / np.exp(a.astype(np.float64)) - 1.0)
    assert rel.max() <= EXP_REL_TOL[real_t], f"max rel error {rel.max():.3g}"
    # the numpy twin describes the same computation (up to FMA contraction)
    model = exp_neg_model(a, EXP_DEGREE[real_t], real_t)
    assert np.max(np.abs(out / model - 1.0)) <= 2 * np.finfo(T.dtype).eps


def test_exp_neg_clamps_far_arguments(rt):
    T, prog = _program(rt, "float32", 8)
    a = np.array([-1e30, -np.inf, -88.0, -200.0, -87.0, -1e-30, 0.0, -0.0], dtype=np.float32)
    out = _run(rt, prog, "check_exp_neg", T, a.shape, a)
    assert np.all(np.isfinite(out)) and np.all(out > 0)
    np.testing.assert_allclose(out[5:], 1.0, rtol=3e-7)
    np.testing.assert_allclose(out[:4], np.exp(np.float64(EXP_MIN["float32"])), rtol=3e-7)


def test_low_degree_is_measurably_worse(rt):
    """The degree is a real knob: degree 3 must fail the float32 tolerance that degree 5 meets."""
    T, prog = _program(rt, "float32", 8, degree=3)
    a = -np.linspace(0, 20, 8192).astype(np.float32)
    out = _run(rt, prog, "check_exp_neg", T, a.shape, a)
    assert np.max(np.abs(out / np.exp(a.astype(np.float64)) - 1.0)) > 10 * EXP_REL_TOL["float32"]


@pytest.mark.parametrize(("degree", "bound"), [(5, 1.1e-7), (12, 4e-16)])
def test_exp_coefficients_approximate_exp_on_the_reduced_range(degree: int, bound: float):
    """Degree 5 (Chebyshev nodes): h^6 e^h / (6! 2^5) = 1.06e-7 relative on [-ln2/2, ln2/2]; degree 12
    (Taylor): h^13 / 13! = 1.6e-16, below float64 rounding."""
    h = np.log(2.0) / 2.0
    f = np.linspace(-h, h, 20001)
    poly = np.polynomial.polynomial.polyval(f, exp_poly_coefficients(degree))
    assert np.max(np.abs(poly / np.exp(f) - 1.0)) <= bound
    assert exp_poly_coefficients(12)[3] == 1.0 / 6.0


def test_exp_coefficients_are_the_same_text_in_another_process():
    """The kernel source, hence PoCL's cached binary, must not change between processes."""
    import subprocess
    import sys

    code = "from s2cl.cl.vecmath import exp_poly_coefficients as c; print(repr([c(d) for d in range(3, 17)]))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.strip() == repr([exp_poly_coefficients(d) for d in range(3, 17)])


def test_rsqrt_accuracy(rt, real_t):
    T, prog = _program(rt, real_t, 8)
    a = np.concatenate([1.0 + np.geomspace(1e-9, 1e12, 65536 - 8), np.ones(8)]).astype(T.dtype)
    out = _run(rt, prog, "check_rsqrt", T, a.shape, a)
    rel = np.abs(out * np.sqrt(a.astype(np.float64)) - 1.0)
    assert rel.max() <= (3e-7 if real_t == "float32" else 5e-16)


def _spd_batch(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    m = rng.normal(size=(n, 6, 4))
    a = np.einsum("nki,nkj->nij", m, m) + 0.1 * np.eye(4)
    b = rng.normal(size=(n, 4))
    return a, b


def _upper(a: np.ndarray) -> np.ndarray:
    iu = np.triu_indices(4)
    return np.stack([a[:, i, j] for i, j in zip(*iu, strict=True)])


def test_ldl4_solve(rt, real_t, lanes):
    T, prog = _program(rt, real_t, lanes)
    n = 4096
    a, b = _spd_batch(n, 1)
    a[7] = np.outer([1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 3.0, 4.0])  # rank 1: must be refused
    a[8] = np.diag([1.0, 1.0, 0.0, 1.0])                          # zero pivot
    a[9, 0, 0] = np.nan                                            # NaN: refused, finite output
    x_dev, ok_dev = rt.empty(4 * n * T.dtype.itemsize), rt.empty(4 * n)
    args = [rt.to_device(_upper(a).astype(T.dtype)), rt.to_device(b.T.copy().astype(T.dtype))]
    rt.kernel(prog, "check_ldl4")(rt.queue, (n // T.lanes,), None, x_dev, ok_dev, *args, np.int32(n))
    x = rt.fetch(x_dev, (4, n), T.dtype).T
    ok = rt.fetch(ok_dev, (n,), np.int32).astype(bool)
    assert not ok[7] and not ok[8] and not ok[9]
    assert np.all(x[[7, 8, 9]] == 0)
    good = np.ones(n, dtype=bool)
    good[[7, 8, 9]] = False
    assert ok[good].all()
    ref = np.linalg.solve(a[good], b[good][..., None])[..., 0]
    cond = np.linalg.cond(a[good])
    err = np.max(np.abs(x[good] - ref), axis=1) / np.max(np.abs(ref), axis=1)
    eps = np.finfo(T.dtype).eps
    assert np.all(err <= 20 * eps * cond), f"worst {np.max(err / (eps * cond)):.3g} eps*cond"
