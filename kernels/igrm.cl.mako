<%doc>
igrm.cl.mako: one IGRM fit (Segl et al. 2012, eq. 2) per pixel, T.lanes pixels per work-item.
The fit itself is s2_igrm_fit_igrm from common/igrm_lm.mako (reusable in fused kernels); this
file only loads, calls and stores.

Template variables
  T      s2cl.cl.vectypes.VecTypes: precision (float32/float64) and lanes (native width on CPUs, 1 on GPUs)
  T1     the same precision with one lane (scalar helpers of the grid initial guess)
  c      s2cl.retrieve.igrm_settings.KernelConfig: n_bands, bounds, tolerances, loss, initial guess, iteration
         limit, exp choice ("poly": own polynomial, "builtin": OpenCL exp), normalisation xc/xw
  exp_coef, exp_consts   s2cl.cl.vecmath.exp_template_vars(...) (used when c.exp == "poly")
  iter_t "uchar" when c.max_iter <= 255, else "ushort"
  args, signature   the argument specs (s2cl.cl.kernel_args) and the function writing them
Defines: none (everything scene-fixed is a rendered literal).
Arguments (IgrmFitter.args; outputs first; all arrays structure-of-arrays, pixel index fastest)
  params      out [7][pitch] real   rmax, rmin, l0 [nm], s [nm], lp [nm], rms residual, log10 condition
  status      out [pitch] uchar     common/s2_status.clh (S2_OK converged, S2_ITERATION_LIMIT,
                                    S2_DEGENERATE, S2_INVALID, S2_STALLED)
  iterations  out [pitch] iter_t    LM trial steps
  bounds      out [pitch] uchar     active-bound bits (see common/igrm_lm.mako)
  refl        in  [n_bands][pitch] real  band reflectance (read with vloadN: any alignment, so the host
                                    may pass its own array in place)
  wavelength  in  [n_bands] real    band centres, nm (the fit's x values, same for all pixels)
  pitch       int                   elements per band row; a multiple of T.lanes
Global size: pitch / T.lanes work-items (the host pads pixels to a multiple of T.lanes).
</%doc>
<%namespace name="vm" file="common/vecmath.mako"/>
<%namespace name="lm" file="common/igrm_lm.mako"/>
<%namespace name="vp" file="common/igrm_varpro.mako"/>
<%def name="ptr(base, plane, const)">\
% if T.lanes == 1:
(${base} + ${plane} * pitch)[gid]\
% elif const:
vload${T.lanes}(gid, ${base} + ${plane} * pitch)\
% else:
((__global ${T.V} *)(${base} + ${plane} * pitch))[gid]\
% endif
</%def>
<%def name="store_int(base, ctype, value)">\
% if T.lanes == 1:
${base}[gid] = (${ctype})(${value});
% else:
((__global ${T.vec(ctype)} *)${base})[gid] = ${T.convert(ctype)}(${value});
% endif
</%def>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
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
${(vp if c.solver == "varpro" else lm).igrm_fit(T, c, "igrm", T1)}

__kernel void igrm_fit(
    ${signature(args, T)})
{
    const int gid = get_global_id(0);
    ${T.R} wl[${c.n_bands}];
    ${T.V} y[${c.n_bands}];
% for i in range(c.n_bands):
    wl[${i}] = wavelength[${i}];
    y[${i}] = ${ptr("refl", i, True)};
% endfor
    ${T.V} out[7];
    ${T.M} st, it, bd;
    s2_igrm_fit_igrm(y, wl, out, &st, &it, &bd);
% for k in range(7):
    ${ptr("params", k, False)} = out[${k}];
% endfor
    ${store_int("status", "uchar", "st")}
    ${store_int("iterations", iter_t, "it")}
    ${store_int("bounds", "uchar", "bd")}
}
