<%doc>
resample.cl.mako: spectra -> band radiance through each band's sparse SRF support.

Template variables
  args          list of s2cl.cl.kernel_args.Arg, the kernel's parameters (host binds the same list)
  signature     function rendering args
  bands         list of dict(name, start, length, offset): grid index of the first support sample,
                number of support samples, offset of the band's weights in `weights`
  n_wavelengths grid size
  stride        values per row of `spectra`: the grid size, or (interpolated) the cube's native samples
  T             s2cl.cl.vectypes.VecTypes of the working precision, one lane (scalar types, literals)
  vw            wavelengths per vector load, 4, 8 or 16 (s2cl.forward.resample.DEFAULT_VECTOR_WIDTH)
  rows          pixels (rows of `spectra`) per work-item, read in an interleaved way
  atmosphere    bool: input is surface reflectance, converted per wavelength to TOA radiance
                L = Lp + G rho / (1 - S rho) before weighting (arrays path_radiance, ground_term,
                spherical_albedo on the grid)
  interpolated  bool: rows of `spectra` hold a cube's native samples; each grid wavelength i takes
                v[lower[i]] + fraction[i] (v[upper[i]] - v[lower[i]]) (upper == lower where fraction is 0:
                s2cl.forward.grid_interpolation), before the atmosphere and the weights
Defines: none (the precision comes from T).
Arguments (in order; see s2cl/forward/resample.py)
  out      [n_bands x n_pixels]  real     band radiance, W m-2 sr-1 um-1 (pixels contiguous)
  spectra  [n_pixels x stride]   real     radiance (or reflectance when atmosphere) per pixel row
  weights  [sum of lengths]      real     normalised SRF weights, band after band
  (interpolated) lower, upper [n_wl] int, fraction [n_wl] real   the grid interpolation table
  (atmosphere) path_radiance, ground_term, spherical_albedo  [n_wl] real
  n_pixels                        uint

Each work-item takes `rows` pixels and reads their rows with `vw`-wide vector loads (rows are
contiguous, so the hardware prefetcher streams them) and accumulates in vectors. A work-item whose rows
all exist addresses them from one pointer; only the last work-item clamps its row pointers and guards
its stores (the same sums, so the bits do not depend on where a pixel falls). Loops over vectors are fine here:
we do not rely on PoCL's implicit work-group vectorisation (it skips kernels with loops or builtin calls).
</%doc>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
<%
    R = T.R
    vtype = f"{R}{vw}"
    lanes = "0123456789abcdef"[:vw]
    # rows reduced together: groups of min(rows, vw) (both powers of two); 1 row: one s2_hsum per band
    group = min(rows, vw)
%>
/* Sum of the lanes as a pairwise tree ((a0 + a1) + (a2 + a3)) + ...: the order the grouped reduction of several
   rows takes (below), so every rows-per-work-item setting gives the same bits. */
static inline ${R} s2_hsum(${vtype} a)
{
<%
    width, expr, k = vw, "a", 0
%>
% while width > 2:
    const ${R}${width // 2} t${k} = ${expr}.even + ${expr}.odd;
<%
    expr, width, k = f"t{k}", width // 2, k + 1
%>
% endwhile
    return ${expr}.s0 + ${expr}.s1;
}

% if interpolated:
/* A row's values at grid wavelengths lo..: each between its two native samples (numpy.interp's rule; where the
   fraction is 0, hi == lo, so the next sample is never read) */
static inline ${vtype} s2_grid${vw}(__global const ${R} *row, const int${vw} lo, const int${vw} hi, const ${vtype} f)
{
    const ${vtype} a = (${vtype})(${", ".join(f"row[lo.s{c}]" for c in lanes)});
    const ${vtype} b = (${vtype})(${", ".join(f"row[hi.s{c}]" for c in lanes)});
    return a + f * (b - a);
}
static inline ${R} s2_grid(__global const ${R} *row, const int i, __global const int *lower,
                           __global const int *upper, __global const ${R} *fraction)
{
    const ${R} a = row[lower[i]];
    return a + fraction[i] * (row[upper[i]] - a);
}
% endif

% if atmosphere:
/* TOA radiance from surface reflectance, per wavelength (6S formulation, see s2cl.atmos.correction.toa). */
static inline ${vtype} s2_toa${vw}(${vtype} rho, ${vtype} lp, ${vtype} g, ${vtype} s)
{
    return lp + g * rho / (${T.lit(1.0)} - s * rho);
}
static inline ${R} s2_toa(${R} rho, ${R} lp, ${R} g, ${R} s)
{
    return lp + g * rho / (${T.lit(1.0)} - s * rho);
}
% endif

<%def name="band_sums(row, whole)">
<%doc> Every band's sums for this work-item's rows; row(r) renders row r's pointer; whole: all rows exist, so
       stores need no guard. </%doc>
% for k, b in enumerate(bands):
<%
    nvec = b["length"] // vw
    s0 = b["start"]
    w0 = b["offset"]
    # row r's values at the vector j's grid wavelengths, and at grid wavelength s0 + t (scalar tails)
    if interpolated:
        vec = lambda r: f"s2_grid{vw}({row(r)}, lo, hi, f)"
        one = lambda r, t: f"s2_grid({row(r)}, {s0 + t}, lower, upper, fraction)"
    else:
        vec = lambda r: f"vload{vw}(j, {row(r)} + {s0})"
        one = lambda r, t: f"{row(r)}[{s0 + t}]"
%>
    {   /* ${b["name"]}: grid samples ${s0}..${s0 + b["length"] - 1} */
  % for r in range(rows):
        ${vtype} acc${r} = (${vtype})(${T.lit(0.0)});
  % endfor
        for (int j = 0; j < ${nvec}; ++j) {
            const ${vtype} w = vload${vw}(j, weights + ${w0});
  % if interpolated:
            const int${vw} lo = vload${vw}(j, lower + ${s0}), hi = vload${vw}(j, upper + ${s0});
            const ${vtype} f = vload${vw}(j, fraction + ${s0});
  % endif
  % if atmosphere:
            const ${vtype} lp = vload${vw}(j, path_radiance + ${s0}), g = vload${vw}(j, ground_term + ${s0});
            const ${vtype} s = vload${vw}(j, spherical_albedo + ${s0});
    % for r in range(rows):
            acc${r} += w * s2_toa${vw}(${vec(r)}, lp, g, s);
    % endfor
  % else:
    % for r in range(rows):
            acc${r} += w * ${vec(r)};
    % endfor
  % endif
        }
  % if group > 1:
    % for g in range(rows // group):
        /* rows ${g * group}..${g * group + group - 1}: their sums at once (faster than one scalar reduction per row;
           python -m bench.bench_resample measures the kernel). Each accumulator is first halved, lanes paired as
           s2_hsum pairs them, to ${group} lanes; then the rows are paired, halving, until lane r holds row r's sum. */
<%
    gtype = f"{R}{group}"
    level = [f"acc{r}" for r in range(g * group, (g + 1) * group)]
    depth, width = 0, vw
%>
      % while width > group:
<%
    names = [f"p{g}_{depth}_{i}" for i in range(len(level))]
    width //= 2
%>
        % for name, x in zip(names, level):
        const ${R}${width} ${name} = ${x}.even + ${x}.odd;
        % endfor
<%
    level = names
    depth += 1
%>
      % endwhile
      % while len(level) > 1:
<%
    pairs = list(zip(level[0::2], level[1::2]))
    names = [f"h{g}_{depth}_{i}" for i in range(len(pairs))]
%>
        % for name, (x, y) in zip(names, pairs):
        const ${gtype} ${name} = (${gtype})(${x}.even, ${y}.even) + (${gtype})(${x}.odd, ${y}.odd);
        % endfor
<%
    level = names
    depth += 1
%>
      % endwhile
        ${gtype} sums${g} = ${level[0]};
      % for t in range(nvec * vw, b["length"]):
        % for r in range(group):
          % if atmosphere:
        sums${g}.s${lanes[r]} += weights[${w0 + t}] * s2_toa(${one(g * group + r, t)}, path_radiance[${s0 + t}], ground_term[${s0 + t}], spherical_albedo[${s0 + t}]);
          % else:
        sums${g}.s${lanes[r]} += weights[${w0 + t}] * ${one(g * group + r, t)};
          % endif
        % endfor
      % endfor
      % if whole:
        vstore${group}(sums${g}, 0, out + ${k}u * n_pixels + i0 + ${g * group}u);
      % else:
        % for r in range(group):
        if (i0 + ${g * group + r}u < n_pixels)
            out[${k}u * n_pixels + i0 + ${g * group + r}u] = sums${g}.s${lanes[r]};
        % endfor
      % endif
    % endfor
  % else:
        /* one row per work-item (group == 1): s2_hsum's tree, then any scalar tail */
        ${R} sum0 = s2_hsum(acc0);
    % for t in range(nvec * vw, b["length"]):
      % if atmosphere:
        sum0 += weights[${w0 + t}] * s2_toa(${one(0, t)}, path_radiance[${s0 + t}], ground_term[${s0 + t}], spherical_albedo[${s0 + t}]);
      % else:
        sum0 += weights[${w0 + t}] * ${one(0, t)};
      % endif
    % endfor
        out[${k}u * n_pixels + i0] = sum0;
  % endif
    }
% endfor
</%def>

__kernel void resample_bands(
    ${signature(args, T)})
{
    /* ${rows} rows per work-item: their loads interleave, so ${rows} streams are in flight at once */
    const uint i0 = get_global_id(0) * ${rows}u;
    if (i0 >= n_pixels)
        return;
% if rows > 1:
    if (i0 + ${rows}u <= n_pixels) {
% endif
        /* all rows exist: they sit at constant offsets from one pointer, so the compiler keeps one base register
           and folds the offsets into the loads (with a pointer per row, PoCL kept a pointer per row and band on
           the stack and reloaded them band after band) */
        __global const ${R} *base = spectra + (size_t)i0 * ${stride}u;
${band_sums(lambda r: f"(base + {r * stride}u)", True)}
% if rows > 1:
    } else {
        /* the last work-item: rows past the end re-read the last row and are not stored */
  % for r in range(rows):
        __global const ${R} *row${r} = spectra + (size_t)min(i0 + ${r}u, n_pixels - 1u) * ${stride}u;
  % endfor
${band_sums(lambda r: f"row{r}", False)}
    }
% endif
}
