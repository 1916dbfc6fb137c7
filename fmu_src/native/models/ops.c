/* ops: C port of models/_ops.py; see ops.h.  Same operations in the same order as the Python. */
#include <math.h>
#include <stdint.h>

#include "ops.h"

double ops_sqrt(double x) { return sqrt(x); }

/* float(math.floor(x)) goes through a Python int, so a zero result is +0.0 (floor(-0.0) too).
 * Below 2^52 in magnitude without the library call: x truncated towards zero is an exact int64
 * and its double exact (a zero +0.0), one less where that is above x (exact too).  From 2^52 on,
 * every double is whole, and inf and nan are their own floor: the library's floor gives x. */
double ops_floor(double x)
{
    double r;
    if (fabs(x) < 4503599627370496.0) {
        r = (double)(int64_t)x;
        return r > x ? r - 1.0 : r;
    }
    r = floor(x);
    return r == 0.0 ? 0.0 : r;
}

void ops_frexp(double x, double *m, int64_t *e)
{
    int ei = 0;
    *m = frexp(x, &ei);
    *e = ei;
}

double ops_ldexp(double m, int64_t e)
{
    /* clamp: beyond +-2200 the result is inf/0 (or m itself for 0, inf, nan) anyway */
    if (e > 2200) e = 2200;
    if (e < -2200) e = -2200;
    return ldexp(m, (int)e);
}

/* frexp of a positive normal x from its bits (the library call otherwise): the biased exponent
 * less 1022, and the significand under the exponent of [0.5, 1).  Both exact, as frexp's. */
static void log_frexp(double x, double *m, int64_t *e)
{
    union { double d; uint64_t u; } b;
    b.d = x;
    if (x > 0.0 && (b.u >> 52) - 1 < 0x7FE) { /* biased exponent 1 .. 0x7FE: normal, finite */
        *e = (int64_t)(b.u >> 52) - 1022;
        b.u = (b.u & UINT64_C(0x000FFFFFFFFFFFFF)) | UINT64_C(0x3FE0000000000000);
        *m = b.d;
        return;
    }
    ops_frexp(x, m, e);
}

double ops_log(double x)
{
    double m, s, s2, poly;
    int64_t e;
    log_frexp(x, &m, &e);
    if (m < OPS_SQRT_HALF) {
        m = m * 2.0;
        e = e - 1;
    }
    s = (m - 1.0) / (m + 1.0);
    s2 = s * s;
    /* Horner over k = 21, 19, .., 1, written out: 1.0 / k is a constant the compiler folds
     * (correctly rounded, as Python's), not a division at every call */
    poly = 1.0 / 21.0;
    poly = poly * s2 + 1.0 / 19.0;
    poly = poly * s2 + 1.0 / 17.0;
    poly = poly * s2 + 1.0 / 15.0;
    poly = poly * s2 + 1.0 / 13.0;
    poly = poly * s2 + 1.0 / 11.0;
    poly = poly * s2 + 1.0 / 9.0;
    poly = poly * s2 + 1.0 / 7.0;
    poly = poly * s2 + 1.0 / 5.0;
    poly = poly * s2 + 1.0 / 3.0;
    poly = poly * s2 + 1.0 / 1.0;
    return (double)e * OPS_LN2 + 2.0 * s * poly;
}

/* 1.0 / k! for k = 0 .. 14 (Python: 1.0 / math.factorial(k), printed with repr). */
static const double INV_FACTORIAL[15] = {
    1.0, 1.0, 0.5, 0.16666666666666666, 0.041666666666666664, 0.008333333333333333,
    0.001388888888888889, 0.0001984126984126984, 2.48015873015873e-05, 2.7557319223985893e-06,
    2.755731922398589e-07, 2.505210838544172e-08, 2.08767569878681e-09, 1.6059043836821613e-10,
    1.1470745597729725e-11};

/* poly 2^n of ops_exp: for -1022 <= n <= 1023 the product with 2^n built from its bits, which
 * is ldexp's result (both are the exact m 2^n correctly rounded, a subnormal one too), without
 * the library call; ops_ldexp otherwise (2^n is not a normal double there). */
static double exp_scale(double m, int64_t n)
{
    if (n >= -1022 && n <= 1023) {
        union { uint64_t u; double d; } p;
        p.u = (uint64_t)(n + 1023) << 52;
        return m * p.d;
    }
    return ops_ldexp(m, n);
}

/* models._ops._horner: sum r^k / k! for k = 0 .. 14, Horner from 1/14! down to 1/0! (the
 * loop's operations in its order, written out). */
static inline double exp_poly_horner(double r)
{
    const double *c = INV_FACTORIAL;
    double poly = c[14] * r + c[13];
    poly = poly * r + c[12];
    poly = poly * r + c[11];
    poly = poly * r + c[10];
    poly = poly * r + c[9];
    poly = poly * r + c[8];
    poly = poly * r + c[7];
    poly = poly * r + c[6];
    poly = poly * r + c[5];
    poly = poly * r + c[4];
    poly = poly * r + c[3];
    poly = poly * r + c[2];
    poly = poly * r + c[1];
    return poly * r + c[0];
}

/* models._ops._estrin: the same sum, pairs joined by r^2, then r^4, then r^8 (the Python
 * expressions as written). */
static inline double exp_poly_estrin(double r)
{
    const double *c = INV_FACTORIAL;
    const double r2 = r * r, r4 = r2 * r2;
    const double q0 = (c[0] + c[1] * r) + (c[2] + c[3] * r) * r2;
    const double q1 = (c[4] + c[5] * r) + (c[6] + c[7] * r) * r2;
    const double q2 = (c[8] + c[9] * r) + (c[10] + c[11] * r) * r2;
    const double q3 = (c[12] + c[13] * r) + c[14] * r2;
    return (q0 + q1 * r4) + (q2 + q3 * r4) * (r4 * r4);
}

/* models._ops._exp_reduced: e^x = poly_of(r) 2^n, inf, 0.0 or nan out of the range (inlined
 * into each caller with its polynomial). */
static inline double exp_reduced(double x, double (*poly_of)(double))
{
    double n, r;
    if (x != x) return x;
    if (x > OPS_EXP_HIGH) return HUGE_VAL;
    if (x < OPS_EXP_LOW) return 0.0;
    n = ops_floor(x * OPS_INV_LN2 + 0.5);
    r = (x - n * OPS_LN2_HI) - n * OPS_LN2_LO;
    return exp_scale(poly_of(r), (int64_t)n);
}

double ops_exp(double x)
{
    return exp_reduced(x, exp_poly_horner);
}

double ops_exp_estrin(double x)
{
    return exp_reduced(x, exp_poly_estrin);
}

/* (+-1) / n! for n = 1, 3, ..., 23 (Python: sign / math.factorial(n), printed with repr). */
static const double SIN_COEFF[12] = {
    1.0, -0.16666666666666666, 0.008333333333333333, -0.0001984126984126984,
    2.7557319223985893e-06, -2.505210838544172e-08, 1.6059043836821613e-10,
    -7.647163731819816e-13, 2.8114572543455206e-15, -8.22063524662433e-18,
    1.9572941063391263e-20, -3.8681701706306835e-23};

double ops_sin2pi(double cycles)
{
    double r, sign, t, t2, poly;
    int n;
    r = cycles - ops_floor(cycles);
    sign = r >= 0.5 ? -1.0 : 1.0;
    r = r >= 0.5 ? r - 0.5 : r;
    r = r > 0.25 ? 0.5 - r : r;
    t = 2.0 * OPS_PI * r;
    t2 = t * t;
    poly = 0.0;
    for (n = 23; n > 0; n -= 2)
        poly = poly * t2 + SIN_COEFF[n / 2];
    return sign * t * poly;
}

double ops_sin(double x) { return ops_sin2pi(x / OPS_TWO_PI); }
