"""Oracles and baselines for the IGRM fit (``s2cl/retrieve/igrm.py``, ``kernels/common/igrm_lm.mako``).

* :func:`fit_scipy`: the oracle: ``scipy.optimize.least_squares`` (trust-region reflective,
  analytic Jacobian) per pixel, float64, same bounds, loss and initial guess as the kernel.
* :func:`fit_numpy_lm`: the same bounded Levenberg-Marquardt as the kernel, vectorised over
  pixels with numpy (closed-form LDL^T 4x4 solve, finished pixels dropped from the work set):
  the baseline of ``bench/bench_igrm.py`` and an independent twin of the kernel's logic.
* :func:`initial_guess`: the kernel's deterministic initial guesses, in numpy.

Parameters are handled as in the kernel: ``p = (rmin, depth = rmax - rmin, L = (l0 - xc)/xw,
S = s/xw)`` with :func:`s2cl.retrieve.igrm.kernel_config` giving ``xc``, ``xw`` and the normalised bounds.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from s2cl.retrieve.igrm import FitStatus, IgrmResult
from s2cl.retrieve.igrm_settings import IgrmSettings, KernelConfig, kernel_config


def model(wavelengths_nm: np.ndarray, rmax, rmin, l0, s) -> np.ndarray:
    """IGRM reflectance (paper eq. 2) at ``wavelengths_nm`` (n_bands,) for parameter arrays
    of shape (n,): returns (n_bands, n) float64."""
    w = np.asarray(wavelengths_nm, dtype=np.float64)[:, None]
    rmax, rmin, l0, s = (np.asarray(v, dtype=np.float64) for v in (rmax, rmin, l0, s))
    return rmax - (rmax - rmin) * np.exp(-((w - l0) ** 2) / (2.0 * s**2))


def _normalise(wavelengths_nm: np.ndarray, c: KernelConfig, dtype) -> np.ndarray:
    return ((np.asarray(wavelengths_nm, dtype=np.float64) - c.xc) / c.xw).astype(dtype)


def _valid(y: np.ndarray, c: KernelConfig) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return np.all((y <= c.max_abs) & (y >= -c.max_abs), axis=0)


def initial_guess(y: np.ndarray, x: np.ndarray, c: KernelConfig) -> tuple[np.ndarray, ...]:
    """The kernel's initial guess (rmin, depth, L, S) and the data depth, in ``y``'s dtype.

    :param y: (n_bands, n) reflectance, invalid pixels already replaced by 0.
    :param x: (n_bands,) normalised wavelengths.
    """
    if c.init == "grid":
        return _init_grid(y, x, c)
    return _init_data(y, x, c)


def _init_data(y: np.ndarray, x: np.ndarray, c: KernelConfig):
    dt = y.dtype.type
    imin = np.argmin(y, axis=0)
    ymin = y.min(axis=0)
    ymax = y.max(axis=0)
    xmin = x[imin]
    depth = ymax - ymin
    yhalf = ymin + depth * dt(0.5)
    xhalf = np.zeros_like(ymin)
    found = np.zeros(y.shape[1], dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(1, y.shape[0]):
            cross = ~found & (xmin <= x[i - 1]) & (y[i - 1] < yhalf) & (y[i] >= yhalf)
            xi = x[i - 1] + (yhalf - y[i - 1]) * (x[i] - x[i - 1]) / (y[i] - y[i - 1])
            xhalf = np.where(cross, xi, xhalf)
            found |= cross
    p2 = np.clip(xmin, dt(c.lo_l), dt(c.hi_l))
    p3 = np.where(found, (xhalf - p2) * dt(1.0 / np.sqrt(2.0 * np.log(2.0))), dt(c.s_guess))
    p3 = np.clip(p3, dt(c.lo_s), dt(c.hi_s)).astype(y.dtype)
    p0 = np.maximum(ymin, dt(c.rmin_lo))
    return p0, ymax - p0, p2.astype(y.dtype), p3, depth


def _init_grid(y: np.ndarray, x: np.ndarray, c: KernelConfig):
    dt = y.dtype.type
    nb = y.shape[0]
    sy = y.sum(axis=0)
    syy = (y * y).sum(axis=0)
    depth = y.max(axis=0) - y.min(axis=0)
    best = np.full(y.shape[1], np.inf, dtype=y.dtype)
    p0, p1 = sy / dt(nb), np.zeros_like(sy)
    p2 = np.full_like(sy, dt(c.grid_l[0]))
    p3 = np.full_like(sy, dt(c.grid_s[0]))
    for gl in c.grid_l:
        for gs in c.grid_s:
            g = np.exp(((x - dt(gl)) * dt(1.0 / gs)) ** 2 * dt(-0.5)).astype(y.dtype)
            sg, sgg = g.sum(), (g * g).sum()
            den = sgg - sg * sg / dt(nb)
            if not den > dt(1e-12 if y.dtype == np.float64 else 1e-6) * sgg:
                continue
            sgy = g @ y
            d = np.maximum((sy * sg / dt(nb) - sgy) / den, dt(0.0))
            rm = (sy + d * sg) / dt(nb)
            cost = syy - 2 * rm * sy + 2 * d * sgy + nb * rm * rm - 2 * rm * d * sg + d * d * sgg
            better = cost < best
            best = np.where(better, cost, best)
            p0 = np.where(better, rm, p0)
            p1 = np.where(better, d, p1)
            p2 = np.where(better, dt(gl), p2)
            p3 = np.where(better, dt(gs), p3)
    p0 = p0 - p1
    p1 = np.maximum(np.where(p0 < dt(c.rmin_lo), p1 + p0 - dt(c.rmin_lo), p1), dt(0.0))
    p0 = np.maximum(p0, dt(c.rmin_lo))
    return p0, p1, p2, p3, depth


def _evaluate(y, x, q, c: KernelConfig) -> np.ndarray:
    """Rows: cost, RSS, upper triangle of J^T W J (10), J^T W r (4) at ``q`` (4, m): (16, m)."""
    dt = y.dtype.type
    q0, q1, q2, q3 = q
    inv_s = dt(1.0) / q3
    t = (x[:, None] - q2) * inv_s
    g = np.exp(t * t * dt(-0.5))
    h = dt(1.0) - g
    r = (q0 + q1) - q1 * g - y
    w1 = q1 * g * inv_s * t
    w2 = w1 * t
    e = np.empty((16, y.shape[1]), dtype=y.dtype)
    np.einsum("ij,ij->j", r, r, out=e[1])
    if c.loss == "soft_l1":
        z = r * r / dt(c.f_scale**2)
        w = dt(1.0) / np.sqrt(dt(1.0) + z)
        e[0] = dt(2.0 * c.f_scale**2) * (z / (np.sqrt(dt(1.0) + z) + dt(1.0))).sum(0)
        e[2] = w.sum(0)
        wh, w1w, w2w, wr = w * h, w * w1, w * w2, w * r
    else:
        e[0] = e[1]
        e[2] = dt(y.shape[0])
        wh, w1w, w2w, wr = h, w1, w2, r
    e[3], e[4], e[5], e[12] = wh.sum(0), w1w.sum(0), w2w.sum(0), wr.sum(0)
    products = {6: (wh, h), 7: (wh, w1), 8: (wh, w2), 9: (w1w, w1), 10: (w1w, w2), 11: (w2w, w2),
                13: (h, wr), 14: (w1, wr), 15: (w2, wr)}
    for row, (u, v) in products.items():
        np.einsum("ij,ij->j", u, v, out=e[row])
    e[[4, 5, 7, 8, 14, 15]] *= dt(-1.0)  # Jacobian columns 2 and 3 are -w1, -w2
    return e


def ldl4_solve(a: list[np.ndarray], b: list[np.ndarray], pivot_rel: float):
    """Batched LDL^T solve of the symmetric 4x4 systems (upper triangle ``a``, 10 arrays) as in
    ``vecmath.ldl4_solve``: returns (x0..x3, ok)."""
    a00, a01, a02, a03, a11, a12, a13, a22, a23, a33 = a
    b0, b1, b2, b3 = b
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d0 = a00
        i0 = 1.0 / d0
        l10, l20, l30 = a01 * i0, a02 * i0, a03 * i0
        d1 = a11 - l10 * a01
        i1 = 1.0 / d1
        t21, t31 = a12 - l20 * a01, a13 - l30 * a01
        l21, l31 = t21 * i1, t31 * i1
        d2 = a22 - l20 * a02 - l21 * t21
        i2 = 1.0 / d2
        t32 = a23 - l30 * a02 - l31 * t21
        l32 = t32 * i2
        d3 = a33 - l30 * a03 - l31 * t31 - l32 * t32
        i3 = 1.0 / d3
        ok = ((d0 > pivot_rel * a00) & (d0 > 0) & (d1 > pivot_rel * a11) & (d2 > pivot_rel * a22)
              & (d3 > pivot_rel * a33))
        z1 = b1 - l10 * b0
        z2 = b2 - l20 * b0 - l21 * z1
        z3 = b3 - l30 * b0 - l31 * z1 - l32 * z2
        x3 = z3 * i3
        x2 = z2 * i2 - l32 * x3
        x1 = z1 * i1 - l21 * x2 - l31 * x3
        x0 = b0 * i0 - l10 * x1 - l20 * x2 - l30 * x3
    zero = np.zeros_like(b0)
    return [np.where(ok, v, zero) for v in (x0, x1, x2, x3)], ok


def fit_numpy_lm(refl: np.ndarray, wavelengths_nm: np.ndarray, settings: IgrmSettings | None = None, *,
                 dtype=np.float32, chunk: int = 65536) -> IgrmResult:
    """The kernel's bounded LM in vectorised numpy (``dtype`` arithmetic), ``chunk`` pixels at a time."""
    return fit_chunked(_lm_chunk, refl, wavelengths_nm, settings, dtype=dtype, chunk=chunk)


def fit_chunked(fit_chunk: Callable[[np.ndarray, np.ndarray, KernelConfig], tuple], refl: np.ndarray,
                wavelengths_nm: np.ndarray, settings: IgrmSettings | None = None, *, dtype=np.float32,
                chunk: int = 65536) -> IgrmResult:
    """``fit_chunk(refl, x, config)`` (a numpy twin of one solver) over ``refl`` ``(bands, pixels)``,
    ``chunk`` pixels at a time, in ``dtype`` arithmetic; the results joined."""
    settings = settings or IgrmSettings()
    refl = np.asarray(refl)
    nb, n = refl.shape
    c = kernel_config(settings, nb, np.dtype(dtype).name)
    x = _normalise(wavelengths_nm, c, dtype)
    parts = [fit_chunk(np.ascontiguousarray(refl[:, i:i + chunk], dtype=dtype), x, c)
             for i in range(0, n, chunk)] or [fit_chunk(np.zeros((nb, 0), dtype=dtype), x, c)]
    return IgrmResult(*(np.concatenate([p[k] for p in parts]) for k in range(10)))


def log10_condition(a) -> np.ndarray:
    """0.5 log10(1 / min d'_i) of the column-scaled J^T W J (upper triangle ``a``, 10 rows), capped
    at 12: the kernel's condition estimate (``kernels/common/igrm_lm.mako``), same operation order."""
    a00, a01, a02, a03, a11, a12, a13, a22, a23, a33 = a
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d0 = a00
        l10, l20, l30 = a01 / d0, a02 / d0, a03 / d0
        d1 = a11 - l10 * a01
        t21, t31 = a12 - l20 * a01, a13 - l30 * a01
        l21, l31 = t21 / d1, t31 / d1
        d2 = a22 - l20 * a02 - l21 * t21
        t32 = a23 - l30 * a02 - l31 * t21
        d3 = a33 - l30 * a03 - l31 * t31 - (t32 / d2) * t32
        m = d1 / a11
        m = np.where(d2 / a22 < m, d2 / a22, m)  # NaN fails the comparison, as in the kernel
        m = np.where(d3 / a33 < m, d3 / a33, m)
        ok = (m > 1e-24) & (d0 > 0)
        v = -0.5 * np.log10(np.where(ok, m, 1.0))
    return np.where(ok, np.minimum(v, 12.0), 12.0)


def _lm_chunk(y: np.ndarray, x: np.ndarray, c: KernelConfig):
    """The kernel's loop over a chunk. State of the live pixels, one row each: p (4), then the
    evaluation rows of :func:`_evaluate` (cost, RSS, J^T W J, J^T W r); finished pixels are
    written out and dropped from the work set."""
    dt = y.dtype.type
    n = y.shape[1]
    valid = _valid(y, c)
    y = np.where(valid, y, dt(0.0))
    *start, depth = initial_guess(y, x, c)
    flat = depth <= dt(c.depth_min)
    state = np.vstack([np.stack(start).astype(y.dtype), _evaluate(y, x, start, c)])
    out = state.copy()  # every pixel's state: p, cost, RSS, J^T W J, J^T W r
    stopped = np.zeros(n, dtype=bool)
    iters = np.zeros(n, dtype=np.int64)
    live = np.flatnonzero(valid & ~flat)
    state, yl = state[:, live], y[:, live]
    lam = np.full(live.size, dt(c.lam0))
    lo = [dt(c.rmin_lo), dt(0.0), dt(c.lo_l), dt(c.lo_s)]
    hi = [None, None, dt(c.hi_l), dt(c.hi_s)]
    for _ in range(c.max_iter):
        if live.size == 0:
            break
        p, f, a, b = state[:4], state[4], state[6:16], state[16:20]
        act = [_active(p[j], b[j], lo[j], hi[j]) for j in range(4)]
        m = _reduced_system(a, b, act, dt(1.0) + lam, lam * dt(c.diag_eps), dt)
        dp, ok = ldl4_solve(m[:10], m[10:], dt(c.pivot_rel))
        q = np.stack(dp) + p
        q[0] = np.maximum(q[0], lo[0])
        q[1] = np.maximum(q[1], dt(0.0))
        q[2] = np.clip(q[2], lo[2], hi[2])
        q[3] = np.clip(q[3], lo[3], hi[3])
        e = _evaluate(yl, x, q, c)
        fn = e[0]
        acc = ok & (fn < f)
        small = np.all(np.abs(q - p) <= dt(c.xtol) * (np.abs(p) + dt(0.1)), axis=0)
        fsmall = (f - fn) <= dt(c.ftol) * f
        tiny = (acc & fsmall & small) | (~acc & ok & small)
        state = np.where(acc, np.vstack([q, e]), state)
        lam = np.maximum(np.where(acc, lam * dt(c.lam_down), lam * dt(c.lam_up)), dt(c.lam_min))
        iters[live] += 1
        # stopping rules at the point kept (kernels/common/igrm_lm.mako, step 4)
        p, f, a, b = state[:4], state[4], state[6:16], state[16:20]
        gf = f * dt(c.gtol**2)
        gsmall = np.ones(live.size, dtype=bool)
        for j, diag in enumerate((0, 4, 7, 9)):
            gsmall &= _active(p[j], b[j], lo[j], hi[j]) | (b[j] ** 2 <= gf * a[diag])
        done = (f <= dt(c.f_abs)) | gsmall | tiny | (lam > dt(c.lam_max))
        if done.any():
            stopped[live[done]] = True
            out[:, live[done]] = state[:, done]
            keep = ~done
            live, yl, lam, state = live[keep], yl[:, keep], lam[keep], state[:, keep]
    out[:, live] = state
    conv = (out[4] <= dt(c.f_abs)) | _gauss_newton_near(out, lo, hi, c, dt)
    return _finish(out[:4], out[5], conv, iters, valid, flat, c, y.dtype, stalled=stopped & ~conv, a=out[6:16])


def _gauss_newton_near(state: np.ndarray, lo, hi, c: KernelConfig, dt) -> np.ndarray:
    """Per pixel: does the undamped Gauss-Newton step from the state's point (free parameters) move
    lp by at most lp_tol (the kernel's verdict CONVERGED, ``kernels/common/igrm_lm.mako``)?"""
    p, b = state[:4], state[16:20]
    act = [_active(p[j], b[j], lo[j], hi[j]) for j in range(4)]
    m = _reduced_system(state[6:16], b, act, dt(1.0), dt(0.0), dt)
    dg, ok = ldl4_solve(m[:10], m[10:], dt(c.pivot_rel))
    dlp = dg[2] + dg[3]
    return ok & (dlp <= dt(c.lp_tol)) & (dlp >= -dt(c.lp_tol))


def _active(pj, bj, lo, hi):
    at_lo = (pj <= lo) & (bj > 0)
    if hi is None:
        return at_lo
    return at_lo | ((pj >= hi) & (bj < 0))


def _reduced_system(a, b, act, damp, dfl, dt):
    a00, a01, a02, a03, a11, a12, a13, a22, a23, a33 = a
    z, one = dt(0.0), dt(1.0)
    a0, a1, a2, a3 = act
    return [
        np.where(a0, one, a00 * damp + dfl), np.where(a0 | a1, z, a01), np.where(a0 | a2, z, a02),
        np.where(a0 | a3, z, a03),
        np.where(a1, one, a11 * damp + dfl), np.where(a1 | a2, z, a12), np.where(a1 | a3, z, a13),
        np.where(a2, one, a22 * damp + dfl), np.where(a2 | a3, z, a23), np.where(a3, one, a33 * damp + dfl),
        np.where(a0, z, -b[0]), np.where(a1, z, -b[1]), np.where(a2, z, -b[2]), np.where(a3, z, -b[3]),
    ]


def _finish(p, rss, conv, iters, valid, flat, c: KernelConfig, dtype, bound_tol: float = 0.0, *,
            stalled=None, a=None):
    dt = np.dtype(dtype).type
    shallow = p[1] <= dt(c.depth_min)
    tol = dt(bound_tol)
    stalled = np.zeros_like(conv) if stalled is None else stalled
    status = np.where(~valid, FitStatus.INVALID_INPUT,
                      np.where(flat | shallow, FitStatus.DEGENERATE,
                               np.where(conv, FitStatus.CONVERGED,
                                        np.where(stalled, FitStatus.STALLED, FitStatus.ITERATION_LIMIT)))
                      ).astype(np.uint8)
    bounds = ((p[2] <= dt(c.lo_l) + tol) * 1 | (p[2] >= dt(c.hi_l) - tol) * 2 | (p[3] <= dt(c.lo_s) + tol) * 4
              | (p[3] >= dt(c.hi_s) - tol) * 8 | (p[1] <= tol) * 16 | (p[0] <= dt(c.rmin_lo) + tol) * 32)
    bounds = np.where(valid, bounds, 0).astype(np.uint8)
    l0 = p[2] * dt(c.xw) + dt(c.xc)
    s = p[3] * dt(c.xw)
    out = [p[0] + p[1], p[0], l0, s, l0 + s, np.sqrt(rss / dt(c.n_bands))]
    out = [np.where(valid, v, dt(0.0)).astype(dtype) for v in out]
    it_dtype = np.uint8 if c.max_iter <= 255 else np.uint16
    cond = None if a is None else np.where(valid, log10_condition(a), 0.0).astype(dtype)
    return (*out, status, iters.astype(it_dtype), bounds, cond)


# -- scipy oracle ---------------------------------------------------------------------------------
def fit_scipy(refl: np.ndarray, wavelengths_nm: np.ndarray, settings: IgrmSettings | None = None, *,
              tol: float = 1e-12, max_nfev: int = 2000) -> IgrmResult:
    """``scipy.optimize.least_squares`` (method ``trf``) per pixel in float64, in physical units
    (rmin, depth, l0 nm, s nm) with the kernel's bounds, loss and initial guess. Slow on purpose.

    Statuses follow the kernel's rules (invalid input, depth <= depth_min -> DEGENERATE);
    ``iterations`` holds scipy's number of function evaluations (capped at 255).
    """
    from scipy.optimize import least_squares

    settings = settings or IgrmSettings()
    refl = np.asarray(refl, dtype=np.float64)
    nb, n = refl.shape
    c = kernel_config(settings, nb, "float64")
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    x = _normalise(wl, c, np.float64)
    valid = _valid(refl, c)
    y = np.where(valid, refl, 0.0)
    p0, p1, p2, p3, depth = initial_guess(y, x, c)
    flat = depth <= c.depth_min
    lo = np.array([settings.rmin_min, 0.0, settings.l0_min_nm, settings.s_min_nm])
    hi = np.array([np.inf, np.inf, settings.l0_max_nm, settings.s_max_nm])
    params = np.stack([p0, p1, p2 * c.xw + c.xc, p3 * c.xw])
    conv = np.zeros(n, dtype=bool)
    nfev = np.zeros(n, dtype=np.int64)
    for i in np.flatnonzero(valid & ~flat):
        yi = y[:, i]

        def fun(p, yi=yi):
            return p[0] + p[1] * (1.0 - np.exp(-((wl - p[2]) ** 2) / (2 * p[3] ** 2))) - yi

        def jac(p):
            t = (wl - p[2]) / p[3]
            g = np.exp(-0.5 * t * t)
            u = p[1] * g / p[3]
            return np.stack([np.ones_like(g), 1.0 - g, -u * t, -u * t * t], axis=1)

        start = np.clip(params[:, i], lo, hi)
        start = np.where(start <= lo, lo + 1e-9 * np.maximum(1.0, np.abs(lo)), start)  # trf needs interior
        res = least_squares(fun, start, jac=jac, bounds=(lo, hi), method="trf", loss=settings.loss,
                            f_scale=settings.f_scale, ftol=tol, xtol=tol, gtol=tol, max_nfev=max_nfev,
                            x_scale=np.array([0.1, 0.1, c.xw, c.xw]))
        params[:, i] = res.x
        conv[i] = res.status > 0
        nfev[i] = res.nfev
    p = np.stack([params[0], params[1], (params[2] - c.xc) / c.xw, params[3] / c.xw])
    rss = ((model(wl, params[0] + params[1], params[0], params[2], params[3]) - y) ** 2).sum(0)
    # trf keeps iterates strictly inside the box: "on a bound" means within 1e-7 (normalised)
    out = _finish(p, rss, conv, np.minimum(nfev, 255), valid, flat, c, np.float64, bound_tol=1e-7)
    return IgrmResult(*out)
