<%doc>
gvmi.cl.mako: Global Vegetation Moisture Index (Segl et al. 2012, eq. 3), T.lanes pixels per work-item:
    GVMI = ((NIR + 0.1) - (SWIR + 0.02)) / ((NIR + 0.1) + (SWIR + 0.02))

Template variables
  T        s2cl.vectypes.VecTypes (precision, lanes)
  max_abs  |reflectance| above which (or NaN/inf) a pixel is invalid
Exports (for fused kernels)
  T.V s2_gvmi_<T.suffix>(T.V nir, T.V swir, T.M *status)
      status 0 valid, 3 invalid input (NaN, inf, |rho| > max_abs, or a denominator below 1e-6,
      i.e. NIR + SWIR <= -0.12); the index is 0 for invalid lanes.
Kernel arguments (outputs first; SoA, pixel index fastest)
  gvmi    out [pitch] real    the index, in [-1, 1] for non-negative reflectance
  status  out [pitch] uchar
  refl    in  [n_bands][pitch] real  band reflectance
  nir, swir  int              row of the NIR and SWIR band in refl
  pitch   int                 elements per band row; a multiple of T.lanes
Global size: pitch / T.lanes.
</%doc>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
#ifndef S2_GVMI_${T.suffix.upper()}
#define S2_GVMI_${T.suffix.upper()}
static inline ${T.V} s2_gvmi_${T.suffix}(const ${T.V} nir, const ${T.V} swir, ${T.M} *status)
{
    const ${T.V} a = nir + ${T.lit(0.1)};
    const ${T.V} b = swir + ${T.lit(0.02)};
    const ${T.V} den = a + b;
    /* NaN and +-inf fail the range comparisons */
    const ${T.M} ok = (nir <= ${T.vlit(max_abs)}) & (nir >= ${T.vlit(-max_abs)})
                    & (swir <= ${T.vlit(max_abs)}) & (swir >= ${T.vlit(-max_abs)}) & (den > ${T.vlit(1e-6)});
    *status = ok ? ((${T.M})(0)) : ((${T.M})(3));
    return ok ? (a - b) / den : ${T.vlit(0.0)};
}
#endif

__kernel void gvmi(
    __global ${T.R} *restrict gvmi,
    __global uchar *restrict status,
    __global const ${T.R} *restrict refl,
    const int nir,
    const int swir,
    const int pitch)
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
