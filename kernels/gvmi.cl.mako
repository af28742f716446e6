<%doc>
gvmi.cl.mako: Global Vegetation Moisture Index (Segl et al. 2012, eq. 3), T.lanes pixels per work-item:
    GVMI = ((NIR + 0.1) - (SWIR + 0.02)) / ((NIR + 0.1) + (SWIR + 0.02))

Template variables
  T        s2cl.vectypes.VecTypes (precision, lanes)
  max_abs  |reflectance| above which (or NaN/inf) a pixel is invalid
The index and its validity rule: s2_gvmi_<T.suffix> of common/stages.mako (the sweep kernel runs
the same function): status S2_OK, or S2_INVALID with index 0 for NaN/inf, |rho| > max_abs, or an
offset reflectance (NIR + 0.1, SWIR + 0.02) that is not positive.
Kernel arguments (s2cl.retrieve.gvmi.ARGS; outputs first; SoA, pixel index fastest)
  gvmi    out [pitch] real    the index, in [-1, 1] for non-negative reflectance
  status  out [pitch] uchar
  refl    in  [n_bands][pitch] real  band reflectance
  nir, swir  int              row of the NIR and SWIR band in refl
  pitch   int                 elements per band row; a multiple of T.lanes
Global size: pitch / T.lanes.
</%doc>
<%namespace name="st" file="common/stages.mako"/>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
${st.gvmi(T, max_abs)}

__kernel void gvmi(
    ${signature(args, T)})
{
    const int gid = get_global_id(0);
    ${T.M} st;
% if T.lanes == 1:
    gvmi[gid] = s2_gvmi_${T.suffix}(refl[nir * pitch + gid], refl[swir * pitch + gid], &st);
    status[gid] = (uchar)st;
% else:
    const ${T.V} n = ((__global const ${T.V} *)(refl + nir * pitch))[gid];
    const ${T.V} s = ((__global const ${T.V} *)(refl + swir * pitch))[gid];
    ((__global ${T.V} *)gvmi)[gid] = s2_gvmi_${T.suffix}(n, s, &st);
    ((__global ${T.vec("uchar")} *)status)[gid] = ${T.convert("uchar")}(st);
% endif
}
