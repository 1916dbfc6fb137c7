/* harmonic: C port of models/harmonic.py; see harmonic.h. */
#include <math.h>

#include "chain.h"
#include "ekf.h"
#include "harmonic.h"
#include "ops.h"
#include "sensor.h"

void harmonic_rotation(double f, double Ts, double *C, double *S)
{
    *C = ops_sin2pi(f * Ts + 0.25);
    *S = ops_sin2pi(f * Ts);
}

void harmonic_predict(double x, double d, double P11, double P12, double P22, double C,
                      double S, double Qh, double *xp, double *dp, double *p11, double *p12,
                      double *p22)
{
    double CC = C * C, SS = S * S, CS = C * S;
    *xp = C * x + S * d;
    *dp = C * d - S * x;
    *p11 = CC * P11 + 2.0 * CS * P12 + SS * P22 + Qh;
    *p12 = CS * (P22 - P11) + (CC - SS) * P12;
    *p22 = SS * P11 - 2.0 * CS * P12 + CC * P22 + Qh;
}

void harmonic_update(double x, double d, double P11, double P12, double P22, double z,
                     double a0, double a1, double a2, double R, double *x_post,
                     double *d_post, double *p11, double *p12, double *p22)
{
    harmonic_update_general(x, d, P11, P12, P22, z, a0, a1, a2, R, 0.0, 0.0, x_post, d_post,
                            p11, p12, p22);
}

void harmonic_update_general(double x, double d, double P11, double P12, double P22, double z,
                             double a0, double a1, double a2, double R, double a3, double a4,
                             double *x_post, double *d_post, double *p11, double *p12,
                             double *p22)
{
    double H = sensor_dh_dx_general(x, a1, a2, a3, a4);
    double Sv = H * H * P11 + R;
    double K1 = P11 * H / Sv;
    double K2 = P12 * H / Sv;
    double e = z - sensor_h_general(x, a0, a1, a2, a3, a4);
    double m11 = 1.0 - K1 * H;
    double m21 = -K2 * H;
    *p11 = m11 * m11 * P11 + K1 * K1 * R;
    *p12 = m11 * (m21 * P11 + P12) + K1 * K2 * R;
    *p22 = m21 * m21 * P11 + 2.0 * m21 * P12 + P22 + K2 * K2 * R;
    *x_post = x + K1 * e;
    *d_post = d + K2 * e;
}

void harmonic_step(double x, double d, double P11, double P12, double P22, double z, double a0,
                   double a1, double a2, double C, double S, double Qh, double R,
                   double *x_post, double *d_post, double *p11, double *p12, double *p22)
{
    harmonic_step_general(x, d, P11, P12, P22, z, a0, a1, a2, C, S, Qh, R, 0.0, 0.0, x_post,
                          d_post, p11, p12, p22);
}

void harmonic_step_general(double x, double d, double P11, double P12, double P22, double z,
                           double a0, double a1, double a2, double C, double S, double Qh,
                           double R, double a3, double a4, double *x_post, double *d_post,
                           double *p11, double *p12, double *p22)
{
    double xp, dp, q11, q12, q22;
    harmonic_predict(x, d, P11, P12, P22, C, S, Qh, &xp, &dp, &q11, &q12, &q22);
    harmonic_update_general(xp, dp, q11, q12, q22, z, a0, a1, a2, R, a3, a4, x_post, d_post,
                            p11, p12, p22);
}

HarmonicState harmonic_estimator_init(int64_t process, double x0, double P0)
{
    HarmonicState s;
    s.drift = drift_initial_state();
    if (process == HARMONIC_GAUSS_MARKOV) {
        EstimatorState e = chain_estimator_init(x0, P0);
        s.x = e.x;
        s.d = 0.0;
        s.P = e.P;
        s.P12 = 0.0;
        s.P22 = 0.0;
        s.drift = e.drift;
    } else if (process == HARMONIC_HARMONIC) {
        s.x = x0;
        s.d = 0.0 * x0;
        s.P = P0;
        s.P12 = 0.0 * P0;
        s.P22 = P0;
    } else {
        s.x = s.d = s.P = s.P12 = s.P22 = NAN;
    }
    return s;
}

HarmonicState harmonic_estimator_step(HarmonicState state, double z, double a0, double a1,
                                      double a2, double R, int64_t process, double A, double Q,
                                      double C, double S, double Qh)
{
    return harmonic_estimator_step_general(state, z, a0, a1, a2, R, process, A, Q, C, S, Qh,
                                           0.0, 0.0, 0.0, 0.0);
}

HarmonicState harmonic_estimator_step_general(HarmonicState state, double z, double a0,
                                              double a1, double a2, double R, int64_t process,
                                              double A, double Q, double C, double S, double Qh,
                                              double a3, double a4, double B, double u)
{
    HarmonicState out = state;
    if (process == HARMONIC_GAUSS_MARKOV) {
        EstimatorState e;
        e.x = state.x;
        e.P = state.P;
        e.drift = state.drift;
        e = chain_estimator_step_general(e, z, a0, a1, a2, A, Q, R, a3, a4, B, u);
        out.x = e.x;
        out.P = e.P;
        out.drift = e.drift;
        return out;
    }
    harmonic_step_general(state.x, state.d, state.P, state.P12, state.P22, z, a0, a1, a2, C, S,
                          Qh, R, a3, a4, &out.x, &out.d, &out.P, &out.P12, &out.P22);
    out.drift = drift_update_general(state.drift, out.x, out.P, a2, a3, a4);
    return out;
}

HarmonicState harmonic_estimator_predict(HarmonicState state, int64_t process, double A,
                                         double Q, double C, double S, double Qh)
{
    return harmonic_estimator_predict_general(state, process, A, Q, C, S, Qh, 0.0, 0.0);
}

HarmonicState harmonic_estimator_predict_general(HarmonicState state, int64_t process, double A,
                                                 double Q, double C, double S, double Qh,
                                                 double B, double u)
{
    HarmonicState out = state;
    if (process == HARMONIC_GAUSS_MARKOV) {
        ekf_predict_general(state.x, state.P, A, Q, B, u, &out.x, &out.P);
        return out;
    }
    harmonic_predict(state.x, state.d, state.P, state.P12, state.P22, C, S, Qh, &out.x, &out.d,
                     &out.P, &out.P12, &out.P22);
    return out;
}
