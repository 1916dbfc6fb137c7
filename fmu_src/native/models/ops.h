/* ops: C port of models/_ops.py (elementwise helpers, arithmetic-only log, exp, sin2pi, sin).
 *
 * Same order of operations as the Python, so that IEEE 754 double arithmetic gives the same
 * bits.  Compile every unit with -std=c99 -O2 -ffp-contract=off -fno-fast-math.  Only exact or
 * correctly rounded library functions are used (sqrt, floor, frexp, ldexp).
 */
#ifndef DRIFTFMU_OPS_H
#define DRIFTFMU_OPS_H

#include <stdint.h>

/* Constants of models/_ops.py, as exact literals (Python repr). */
#define OPS_LN2 0.6931471805599453
#define OPS_SQRT_HALF 0.7071067811865476
#define OPS_PI 3.141592653589793
/* 2 pi (models._ops.TWO_PI, the exact double of pi): ops_sin divides by it. */
#define OPS_TWO_PI 6.283185307179586
/* exp: ln 2 split (fdlibm), 1 / ln 2, and the range limits of models._ops.exp. */
#define OPS_LN2_HI 0.6931471803691238
#define OPS_LN2_LO 1.9082149292705877e-10
#define OPS_INV_LN2 1.4426950408889634
#define OPS_EXP_HIGH 709.78
#define OPS_EXP_LOW -745.1332191019412

/* Correctly rounded square root. */
double ops_sqrt(double x);
/* Floor (as a double), as Python's float(math.floor(x)): floor(-0.0) is +0.0. */
double ops_floor(double x);
/* Mantissa in [0.5, 1) (*m) and integer exponent (*e), exactly: x = m 2^e. */
void ops_frexp(double x, double *m, int64_t *e);
/* m 2^e, exactly (one rounding when the result is subnormal). */
double ops_ldexp(double m, int64_t e);
/* Natural logarithm of a positive x by arithmetic only (models._ops.log). */
double ops_log(double x);
/* e^x by arithmetic only (models._ops.exp). */
double ops_exp(double x);
/* e^x by arithmetic only, its polynomial by Estrin's scheme (models._ops.exp_estrin). */
double ops_exp_estrin(double x);
/* sin(2 pi c) by arithmetic only (models._ops.sin2pi). */
double ops_sin2pi(double cycles);
/* sin(x), x in radians, by arithmetic only: ops_sin2pi(x / (2 pi)) (models._ops.sin). */
double ops_sin(double x);

#endif
