<%doc>
index.cl.mako: a normalised-difference index (s2cl.retrieve.indices), T.lanes pixels per work-item:
    index = ((rho_a + o_a) - (rho_b + o_b)) / ((rho_a + o_a) + (rho_b + o_b))
e.g. GVMI (Segl et al. 2012, eq. 3): a = NIR, b = SWIR, offsets 0.1 and 0.02.

Template variables
  T        s2cl.cl.vectypes.VecTypes (precision, lanes)
  nd       s2cl.retrieve.indices.NormalisedDifference (kind, offsets)
  max_abs  |reflectance| above which (or NaN/inf) a pixel is invalid
The index and its validity rule: s2_<nd.kind>_<T.suffix> of common/stages.mako (the sweep kernel runs
the same function): status S2_OK, or S2_INVALID with index 0 for NaN/inf, |rho| > max_abs, or an
offset term (rho + o) that is not positive.
Kernel arguments (s2cl.retrieve.index_kernel.ARGS; outputs first; SoA, pixel index fastest)
  index   out [pitch] real    the index, in (-1, 1) where valid
  status  out [pitch] uchar
  refl    in  [n_bands][pitch] real  band reflectance
  band_a, band_b  int         rows of band a and band b in refl
  pitch   int                 elements per band row; a multiple of T.lanes
Global size: pitch / T.lanes.
</%doc>
<%namespace name="st" file="common/stages.mako"/>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
${st.normalised_difference(T, nd, max_abs)}

__kernel void normalised_difference(
    ${signature(args, T)})
{
    const int gid = get_global_id(0);
    ${T.M} st;
% if T.lanes == 1:
    index[gid] = s2_${nd.kind}_${T.suffix}(refl[band_a * pitch + gid], refl[band_b * pitch + gid], &st);
    status[gid] = (uchar)st;
% else:
    const ${T.V} a = ((__global const ${T.V} *)(refl + band_a * pitch))[gid];
    const ${T.V} b = ((__global const ${T.V} *)(refl + band_b * pitch))[gid];
    ((__global ${T.V} *)index)[gid] = s2_${nd.kind}_${T.suffix}(a, b, &st);
    ((__global ${T.vec("uchar")} *)status)[gid] = ${T.convert("uchar")}(st);
% endif
}
