/* noise: C port of models/noise.py (counter-based Gaussian noise, a pure function of
 * (seed, stream, k)).  Integers are uint64_t (Python's `int & MASK64`); a negative seed is
 * converted to uint64_t as two's complement, as `int(seed) & MASK64` does. */
#ifndef DRIFTFMU_NOISE_H
#define DRIFTFMU_NOISE_H

#include <math.h>
#include <stdint.h>

#define NOISE_MASK64 UINT64_C(0xFFFFFFFFFFFFFFFF)
#define NOISE_GOLDEN UINT64_C(0x9E3779B97F4A7C15)

/* Streams (models.noise.STREAM_*). */
#define NOISE_STREAM_PROCESS 1
#define NOISE_STREAM_MEASUREMENT 2
#define NOISE_STREAM_SENSOR_Y 3
#define NOISE_STREAM_PHASE 4
#define NOISE_STREAM_MEASUREMENT_Y 5
#define NOISE_STREAM_INPUT 6
/* the sensor's slow errors (models/errors.py); index 0 is the draw before sample 1 */
#define NOISE_STREAM_TURN_ON 7
#define NOISE_STREAM_RANDOM_WALK 8
#define NOISE_STREAM_BIAS_GM 9
#define NOISE_STREAM_FLICKER 16 /* component i: NOISE_STREAM_FLICKER + i */

#define NOISE_P_LOW 0.02425

/* SplitMix64 finaliser (models.noise._mix).  It, noise_central, noise_normal_keyed and the
 * ziggurat's noise_ziggurat_of and noise_ziggurat_keyed are C99
 * inline definitions here (a native sensor draws several streams a sample: no call each), with
 * their external definitions in noise.c. */
inline uint64_t noise_mix(uint64_t z)
{
    z = (z ^ (z >> 30)) * UINT64_C(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)) * UINT64_C(0x94D049BB133111EB);
    return z ^ (z >> 31);
}
/* 64-bit key of a (seed, stream) pair. */
uint64_t noise_key(uint64_t seed, uint64_t stream);
/* 64 random bits for sample k of stream under seed. */
uint64_t noise_bits(uint64_t seed, uint64_t stream, uint64_t k);
/* Uniform draw in (0, 1) on a grid of 2^-52. */
double noise_uniform(uint64_t seed, uint64_t stream, uint64_t k);
/* The central branch of noise_inverse_normal_cdf (noise._central), for p_low <= p <= 1 - p_low:
 * the batch kernel evaluates it for several runs at once and the tails one by one. */
inline double noise_central(double p)
{
    /* Acklam's coefficients (models.noise._A, _B) */
    static const double A[6] = {-3.969683028665376e+01, 2.209460984245205e+02,
                                -2.759285104469687e+02, 1.383577518672690e+02,
                                -3.066479806614716e+01, 2.506628277459239e+00};
    static const double B[5] = {-5.447609879822406e+01, 1.615858368580409e+02,
                                -1.556989798598866e+02, 6.680131188771972e+01,
                                -1.328068155288572e+01};
    double q = p - 0.5;
    double r = q * q;
    double num = (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q;
    double den = ((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0;
    return num / den;
}
/* Acklam's inverse normal CDF of p in (0, 1). */
double noise_inverse_normal_cdf(double p);
/* Standard normal draw for sample k of stream under seed. */
double noise_normal(uint64_t seed, uint64_t stream, uint64_t k);
/* The same draw from the stream's key (noise_key(seed, stream)), for a caller that keeps the
 * key instead of deriving it at every sample (C only: Python's key is cached, _key_int). */
inline double noise_normal_keyed(uint64_t key, uint64_t k)
{
    const uint64_t bits = noise_mix(key + k * NOISE_GOLDEN);
    /* (bits >> 12 < 2^52: the same double through int64_t, whose conversion is one
     * instruction where uint64_t's is several) */
    const double p = ((double)(int64_t)(bits >> 12) + 0.5) * 2.220446049250313e-16;
    /* noise_inverse_normal_cdf, its central branch here and its tails out of line */
    return p < NOISE_P_LOW || p > 1.0 - NOISE_P_LOW ? noise_inverse_normal_cdf(p)
                                                    : noise_central(p);
}

/* The ziggurat (models.noise.ziggurat_of): the slow errors' draws.  Its tables (noise.ZIG_X,
 * ZIG_RATIO, ZIG_F) are defined in noise.c from the generated ziggurat_table.h. */
#define NOISE_ZIG_N 256
#define NOISE_ZIG_R 3.6541528853610088
extern const double noise_zig_x[NOISE_ZIG_N + 1];
extern const double noise_zig_ratio[NOISE_ZIG_N];
extern const double noise_zig_f[NOISE_ZIG_N + 1];
/* The draw whose first try (word w: layer i, u, x) was not in its layer's fast region
 * (noise._ziggurat_rest). */
double noise_ziggurat_rest(uint64_t w, unsigned i, double u, double x);
/* The standard normal draw of the 64-bit word w: its layer's fast region inline, the rest out
 * of line. */
inline double noise_ziggurat_of(uint64_t w)
{
    const unsigned i = (unsigned)(w & 0xFF);
    /* (w >> 11 < 2^53: exact through int64_t, one conversion instruction) */
    const double u = (double)(int64_t)(w >> 11) * 2.220446049250313e-16 - 1.0;
    const double x = u * noise_zig_x[i];
    return fabs(u) < noise_zig_ratio[i] ? x : noise_ziggurat_rest(w, i, u, x);
}
/* Standard normal draw for sample k of stream under seed by the ziggurat (noise.ziggurat). */
double noise_ziggurat(uint64_t seed, uint64_t stream, uint64_t k);
/* The same draw from the stream's key. */
inline double noise_ziggurat_keyed(uint64_t key, uint64_t k)
{
    return noise_ziggurat_of(noise_mix(key + k * NOISE_GOLDEN));
}

#endif
