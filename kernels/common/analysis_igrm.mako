<%doc>
analysis_igrm.mako: the IGRM family in the sweep kernel (s2cl.retrieve.families.igrm), spliced by sweep.cl.mako.
  functions(T, T1, c, exp_coef, exp_consts): the fit's device functions (c: s2cl.retrieve.igrm_settings kernel
      config; exp_*: the polynomial exp of common/vecmath.mako)
  body(T, n_slots): sorts the slots by band centre (stable; the centres are the same for every lane, as the direct
      API needs increasing wavelengths), fits, and sets value (lp, nm), st, bd (active-bound bits) and code
      (condition code round(20 log10 cond), at most 240: the estimate's cap of 12 decades)
</%doc>
<%namespace name="vm" file="vecmath.mako"/>
<%namespace name="lm" file="igrm_lm.mako"/>
<%namespace name="vp" file="igrm_varpro.mako"/>
<%def name="functions(T, T1, c, exp_coef, exp_consts)">
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
${(vp if c.solver == "varpro" else lm).igrm_fit(T, c, "sweep", T1)}
</%def>
<%def name="body(T, n_slots)">
% for i in range(n_slots):
  % for j in range(n_slots - 1 - i):
    if (x[${j}] > x[${j + 1}]) {
        const ${T.R} tx = x[${j}]; x[${j}] = x[${j + 1}]; x[${j + 1}] = tx;
        const ${T.V} tr = rho[${j}]; rho[${j}] = rho[${j + 1}]; rho[${j + 1}] = tr;
    }
  % endfor
% endfor
    ${T.V} out[7];
    ${T.M} st, it, bd;
    s2_igrm_fit_sweep(rho, x, out, &st, &it, &bd);
    const ${T.V} value = out[4];
    const ${T.V} code = out[6] * ${T.lit(20.0)} + ${T.lit(0.5)};
</%def>
