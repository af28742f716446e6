<%doc>
analysis_sam.mako: the SAM family in the sweep kernel (s2cl.retrieve.families.sam), spliced by sweep.cl.mako.
  functions(T, n_slots, n_classes, max_abs): the SAM stage of common/stages.mako
  body(T, ctx, n_classes, cos_min): the configuration's class references (refs[variant][class] of each slot, the
      same for every lane), scaled to unit length; then sets value (the class, n_classes for none), st, bd, code
      (0). ctx: s2cl.retrieve.family.SweepContext (strides, counts, var0); cos_min below -1: no angle threshold
</%doc>
<%namespace name="st" file="stages.mako"/>
<%def name="functions(T, n_slots, n_classes, max_abs)">
${st.sam(T, n_slots, n_classes, max_abs)}
</%def>
<%def name="body(T, ctx, n_classes, cos_min)">
<% n_slots = len(ctx.counts) %>
    ${T.R} ref[${n_classes * n_slots}];
% for j in range(n_classes):
    {
        ${T.R} n2 = ${T.lit(0.0)};
  % for k in range(n_slots):
        ref[${j * n_slots + k}] = refs[(${ctx.var0[k]}u + (cfg / ${ctx.strides[k]}u) % ${ctx.counts[k]}u) * ${n_classes}u + ${j}u];
        n2 += ref[${j * n_slots + k}] * ref[${j * n_slots + k}];
  % endfor
        const ${T.R} inv = n2 > ${T.lit(0.0)} ? ${T.lit(1.0)} / sqrt(n2) : ${T.lit(0.0)};
  % for k in range(n_slots):
        ref[${j * n_slots + k}] *= inv;
  % endfor
    }
% endfor
    ${T.M} best, st;
    ${T.V} dot, norm2;
    s2_sam_${T.suffix}_${n_slots}_${n_classes}(rho, ref, ${T.lit(cos_min)}, &best, &dot, &norm2, &st);
    const ${T.M} ok = st == ((${T.M})(S2_OK));
    const ${T.V} value = ok ? ${T.convert(T.R) if T.lanes > 1 else '(' + T.R + ')'}(best) : (${T.V})(${T.lit(float(n_classes))});
    const ${T.M} bd = (${T.M})(0), code = (${T.M})(0);
</%def>
