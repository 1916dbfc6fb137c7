/* drift: C port of models/drift.py; see drift.h. */
#include <math.h>

#include "drift.h"

DriftState drift_initial_state(void)
{
    DriftState s = {0, 0.0, 0.0, 0.0, 0.0};
    return s;
}

double drift_running_mean(double mean_prev, double value, int64_t k)
{
    return ((double)(k - 1) * mean_prev + value) / (double)k;
}

DriftState drift_update(DriftState state, double x_post, double P_post, double a2)
{
    DriftState out;
    double x2 = x_post * x_post;
    out.k = state.k + 1;
    out.s1 = drift_running_mean(state.s1, x2 + P_post, out.k);
    out.dc2 = drift_running_mean(state.dc2, a2 * x2, out.k);
    out.s3 = drift_running_mean(state.s3, x2, out.k);
    out.dc3 = drift_running_mean(state.dc3, a2 * out.s3, out.k);
    return out;
}

void drift_estimates(DriftState state, double a2, double *dc1, double *dc2, double *dc3)
{
    *dc1 = a2 * state.s1;
    *dc2 = state.dc2;
    *dc3 = state.dc3;
}

double drift_select(const double dcs[3], int64_t estimator)
{
    if (estimator < 1 || estimator > 3) return NAN;
    return dcs[estimator - 1];
}
