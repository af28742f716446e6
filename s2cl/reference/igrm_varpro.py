"""The IGRM fit by variable projection in vectorised numpy: the twin of ``kernels/common/igrm_varpro.mako``.

Levenberg-Marquardt on (L, S) (normalised l0 and s) with (rmin, depth) solved exactly in their box at
every point, Kaufman's projected Jacobian, the kernel's stopping rules and, at the end, the
four-parameter verdict and condition estimate of :mod:`s2cl.reference.igrm`. Used by the sweep's numpy
twin (:mod:`s2cl.reference.sweep`), by tests and as bench's "same algorithm in numpy" baseline.
"""

from __future__ import annotations

import numpy as np

from s2cl.reference.igrm import _evaluate, _finish, _gauss_newton_near, _valid, fit_chunked, initial_guess
from s2cl.retrieve.igrm import IgrmResult
from s2cl.retrieve.igrm_settings import IgrmSettings, KernelConfig


def fit_numpy_varpro(refl: np.ndarray, wavelengths_nm: np.ndarray, settings: IgrmSettings | None = None, *,
                     dtype=np.float32, chunk: int = 65536) -> IgrmResult:
    """The kernel's variable-projection fit in vectorised numpy (``dtype`` arithmetic), ``chunk`` pixels at a time."""
    return fit_chunked(_varpro_chunk, refl, wavelengths_nm, settings, dtype=dtype, chunk=chunk)


def project(y: np.ndarray, ybar: np.ndarray, x: np.ndarray, L: np.ndarray, S: np.ndarray, c: KernelConfig):
    """At (L, S): g, t, the best (rmin, depth) in the box, residuals and cost (the kernel's s2_igrm_vp_eval)."""
    dt = y.dtype.type
    nb = y.shape[0]
    t = (x[:, None] - L) * (dt(1.0) / S)
    g = np.exp(t * t * dt(-0.5))
    h = dt(1.0) - g
    hbar = h.sum(0) * dt(1.0 / nb)
    hc = h - hbar
    shh, shy = (hc * hc).sum(0), (hc * (y - ybar)).sum(0)
    sh2, shy0 = (h * h).sum(0), (h * (y - dt(c.rmin_lo))).sum(0)
    spread = shh > dt(1e-30 if y.dtype == np.float64 else 1e-20)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(spread, shy / np.where(spread, shh, 1), dt(0.0))
        a = ybar - d * hbar
        inside = (d >= 0) & (a >= dt(c.rmin_lo))
        a1 = np.maximum(ybar, dt(c.rmin_lo))
        d2 = np.maximum(np.where(sh2 > 0, shy0 / np.where(sh2 > 0, sh2, 1), dt(0.0)), dt(0.0))
    c1 = ((a1 - y) ** 2).sum(0)
    c2 = ((dt(c.rmin_lo) + d2 * h - y) ** 2).sum(0)
    edge2 = c2 < c1
    a = np.where(inside, a, np.where(edge2, dt(c.rmin_lo), a1))
    d = np.where(inside, d, np.where(edge2, d2, dt(0.0)))
    r = a + d * h - y
    return g, t, r, a, d, (r * r).sum(0)


def jacobian(g, t, r, a, d, S, c: KernelConfig):
    """Kaufman's projected J^T J on (L, S) and J^T r (the kernel's s2_igrm_vp_jac): A00, A01, A11, b0, b1."""
    dt = g.dtype.type
    nb = g.shape[0]
    jl = (-d / S) * g * t
    js = jl * t
    h = dt(1.0) - g
    free_a = a > dt(c.rmin_lo)
    ml = np.where(free_a, jl.sum(0) * dt(1.0 / nb), dt(0.0))
    ms = np.where(free_a, js.sum(0) * dt(1.0 / nb), dt(0.0))
    h = h - np.where(free_a, h.sum(0) * dt(1.0 / nb), dt(0.0))
    hh = (h * h).sum(0)
    use_h = (d > 0) & (hh > dt(1e-30 if g.dtype == np.float64 else 1e-20))
    with np.errstate(divide="ignore", invalid="ignore"):
        kl = np.where(use_h, (h * jl).sum(0) / np.where(use_h, hh, 1), dt(0.0))
        ks = np.where(use_h, (h * js).sum(0) / np.where(use_h, hh, 1), dt(0.0))
    pl, ps = jl - ml - kl * h, js - ms - ks * h
    return (pl * pl).sum(0), (pl * ps).sum(0), (ps * ps).sum(0), (jl * r).sum(0), (js * r).sum(0)


def _active(p, b, lo, hi):
    return ((p <= lo) & (b > 0)) | ((p >= hi) & (b < 0))


def _varpro_chunk(y: np.ndarray, x: np.ndarray, c: KernelConfig):
    """The kernel's loop over a chunk; finished pixels are dropped from the work set."""
    dt = y.dtype.type
    n = y.shape[1]
    valid = _valid(y, c)
    y = np.where(valid, y, dt(0.0))
    a0, d0, L, S, depth = initial_guess(y, x, c)
    flat = depth <= dt(c.depth_min)
    ybar = y.sum(0) * dt(1.0 / y.shape[0])
    g, t, r, a, d, f = project(y, ybar, x, L, S, c)
    a, d = np.where(flat, a0, a), np.where(flat, d0, d)  # a flat spectrum reports the initial guess
    A00, A01, A11, b0, b1 = jacobian(g, t, r, a, d, S, c)
    # state rows: a, d, L, S, f, A00, A01, A11, b0, b1
    state = np.vstack([a, d, L, S, f, A00, A01, A11, b0, b1]).astype(y.dtype)
    out = state.copy()
    stopped = np.zeros(n, dtype=bool)
    iters = np.zeros(n, dtype=np.int64)
    live = np.flatnonzero(valid & ~flat)
    state, yl, yb = state[:, live], y[:, live], ybar[live]
    lam = np.full(live.size, dt(c.lam0))
    lo_l, hi_l, lo_s, hi_s = dt(c.lo_l), dt(c.hi_l), dt(c.lo_s), dt(c.hi_s)
    for _ in range(c.max_iter):
        if live.size == 0:
            break
        a, d, L, S, f, A00, A01, A11, b0, b1 = state
        act2, act3 = _active(L, b0, lo_l, hi_l), _active(S, b1, lo_s, hi_s)
        damp, dfloor = dt(1.0) + lam, lam * dt(c.diag_eps)
        m00 = np.where(act2, dt(1.0), A00 * damp + dfloor)
        m11 = np.where(act3, dt(1.0), A11 * damp + dfloor)
        m01 = np.where(act2 | act3, dt(0.0), A01)
        r0, r1 = np.where(act2, dt(0.0), -b0), np.where(act3, dt(0.0), -b1)
        det = m00 * m11 - m01 * m01
        ok = det > dt(c.pivot_rel) * m00 * m11
        inv_det = dt(1.0) / np.where(ok, det, dt(1.0))
        q2 = np.clip(L + (r0 * m11 - m01 * r1) * inv_det, lo_l, hi_l)
        q3 = np.clip(S + (m00 * r1 - m01 * r0) * inv_det, lo_s, hi_s)
        gq, tq, rq, q0, q1, fn = project(yl, yb, x, q2, q3, c)
        acc = ok & (fn < f)
        p, q = np.stack([a, d, L, S]), np.stack([q0, q1, q2, q3])
        small = np.all(np.abs(q - p) <= dt(c.xtol) * (np.abs(p) + dt(0.1)), axis=0)
        fsmall = (f - fn) <= dt(c.ftol) * f
        tiny = (acc & fsmall & small) | (~acc & ok & small)
        if acc.any():
            jac = jacobian(gq, tq, rq, q0, q1, q3, c)
            new = np.vstack([q0, q1, q2, q3, fn, *jac])
            state = np.where(acc, new, state)
        lam = np.maximum(np.where(acc, lam * dt(c.lam_down), lam * dt(c.lam_up)), dt(c.lam_min))
        iters[live] += 1
        a, d, L, S, f, A00, A01, A11, b0, b1 = state
        gf = f * dt(c.gtol**2)
        gsmall = ((_active(L, b0, lo_l, hi_l) | (b0 * b0 <= gf * A00))
                  & (_active(S, b1, lo_s, hi_s) | (b1 * b1 <= gf * A11)))
        done = (f <= dt(c.f_abs)) | gsmall | tiny | (lam > dt(c.lam_max))
        if done.any():
            stopped[live[done]] = True
            out[:, live[done]] = state[:, done]
            keep = ~done
            live, yl, yb, lam, state = live[keep], yl[:, keep], yb[keep], lam[keep], state[:, keep]
    out[:, live] = state
    p = out[:4]
    e = _evaluate(y, x, p, c)  # the four-parameter system at the solution: verdict, condition, RSS
    full = np.vstack([p, e])
    lo = [dt(c.rmin_lo), dt(0.0), lo_l, lo_s]
    hi = [None, None, hi_l, hi_s]
    conv = (out[4] <= dt(c.f_abs)) | _gauss_newton_near(full, lo, hi, c, dt)
    return _finish(p, e[1], conv, iters, valid, flat, c, y.dtype, stalled=stopped & ~conv, a=e[2:12])
