<%doc>
common/igrm_varpro.mako: the IGRM fit by variable projection (Golub & Pereyra 1973; Kaufman 1975), the
default solver (igrm.solver = "varpro"; common/igrm_lm.mako is the four-parameter LM it replaces, kept for
the soft-L1 loss and as solver = "lm").

The model rho = rmin + depth (1 - g), g = exp(-t^2/2), t = (x - L)/S is linear in (rmin, depth): for any
(L, S) their best values solve a 2 x 2 least-squares problem with the box rmin >= c.rmin_lo, depth >= 0
(closed form; when the unconstrained optimum is outside the box, the better of the two edges). The
Levenberg-Marquardt iteration then runs on (L, S) alone, on the projected cost
f(L, S) = min over (rmin, depth) of sum r^2, with Kaufman's Jacobian: the derivative of the residual
with respect to (L, S) at fixed (rmin, depth), projected off the span of the free linear columns (1 and
1 - g). The valley along which the four-parameter LM creeps (rmin, depth and the edge trading off
against each other) is solved exactly at every step, so fits converge in fewer iterations and end
nearer the optimum (measured in bench/igrm_accuracy.py).

Contract: as common/igrm_lm.mako's s2_igrm_fit_<name> (same outputs, statuses, bound bits, condition
estimate, verdict); `iterations` counts trial steps on (L, S). The verdict runs the four-parameter
undamped Gauss-Newton step at the solution (s2_igrm_eval_<name> of igrm_lm.mako, once per pixel).
Needs: everything igrm_lm.mako needs, and igrm_lm.mako's eval_fn, condition_fn and initial guesses
(this file calls them through the `lm` namespace).
</%doc>
<%namespace name="lm" file="igrm_lm.mako"/>

<%def name="mconst(T, v)">((${T.M})(${v}))</%def>

## At (L, S): g and t per band, the best (rmin, depth) in the box, residuals and the cost f.
<%def name="project_fn(T, c, name)">
static inline void s2_igrm_vp_eval_${name}(const ${T.V} *y, const ${T.R} *x, const ${T.V} ybar,
    const ${T.V} L, const ${T.V} S, ${T.V} *g, ${T.V} *t, ${T.V} *r, ${T.V} *a, ${T.V} *d, ${T.V} *f)
{
    const ${T.V} zero = ${T.vlit(0.0)};
    const ${T.V} inv_s = ${T.vlit(1.0)} / S;
    ${T.V} hsum = zero;
% for i in range(c.n_bands):
    t[${i}] = (x[${i}] - L) * inv_s;
    g[${i}] = ${lm.exp_call(T, c, f"t[{i}] * t[{i}] * {T.lit(-0.5)}")};
    hsum += ${T.lit(1.0)} - g[${i}];
% endfor
    /* unconstrained optimum, centred: depth = sum hc (y - ybar) / sum hc^2, rmin = ybar - depth hbar */
    const ${T.V} hbar = hsum * ${T.lit(1.0 / c.n_bands)};
    ${T.V} shh = zero, shy = zero, sh2 = zero, shy0 = zero;
% for i in range(c.n_bands):
    {
        const ${T.V} h = ${T.lit(1.0)} - g[${i}];
        const ${T.V} hc = h - hbar;
        shh += hc * hc;
        shy += hc * (y[${i}] - ybar);
        sh2 += h * h;
        shy0 += h * (y[${i}] - ${T.lit(c.rmin_lo)});
    }
% endfor
    const ${T.M} spread = shh > ${T.vlit(1e-30 if T.double else 1e-20)};
    ${T.V} dd = spread ? shy / shh : zero;
    ${T.V} aa = ybar - dd * hbar;
    const ${T.M} inside = (dd >= zero) & (aa >= ${T.vlit(c.rmin_lo)});
    if (!(${lm.all_lanes(T, "inside")})) {
        /* edges of the box: depth = 0 (rmin = max(ybar, lo)), and rmin = lo (depth = max(.., 0)) */
        const ${T.V} a1 = ybar > ${T.vlit(c.rmin_lo)} ? ybar : ${T.vlit(c.rmin_lo)};
        ${T.V} d2 = sh2 > zero ? shy0 / sh2 : zero;
        d2 = d2 > zero ? d2 : zero;
        ${T.V} c1 = zero, c2 = zero;
% for i in range(c.n_bands):
        {
            const ${T.V} h = ${T.lit(1.0)} - g[${i}];
            const ${T.V} r1 = a1 - y[${i}];
            const ${T.V} r2 = ${T.lit(c.rmin_lo)} + d2 * h - y[${i}];
            c1 += r1 * r1;
            c2 += r2 * r2;
        }
% endfor
        const ${T.M} edge2 = c2 < c1;
        aa = inside ? aa : (edge2 ? ${T.vlit(c.rmin_lo)} : a1);
        dd = inside ? dd : (edge2 ? d2 : zero);
    }
    ${T.V} cost = zero;
% for i in range(c.n_bands):
    r[${i}] = aa + dd * (${T.lit(1.0)} - g[${i}]) - y[${i}];
    cost += r[${i}] * r[${i}];
% endfor
    *a = aa;
    *d = dd;
    *f = cost;
}

## Kaufman's Jacobian at the point of the last s2_igrm_vp_eval: (J^T J) on (L, S) and J^T r.
static inline void s2_igrm_vp_jac_${name}(const ${T.V} *g, const ${T.V} *t, const ${T.V} *r,
    const ${T.V} a, const ${T.V} d, const ${T.V} S, ${T.V} *A00, ${T.V} *A01, ${T.V} *A11, ${T.V} *b0, ${T.V} *b1)
{
    const ${T.V} zero = ${T.vlit(0.0)};
    const ${T.V} scale = -d / S;
    ${T.V} jl[${c.n_bands}], js[${c.n_bands}], h[${c.n_bands}];
    ${T.V} ml = zero, ms = zero, hbar = zero;
% for i in range(c.n_bands):
    jl[${i}] = scale * g[${i}] * t[${i}];
    js[${i}] = jl[${i}] * t[${i}];
    h[${i}] = ${T.lit(1.0)} - g[${i}];
    ml += jl[${i}]; ms += js[${i}]; hbar += h[${i}];
% endfor
    /* the free linear columns: 1 (rmin above its bound) and 1 - g (depth above 0) */
    const ${T.M} free_a = a > ${T.vlit(c.rmin_lo)};
    const ${T.M} free_d = d > zero;
    ml = free_a ? ml * ${T.lit(1.0 / c.n_bands)} : zero;
    ms = free_a ? ms * ${T.lit(1.0 / c.n_bands)} : zero;
    hbar = free_a ? hbar * ${T.lit(1.0 / c.n_bands)} : zero;
    ${T.V} hh = zero, hl = zero, hs = zero;
% for i in range(c.n_bands):
    h[${i}] -= hbar;
    hh += h[${i}] * h[${i}];
    hl += h[${i}] * jl[${i}];
    hs += h[${i}] * js[${i}];
% endfor
    const ${T.M} use_h = free_d & (hh > ${T.vlit(1e-30 if T.double else 1e-20)});
    const ${T.V} kl = use_h ? hl / hh : zero;
    const ${T.V} ks = use_h ? hs / hh : zero;
    ${T.V} s00 = zero, s01 = zero, s11 = zero, sr0 = zero, sr1 = zero;
% for i in range(c.n_bands):
    {
        const ${T.V} pl = jl[${i}] - ml - kl * h[${i}];
        const ${T.V} ps = js[${i}] - ms - ks * h[${i}];
        s00 += pl * pl; s01 += pl * ps; s11 += ps * ps;
        sr0 += jl[${i}] * r[${i}]; sr1 += js[${i}] * r[${i}];
    }
% endfor
    *A00 = s00; *A01 = s01; *A11 = s11; *b0 = sr0; *b1 = sr1;
}
</%def>

<%def name="igrm_fit(T, c, name, T1=None)">
#include "common/s2_status.clh"
${lm.eval_fn(T, c, name)}
${lm.condition_fn(T, name)}
${project_fn(T, c, name)}
static inline void s2_igrm_fit_${name}(const ${T.V} *yin, const ${T.R} *wavelength_nm, ${T.V} *out,
    ${T.M} *status, ${T.M} *iterations, ${T.M} *bounds)
{
    const ${T.V} zero = ${T.vlit(0.0)};
    const ${T.V} one = ${T.vlit(1.0)};
    ${T.R} x[${c.n_bands}];
    ${T.V} y[${c.n_bands}];
    ${T.M} valid = ${mconst(T, 0)} == ${mconst(T, 0)};
% for i in range(c.n_bands):
    x[${i}] = (wavelength_nm[${i}] - ${T.lit(c.xc)}) * ${T.lit(1.0 / c.xw)};
    /* NaN and +-inf fail both comparisons */
    valid = valid & (yin[${i}] <= ${T.vlit(c.max_abs)}) & (yin[${i}] >= ${T.vlit(-c.max_abs)});
% endfor
    ${T.V} ybar = zero;
% for i in range(c.n_bands):
    y[${i}] = valid ? yin[${i}] : zero;
    ybar += y[${i}];
% endfor
    ybar *= ${T.lit(1.0 / c.n_bands)};

    ${T.V} p0, p1, p2, p3, depth;
% if c.init == "grid":
${lm.init_grid(T, T1, c)}
% else:
${lm.init_data(T, c)}
% endif
    const ${T.M} flat = depth <= ${T.vlit(c.depth_min)};
    ${T.M} done = flat | !valid;
    ${T.M} stopped = ${mconst(T, 0)};
    ${T.M} it = ${mconst(T, 0)};
    ${T.V} lam = ${T.vlit(c.lam0)};

    /* the point (L, S) = (p2, p3), its linear parameters (p0, p1), cost, Jacobian */
    ${T.V} g[${c.n_bands}], t[${c.n_bands}], r[${c.n_bands}];
    ${T.V} f, a0, d0;
    s2_igrm_vp_eval_${name}(y, x, ybar, p2, p3, g, t, r, &a0, &d0, &f);
    /* a flat spectrum never iterates and reports the initial guess (the data's range), as the LM does */
    p0 = flat ? p0 : a0;
    p1 = flat ? p1 : d0;
    ${T.V} A00, A01, A11, b0, b1;
    s2_igrm_vp_jac_${name}(g, t, r, p0, p1, p3, &A00, &A01, &A11, &b0, &b1);

    for (int k = 0; k < ${c.max_iter}; ++k) {
        if (${lm.all_lanes(T, "done")})
            break;
        const ${T.M} live = !done;
        /* active bounds of L and S: on the bound with the gradient pointing outwards */
        const ${T.M} act2 = ((p2 <= ${T.vlit(c.lo_l)}) & (b0 > zero)) | ((p2 >= ${T.vlit(c.hi_l)}) & (b0 < zero));
        const ${T.M} act3 = ((p3 <= ${T.vlit(c.lo_s)}) & (b1 > zero)) | ((p3 >= ${T.vlit(c.hi_s)}) & (b1 < zero));
        /* damped 2 x 2 normal equations on the free parameters */
        const ${T.V} damp = one + lam;
        const ${T.V} dfloor = lam * ${T.lit(c.diag_eps)};
        const ${T.V} m00 = act2 ? one : A00 * damp + dfloor;
        const ${T.V} m11 = act3 ? one : A11 * damp + dfloor;
        const ${T.V} m01 = (act2 | act3) ? zero : A01;
        const ${T.V} r0 = act2 ? zero : -b0;
        const ${T.V} r1 = act3 ? zero : -b1;
        const ${T.V} det = m00 * m11 - m01 * m01;
        const ${T.M} ok = det > ${T.lit(c.pivot_rel)} * m00 * m11;
        const ${T.V} inv_det = one / (ok ? det : one);
        ${T.V} q2 = p2 + (r0 * m11 - m01 * r1) * inv_det;
        ${T.V} q3 = p3 + (m00 * r1 - m01 * r0) * inv_det;
        q2 = q2 < ${T.vlit(c.lo_l)} ? ${T.vlit(c.lo_l)} : (q2 > ${T.vlit(c.hi_l)} ? ${T.vlit(c.hi_l)} : q2);
        q3 = q3 < ${T.vlit(c.lo_s)} ? ${T.vlit(c.lo_s)} : (q3 > ${T.vlit(c.hi_s)} ? ${T.vlit(c.hi_s)} : q3);
        /* the projected cost there */
        ${T.V} gq[${c.n_bands}], tq[${c.n_bands}], rq[${c.n_bands}];
        ${T.V} q0, q1, fn;
        s2_igrm_vp_eval_${name}(y, x, ybar, q2, q3, gq, tq, rq, &q0, &q1, &fn);
        const ${T.M} acc = live & ok & (fn < f);
        ${T.M} small = ${mconst(T, 0)} == ${mconst(T, 0)};
% for q, p in [("q0", "p0"), ("q1", "p1"), ("q2", "p2"), ("q3", "p3")]:
        {
            const ${T.V} step = ${q} - ${p};
            const ${T.V} mag = ${p} < zero ? -${p} : ${p};
            small = small & (step <= ${T.lit(c.xtol)} * (mag + ${T.lit(0.1)}))
                          & (step >= -${T.lit(c.xtol)} * (mag + ${T.lit(0.1)}));
        }
% endfor
        const ${T.M} fsmall = (f - fn) <= ${T.lit(c.ftol)} * f;
        const ${T.M} tiny = (acc & fsmall & small) | (live & !acc & ok & small);
        /* accept or reject */
        p0 = acc ? q0 : p0; p1 = acc ? q1 : p1; p2 = acc ? q2 : p2; p3 = acc ? q3 : p3;
        f = acc ? fn : f;
% for i in range(c.n_bands):
        g[${i}] = acc ? gq[${i}] : g[${i}]; t[${i}] = acc ? tq[${i}] : t[${i}]; r[${i}] = acc ? rq[${i}] : r[${i}];
% endfor
        if (!(${lm.all_lanes(T, "!acc")})) {
            ${T.V} n00, n01, n11, nb0, nb1;
            s2_igrm_vp_jac_${name}(g, t, r, p0, p1, p3, &n00, &n01, &n11, &nb0, &nb1);
            A00 = acc ? n00 : A00; A01 = acc ? n01 : A01; A11 = acc ? n11 : A11;
            b0 = acc ? nb0 : b0; b1 = acc ? nb1 : b1;
        }
        lam = acc ? lam * ${T.lit(c.lam_down)} : (live ? lam * ${T.lit(c.lam_up)} : lam);
        lam = lam < ${T.vlit(c.lam_min)} ? ${T.vlit(c.lam_min)} : lam;
        /* stopping rules at the point kept */
        const ${T.V} gf = f * ${T.lit(c.gtol**2)};
        const ${T.M} n2 = ((p2 <= ${T.vlit(c.lo_l)}) & (b0 > zero)) | ((p2 >= ${T.vlit(c.hi_l)}) & (b0 < zero));
        const ${T.M} n3 = ((p3 <= ${T.vlit(c.lo_s)}) & (b1 > zero)) | ((p3 >= ${T.vlit(c.hi_s)}) & (b1 < zero));
        const ${T.M} gsmall = (n2 | (b0 * b0 <= gf * A00)) & (n3 | (b1 * b1 <= gf * A11));
        const ${T.M} stop = live & ((f <= ${T.vlit(c.f_abs)}) | gsmall | tiny | (lam > ${T.vlit(c.lam_max)}));
        it = it + (live ? ${mconst(T, 1)} : ${mconst(T, 0)});
        done = done | stop;
        stopped = stopped | stop;
    }

    /* the four-parameter system at the solution: verdict, condition estimate, RSS */
    ${T.V} e[16];
    s2_igrm_eval_${name}(y, x, p0, p1, p2, p3, e);
    const ${T.V} rss = e[1];
    const ${T.V} a00 = e[2], a01 = e[3], a02 = e[4], a03 = e[5], a11 = e[6], a12 = e[7], a13 = e[8];
    const ${T.V} a22 = e[9], a23 = e[10], a33 = e[11];
    const ${T.V} c0 = e[12], c1 = e[13], c2 = e[14], c3 = e[15];
    ${T.M} conv;
    {
        const ${T.M} act0 = (p0 <= ${T.vlit(c.rmin_lo)}) & (c0 > zero);
        const ${T.M} act1 = (p1 <= zero) & (c1 > zero);
        const ${T.M} act2 = ((p2 <= ${T.vlit(c.lo_l)}) & (c2 > zero)) | ((p2 >= ${T.vlit(c.hi_l)}) & (c2 < zero));
        const ${T.M} act3 = ((p3 <= ${T.vlit(c.lo_s)}) & (c3 > zero)) | ((p3 >= ${T.vlit(c.hi_s)}) & (c3 < zero));
        ${T.V} dg[4];
        const ${T.M} gn_ok = s2_ldl4_solve_${T.suffix}(
            act0 ? one : a00, (act0 | act1) ? zero : a01, (act0 | act2) ? zero : a02, (act0 | act3) ? zero : a03,
            act1 ? one : a11, (act1 | act2) ? zero : a12, (act1 | act3) ? zero : a13,
            act2 ? one : a22, (act2 | act3) ? zero : a23,
            act3 ? one : a33,
            act0 ? zero : -c0, act1 ? zero : -c1, act2 ? zero : -c2, act3 ? zero : -c3, dg);
        const ${T.V} dlp = dg[2] + dg[3];
        const ${T.M} near = gn_ok & (dlp <= ${T.vlit(c.lp_tol)}) & (dlp >= ${T.vlit(-c.lp_tol)});
        conv = (f <= ${T.vlit(c.f_abs)}) | near;
    }
${lm.verdict_and_outputs(T, c, name)}
}
</%def>
