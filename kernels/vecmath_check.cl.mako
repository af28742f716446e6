<%doc>
vecmath_check.cl.mako: elementwise wrappers that expose the common/vecmath.mako helpers to tests
and to bench/ (their accuracy is a stated, tested property).

Template variables
  T         s2cl.cl.vectypes.VecTypes (precision, lanes)
  exp_coef  exp polynomial coefficients (s2cl.cl.vecmath.exp_poly_coefficients)
  exp_consts dict: emin, ln2_hi, ln2_lo, magic (s2cl.cl.vecmath, per precision)
Kernels (one work-item = T.lanes consecutive elements; n must be a multiple of T.lanes)
  check_exp_neg(out[n] real, a[n] real)             out = s2_exp_neg(a)
  check_rsqrt(out[n] real, a[n] real)               out = s2_rsqrt(a)
  check_ldl4(x[4][n] real, ok[n] int32, a[10][n] real, b[4][n] real)
      a rows: a00 a01 a02 a03 a11 a12 a13 a22 a23 a33 (upper triangle, row-major);
      x = A^-1 b where ok, else 0; plane stride n.
</%doc>
<%namespace name="vm" file="common/vecmath.mako"/>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
${vm.exp_neg(T, exp_coef, exp_consts["emin"], exp_consts["ln2_hi"], exp_consts["ln2_lo"], exp_consts["magic"])}
${vm.rsqrt(T)}
${vm.ldl4_solve(T, 1e-12 if T.double else 1e-6)}
<%def name="ld(ptr, plane)">\
% if T.lanes == 1:
${ptr}[${plane} * n + gid]\
% else:
((__global const ${T.V} *)(${ptr} + ${plane} * n))[gid]\
% endif
</%def>
<%def name="st(ptr, plane)">\
% if T.lanes == 1:
${ptr}[${plane} * n + gid]\
% else:
((__global ${T.V} *)(${ptr} + ${plane} * n))[gid]\
% endif
</%def>

__kernel void check_exp_neg(__global ${T.R} *out, __global const ${T.R} *a, const int n)
{
    const int gid = get_global_id(0);
    ${st("out", 0)} = s2_exp_neg_${T.suffix}(${ld("a", 0)});
}

__kernel void check_rsqrt(__global ${T.R} *out, __global const ${T.R} *a, const int n)
{
    const int gid = get_global_id(0);
    ${st("out", 0)} = s2_rsqrt_${T.suffix}(${ld("a", 0)});
}

__kernel void check_ldl4(__global ${T.R} *x, __global int *ok, __global const ${T.R} *a,
                         __global const ${T.R} *b, const int n)
{
    const int gid = get_global_id(0);
    ${T.V} sol[4];
    const ${T.M} good = s2_ldl4_solve_${T.suffix}(
% for k in range(10):
        ${ld("a", k)},
% endfor
        ${ld("b", 0)}, ${ld("b", 1)}, ${ld("b", 2)}, ${ld("b", 3)}, sol);
% for k in range(4):
    ${st("x", k)} = sol[${k}];
% endfor
% if T.lanes == 1:
    ok[gid] = good;
% else:
    ((__global ${T.vec("int")} *)ok)[gid] = ${T.convert("int")}(good) & 1;
% endif
}
