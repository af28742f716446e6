<%doc>
resample.cl.mako: spectra -> band radiance through each band's sparse SRF support.

Template variables
  args          list of s2cl.kernel_args.Arg, the kernel's parameters (host binds the same list)
  signature     function rendering args
  bands         list of dict(name, start, length, offset): grid index of the first support sample,
                number of support samples, offset of the band's weights in `weights`
  n_wavelengths row stride of `spectra` (grid size)
  vw            wavelengths per vector load, 4, 8 or 16 (s2cl.resample.DEFAULT_VECTOR_WIDTH)
  atmosphere    bool: input is surface reflectance, converted per wavelength to TOA radiance
                L = Lp + G rho / (1 - S rho) before weighting (arrays path_radiance, ground_term,
                spherical_albedo on the grid)
Defines
  S2_DOUBLE     float64 build
Arguments (in order; see s2cl/resample.py)
  out      [n_bands x n_pixels]  real_t   band radiance, W m-2 sr-1 um-1 (pixels contiguous)
  spectra  [n_pixels x n_wl]     real_t   radiance (or reflectance when atmosphere) per pixel row
  weights  [sum of lengths]      real_t   normalised SRF weights, band after band
  (atmosphere) path_radiance, ground_term, spherical_albedo  [n_wl] real_t
  n_pixels                        uint

One work-item per pixel; each reads its row with `vw`-wide vector loads (rows are contiguous, so
the hardware prefetcher streams them) and accumulates in vectors. Loops over vectors are fine here:
we do not rely on PoCL's implicit work-group vectorisation (shared/notes/pocl-performance.md).
</%doc>
#include "common/s2_real.clh"

<%
    vtype = f"real{vw}_t"
    lanes = "0123456789abcdef"[:vw]
%>
static inline real_t s2_hsum(${vtype} a)
{
    return ${" + ".join(f"a.s{c}" for c in lanes)};
}

% if atmosphere:
/* TOA radiance from surface reflectance, per wavelength (6S formulation, see s2cl/atmosphere.py). */
static inline ${vtype} s2_toa${vw}(${vtype} rho, ${vtype} lp, ${vtype} g, ${vtype} s)
{
    return lp + g * rho / (S2_R(1.0) - s * rho);
}
static inline real_t s2_toa(real_t rho, real_t lp, real_t g, real_t s)
{
    return lp + g * rho / (S2_R(1.0) - s * rho);
}
% endif

__kernel void resample_bands(
    ${signature(args)})
{
    const uint i = get_global_id(0);
    if (i >= n_pixels)
        return;
    __global const real_t *row = spectra + (size_t)i * ${n_wavelengths}u;
% for k, b in enumerate(bands):
<%
    nvec = b["length"] // vw
    tail = b["length"] - nvec * vw
    s0 = b["start"]
    w0 = b["offset"]
%>
    {   /* ${b["name"]}: grid samples ${s0}..${s0 + b["length"] - 1} */
        ${vtype} acc = (${vtype})(S2_R(0.0));
        for (int j = 0; j < ${nvec}; ++j) {
  % if atmosphere:
            const ${vtype} x = s2_toa${vw}(vload${vw}(j, row + ${s0}), vload${vw}(j, path_radiance + ${s0}),
                                     vload${vw}(j, ground_term + ${s0}), vload${vw}(j, spherical_albedo + ${s0}));
  % else:
            const ${vtype} x = vload${vw}(j, row + ${s0});
  % endif
            acc += vload${vw}(j, weights + ${w0}) * x;
        }
        real_t sum = s2_hsum(acc);
  % for t in range(nvec * vw, b["length"]):
    % if atmosphere:
        sum += weights[${w0 + t}] * s2_toa(row[${s0 + t}], path_radiance[${s0 + t}], ground_term[${s0 + t}], spherical_albedo[${s0 + t}]);
    % else:
        sum += weights[${w0 + t}] * row[${s0 + t}];
    % endif
  % endfor
        out[${k}u * n_pixels + i] = sum;
    }
% endfor
}
