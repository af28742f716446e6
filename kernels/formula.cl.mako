<%doc>
formula.cl.mako: a retrieval written as a formula of band reflectances (s2cl.retrieve.families.formula), T.lanes pixels
per work-item, e.g. S2REP (Frampton et al. 2013): 705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5).

Template variables
  T        s2cl.cl.vectypes.VecTypes (precision, lanes)
  formula  s2cl.retrieve.families.formula.Formula (its bands, in order, are the rows of refl)
  max_abs  |reflectance| above which (or NaN/inf) a pixel is invalid
The value and its validity rule: s2_formula_<T.suffix> from Formula.device_source (the numpy twin is
Formula.evaluate): status S2_OK, or S2_INVALID with value 0 for NaN/inf or |rho| > max_abs in a band, a zero
denominator, sqrt of a negative or log of a non-positive number, or an intermediate beyond 1e30 in magnitude.
Kernel arguments (s2cl.retrieve.families.formula.ARGS; outputs first; SoA, pixel index fastest)
  value   out [pitch] real    the formula's value (0 where invalid)
  status  out [pitch] uchar
  refl    in  [n_bands][pitch] real  band reflectance, row i = formula.bands[i]
  pitch   int                 elements per band row; a multiple of T.lanes
Global size: pitch / T.lanes.
</%doc>
<% n = len(formula.bands) %>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
${formula.device_source(T, max_abs)}

__kernel void formula(
    ${signature(args, T)})
{
    const int gid = get_global_id(0);
    ${T.M} st;
% if T.lanes == 1:
    value[gid] = s2_formula_${T.suffix}(${", ".join(f"refl[{i} * pitch + gid]" for i in range(n))}, &st);
    status[gid] = (uchar)st;
% else:
  % for i in range(n):
    const ${T.V} b${i} = ((__global const ${T.V} *)(refl + ${i} * pitch))[gid];
  % endfor
    ((__global ${T.V} *)value)[gid] = s2_formula_${T.suffix}(${", ".join(f"b{i}" for i in range(n))}, &st);
    ((__global ${T.vec("uchar")} *)status)[gid] = ${T.convert("uchar")}(st);
% endif
}
