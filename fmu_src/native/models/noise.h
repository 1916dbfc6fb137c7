/* noise: C port of models/noise.py (counter-based Gaussian noise, a pure function of
 * (seed, stream, k)).  Integers are uint64_t (Python's `int & MASK64`); a negative seed is
 * converted to uint64_t as two's complement, as `int(seed) & MASK64` does. */
#ifndef DRIFTFMU_NOISE_H
#define DRIFTFMU_NOISE_H

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

/* SplitMix64 finaliser (models.noise._mix). */
uint64_t noise_mix(uint64_t z);
/* 64-bit key of a (seed, stream) pair. */
uint64_t noise_key(uint64_t seed, uint64_t stream);
/* 64 random bits for sample k of stream under seed. */
uint64_t noise_bits(uint64_t seed, uint64_t stream, uint64_t k);
/* Uniform draw in (0, 1) on a grid of 2^-52. */
double noise_uniform(uint64_t seed, uint64_t stream, uint64_t k);
/* The central branch of noise_inverse_normal_cdf (noise._central), for p_low <= p <= 1 - p_low:
 * the batch kernel evaluates it for several runs at once and the tails one by one. */
double noise_central(double p);
/* Acklam's inverse normal CDF of p in (0, 1). */
double noise_inverse_normal_cdf(double p);
/* Standard normal draw for sample k of stream under seed. */
double noise_normal(uint64_t seed, uint64_t stream, uint64_t k);
/* The same draw from the stream's key (noise_key(seed, stream)), for a caller that keeps the
 * key instead of deriving it at every sample (C only: Python's key is cached, _key_int). */
double noise_normal_keyed(uint64_t key, uint64_t k);

#endif
