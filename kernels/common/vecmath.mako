<%doc>
common/vecmath.mako: Mako defs that emit `static inline` math helpers for explicit-lane code.

Why: PoCL 3.0 does not inline builtin math (exp, sqrt, fma, fmin, fmax); one call in a hot loop
costs ~10-20x (`python -m bench.bench_igrm`: the "builtin exp" row). These helpers use only + - * /, comparisons,
the ternary operator and as_* bit casts, which compile to inline vector instructions.

Every def takes T, an s2cl.cl.vectypes.VecTypes (T.V real lanes, T.M comparison mask, T.IB integer
lanes of the same width, T.R scalar real, T.lit(x) literal, T.suffix e.g. "f8"), and emits its
function once per type (#ifndef guard), so several templates may call the same def.

Exports (X = T.suffix):
  T.V  s2_exp_neg_X(T.V a)                  exp(a) for a <= 0 (see exp_neg below)
  T.V  s2_rsqrt_X(T.V a)                     1/sqrt(a) for a >= 1 (Newton from a bit guess)
  T.M  s2_ldl4_solve_X(a00..a33, b0..b3, T.V *x)
                                           solves the symmetric 4x4 system A x = b by LDL^T
                                           (no sqrt); returns the mask of lanes whose pivots
                                           were all > pivot_rel * diagonal (x is 0 elsewhere)
Mako helpers: absv(T, e), maxv(T, a, b), minv(T, a, b), clampv(T, e, lo, hi): expressions.
</%doc>

<%def name="absv(T, e)">((${e}) < ${T.vlit(0.0)} ? -(${e}) : (${e}))</%def>
<%def name="minv(T, a, b)">((${a}) < (${b}) ? (${a}) : (${b}))</%def>
<%def name="maxv(T, a, b)">((${a}) > (${b}) ? (${a}) : (${b}))</%def>

## exp(a), a <= 0. a = n ln2 + f (Cody-Waite, two-part ln2), |f| <= ln2/2; exp(f) by the
## polynomial `coef` (ascending, from s2cl.cl.vecmath.exp_poly_coefficients); 2^n from the exponent
## bits. n comes from the round-to-nearest "magic number" trick (a*log2e + 1.5*2^p - 1.5*2^p),
## exact because no fast-math option is ever passed. Arguments below emin (-87 float, -708
## double) are clamped, so results are normal numbers >= exp(emin): finite, never 0.
<%def name="exp_neg(T, coef, emin, ln2_hi, ln2_lo, magic)">
#ifndef S2_EXP_NEG_${T.suffix.upper()}
#define S2_EXP_NEG_${T.suffix.upper()}
static inline ${T.V} s2_exp_neg_${T.suffix}(${T.V} a)
{
    a = a < ${T.vlit(emin)} ? ${T.vlit(emin)} : a;
    const ${T.V} big = a * ${T.lit(1.4426950408889634)} + ${T.lit(magic)};
    const ${T.V} n = big - ${T.lit(magic)};
    ${T.V} f = a - n * ${T.lit(ln2_hi)};
    f = f - n * ${T.lit(ln2_lo)};
    ${T.V} p = ${T.vlit(coef[-1])};
% for c in reversed(coef[:-1]):
    p = p * f + ${T.lit(c)};
% endfor
    const ${T.IB} e = as_${T.IB}(big) - as_${T.IB}(${T.vlit(magic)});
% if T.double:
    return p * as_${T.V}((e + (${T.IB})1023) << 52);
% else:
    return p * as_${T.V}((e + (${T.IB})127) << 23);
% endif
}
#endif
</%def>

## 1/sqrt(a) for a >= 1 (the soft-L1 weight). Bit-level first guess (relative error < 3.5 %),
## then Newton steps y <- y (3/2 - a y^2 / 2): 3 for float (~1 ulp), 4 for double.
<%def name="rsqrt(T)">
#ifndef S2_RSQRT_${T.suffix.upper()}
#define S2_RSQRT_${T.suffix.upper()}
static inline ${T.V} s2_rsqrt_${T.suffix}(const ${T.V} a)
{
% if T.double:
    ${T.V} y = as_${T.V}((${T.IB})0x5FE6EB50C7B537A9L - (as_${T.IB}(a) >> 1));
    const int steps = 4;
% else:
    ${T.V} y = as_${T.V}((${T.IB})0x5F3759DF - (as_${T.IB}(a) >> 1));
    const int steps = 3;
% endif
    const ${T.V} half_a = a * ${T.lit(0.5)};
    for (int k = 0; k < steps; ++k)
        y = y * (${T.lit(1.5)} - half_a * y * y);
    return y;
}
#endif
</%def>

## Symmetric positive (semi)definite 4x4 solve by LDL^T without square roots. A lane whose
## pivot D_k is not > pivot_rel * a_kk (numerically singular or NaN) gets x = 0 and mask false.
<%def name="ldl4_solve(T, pivot_rel)">
#ifndef S2_LDL4_${T.suffix.upper()}
#define S2_LDL4_${T.suffix.upper()}
static inline ${T.M} s2_ldl4_solve_${T.suffix}(
    const ${T.V} a00, const ${T.V} a01, const ${T.V} a02, const ${T.V} a03,
    const ${T.V} a11, const ${T.V} a12, const ${T.V} a13,
    const ${T.V} a22, const ${T.V} a23, const ${T.V} a33,
    const ${T.V} b0, const ${T.V} b1, const ${T.V} b2, const ${T.V} b3,
    ${T.V} *x)
{
    const ${T.V} one = ${T.vlit(1.0)};
    const ${T.V} d0 = a00;
    const ${T.V} i0 = one / d0;
    const ${T.V} l10 = a01 * i0, l20 = a02 * i0, l30 = a03 * i0;
    const ${T.V} d1 = a11 - l10 * a01;
    const ${T.V} i1 = one / d1;
    const ${T.V} t21 = a12 - l20 * a01, t31 = a13 - l30 * a01;
    const ${T.V} l21 = t21 * i1, l31 = t31 * i1;
    const ${T.V} d2 = a22 - l20 * a02 - l21 * t21;
    const ${T.V} i2 = one / d2;
    const ${T.V} t32 = a23 - l30 * a02 - l31 * t21;
    const ${T.V} l32 = t32 * i2;
    const ${T.V} d3 = a33 - l30 * a03 - l31 * t31 - l32 * t32;
    const ${T.V} i3 = one / d3;
    const ${T.M} ok = (d0 > ${T.lit(pivot_rel)} * a00) & (d0 > ${T.vlit(0.0)})
                    & (d1 > ${T.lit(pivot_rel)} * a11) & (d2 > ${T.lit(pivot_rel)} * a22)
                    & (d3 > ${T.lit(pivot_rel)} * a33);
    const ${T.V} z0 = b0;
    const ${T.V} z1 = b1 - l10 * z0;
    const ${T.V} z2 = b2 - l20 * z0 - l21 * z1;
    const ${T.V} z3 = b3 - l30 * z0 - l31 * z1 - l32 * z2;
    const ${T.V} x3 = z3 * i3;
    const ${T.V} x2 = z2 * i2 - l32 * x3;
    const ${T.V} x1 = z1 * i1 - l21 * x2 - l31 * x3;
    const ${T.V} x0 = z0 * i0 - l10 * x1 - l20 * x2 - l30 * x3;
    const ${T.V} zero = ${T.vlit(0.0)};
    x[0] = ok ? x0 : zero;
    x[1] = ok ? x1 : zero;
    x[2] = ok ? x2 : zero;
    x[3] = ok ? x3 : zero;
    return ok;
}
#endif
</%def>
