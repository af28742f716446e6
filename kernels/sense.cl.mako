<%doc>
sense.cl.mako: the per-pixel stages of the sensor chain, per pixel and band: noise-free band radiance ->
each stage that is on, in the chain's order (s2cl.forward.stages.STAGES, the per-pixel ones).
A stage that is off has no code and no arguments in the compiled kernel.

Template variables
  args       list of s2cl.cl.kernel_args.Arg (host binds the same list: s2cl.forward.sense.sense_args)
  signature  function rendering args
  n_bands    number of bands (unrolled)
  band_ids   global index of each band: its deviate is lane (id & 3) of Philox counter group (id >> 2),
             so a band's noise does not depend on which other bands share the kernel
  stages     the stages that are on (s2cl.forward.stages.Stage), in order: each splices its device
             functions (common/stages.mako: def `stage.device`) and its step (def `stage.device`_step)
  segments   the stages cut where one acts across bands (s2cl.forward.stages.segments): the bands of a
             pixel are run through each per-band segment, then through the stage across them (on X[k])
  site       site(k): how band k's steps read their values and write their outputs (s2cl.forward.sense.SenseSite)
  across     the site of a stage across bands
  deviates   whether a stage takes a standard normal deviate per band (common/random.mako)
  T          s2cl.cl.vectypes.VecTypes of the working precision, one lane
Arguments (in order; s2cl.forward.sense.sense_args)
  each stage's outputs  [n_bands x n_pixels]   (noisy, dn, flags, calibrated, reflectance, ...)
  radiance              [n_bands x n_pixels] real  noise-free band radiance (input)
  each stage's values   [n_bands] real            (noise_a, noise_b, lmin, lmax, scale, gain, lp, g, s, ...)
  (deviates) seed, frame  uint    noise stream (see common/random.mako)
  pixel_offset          uint    index of this chunk's first pixel (deviates key on the global index)
  each stage's scalars  (maxdn, ...)
  n_pixels              uint
Units: radiance W m-2 sr-1 um-1 throughout.
</%doc>
<%namespace name="st" file="common/stages.mako"/>
<%namespace name="rn" file="common/random.mako"/>
<% R = T.R %>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
% if deviates:
${rn.random(T)}
% endif
% for s in stages:
${getattr(st, s.device)(T)}
% endfor

__kernel void sense_bands(
    ${signature(args, T)})
{
    const uint i = get_global_id(0);
    if (i >= n_pixels)
        return;
% if deviates:
    const uint pixel = pixel_offset + i;
  % for g in sorted({bid >> 2 for bid in band_ids}):
    const ${R}4 z${g} = s2_normal4_${T.suffix}(seed, S2_TAG_SENSOR_NOISE, pixel, ${g}u, frame, 0u);
  % endfor
% endif
% if len(segments) > 1:
    ${R} X[${n_bands}];
% endif
% for si, (kind, group) in enumerate(segments):
  % if kind == "bands":
    % for s in group:
${getattr(st, s.device + "_step")(T, across)}
    % endfor
  % else:
    % for k in range(n_bands):
    {
        const size_t at = (size_t)${k}u * n_pixels + i;
        ${R} L = ${"radiance[at]" if si == 0 else f"X[{k}]"};
      % for s in group:
${getattr(st, s.device + "_step")(T, site(k))}
      % endfor
      % if si < len(segments) - 1:
        X[${k}] = L;
      % endif
    }
    % endfor
  % endif
% endfor
}
