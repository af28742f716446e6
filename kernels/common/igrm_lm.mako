<%doc>
common/igrm_lm.mako: the batched IGRM Levenberg-Marquardt fit as `static inline` device functions,
for igrm.cl.mako and for fused kernels (gather -> ... -> IGRM -> metric) that call it per pixel.

Model (Segl et al. 2012, eq. 2), per pixel:
    rho(l) = rmax - (rmax - rmin) exp(-(l - l0)^2 / (2 s^2))
Fitted parameters, in normalised units (xc = c.xc nm, xw = c.xw nm):
    p0 = rmin >= c.rmin_lo, p1 = depth = rmax - rmin >= 0, p2 = L = (l0 - xc)/xw, p3 = S = s/xw
    rho = p0 + p1 (1 - g),  g = exp(-t^2/2),  t = (x - L)/S
so that rmax >= rmin is the box bound depth >= 0, every bound is a box bound, and all four
parameters are O(1).

Contract of  void s2_igrm_fit_<name>(const V *y, const R *wavelength_nm, V *out,
                                      M *status, M *iterations, M *bounds)
  y             [n_bands] V   band reflectances; lane k of every V is pixel k (T.lanes pixels)
  wavelength_nm [n_bands] R   band centres in nm, the same for all lanes (any order is allowed,
                              but the data initial guess assumes increasing wavelength)
  out           [7] V         rmax, rmin, l0 [nm], s [nm], lp = l0 + s [nm], rms residual
                              (sqrt(sum r^2 / n_bands), reflectance, plain least squares even
                              with the soft-L1 loss), log10 of the fit's condition estimate (below);
                              all 0 for INVALID lanes, always finite
  status        M             common/s2_status.clh: S2_OK (converged), S2_ITERATION_LIMIT,
                              S2_DEGENERATE, S2_INVALID, S2_STALLED
  iterations    M             LM trial steps taken (accepted or rejected)
  bounds        M             bit 1 l0 at lower bound, 2 l0 at upper, 4 s at lower, 8 s at upper,
                              16 depth at 0 (rmax = rmin), 32 rmin at its lower bound;
                              0 for INVALID lanes
Render-time constants: everything in `c`, an s2cl.retrieve.igrm_settings.KernelConfig (bounds, tolerances, loss,
initial guess, iteration limit, exp choice); see s2cl/retrieve/igrm_settings.py for their meaning and defaults.
Needs (emitted by the including template): s2_exp_neg_<T.suffix> (exp="poly"),
s2_exp_neg_<suffix of 1 lane> (init="grid", exp="poly"), s2_rsqrt_<T.suffix> (loss="soft_l1"),
s2_ldl4_solve_<T.suffix>.

Algorithm (one iteration, every lane in lock-step, finished lanes frozen by masks):
  1. active set: a parameter that sits on its bound with the gradient pointing outwards
     is held (its row and column of the normal matrix become the identity, its step 0);
  2. solve (J^T W J + lam (diag(J^T W J) + eps)) dp = -J^T W r by LDL^T, project p + dp on the box;
  3. evaluate cost, J^T W J and J^T W r at the trial point in one pass over the bands (the exp
     is the only transcendental); accept if the cost decreased (lam *= down) else lam *= up;
  4. stop when: cost <= f_abs (exact fit at working precision), or the scaled gradient is below
     gtol (MINPACK's test, on free parameters, at the point kept), or an accepted step changed the
     cost by <= ftol relative AND every parameter by <= xtol (|p| + 0.1), or a rejected step was that
     small, or lam > lam_max.
Verdict (after the loop, every lane with a red edge): CONVERGED (S2_OK) when the fit is exact, or
when the undamped Gauss-Newton step from the returned point (the model's estimate of where the
optimum is; free parameters only) moves lp = l0 + s by at most c.lp_tol (igrm.lp_tol_nm, 1e-3 nm):
the returned lp is that close to the optimum. Otherwise STALLED if a stopping rule fired (in float32
the cost cannot resolve a flat valley, and rounding in J^T r, amplified by the valley's conditioning,
makes that step large: the fit stopped where the working precision ran out, possibly nanometres from
the float64 optimum), else ITERATION_LIMIT. A stall is never called converged. Measured on sweep
pixels of Lib1 and Lib2 (float32): 99.99 % of CONVERGED fits are within 1e-3 nm of the float64
optimum, against 1-15 % of the others.
Condition estimate (out[6]): J^T W J at the solution, columns scaled to a unit diagonal; its LDL^T
pivots d'_i lie in (0, 1] and 1 / min d'_i is a lower bound of that matrix's condition number (the
2-norm condition of the scaled Jacobian is its square root): out[6] = 0.5 log10(1 / min d'_i),
capped at 12 (singular, e.g. two bands on one wavelength). A design whose bands cannot pin the
four parameters shows a large value.
</%doc>

<%def name="exp_call(T, c, e)">\
% if c.exp == "poly":
s2_exp_neg_${T.suffix}(${e})\
% else:
exp(${e})\
% endif
</%def>

<%def name="all_lanes(T, m)">\
% if T.lanes == 1:
(${m})\
% else:
(${" & ".join(f"({m}).s{'0123456789abcdef'[k]}" for k in range(T.lanes))})\
% endif
</%def>

<%def name="mconst(T, v)">((${T.M})(${v}))</%def>

## One pass over the bands at parameters (q0..q3): cost, plain residual sum of squares, the
## upper triangle of J^T W J and J^T W r (W = soft-L1 weights, or 1).
<%def name="eval_fn(T, c, name)">
static inline void s2_igrm_eval_${name}(const ${T.V} *y, const ${T.R} *x,
    const ${T.V} q0, const ${T.V} q1, const ${T.V} q2, const ${T.V} q3, ${T.V} *e)
{
    const ${T.V} zero = ${T.vlit(0.0)};
    const ${T.V} inv_s = ${T.vlit(1.0)} / q3;
    const ${T.V} rmax = q0 + q1;
    ${T.V} f = zero, rss = zero, sh = zero, s1 = zero, s2 = zero, shh = zero, sh1 = zero, sh2 = zero;
    ${T.V} s11 = zero, s12 = zero, s22 = zero, sr = zero, shr = zero, s1r = zero, s2r = zero;
% if c.loss == "soft_l1":
    ${T.V} sw = zero;
% endif
% for i in range(c.n_bands):
    {
        /* residual r = rmin + depth (1 - g) - y; Jacobian row (1, h, -w1, -w2) */
        const ${T.V} t = (x[${i}] - q2) * inv_s;
        const ${T.V} g = ${exp_call(T, c, f"t * t * {T.lit(-0.5)}")};
        const ${T.V} h = ${T.lit(1.0)} - g;
        const ${T.V} r = rmax - q1 * g - y[${i}];
        const ${T.V} w1 = q1 * g * inv_s * t;
        const ${T.V} w2 = w1 * t;
  % if c.loss == "soft_l1":
        const ${T.V} z = r * r * ${T.lit(1.0 / c.f_scale**2)};
        const ${T.V} opz = ${T.lit(1.0)} + z;
        const ${T.V} w = s2_rsqrt_${T.suffix}(opz);
        f += z / (opz * w + ${T.lit(1.0)});
        rss += r * r;
        const ${T.V} wh = w * h, w1w = w * w1, w2w = w * w2, wr = w * r;
        sw += w; sh += wh; s1 += w1w; s2 += w2w;
        shh += wh * h; sh1 += wh * w1; sh2 += wh * w2;
        s11 += w1w * w1; s12 += w1w * w2; s22 += w2w * w2;
        sr += wr; shr += wh * r; s1r += w1w * r; s2r += w2w * r;
  % else:
        f += r * r;
        sh += h; s1 += w1; s2 += w2;
        shh += h * h; sh1 += h * w1; sh2 += h * w2;
        s11 += w1 * w1; s12 += w1 * w2; s22 += w2 * w2;
        sr += r; shr += h * r; s1r += w1 * r; s2r += w2 * r;
  % endif
    }
% endfor
% if c.loss == "soft_l1":
    e[0] = f * ${T.lit(2.0 * c.f_scale**2)};
    e[1] = rss;
    e[2] = sw;
% else:
    e[0] = f;
    e[1] = f;
    e[2] = ${T.vlit(float(c.n_bands))};
% endif
    e[3] = sh; e[4] = -s1; e[5] = -s2;
    e[6] = shh; e[7] = -sh1; e[8] = -sh2;
    e[9] = s11; e[10] = s12; e[11] = s22;
    e[12] = sr; e[13] = shr; e[14] = -s1r; e[15] = -s2r;
}
</%def>

## Deterministic initial guess from the data: rmin, l0 at the smallest band value (rmin and l0
## clipped into their bounds), rmax the largest value, s from the first half-depth crossing after the minimum
## (linear interpolation; s = (l_half - l0) / sqrt(2 ln 2)), else s_guess; s clipped to its bounds.
<%def name="init_data(T, c)">
    {
        ${T.V} ymin = y[0], ymax = y[0], xmin = ${T.vlit(0.0)} + x[0];
% for i in range(1, c.n_bands):
        {
            const ${T.M} lt = y[${i}] < ymin;
            ymin = lt ? y[${i}] : ymin;
            xmin = lt ? (${T.vlit(0.0)} + x[${i}]) : xmin;
            ymax = y[${i}] > ymax ? y[${i}] : ymax;
        }
% endfor
        depth = ymax - ymin;
        const ${T.V} yhalf = ymin + depth * ${T.lit(0.5)};
        ${T.V} xhalf = ${T.vlit(0.0)};
        ${T.M} found = ${mconst(T, 0)};
% for i in range(1, c.n_bands):
        {
            const ${T.M} cross = !found & (xmin <= x[${i - 1}]) & (y[${i - 1}] < yhalf) & (y[${i}] >= yhalf);
            const ${T.V} xi = x[${i - 1}] + (yhalf - y[${i - 1}]) * (x[${i}] - x[${i - 1}]) / (y[${i}] - y[${i - 1}]);
            xhalf = cross ? xi : xhalf;
            found = found | cross;
        }
% endfor
        p2 = xmin < ${T.vlit(c.lo_l)} ? ${T.vlit(c.lo_l)} : (xmin > ${T.vlit(c.hi_l)} ? ${T.vlit(c.hi_l)} : xmin);
        p3 = found ? (xhalf - p2) * ${T.lit(1.0 / (2.0 * 0.6931471805599453) ** 0.5)} : ${T.vlit(c.s_guess)};
        p3 = p3 < ${T.vlit(c.lo_s)} ? ${T.vlit(c.lo_s)} : (p3 > ${T.vlit(c.hi_s)} ? ${T.vlit(c.hi_s)} : p3);
        p0 = ymin < ${T.vlit(c.rmin_lo)} ? ${T.vlit(c.rmin_lo)} : ymin;
        p1 = ymax - p0;
    }
</%def>

## Deterministic initial guess by variable projection on a grid of (l0, s): for each candidate
## the best (rmax, depth >= 0) is a 2x2 linear least-squares problem; the candidate with the
## smallest cost wins (first one on ties). With uniform wavelengths the Gaussian values are the
## same for all lanes, so they are scalars here; only sum g y is per lane.
<%def name="init_grid(T, T1, c)">
    {
        ${T.V} ymin = y[0], ymax = y[0], sy = zero, syy = zero;
% for i in range(c.n_bands):
        ymin = y[${i}] < ymin ? y[${i}] : ymin;
        ymax = y[${i}] > ymax ? y[${i}] : ymax;
        sy += y[${i}];
        syy += y[${i}] * y[${i}];
% endfor
        depth = ymax - ymin;
        ${T.V} best = ${T.vlit(3.0e38 if not T.double else 1.0e300)};
        p0 = sy * ${T.lit(1.0 / c.n_bands)};   /* rmax of the best candidate until the end */
        p1 = zero;
        p2 = ${T.vlit(c.grid_l[0])};
        p3 = ${T.vlit(c.grid_s[0])};
% for gl in c.grid_l:
  % for gs in c.grid_s:
        {
            ${T.R} g[${c.n_bands}];
            ${T.R} sg = ${T.lit(0.0)}, sgg = ${T.lit(0.0)};
    % for i in range(c.n_bands):
            {
                const ${T.R} t = (x[${i}] - ${T.lit(gl)}) * ${T.lit(1.0 / gs)};
      % if c.exp == "poly":
                g[${i}] = s2_exp_neg_${T1.suffix}(t * t * ${T.lit(-0.5)});
      % else:
                g[${i}] = exp(t * t * ${T.lit(-0.5)});
      % endif
                sg += g[${i}];
                sgg += g[${i}] * g[${i}];
            }
    % endfor
            const ${T.R} den = sgg - sg * sg * ${T.lit(1.0 / c.n_bands)};
            if (den > ${T.lit(1e-12 if T.double else 1e-6)} * sgg) {
                const ${T.R} inv_den = ${T.lit(1.0)} / den;
                ${T.V} sgy = zero;
    % for i in range(c.n_bands):
                sgy += g[${i}] * y[${i}];
    % endfor
                ${T.V} d = (sy * sg * ${T.lit(1.0 / c.n_bands)} - sgy) * inv_den;
                d = d < zero ? zero : d;
                const ${T.V} rm = (sy + d * sg) * ${T.lit(1.0 / c.n_bands)};
                const ${T.V} cost = syy - ${T.lit(2.0)} * rm * sy + ${T.lit(2.0)} * d * sgy
                    + ${T.lit(float(c.n_bands))} * rm * rm - ${T.lit(2.0)} * rm * d * sg + d * d * sgg;
                const ${T.M} better = cost < best;
                best = better ? cost : best;
                p0 = better ? rm : p0;
                p1 = better ? d : p1;
                p2 = better ? ${T.vlit(gl)} : p2;
                p3 = better ? ${T.vlit(gs)} : p3;
            }
        }
  % endfor
% endfor
        p0 = p0 - p1;
        p1 = p0 < ${T.vlit(c.rmin_lo)} ? p1 + p0 - ${T.vlit(c.rmin_lo)} : p1;
        p1 = p1 < zero ? zero : p1;
        p0 = p0 < ${T.vlit(c.rmin_lo)} ? ${T.vlit(c.rmin_lo)} : p0;
    }
</%def>

## 0.5 log10(1 / min d'_i) of the column-scaled J^T W J (see the contract), capped at 12.
<%def name="condition_fn(T, name)">
static inline ${T.V} s2_igrm_log10_condition_${name}(const ${T.V} a00, const ${T.V} a01, const ${T.V} a02,
    const ${T.V} a03, const ${T.V} a11, const ${T.V} a12, const ${T.V} a13, const ${T.V} a22, const ${T.V} a23,
    const ${T.V} a33)
{
    /* pivots of the unscaled matrix; pivot i of the scaled one is d_i / a_ii */
    const ${T.V} d0 = a00;
    const ${T.V} l10 = a01 / d0, l20 = a02 / d0, l30 = a03 / d0;
    const ${T.V} d1 = a11 - l10 * a01;
    const ${T.V} t21 = a12 - l20 * a01, t31 = a13 - l30 * a01;
    const ${T.V} l21 = t21 / d1, l31 = t31 / d1;
    const ${T.V} d2 = a22 - l20 * a02 - l21 * t21;
    const ${T.V} t32 = a23 - l30 * a02 - l31 * t21;
    const ${T.V} d3 = a33 - l30 * a03 - l31 * t31 - (t32 / d2) * t32;
    ${T.V} m = d1 / a11;
    m = d2 / a22 < m ? d2 / a22 : m;
    m = d3 / a33 < m ? d3 / a33 : m;
    /* NaN (a zero column) and tiny pivots fail this test: capped */
    const ${T.M} ok = (m > ${T.vlit(1e-24)}) & (d0 > ${T.vlit(0.0)});
    const ${T.V} v = ${T.lit(-0.5)} * log10(ok ? m : ${T.vlit(1.0)});
    return ok ? (v < ${T.vlit(12.0)} ? v : ${T.vlit(12.0)}) : ${T.vlit(12.0)};
}
</%def>

<%def name="igrm_fit(T, c, name, T1=None)">
#include "common/s2_status.clh"
${eval_fn(T, c, name)}
${condition_fn(T, name)}
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
% for i in range(c.n_bands):
    y[${i}] = valid ? yin[${i}] : zero;
% endfor

    ${T.V} p0, p1, p2, p3, depth;
% if c.init == "grid":
${init_grid(T, T1, c)}
% else:
${init_data(T, c)}
% endif
    const ${T.M} flat = depth <= ${T.vlit(c.depth_min)};
    ${T.M} done = flat | !valid;
    ${T.M} conv = ${mconst(T, 0)};
    ${T.M} stopped = ${mconst(T, 0)};
    ${T.M} it = ${mconst(T, 0)};
    ${T.V} lam = ${T.vlit(c.lam0)};

    ${T.V} e[16];
    s2_igrm_eval_${name}(y, x, p0, p1, p2, p3, e);
    ${T.V} f = e[0], rss = e[1];
    ${T.V} a00 = e[2], a01 = e[3], a02 = e[4], a03 = e[5], a11 = e[6], a12 = e[7], a13 = e[8];
    ${T.V} a22 = e[9], a23 = e[10], a33 = e[11], b0 = e[12], b1 = e[13], b2 = e[14], b3 = e[15];

    for (int k = 0; k < ${c.max_iter}; ++k) {
        if (${all_lanes(T, "done")})
            break;
        const ${T.M} live = !done;
        /* 1. active set */
        const ${T.M} act0 = (p0 <= ${T.vlit(c.rmin_lo)}) & (b0 > zero);
        const ${T.M} act1 = (p1 <= zero) & (b1 > zero);
        const ${T.M} act2 = ((p2 <= ${T.vlit(c.lo_l)}) & (b2 > zero)) | ((p2 >= ${T.vlit(c.hi_l)}) & (b2 < zero));
        const ${T.M} act3 = ((p3 <= ${T.vlit(c.lo_s)}) & (b3 > zero)) | ((p3 >= ${T.vlit(c.hi_s)}) & (b3 < zero));
        /* 2. damped, reduced normal equations */
        const ${T.V} damp = one + lam;
        const ${T.V} dfloor = lam * ${T.lit(c.diag_eps)};
        ${T.V} dp[4];
        const ${T.M} ok = s2_ldl4_solve_${T.suffix}(
            act0 ? one : a00 * damp + dfloor,
            (act0 | act1) ? zero : a01, (act0 | act2) ? zero : a02, (act0 | act3) ? zero : a03,
            act1 ? one : a11 * damp + dfloor,
            (act1 | act2) ? zero : a12, (act1 | act3) ? zero : a13,
            act2 ? one : a22 * damp + dfloor,
            (act2 | act3) ? zero : a23,
            act3 ? one : a33 * damp + dfloor,
            act0 ? zero : -b0, act1 ? zero : -b1, act2 ? zero : -b2, act3 ? zero : -b3, dp);
        /* projected trial point */
        ${T.V} q0 = p0 + dp[0];
        q0 = q0 < ${T.vlit(c.rmin_lo)} ? ${T.vlit(c.rmin_lo)} : q0;
        ${T.V} q1 = p1 + dp[1];
        q1 = q1 < zero ? zero : q1;
        ${T.V} q2 = p2 + dp[2];
        q2 = q2 < ${T.vlit(c.lo_l)} ? ${T.vlit(c.lo_l)} : (q2 > ${T.vlit(c.hi_l)} ? ${T.vlit(c.hi_l)} : q2);
        ${T.V} q3 = p3 + dp[3];
        q3 = q3 < ${T.vlit(c.lo_s)} ? ${T.vlit(c.lo_s)} : (q3 > ${T.vlit(c.hi_s)} ? ${T.vlit(c.hi_s)} : q3);
        /* 3. evaluate there */
        s2_igrm_eval_${name}(y, x, q0, q1, q2, q3, e);
        const ${T.V} fn = e[0];
        const ${T.M} acc = live & ok & (fn < f);
        /* step size and cost change of this trial (before the state moves) */
        ${T.M} small = ${mconst(T, 0)} == ${mconst(T, 0)};
% for j, (q, p) in enumerate([("q0", "p0"), ("q1", "p1"), ("q2", "p2"), ("q3", "p3")]):
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
        f = acc ? fn : f; rss = acc ? e[1] : rss;
        a00 = acc ? e[2] : a00; a01 = acc ? e[3] : a01; a02 = acc ? e[4] : a02; a03 = acc ? e[5] : a03;
        a11 = acc ? e[6] : a11; a12 = acc ? e[7] : a12; a13 = acc ? e[8] : a13;
        a22 = acc ? e[9] : a22; a23 = acc ? e[10] : a23; a33 = acc ? e[11] : a33;
        b0 = acc ? e[12] : b0; b1 = acc ? e[13] : b1; b2 = acc ? e[14] : b2; b3 = acc ? e[15] : b3;
        lam = acc ? lam * ${T.lit(c.lam_down)} : (live ? lam * ${T.lit(c.lam_up)} : lam);
        lam = lam < ${T.vlit(c.lam_min)} ? ${T.vlit(c.lam_min)} : lam;
        /* 4. stopping rules at the point kept */
        const ${T.V} gf = f * ${T.lit(c.gtol**2)};
        const ${T.M} n0 = (p0 <= ${T.vlit(c.rmin_lo)}) & (b0 > zero);
        const ${T.M} n1 = (p1 <= zero) & (b1 > zero);
        const ${T.M} n2 = ((p2 <= ${T.vlit(c.lo_l)}) & (b2 > zero)) | ((p2 >= ${T.vlit(c.hi_l)}) & (b2 < zero));
        const ${T.M} n3 = ((p3 <= ${T.vlit(c.lo_s)}) & (b3 > zero)) | ((p3 >= ${T.vlit(c.hi_s)}) & (b3 < zero));
        const ${T.M} gsmall = (n0 | (b0 * b0 <= gf * a00)) & (n1 | (b1 * b1 <= gf * a11))
                            & (n2 | (b2 * b2 <= gf * a22)) & (n3 | (b3 * b3 <= gf * a33));
        const ${T.M} stop = live & ((f <= ${T.vlit(c.f_abs)}) | gsmall | tiny | (lam > ${T.vlit(c.lam_max)}));
        it = it + (live ? ${mconst(T, 1)} : ${mconst(T, 0)});
        done = done | stop;
        stopped = stopped | stop;
    }
    /* verdict: converged where the undamped Gauss-Newton step from the returned point moves lp by at
       most lp_tol (or the fit is exact); otherwise a stall (if stopped) or the iteration limit */
    {
        const ${T.M} act0 = (p0 <= ${T.vlit(c.rmin_lo)}) & (b0 > zero);
        const ${T.M} act1 = (p1 <= zero) & (b1 > zero);
        const ${T.M} act2 = ((p2 <= ${T.vlit(c.lo_l)}) & (b2 > zero)) | ((p2 >= ${T.vlit(c.hi_l)}) & (b2 < zero));
        const ${T.M} act3 = ((p3 <= ${T.vlit(c.lo_s)}) & (b3 > zero)) | ((p3 >= ${T.vlit(c.hi_s)}) & (b3 < zero));
        ${T.V} dg[4];
        const ${T.M} gn_ok = s2_ldl4_solve_${T.suffix}(
            act0 ? one : a00, (act0 | act1) ? zero : a01, (act0 | act2) ? zero : a02, (act0 | act3) ? zero : a03,
            act1 ? one : a11, (act1 | act2) ? zero : a12, (act1 | act3) ? zero : a13,
            act2 ? one : a22, (act2 | act3) ? zero : a23,
            act3 ? one : a33,
            act0 ? zero : -b0, act1 ? zero : -b1, act2 ? zero : -b2, act3 ? zero : -b3, dg);
        const ${T.V} dlp = dg[2] + dg[3];
        const ${T.M} near = gn_ok & (dlp <= ${T.vlit(c.lp_tol)}) & (dlp >= ${T.vlit(-c.lp_tol)});
        conv = (f <= ${T.vlit(c.f_abs)}) | near;
    }

${verdict_and_outputs(T, c, name)}
}
</%def>

## Status, iterations, bound bits and the seven outputs, from the fit's final state (shared with
## common/igrm_varpro.mako): valid, flat, conv, stopped, it, p0..p3, rss and the four-parameter
## J^T W J upper triangle a00..a33 at the returned point.
<%def name="verdict_and_outputs(T, c, name)">
    const ${T.M} shallow = p1 <= ${T.vlit(c.depth_min)};
    *status = !valid ? ${mconst(T, "S2_INVALID")} : ((flat | shallow) ? ${mconst(T, "S2_DEGENERATE")}
              : (conv ? ${mconst(T, "S2_OK")} : (stopped ? ${mconst(T, "S2_STALLED")} : ${mconst(T, "S2_ITERATION_LIMIT")})));
    *iterations = it;
    *bounds = !valid ? ${mconst(T, 0)} :
              ((p2 <= ${T.vlit(c.lo_l)} ? ${mconst(T, 1)} : ${mconst(T, 0)})
             | (p2 >= ${T.vlit(c.hi_l)} ? ${mconst(T, 2)} : ${mconst(T, 0)})
             | (p3 <= ${T.vlit(c.lo_s)} ? ${mconst(T, 4)} : ${mconst(T, 0)})
             | (p3 >= ${T.vlit(c.hi_s)} ? ${mconst(T, 8)} : ${mconst(T, 0)})
             | (p1 <= zero ? ${mconst(T, 16)} : ${mconst(T, 0)})
             | (p0 <= ${T.vlit(c.rmin_lo)} ? ${mconst(T, 32)} : ${mconst(T, 0)}));
    const ${T.V} l0 = p2 * ${T.lit(c.xw)} + ${T.lit(c.xc)};
    const ${T.V} s = p3 * ${T.lit(c.xw)};
    out[0] = valid ? p0 + p1 : zero;
    out[1] = valid ? p0 : zero;
    out[2] = valid ? l0 : zero;
    out[3] = valid ? s : zero;
    out[4] = valid ? l0 + s : zero;
    out[5] = valid ? sqrt(rss * ${T.lit(1.0 / c.n_bands)}) : zero;
    out[6] = valid ? s2_igrm_log10_condition_${name}(a00, a01, a02, a03, a11, a12, a13, a22, a23, a33) : zero;
</%def>
