/* drift: C port of models/drift.py; see drift.h. */
#include <math.h>

#include "drift.h"
#include "sensor.h"

DriftState drift_initial_state(void)
{
    DriftState s = {0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    return s;
}

double drift_running_mean(double mean_prev, double value, int64_t k)
{
    return ((double)(k - 1) * mean_prev + value) / (double)k;
}

void drift_posterior_moments(double x, double P, double *m2, double *m3, double *m4)
{
    double x2 = x * x;
    *m2 = x2 + P;
    *m3 = x2 * x + 3.0 * x * P;
    *m4 = x2 * x2 + 6.0 * x2 * P + 3.0 * P * P;
}

DriftState drift_update_general(DriftState state, double x_post, double P_post, double a2,
                                double a3, double a4)
{
    DriftState out = state; /* keeps t1, q1, t3, q3 on the quadratic path, as Python */
    double x2 = x_post * x_post, m2, m3, m4, x3, x4;
    out.k = state.k + 1;
    out.s1 = drift_running_mean(state.s1, x2 + P_post, out.k);
    if (!sensor_higher(a3, a4)) {
        out.dc2 = drift_running_mean(state.dc2, a2 * x2, out.k);
        out.s3 = drift_running_mean(state.s3, x2, out.k);
        out.dc3 = drift_running_mean(state.dc3, a2 * out.s3, out.k);
        return out;
    }
    drift_posterior_moments(x_post, P_post, &m2, &m3, &m4);
    x3 = x2 * x_post;
    x4 = x2 * x2;
    out.t1 = drift_running_mean(state.t1, m3, out.k);
    out.q1 = drift_running_mean(state.q1, m4, out.k);
    out.dc2 = drift_running_mean(state.dc2, a2 * x2 + a3 * x3 + a4 * x4, out.k);
    out.s3 = drift_running_mean(state.s3, x2, out.k);
    out.t3 = drift_running_mean(state.t3, x3, out.k);
    out.q3 = drift_running_mean(state.q3, x4, out.k);
    out.dc3 = drift_running_mean(state.dc3, a2 * out.s3 + a3 * out.t3 + a4 * out.q3, out.k);
    return out;
}

DriftState drift_update(DriftState state, double x_post, double P_post, double a2)
{
    return drift_update_general(state, x_post, P_post, a2, 0.0, 0.0);
}

void drift_estimates_general(DriftState state, double a2, double a3, double a4, double *dc1,
                             double *dc2, double *dc3)
{
    if (!sensor_higher(a3, a4))
        *dc1 = a2 * state.s1;
    else
        *dc1 = a2 * state.s1 + a3 * state.t1 + a4 * state.q1;
    *dc2 = state.dc2;
    *dc3 = state.dc3;
}

void drift_estimates(DriftState state, double a2, double *dc1, double *dc2, double *dc3)
{
    drift_estimates_general(state, a2, 0.0, 0.0, dc1, dc2, dc3);
}

double drift_select(const double dcs[3], int64_t estimator)
{
    if (estimator < 1 || estimator > 3) return NAN;
    return dcs[estimator - 1];
}
