/* bias: C port of models/bias.py; see bias.h. */
#include "bias.h"
#include "drift.h"
#include "dualaxis.h"
#include "ekf.h"
#include "ops.h"
#include "sensor.h"

double bias_factor(double tau_b, double Ts)
{
    return tau_b == 0.0 ? 1.0 : ops_exp(-Ts / tau_b);
}

Bias bias_init(double b0, double Pb0)
{
    Bias out;
    out.b = b0;
    out.Pxb = 0.0 * Pb0;
    out.Pbb = Pb0;
    return out;
}

double bias_expected(double x, double P, double a0, double a1, double a2, double a3, double a4)
{
    double m2, m3, m4;
    if (!sensor_higher(a3, a4)) return a0 + a1 * x + a2 * (x * x + P);
    drift_posterior_moments(x, P, &m2, &m3, &m4);
    return a0 + a1 * x + a2 * m2 + a3 * m3 + a4 * m4;
}

double bias_spread(double R, double a2, double P) { return R + 2.0 * a2 * a2 * P * P; }

void bias_predict(double x, double P, Bias bias, double A, double Q, double Fb, double Qb,
                  double B, double u, double *x_pred, double *P_pred, Bias *b_pred)
{
    ekf_predict_general(x, P, A, Q, B, u, x_pred, P_pred);
    b_pred->b = Fb * bias.b;
    b_pred->Pxb = A * Fb * bias.Pxb;
    b_pred->Pbb = Fb * Fb * bias.Pbb + Qb;
}

void bias_update(double x_pred, double P_pred, Bias bias, double z, double a0, double a1,
                 double a2, double R, double a3, double a4, double *x, double *P, Bias *b)
{
    double H = sensor_dh_dx_general(x_pred, a1, a2, a3, a4);
    double e = z - bias_expected(x_pred, P_pred, a0, a1, a2, a3, a4) - bias.b;
    dualaxis__row2(x_pred, bias.b, P_pred, bias.Pxb, bias.Pbb, H, 1.0, e,
                   bias_spread(R, a2, P_pred), x, &b->b, P, &b->Pxb, &b->Pbb);
}

EstimatorState bias_estimator_step(EstimatorState state, Bias *bias, double z, double a0,
                                   double a1, double a2, double A, double Q, double R,
                                   double Fb, double Qb, double a3, double a4, double B,
                                   double u)
{
    EstimatorState out;
    double x_pred, P_pred;
    Bias b_pred;
    bias_predict(state.x, state.P, *bias, A, Q, Fb, Qb, B, u, &x_pred, &P_pred, &b_pred);
    bias_update(x_pred, P_pred, b_pred, z, a0, a1, a2, R, a3, a4, &out.x, &out.P, bias);
    out.drift = drift_update_general(state.drift, out.x, out.P, a2, a3, a4);
    return out;
}

EstimatorState bias_estimator_predict(EstimatorState state, Bias *bias, double A, double Q,
                                      double Fb, double Qb, double B, double u)
{
    EstimatorState out = state;
    bias_predict(state.x, state.P, *bias, A, Q, Fb, Qb, B, u, &out.x, &out.P, bias);
    return out;
}

double bias_compensate(double z, double dc, double b) { return chain_compensate(z, dc) - b; }
