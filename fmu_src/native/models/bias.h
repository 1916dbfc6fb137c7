/* bias: C port of models/bias.py (the DriftEstimator's filter over [x, b]: a random-walk or
 * Gauss-Markov bias b beside the state x, z = h(x) + b + v).  Tuples come back through
 * out-pointers in the order of the Python tuple; the guidance functions (qb_*,
 * steady_variance) and the batch check are not ported. */
#ifndef DRIFTFMU_BIAS_H
#define DRIFTFMU_BIAS_H

#include "chain.h"

/* models.bias.Bias, same fields in the same order. */
typedef struct {
    double b, Pxb, Pbb;
} Bias;

/* F_b: exp(-Ts / tau_b) (arithmetic only), 1 for tau_b = 0. */
double bias_factor(double tau_b, double Ts);
Bias bias_init(double b0, double Pb0);
/* E[h(x)] under N(x, P). */
double bias_expected(double x, double P, double a0, double a1, double a2, double a3, double a4);
/* R + 2 a2^2 P^2. */
double bias_spread(double R, double a2, double P);
void bias_predict(double x, double P, Bias bias, double A, double Q, double Fb, double Qb,
                  double B, double u, double *x_pred, double *P_pred, Bias *b_pred);
void bias_update(double x_pred, double P_pred, Bias bias, double z, double a0, double a1,
                 double a2, double R, double a3, double a4, double *x, double *P, Bias *b);
/* (state, bias) of models.bias.estimator_step / estimator_predict: state and *bias in and
 * out. */
EstimatorState bias_estimator_step(EstimatorState state, Bias *bias, double z, double a0,
                                   double a1, double a2, double A, double Q, double R,
                                   double Fb, double Qb, double a3, double a4, double B,
                                   double u);
EstimatorState bias_estimator_predict(EstimatorState state, Bias *bias, double A, double Q,
                                      double Fb, double Qb, double B, double u);
/* z - dc - b. */
double bias_compensate(double z, double dc, double b);

#endif
