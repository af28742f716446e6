<%doc>
common/random.mako: counter-based Gaussian deviates (Philox4x32-10 + Box-Muller), for kernels that add
sensor noise on the device (sense.cl.mako). The host twin is s2cl/forward/noise.py (bit-exact words,
the same deviates to rounding); the sweep takes its deviates from there.

  random(T)   emits, for the working precision of T (scalar types):
    uint4 s2_philox_words(uint seed, uint tag, uint c0, uint c1, uint c2, uint c3)
        raw Philox4x32-10 words of one counter (exposed for bit-exact tests)
    R  s2_uniform_<sfx>(uint x)       ((x >> 9) + 0.5) 2^-23: strictly inside (0, 1), exact in float and double
    R4 s2_normal4_<sfx>(uint seed, uint tag, uint pixel, uint group, uint frame, uint draw)
        four standard normals from one Philox call: Box-Muller on (u0, u1) and (u2, u3),
        r = sqrt(-2 ln u), (r cospi(2u'), r sinpi(2u'))
    S2_TAG_SENSOR_NOISE  the stream tag of sensor noise

A deviate is a pure function of (seed, pixel, band, frame, draw): key = {seed, tag}, counter =
{pixel, band >> 2, frame, draw}; the normal of band k is lane (k & 3) of s2_normal4. "draw" counts
Philox calls, not normals. Same seed, same value, whatever the work-group size, chunking, pixel order
or device. Uses pyopencl's Random123 header (pyopencl adds its include path to every build).
</%doc>

<%def name="random(T)">
#include <pyopencl-random123/philox.cl>
#ifndef S2_TAG_SENSOR_NOISE
#define S2_TAG_SENSOR_NOISE 0x53324e31u /* "S2N1" */
static inline uint4 s2_philox_words(uint seed, uint tag, uint c0, uint c1, uint c2, uint c3)
{
    philox4x32_key_t k = {{seed, tag}};
    philox4x32_ctr_t c = {{c0, c1, c2, c3}};
    philox4x32_ctr_t r = philox4x32(c, k);
    return (uint4)(r.v[0], r.v[1], r.v[2], r.v[3]);
}
#endif
#ifndef S2_RANDOM_${T.suffix.upper()}
#define S2_RANDOM_${T.suffix.upper()}
static inline ${T.R} s2_uniform_${T.suffix}(uint x)
{
    return ((${T.R})(x >> 9) + ${T.lit(0.5)}) * ${T.lit(1.1920928955078125e-07)}; /* 2^-23 */
}

static inline ${T.R}4 s2_normal4_${T.suffix}(uint seed, uint tag, uint pixel, uint group, uint frame, uint draw)
{
    const uint4 w = s2_philox_words(seed, tag, pixel, group, frame, draw);
    const ${T.R} r0 = sqrt(${T.lit(-2.0)} * log(s2_uniform_${T.suffix}(w.s0)));
    const ${T.R} r1 = sqrt(${T.lit(-2.0)} * log(s2_uniform_${T.suffix}(w.s2)));
    const ${T.R} t0 = ${T.lit(2.0)} * s2_uniform_${T.suffix}(w.s1);
    const ${T.R} t1 = ${T.lit(2.0)} * s2_uniform_${T.suffix}(w.s3);
    return (${T.R}4)(r0 * cospi(t0), r0 * sinpi(t0), r1 * cospi(t1), r1 * sinpi(t1));
}
#endif
</%def>
