<%doc>
sam.cl.mako: Spectral Angle Mapper, T.lanes pixels per work-item: the reference with the smallest
spectral angle to the pixel, optionally only if that angle is within a threshold.

Template variables
  T        s2cl.vectypes.VecTypes (precision, lanes)
  n_bands  number of bands (unrolled)
  n_refs   number of reference spectra
  max_abs  |reflectance| above which (or NaN/inf) a pixel is invalid
Exports (for fused kernels)
  void s2_sam_<T.suffix>(const T.V *p, __global const T.R *refs, T.R cos_min,
                         T.M *best, T.V *angle, T.M *status)
      p [n_bands] pixel lanes; refs [n_refs][n_bands] references scaled to unit length.
      best: index of the reference with the largest cosine (the first one on ties: identical
      references never split a class at random), -1 unless status is 0.
      angle: that angle in radians, [0, pi]; 0 unless status is 0 or 1.
      status: 0 classified, 1 unclassified (angle > threshold, i.e. cos < cos_min),
              2 zero vector (|p|^2 <= 1e-30: no direction), 3 invalid input (NaN, inf, |rho| > max_abs).
Why cosines: argmin angle = argmax p.r/|r| with unit references, so the hot loop is multiply-adds;
the square root and acos run once per pixel, for the winner only.
Kernel arguments (outputs first; SoA, pixel index fastest)
  best     out [pitch] int    reference index or -1
  angle    out [pitch] real   radians
  status   out [pitch] uchar
  refl     in  [n_bands][pitch] real
  refs     in  [n_refs][n_bands] real  unit-length references
  cos_min  real               cos(threshold); -2 for no threshold
  pitch    int                elements per band row; a multiple of T.lanes
Global size: pitch / T.lanes.
</%doc>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
#ifndef S2_SAM_${T.suffix.upper()}_${n_bands}_${n_refs}
#define S2_SAM_${T.suffix.upper()}_${n_bands}_${n_refs}
static inline void s2_sam_${T.suffix}(const ${T.V} *p, __global const ${T.R} *refs, const ${T.R} cos_min,
                                      ${T.M} *best, ${T.V} *angle, ${T.M} *status)
{
    const ${T.V} zero = ${T.vlit(0.0)};
    ${T.M} valid = ((${T.M})(0)) == ((${T.M})(0));
    ${T.V} norm2 = zero;
% for i in range(n_bands):
    valid = valid & (p[${i}] <= ${T.vlit(max_abs)}) & (p[${i}] >= ${T.vlit(-max_abs)});
    norm2 += p[${i}] * p[${i}];
% endfor
    ${T.V} top = ${T.vlit(-3.0e38 if not T.double else -1.0e300)};
    ${T.M} arg = (${T.M})(0);
    for (int k = 0; k < ${n_refs}; ++k) {
        __global const ${T.R} *r = refs + k * ${n_bands};
        ${T.V} dot = zero;
% for i in range(n_bands):
        dot += p[${i}] * r[${i}];
% endfor
        const ${T.M} better = dot > top;
        top = better ? dot : top;
        arg = better ? ((${T.M})(k)) : arg;
    }
    const ${T.M} nonzero = norm2 > ${T.vlit(1e-30)};
    const ${T.V} safe2 = (valid & nonzero) ? norm2 : ${T.vlit(1.0)};
    ${T.V} c = (valid & nonzero) ? top / sqrt(safe2) : ${T.vlit(1.0)};
    c = c > ${T.vlit(1.0)} ? ${T.vlit(1.0)} : (c < ${T.vlit(-1.0)} ? ${T.vlit(-1.0)} : c);
    const ${T.M} inside = c >= cos_min;
    *status = !valid ? ((${T.M})(3)) : (!nonzero ? ((${T.M})(2)) : (inside ? ((${T.M})(0)) : ((${T.M})(1))));
    *best = (valid & nonzero & inside) ? arg : ((${T.M})(-1));
    *angle = (valid & nonzero) ? acos(c) : zero;
}
#endif

__kernel void sam_classify(
    __global int *restrict best,
    __global ${T.R} *restrict angle,
    __global uchar *restrict status,
    __global const ${T.R} *restrict refl,
    __global const ${T.R} *restrict refs,
    const ${T.R} cos_min,
    const int pitch)
{
    const int gid = get_global_id(0);
    ${T.V} p[${n_bands}];
% for i in range(n_bands):
  % if T.lanes == 1:
    p[${i}] = refl[${i} * pitch + gid];
  % else:
    p[${i}] = ((__global const ${T.V} *)(refl + ${i} * pitch))[gid];
  % endif
% endfor
    ${T.M} b, st;
    ${T.V} a;
    s2_sam_${T.suffix}(p, refs, cos_min, &b, &a, &st);
% if T.lanes == 1:
    best[gid] = b;
    angle[gid] = a;
    status[gid] = (uchar)st;
% else:
    ((__global ${T.vec("int")} *)best)[gid] = ${T.convert("int")}(b);
    ((__global ${T.V} *)angle)[gid] = a;
    ((__global ${T.vec("uchar")} *)status)[gid] = ${T.convert("uchar")}(st);
% endif
}
