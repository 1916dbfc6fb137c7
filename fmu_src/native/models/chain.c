/* chain: C port of the estimator part of models/chain.py; see chain.h. */
#include "chain.h"
#include "ekf.h"

EstimatorState chain_estimator_init(double x0, double P0)
{
    EstimatorState s;
    s.x = x0;
    s.P = P0;
    s.drift = drift_initial_state();
    return s;
}

EstimatorState chain_estimator_step_general(EstimatorState state, double z, double a0,
                                            double a1, double a2, double A, double Q, double R,
                                            double a3, double a4, double B, double u)
{
    EstimatorState out;
    ekf_step_general(state.x, state.P, z, a0, a1, a2, A, Q, R, a3, a4, B, u, &out.x, &out.P);
    out.drift = drift_update_general(state.drift, out.x, out.P, a2, a3, a4);
    return out;
}

EstimatorState chain_estimator_step(EstimatorState state, double z, double a0, double a1,
                                    double a2, double A, double Q, double R)
{
    return chain_estimator_step_general(state, z, a0, a1, a2, A, Q, R, 0.0, 0.0, 0.0, 0.0);
}

double chain_compensate(double z, double dc) { return z - dc; }
