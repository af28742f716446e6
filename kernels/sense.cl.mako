<%doc>
sense.cl.mako: the radiometric stage of the sensor, per pixel and band:
  noise-free band radiance -> (+ Gaussian noise) -> (quantise to DN) -> (calibrate back to radiance)
  -> (atmospheric correction to band reflectance)

Template variables
  args       list of s2cl.cl.kernel_args.Arg (host binds the same list)
  signature  function rendering args
  n_bands    number of bands (unrolled)
  band_ids   global index of each band: its noise is lane (id & 3) of Philox counter group (id >> 2),
             so a band's noise does not depend on which other bands share the kernel
  noise, quantise, calibrate, correct   bools: which stages exist. A stage that is off has no code
             and no arguments in the compiled kernel.
  T          s2cl.cl.vectypes.VecTypes of the working precision, one lane: the types of the kernel and
             of the shared stage functions (common/stages.mako: quantise, calibrate, correct, the same
             code the sweep kernel runs; common/random.mako: the noise)
Defines: none.
Arguments (in order; see s2cl/forward/sense.py)
  (noise)     noisy       [n_bands x n_pixels] real  radiance with noise
  (quantise)  dn          [n_bands x n_pixels] ushort  digital numbers
  (quantise)  flags       [n_bands x n_pixels] uchar   S2_FLAG_LOW / _HIGH / _NODATA (common/s2_status.clh)
  (calibrate) calibrated  [n_bands x n_pixels] real  radiance from DN
  (correct)   reflectance [n_bands x n_pixels] real  band reflectance (s2cl.atmos.correction)
              radiance    [n_bands x n_pixels] real  noise-free band radiance (input)
  (noise)     noise_a, noise_b [n_bands] real   sigma^2 = a + b max(L, 0)  (width scaling applied)
  (quantise)  lmin, lmax, scale [n_bands] real
  (calibrate) gain        [n_bands] real
  (correct)   band_lp, band_g, band_s [n_bands] real  band-effective path radiance, ground term,
              spherical albedo of the state assumed by the correction
  (noise)     seed, frame  uint    noise stream (see common/random.mako)
              pixel_offset uint    index of this chunk's first pixel (noise keys on the global index)
  (quantise)  maxdn        uint    2^bits - 1
              n_pixels     uint
Units: radiance W m-2 sr-1 um-1 throughout.
</%doc>
<%namespace name="st" file="common/stages.mako"/>
<%namespace name="rn" file="common/random.mako"/>
<% R = T.R %>
% if T.double:
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
% if noise:
${rn.random(T)}
${st.noise(T)}
% endif
% if quantise:
${st.quantise(T)}
% endif
% if calibrate:
${st.calibrate(T)}
% endif
% if correct:
${st.correct(T)}
% endif

__kernel void sense_bands(
    ${signature(args, T)})
{
    const uint i = get_global_id(0);
    if (i >= n_pixels)
        return;
% if noise:
    const uint pixel = pixel_offset + i;
  % for g in sorted({bid >> 2 for bid in band_ids}):
    const ${R}4 z${g} = s2_normal4_${T.suffix}(seed, S2_TAG_SENSOR_NOISE, pixel, ${g}u, frame, 0u);
  % endfor
% endif
% for k in range(n_bands):
    {
        const size_t at = (size_t)${k}u * n_pixels + i;
        ${R} L = radiance[at];
  % if noise:
        L = s2_add_noise_${T.suffix}(L, s2_noise_sigma_${T.suffix}(L, noise_a[${k}], noise_b[${k}]),
                                      z${band_ids[k] >> 2}.s${band_ids[k] & 3});
        noisy[at] = L;
  % endif
  % if quantise:
        ${T.M} flag;
        const ${R} q = s2_quantise_${T.suffix}(L, lmin[${k}], lmax[${k}], scale[${k}], (${R})maxdn, &flag);
        dn[at] = (ushort)q;
        flags[at] = (uchar)flag;
  % endif
  % if calibrate:
        L = s2_calibrate_${T.suffix}(q, flag, lmin[${k}], gain[${k}]);
        calibrated[at] = L;
  % endif
  % if correct:
        reflectance[at] = s2_correct_${T.suffix}(L, band_lp[${k}], band_g[${k}], band_s[${k}]);
  % endif
    }
% endfor
}
