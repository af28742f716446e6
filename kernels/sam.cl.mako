<%doc>
sam.cl.mako: Spectral Angle Mapper, T.lanes pixels per work-item: the reference with the smallest
spectral angle to the pixel, if that angle is within the threshold.
The classification and its status: s2_sam_<T.suffix>_<n_bands>_<n_refs> of common/stages.mako (the
sweep kernel runs the same function); this kernel adds the angle in radians for the output.
Template variables
  T        s2cl.cl.vectypes.VecTypes (precision, lanes)
  n_bands  number of bands (unrolled)
  n_refs   number of reference spectra
  max_abs  |reflectance| above which (or NaN/inf) a pixel is invalid
Kernel arguments (s2cl.retrieve.sam.ARGS; outputs first; SoA, pixel index fastest)
  best     out [pitch] int    reference index (the first on ties), -1 unless status is S2_OK
  angle    out [pitch] real   radians in [0, pi] (S2_OK and S2_UNCLASSIFIED), else 0
  status   out [pitch] uchar  common/s2_status.clh: S2_OK, S2_UNCLASSIFIED, S2_DEGENERATE (zero
                              vector), S2_INVALID
  refl     in  [n_bands][pitch] real
  refs     in  [n_refs][n_bands] real  unit-length references
  cos_min  real               cos(threshold); -2 for no threshold
  pitch    int                elements per band row; a multiple of T.lanes
Global size: pitch / T.lanes. Why cosines: argmin angle = argmax p.r with unit references, so the hot
loop is multiply-adds; the square root and acos run once per pixel, for the winner only.
</%doc>
<%namespace name="st" file="common/stages.mako"/>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
${st.sam(T, n_bands, n_refs, max_abs)}

__kernel void sam_classify(
    ${signature(args, T)})
{
    const int gid = get_global_id(0);
    ${T.R} ref[${n_refs * n_bands}];
    for (int k = 0; k < ${n_refs * n_bands}; ++k)
        ref[k] = refs[k];
    ${T.V} p[${n_bands}];
% for i in range(n_bands):
  % if T.lanes == 1:
    p[${i}] = refl[${i} * pitch + gid];
  % else:
    p[${i}] = ((__global const ${T.V} *)(refl + ${i} * pitch))[gid];
  % endif
% endfor
    ${T.M} b, st;
    ${T.V} dot, norm2;
    s2_sam_${T.suffix}_${n_bands}_${n_refs}(p, ref, cos_min, &b, &dot, &norm2, &st);
    const ${T.M} directed = (st == ((${T.M})(S2_OK))) | (st == ((${T.M})(S2_UNCLASSIFIED)));
    ${T.V} c = directed ? dot / sqrt(directed ? norm2 : ${T.vlit(1.0)}) : ${T.vlit(1.0)};
    c = c > ${T.vlit(1.0)} ? ${T.vlit(1.0)} : (c < ${T.vlit(-1.0)} ? ${T.vlit(-1.0)} : c);
    const ${T.V} a = directed ? acos(c) : ${T.vlit(0.0)};
    const ${T.M} ok = st == ((${T.M})(S2_OK));
    b = ok ? b : ((${T.M})(-1));
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
