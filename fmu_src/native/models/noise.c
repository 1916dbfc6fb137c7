/* noise: C port of models/noise.py; see noise.h. */
#include "noise.h"
#include "ops.h"

/* The external definitions of the inline functions of noise.h. */
extern inline uint64_t noise_mix(uint64_t z);
extern inline double noise_central(double p);
extern inline double noise_normal_keyed(uint64_t key, uint64_t k);
extern inline double noise_ziggurat_of(uint64_t w);
extern inline double noise_ziggurat_keyed(uint64_t key, uint64_t k);

/* noise_zig_x, noise_zig_ratio, noise_zig_f */
#include "ziggurat_table.h"

uint64_t noise_key(uint64_t seed, uint64_t stream)
{
    return noise_mix(noise_mix(seed) ^ (stream * NOISE_GOLDEN));
}

uint64_t noise_bits(uint64_t seed, uint64_t stream, uint64_t k)
{
    return noise_mix(noise_key(seed, stream) + k * NOISE_GOLDEN);
}

/* The uniform in (0, 1) of a word (models.noise._open_uniform): (w >> 12) < 2^52, exact as a
 * double through int64_t, and so is + 0.5. */
static double open_uniform(uint64_t w)
{
    return ((double)(int64_t)(w >> 12) + 0.5) * 2.220446049250313e-16;
}

double noise_uniform(uint64_t seed, uint64_t stream, uint64_t k)
{
    return open_uniform(noise_bits(seed, stream, k));
}

static const double C_[6] = {-7.784894002430293e-03, -3.223964580411365e-01,
                             -2.400758277161838e+00, -2.549732539343734e+00,
                             4.374664141464968e+00, 2.938163982698783e+00};
static const double D_[4] = {7.784695709041462e-03, 3.224671290700398e-01,
                             2.445134137142996e+00, 3.754408661907416e+00};


static double lower_tail(double p)
{
    double q = ops_sqrt(-2.0 * ops_log(p));
    double num = ((((C_[0] * q + C_[1]) * q + C_[2]) * q + C_[3]) * q + C_[4]) * q + C_[5];
    double den = (((D_[0] * q + D_[1]) * q + D_[2]) * q + D_[3]) * q + 1.0;
    return num / den;
}

double noise_inverse_normal_cdf(double p)
{
    if (p < NOISE_P_LOW) return lower_tail(p);
    if (p > 1.0 - NOISE_P_LOW) return -lower_tail(1.0 - p);
    return noise_central(p);
}

double noise_normal(uint64_t seed, uint64_t stream, uint64_t k)
{
    return noise_inverse_normal_cdf(noise_uniform(seed, stream, k));
}



/* models.noise._density: exp(-x^2/2) */
static double density(double x)
{
    return ops_exp(-0.5 * x * x);
}

/* models.noise._next_word */
static uint64_t next_word(uint64_t w)
{
    return noise_mix(w + NOISE_GOLDEN);
}

double noise_ziggurat_rest(uint64_t w, unsigned i, double u, double x)
{
    for (;;) {
        double y;
        if (i == 0) {
            for (;;) { /* the tail beyond NOISE_ZIG_R */
                double a, b;
                w = next_word(w);
                a = -ops_log(open_uniform(w)) / NOISE_ZIG_R;
                w = next_word(w);
                b = -ops_log(open_uniform(w));
                if (b + b > a * a)
                    return u >= 0.0 ? NOISE_ZIG_R + a : -(NOISE_ZIG_R + a);
            }
        }
        w = next_word(w);
        y = noise_zig_f[i] + open_uniform(w) * (noise_zig_f[i + 1] - noise_zig_f[i]);
        if (y < density(x))
            return x;
        w = next_word(w);
        i = (unsigned)(w & 0xFF);
        u = (double)(int64_t)(w >> 11) * 2.220446049250313e-16 - 1.0;
        x = u * noise_zig_x[i];
        if (fabs(u) < noise_zig_ratio[i])
            return x;
    }
}

double noise_ziggurat(uint64_t seed, uint64_t stream, uint64_t k)
{
    return noise_ziggurat_of(noise_bits(seed, stream, k));
}
