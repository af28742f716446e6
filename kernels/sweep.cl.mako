<%doc>
sweep.cl.mako: one band configuration x T.lanes pixels per work-item, fused end to end:
  gather noise-free band radiance of the configuration's variants (tables of s2cl/sweep/tables.py) -> each
  per-pixel stage of the chain that is on, in its order (s2cl.forward.stages; the deviates z are common random
  numbers: z depends on pixel and band only)
  -> analysis (IGRM fit -> lp; a normalised-difference index such as GVMI; a formula; SAM class) -> one index,
  one status and one bounds/condition byte per pixel.
Every stage is the function `s2cl simulate` runs (common/stages.mako, common/igrm_lm.mako): a pixel
gets the same verdict on both paths (tests/test_one_rule.py). The spectral integral is not here: it
ran once per (variant, spectrum) on the host.

Template variables
  T          s2cl.cl.vectypes.VecTypes (precision, lanes)
  n_slots    number of band slots;  counts[k], strides[k]: mixed-radix decoding of the
             configuration number (last slot fastest): v_k = (cfg / strides[k]) % counts[k]
  row0[k]    first row of slot k in radiance/sigma (rows: variants, columns: spectra)
  var0[k]    first entry of slot k in the per-variant arrays (centre, the stages' per-variant values)
  n_spectra, copies, pitch   pixel p belongs to spectrum p / copies; rows of z and outputs
             have `pitch` entries (a multiple of T.lanes; padded lanes are ignored by the host)
  stages, segments  the stages that are on, in order, and cut where one acts across bands
             (s2cl.forward.stages): each splices its device functions and its step (common/stages.mako)
  site       site(k): how slot k's steps read their values (s2cl.sweep.kernel.SweepSite: a per-band value is
             a literal, a per-variant one a table entry [var], a per-pixel one a gather [row + spectrum]);
             across: the site of a stage across the slots (on X[k])
  vc         s2cl.sweep.kernel.VectorCode: gathers, vector loads and stores, lanes
  analysis_functions, analysis_body   the analysis family's OpenCL C (s2cl.retrieve.family.Family.sweep_code):
             its device functions, and the body that reads rho[k], x[k] (and cfg) and sets value, st, bd, code
  profile    set of profile switches (s2cl.sweep.kernel.PROFILES; empty in every sweep, where they compile out):
             iterations   the condition output carries the IGRM fit's iterations (`it`, modulo 256), not the code
             reflectance  extra output rho_out [n_configs][n_slots][pitch]: the corrected reflectance per slot
             no_fit       the analysis is replaced by value = the sum of rho[k] x[k] (st = bd = code = 0)
             fit_only     rho[k] read from the extra input rho_in (layout of rho_out): no gather and none of the
                          chain's stages
Arguments (s2cl.sweep.kernel.kernel_args)
  index     out [n_configs][pitch] real   igrm: lp (nm); index: its value; sam: class (n_classes: none)
  status    out [n_configs][pitch] uchar  common/s2_status.clh
  bounds    out [n_configs][pitch] uchar  igrm: active-bound bits (see common/igrm_lm.mako); else 0
  condition out [n_configs][pitch] uchar  igrm: condition code round(20 log10 cond), 240 = the cap of 12
                                          decades (singular); else 0
  radiance  in  [rows][n_spectra] real    W m-2 sr-1 um-1
  each stage's per-pixel values  in [rows][n_spectra] real   (sigma: noise standard deviation, same units)
  each stage's per-variant values  in [variants] real        (lp, g, s: band-effective correction terms)
  z         in  [n_slots][pitch] real     (a stage takes deviates) standard normal deviates
  centre    in  [variants] real           band centre (nm)
  refs      in  [variants][n_classes] real  (sam) class reference reflectances
  config_start uint, n_configs uint
Global size: (pitch / T.lanes, n_configs).
No builtin math in the hot path (PoCL does not inline it: kernels/common/vecmath.mako).
</%doc>
<%namespace name="st" file="common/stages.mako"/>
<%
    V, R, L = T.V, T.R, T.lanes
%>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
% for s in stages:
${getattr(st, s.device)(T)}
% endfor
${analysis_functions}

__kernel void sweep_configs(
    ${signature(args, T)})
{
    const uint blk = get_global_id(0);
    const uint c = get_global_id(1);
    if (c >= n_configs)
        return;
    const uint cfg = config_start + c;
    const uint p0 = blk * ${L}u;
% for l in range(L):
    const uint sp${l} = min((p0 + ${l}u) / ${copies}u, ${n_spectra - 1}u);
% endfor
    ${V} rho[${n_slots}];
    ${R} x[${n_slots}];
% if "fit_only" in profile:
  % for k in range(n_slots):
    rho[${k}] = ${vc.vload(f"(rho_in + ((size_t)c * {n_slots}u + {k}u) * {pitch}u + p0)")};
    x[${k}] = centre[${var0[k]}u + (cfg / ${strides[k]}u) % ${counts[k]}u];
  % endfor
% else:
  % if len(segments) > 1:
    ${V} X[${n_slots}];
  % endif
  % for si, (kind, group) in enumerate(segments):
    % if kind == "bands":
      % for s in group:
${getattr(st, s.device + "_step")(T, across)}
      % endfor
    % else:
      % for k in range(n_slots):
    {   /* slot ${k} */
        const uint v = (cfg / ${strides[k]}u) % ${counts[k]}u;
        const uint row = (${row0[k]}u + v) * ${n_spectra}u;
        const uint var = ${var0[k]}u + v;
        ${V} L = ${vc.gather("radiance", "row") if si == 0 else f"X[{k}]"};
        % for s in group:
${getattr(st, s.device + "_step")(T, site(k))}
        % endfor
        % if si < len(segments) - 1:
        X[${k}] = L;
        % else:
        rho[${k}] = L;
        x[${k}] = centre[var];
        % endif
    }
      % endfor
    % endif
  % endfor
% endif
% if "reflectance" in profile:
  % for k in range(n_slots):
    ${vc.vstore(f"rho[{k}]", f"(rho_out + ((size_t)c * {n_slots}u + {k}u) * {pitch}u + p0)")}
  % endfor
% endif
    const size_t at = (size_t)c * ${pitch}u + p0;
    {   /* the analysis: its family's body (s2cl.retrieve.family.Family.sweep_code) */
% if "no_fit" in profile:
        ${V} value = ${T.vlit(0.0)};
  % for k in range(n_slots):
        value += rho[${k}] * x[${k}];
  % endfor
        const ${T.M} st = (${T.M})(0), bd = (${T.M})(0);
        const ${V} code = ${T.vlit(0.0)};
% else:
${analysis_body}
% endif
% if "iterations" in profile:
        const ${T.M} it_out = it;
  % for l in range(L):
        condition[at + ${l}] = (uchar)${vc.lane("it_out", l)};
  % endfor
% endif
        ${vc.vstore("value", "(index + at)")}
% for l in range(L):
        status[at + ${l}] = (uchar)${vc.lane("st", l)};
        bounds[at + ${l}] = (uchar)${vc.lane("bd", l)};
  % if "iterations" not in profile:
        condition[at + ${l}] = (uchar)${vc.lane("code", l)};
  % endif
% endfor
    }
}
