<%doc>
sweep.cl.mako: one band configuration × T.lanes pixels per work-item, fused end to end:
  gather noise-free band radiance and sigma of the configuration's variants (tables of
  s2cl/sweep_tables.py) -> + sigma z (common random numbers: z depends on pixel and band slot only)
  -> quantise (ties round up) -> calibrate -> band-effective atmospheric correction -> analysis
  (IGRM fit -> inflection wavelength lp; GVMI; SAM class) -> one index and one status per pixel.
The spectral integral is not here: it ran once per (variant, spectrum) on the host.

Template variables
  T          s2cl.vectypes.VecTypes (precision, lanes);  T1: the same with one lane
  n_slots    number of band slots;  counts[k], strides[k]: mixed-radix decoding of the
             configuration number (last slot fastest): v_k = (cfg / strides[k]) % counts[k]
  row0[k]    first row of slot k in radiance/sigma (rows: variants, columns: spectra)
  var0[k]    first entry of slot k in the per-variant arrays (centre, lp, g, s)
  n_spectra, copies, pitch   pixel p belongs to spectrum p / copies; rows of z and outputs
             have `pitch` entries (a multiple of T.lanes; padded lanes are ignored by the host)
  lmin[k], lmax[k], maxdn    radiometry of each slot (literals)
  noise, quantise            bools
  kind       "igrm" | "gvmi" | "sam";  nir, swir (gvmi slots); n_classes, cos2_min (sam;
             cos2_min < 0: no angle threshold);  c, exp_coef, exp_consts (igrm: see igrm.cl.mako)
Arguments
  index     out [n_configs][pitch] real   igrm: lp (nm); gvmi: GVMI; sam: class (n_classes: none)
  status    out [n_configs][pitch] uchar  see s2cl/analysis.py
  bounds    out [n_configs][pitch] uchar  igrm active-bound bits (0 otherwise)
  radiance  in  [rows][n_spectra] real    W m-2 sr-1 um-1
  sigma     in  [rows][n_spectra] real    noise standard deviation, same units
  z         in  [n_slots][pitch] real     standard normal deviates
  centre, lp, g, s  in [variants] real    band centre (nm), band-effective correction terms
  refs      in  [variants][n_classes] real  (sam) class reference reflectances
  config_start uint, n_configs uint
Global size: (pitch / T.lanes, n_configs).
No builtin math in the hot path (shared/notes/pocl-performance.md): rounding by the 1.5*2^23
(or 1.5*2^52) trick, vector ternaries instead of select/fmin/fmax.
</%doc>
<%namespace name="vm" file="common/vecmath.mako"/>
<%namespace name="lm" file="common/igrm_lm.mako"/>
<%
    V, R, L = T.V, T.R, T.lanes
    lanes = "0123456789abcdef"[:L]
    magic = T.lit(6755399441055744.0 if T.double else 12582912.0)
    def gather(table, row):
        if L == 1:
            return f"{table}[{row} + sp0]"
        return f"({V})(" + ", ".join(f"{table}[{row} + sp{l}]" for l in range(L)) + ")"
    def vload(ptr):
        return f"{ptr}[0]" if L == 1 else f"vload{L}(0, {ptr})"
    def vstore(value, ptr):
        return f"{ptr}[0] = {value};" if L == 1 else f"vstore{L}({value}, 0, {ptr});"
    def lane(expr, l):
        return expr if L == 1 else f"({expr}).s{lanes[l]}"
%>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
% if kind == "igrm":
  % if c.exp == "poly":
${vm.exp_neg(T, exp_coef, exp_consts["emin"], exp_consts["ln2_hi"], exp_consts["ln2_lo"], exp_consts["magic"])}
    % if c.init == "grid" and T.lanes != 1:
${vm.exp_neg(T1, exp_coef, exp_consts["emin"], exp_consts["ln2_hi"], exp_consts["ln2_lo"], exp_consts["magic"])}
    % endif
  % endif
  % if c.loss == "soft_l1":
${vm.rsqrt(T)}
  % endif
${vm.ldl4_solve(T, c.pivot_rel)}
${lm.igrm_fit(T, c, "sweep", T1)}
% endif

/* Radiance -> DN -> radiance, DN = floor(x) + (frac(x) >= 0.5) clipped to [0, maxdn]; rint by the
   magic constant, then ties (rounded to even) moved up. Exact for 0 <= x < 2^22. */
static inline ${V} s2_requantise(const ${V} L, const ${R} lmin, const ${R} scale, const ${R} gain,
                                  const ${R} maxdn)
{
    const ${V} x = (L - lmin) * scale;
    ${V} r = (x + ${magic}) - ${magic};
    r = (x - r == ${T.lit(0.5)}) ? r + ${T.lit(1.0)} : r;
    r = r > maxdn ? (${V})(maxdn) : r;
    r = x > ${T.lit(0.0)} ? r : (${V})(${T.lit(0.0)});
    return lmin + r * gain;
}

__kernel void sweep_configs(
    __global ${R} *restrict index,
    __global uchar *restrict status,
    __global uchar *restrict bounds,
    __global const ${R} *restrict radiance,
    __global const ${R} *restrict sigma,
    __global const ${R} *restrict z,
    __global const ${R} *restrict centre,
    __global const ${R} *restrict lp,
    __global const ${R} *restrict g,
    __global const ${R} *restrict s,
    __global const ${R} *restrict refs,
    const uint config_start,
    const uint n_configs)
{
    const uint blk = get_global_id(0);
    const uint c = get_global_id(1);
    if (c >= n_configs)
        return;
    const uint cfg = config_start + c;
    const uint p0 = blk * ${L}u;
% for l in range(L):
    const uint sp${l} = min((p0 + ${l}u) / ${copies}u, ${n_spectra - 1}u);
% endfor
    ${V} rho[${n_slots}];
    ${R} x[${n_slots}];
% for k in range(n_slots):
    {   /* slot ${k} */
        const uint v = (cfg / ${strides[k]}u) % ${counts[k]}u;
        const uint row = (${row0[k]}u + v) * ${n_spectra}u;
        const uint var = ${var0[k]}u + v;
        ${V} L = ${gather("radiance", "row")};
  % if noise:
        L = L + ${gather("sigma", "row")} * ${vload(f"(z + {k}u * {pitch}u + p0)")};
  % endif
  % if quantise:
        L = s2_requantise(L, ${T.lit(lmin[k])}, ${T.lit(maxdn / (lmax[k] - lmin[k]))},
                          ${T.lit((lmax[k] - lmin[k]) / maxdn)}, ${T.lit(float(maxdn))});
  % endif
        const ${V} y = (L - lp[var]) / g[var];
        const ${V} d = ${T.lit(1.0)} + s[var] * y;
        rho[${k}] = y / (d > ${T.lit(1e-6)} ? d : (${V})(${T.lit(1e-6)}));
        x[${k}] = centre[var];
    }
% endfor
    const size_t at = (size_t)c * ${pitch}u + p0;
% if kind == "gvmi":
    const ${V} num = (rho[${nir}] + ${T.lit(0.1)}) - (rho[${swir}] + ${T.lit(0.02)});
    const ${V} den = (rho[${nir}] + ${T.lit(0.1)}) + (rho[${swir}] + ${T.lit(0.02)});
    const ${T.M} ok = den > ${T.lit(0.0)};
    ${vstore(f"ok ? num / den : ({V})({T.lit(0.0)})", "(index + at)")}
  % for l in range(L):
    status[at + ${l}] = ${lane("ok", l)} ? 0 : 3;
    bounds[at + ${l}] = 0;
  % endfor
% elif kind == "sam":
    ${V} norm2 = ${T.vlit(0.0)};
  % for k in range(n_slots):
    norm2 = norm2 + rho[${k}] * rho[${k}];
  % endfor
    ${V} best_score = (${V})(${T.lit(-3.0)});
    ${V} best_class = (${V})(${T.lit(float(n_classes))});
  % for j in range(n_classes):
    {   /* class ${j}: compare sign(cos) cos^2 (monotone in the angle) without sqrt */
        ${V} dot = ${T.vlit(0.0)};
        ${R} ref2 = ${T.lit(0.0)};
    % for k in range(n_slots):
        {
            const uint var = ${var0[k]}u + (cfg / ${strides[k]}u) % ${counts[k]}u;
            const ${R} r = refs[var * ${n_classes}u + ${j}u];
            dot = dot + rho[${k}] * r;
            ref2 = ref2 + r * r;
        }
    % endfor
        const ${V} denom = norm2 * ref2;
        const ${V} cos2 = denom > ${T.lit(0.0)} ? dot * dot / denom : (${V})(${T.lit(0.0)});
        const ${V} score = dot >= ${T.lit(0.0)} ? cos2 : -cos2;
        const ${T.M} better = score > best_score;
        best_class = better ? (${V})(${T.lit(float(j))}) : best_class;
        best_score = better ? score : best_score;
    }
  % endfor
    const ${T.M} valid = norm2 > ${T.lit(0.0)};
  % if cos2_min >= 0:
    const ${T.M} close = best_score >= ${T.lit(cos2_min)};
  % else:
    const ${T.M} close = valid;
  % endif
    ${vstore(f"(valid & close) ? best_class : ({V})({T.lit(float(n_classes))})", "(index + at)")}
  % for l in range(L):
    status[at + ${l}] = !${lane("valid", l)} ? 3 : (${lane("close", l)} ? 0 : 2);
    bounds[at + ${l}] = 0;
  % endfor
% else:
    ${V} out[6];
    ${T.M} st, it, bd;
    s2_igrm_fit_sweep(rho, x, out, &st, &it, &bd);
    ${vstore("out[4]", "(index + at)")}
  % for l in range(L):
    status[at + ${l}] = (uchar)${lane("st", l)};
    bounds[at + ${l}] = (uchar)${lane("bd", l)};
  % endfor
% endif
}
