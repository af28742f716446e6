<%doc>
common/stages.mako: the stages of the sensor chain after resampling, as `static inline` device
functions written once and spliced by every kernel that runs them: the standalone kernels
(sense.cl.mako, index.cl.mako, sam.cl.mako) and the fused sweep kernel (sweep.cl.mako). A rule
(rounding, clipping, what counts as invalid, which status a pixel gets) therefore cannot differ
between `s2cl simulate` and a sweep. Status codes and pixel flags: common/s2_status.clh.
numpy twins (float64): s2cl/reference/stages.py. The chain's stages are declared in s2cl/forward/stages.py,
which names each one's def here.

Every def takes T (s2cl.cl.vectypes.VecTypes: precision and lanes; T.lanes == 1 gives scalar code)
and emits functions named with T.suffix, each guarded so that a kernel may splice a def twice.
No builtin math in the per-pixel path (PoCL does not inline it; `python -m bench.bench_igrm` times the fit with builtin exp against ours).

A chain stage NAME has two defs: NAME(T), its device functions, and NAME_step(T, c), the statements the
kernels splice per band (per pixel and band slot; a stage across bands: once per pixel) in the chain's order.
A step reads and updates `L` (the band's radiance, then its reflectance after `correct`) and may leave
values for later steps (`q`, `flag`). `c` is the kernel's site (s2cl.forward.sense.SenseSite,
s2cl.sweep.kernel.SweepSite): c.value(NAME) is the expression of one of the stage's values (its Value in
s2cl/forward/stages.py) for this band, c.has(NAME) whether the kernel has it, c.store(OUTPUT, expr) the
statement that writes an output (empty where the kernel has none), c.deviate() the band's standard normal
deviate; a step across bands works on X[0 .. c.n - 1] with c.pairs(NAME), the values [k][j].

  noise(T)      V s2_noise_sigma_<sfx>(V L, R a, R b): sqrt(a + b max(L, 0)), the sensor's noise sigma at
                radiance L (s2cl.sensor.noise_model; the one builtin here: once per pixel and band, not in a loop);
                V s2_add_noise_<sfx>(V L, V sigma, V z): L + sigma z for a standard normal deviate z.
                Step: sigma from the kernel's table where it has one (a sweep), else from L; stores `noisy`.
  crosstalk(T)  (no function: the step is a sum of literals) Step across bands: X[k] += sum over j of
                c[k][j] X[j], every band from the others' radiance before the step; stores `noisy`.
  quantise(T)   V s2_quantise_<sfx>(V L, R lmin, R lmax, R scale, R maxdn, M *flags)
                DN as a real: x = (L - lmin) scale; DN = floor(x) + (x - floor(x) >= 0.5) (ties up),
                clipped into [0, maxdn]. flags: S2_FLAG_NODATA (L NaN), else S2_FLAG_LOW (L < lmin),
                S2_FLAG_HIGH (L > lmax), else 0. Step: leaves q (DN) and flag; stores `dn`, `flags`.
  calibrate(T)  V s2_calibrate_<sfx>(V dn, M flags, R lmin, R gain)
                lmin + dn gain; NaN where flags has S2_FLAG_NODATA. Step: from q and flag; stores `calibrated`.
  calibration_error(T)  V s2_calibration_error_<sfx>(V L, R gain): L gain, gain = 1 + the band's relative
                calibration error. Step: after calibrate; stores `calibrated` again (it carries the error).
  correct(T)    V s2_correct_<sfx>(V L, R lp, R g, R s)
                band-effective inverse: y = (L - lp) / g, rho = y / max(1 + s y, 1e-6); NaN stays NaN.
                Step: L becomes the band reflectance; stores `reflectance`.
  normalised_difference(T, nd, max_abs)  V s2_<nd.kind>_<sfx>(V a, V b, M *status)
                ((a + o_a) - (b + o_b)) / ((a + o_a) + (b + o_b)), offsets nd.offsets
                (s2cl.retrieve.indices; GVMI, Segl et al. 2012 eq. 3: o = 0.1, 0.02);
                S2_INVALID (index 0) unless both reflectances are finite, |rho| <= max_abs, and both
                offset terms are positive (then the index lies in (-1, 1)); else S2_OK.
  sam(T, n_bands, n_classes, max_abs)
                void s2_sam_<sfx>_<n_bands>_<n_classes>(const V *p, const R *ref, R cos_min,
                                                       M *best, V *dot, V *norm2, M *status)
                ref [n_classes][n_bands]: unit-length class references (the same for every lane).
                best: the class of largest p.ref (the first on ties); dot, norm2: its p.ref and |p|^2.
                status: S2_INVALID (not finite or |rho| > max_abs), S2_DEGENERATE (|p|^2 <= 1e-30),
                S2_UNCLASSIFIED (angle above the threshold, i.e. cos < cos_min; cos_min < -1: none),
                else S2_OK. The threshold test is sqrt-free: dot >= cos_min |p| in squares.
</%doc>

<%def name="_magic(T)">${T.lit(6755399441055744.0 if T.double else 12582912.0)}</%def>
<%def name="_m(T, v)">((${T.M})(${v}))</%def>

<%def name="noise(T)">
#ifndef S2_NOISE_${T.suffix.upper()}
#define S2_NOISE_${T.suffix.upper()}
static inline ${T.V} s2_noise_sigma_${T.suffix}(const ${T.V} L, const ${T.R} a, const ${T.R} b)
{
    return sqrt(a + b * fmax(L, (${T.V})(${T.lit(0.0)})));
}
static inline ${T.V} s2_add_noise_${T.suffix}(const ${T.V} L, const ${T.V} sigma, const ${T.V} z)
{
    return L + sigma * z;
}
#endif
</%def>

<%def name="noise_step(T, c)">
<% sigma = c.value("sigma") if c.has("sigma") else f"s2_noise_sigma_{T.suffix}(L, {c.value('noise_a')}, {c.value('noise_b')})" %>
        L = s2_add_noise_${T.suffix}(L, ${sigma}, ${c.deviate()});
        ${c.store("noisy", "L")}
</%def>

<%def name="crosstalk(T)">
</%def>

<%def name="crosstalk_step(T, c)">
    {   /* crosstalk: every band gains from the others of its focal plane (their radiance before this step) */
        ${T.V} own[${c.n}];
% for k in range(c.n):
        own[${k}] = X[${k}];
% endfor
% for k, row in enumerate(c.pairs("crosstalk")):
<% terms = "".join(f" + {T.lit(v)} * own[{j}]" for j, v in enumerate(row) if j != k and v != 0.0) %>\
  % if terms:
        X[${k}] = own[${k}]${terms};
        ${c.store("noisy", k, f"X[{k}]")}
  % endif
% endfor
    }
</%def>

<%def name="quantise(T)">
#include "common/s2_status.clh"
#ifndef S2_QUANTISE_${T.suffix.upper()}
#define S2_QUANTISE_${T.suffix.upper()}
static inline ${T.V} s2_quantise_${T.suffix}(const ${T.V} L, const ${T.R} lmin, const ${T.R} lmax,
                                            const ${T.R} scale, const ${T.R} maxdn, ${T.M} *flags)
{
    const ${T.V} zero = ${T.vlit(0.0)};
    const ${T.V} x = (L - lmin) * scale;
    /* x clipped first: then the round-to-nearest-even trick is exact (maxdn < 2^16) */
    const ${T.V} xc = x > zero ? (x > maxdn ? (${T.V})(maxdn) : x) : zero;
    ${T.V} r = (xc + ${_magic(T)}) - ${_magic(T)};
    r = (xc - r == ${T.lit(0.5)}) ? r + ${T.lit(1.0)} : r;   /* ties (rounded to even) go up */
    const ${T.M} nodata = L != L;
    const ${T.M} low = !(L >= lmin);
    const ${T.M} high = L > lmax;
    *flags = nodata ? ${_m(T, "S2_FLAG_NODATA")}
                    : (low ? ${_m(T, "S2_FLAG_LOW")} : (high ? ${_m(T, "S2_FLAG_HIGH")} : ${_m(T, 0)}));
    return r;
}
#endif
</%def>

<%def name="quantise_step(T, c)">
        ${T.M} flag;
        const ${T.V} q = s2_quantise_${T.suffix}(L, ${c.value("lmin")}, ${c.value("lmax")}, ${c.value("scale")},
                                                ${c.value("maxdn")}, &flag);
        ${c.store("dn", "q")}
        ${c.store("flags", "flag")}
</%def>

<%def name="calibrate(T)">
#include "common/s2_status.clh"
#ifndef S2_CALIBRATE_${T.suffix.upper()}
#define S2_CALIBRATE_${T.suffix.upper()}
static inline ${T.V} s2_calibrate_${T.suffix}(const ${T.V} dn, const ${T.M} flags, const ${T.R} lmin,
                                             const ${T.R} gain)
{
    const ${T.M} nodata = (flags & ${_m(T, "S2_FLAG_NODATA")}) != ${_m(T, 0)};
    return nodata ? (${T.V})(${"NAN" if not T.double else "(double)NAN"}) : lmin + dn * gain;
}
#endif
</%def>

<%def name="calibrate_step(T, c)">
        L = s2_calibrate_${T.suffix}(q, flag, ${c.value("lmin")}, ${c.value("gain")});
        ${c.store("calibrated", "L")}
</%def>

<%def name="calibration_error(T)">
#ifndef S2_CALIBRATION_ERROR_${T.suffix.upper()}
#define S2_CALIBRATION_ERROR_${T.suffix.upper()}
static inline ${T.V} s2_calibration_error_${T.suffix}(const ${T.V} L, const ${T.R} gain)
{
    return L * gain;   /* NaN (no data) stays NaN */
}
#endif
</%def>

<%def name="calibration_error_step(T, c)">
        L = s2_calibration_error_${T.suffix}(L, ${c.value("cal_error_gain")});
        ${c.store("calibrated", "L")}
</%def>

<%def name="correct(T)">
#ifndef S2_CORRECT_${T.suffix.upper()}
#define S2_CORRECT_${T.suffix.upper()}
static inline ${T.V} s2_correct_${T.suffix}(const ${T.V} L, const ${T.R} lp, const ${T.R} g, const ${T.R} s)
{
    const ${T.V} y = (L - lp) / g;
    const ${T.V} d = ${T.lit(1.0)} + s * y;
    /* a denominator below 1e-6 (radiance far below the path radiance) is clamped: finite output */
    return y / (d > ${T.lit(1e-6)} ? d : (${T.V})(${T.lit(1e-6)}));
}
#endif
</%def>

<%def name="correct_step(T, c)">
        L = s2_correct_${T.suffix}(L, ${c.value("lp")}, ${c.value("g")}, ${c.value("s")});
        ${c.store("reflectance", "L")}
</%def>

<%def name="normalised_difference(T, nd, max_abs)">
#include "common/s2_status.clh"
#ifndef S2_${nd.kind.upper()}_${T.suffix.upper()}
#define S2_${nd.kind.upper()}_${T.suffix.upper()}
/* ${nd.title} */
static inline ${T.V} s2_${nd.kind}_${T.suffix}(const ${T.V} rho_a, const ${T.V} rho_b, ${T.M} *status)
{
    const ${T.V} a = rho_a + ${T.lit(nd.offsets[0])};
    const ${T.V} b = rho_b + ${T.lit(nd.offsets[1])};
    /* NaN and +-inf fail the range comparisons */
    const ${T.M} ok = (rho_a <= ${T.vlit(max_abs)}) & (rho_a >= ${T.vlit(-max_abs)})
                    & (rho_b <= ${T.vlit(max_abs)}) & (rho_b >= ${T.vlit(-max_abs)})
                    & (a > ${T.vlit(0.0)}) & (b > ${T.vlit(0.0)});
    *status = ok ? ${_m(T, "S2_OK")} : ${_m(T, "S2_INVALID")};
    return ok ? (a - b) / (a + b) : ${T.vlit(0.0)};
}
#endif
</%def>

<%def name="sam(T, n_bands, n_classes, max_abs)">
#include "common/s2_status.clh"
#ifndef S2_SAM_${T.suffix.upper()}_${n_bands}_${n_classes}
#define S2_SAM_${T.suffix.upper()}_${n_bands}_${n_classes}
static inline void s2_sam_${T.suffix}_${n_bands}_${n_classes}(const ${T.V} *p, const ${T.R} *ref,
    const ${T.R} cos_min, ${T.M} *best, ${T.V} *dot, ${T.V} *norm2, ${T.M} *status)
{
    const ${T.V} zero = ${T.vlit(0.0)};
    ${T.M} valid = ${_m(T, 0)} == ${_m(T, 0)};
    ${T.V} n2 = zero;
% for i in range(n_bands):
    valid = valid & (p[${i}] <= ${T.vlit(max_abs)}) & (p[${i}] >= ${T.vlit(-max_abs)});
    n2 = n2 + p[${i}] * p[${i}];
% endfor
    ${T.V} top = ${T.vlit(-3.0e38 if not T.double else -1.0e300)};
    ${T.M} arg = ${_m(T, 0)};
% for j in range(n_classes):
    {
        ${T.V} d = zero;
  % for i in range(n_bands):
        d = d + p[${i}] * ref[${j * n_bands + i}];
  % endfor
        const ${T.M} better = d > top;   /* strict: the first class wins ties */
        top = better ? d : top;
        arg = better ? ${_m(T, j)} : arg;
    }
% endfor
    const ${T.M} nonzero = n2 > ${T.vlit(1e-30)};
    /* angle <= threshold  <=>  top >= cos_min |p|, compared in squares with the signs kept */
    const ${T.V} lhs = top * top;
    const ${T.V} rhs = (cos_min * cos_min) * n2;
    const ${T.M} inside = cos_min < ${T.lit(-1.0)} ? ${_m(T, 0)} == ${_m(T, 0)}
        : (top >= zero ? (cos_min <= ${T.lit(0.0)} ? ${_m(T, 0)} == ${_m(T, 0)} : lhs >= rhs)
                       : (cos_min < ${T.lit(0.0)} ? lhs <= rhs : ${_m(T, 0)} != ${_m(T, 0)}));
    *status = !valid ? ${_m(T, "S2_INVALID")} : (!nonzero ? ${_m(T, "S2_DEGENERATE")}
              : (inside ? ${_m(T, "S2_OK")} : ${_m(T, "S2_UNCLASSIFIED")}));
    *best = arg;
    *dot = top;
    *norm2 = n2;
}
#endif
</%def>
