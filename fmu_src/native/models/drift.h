/* drift: C port of models/drift.py (the letter's EKF1-3 drift estimators).  Only what the FMUs
 * use (gap_db, expected_gap_db and references are not ported). */
#ifndef DRIFTFMU_DRIFT_H
#define DRIFTFMU_DRIFT_H

#include <stdint.h>

/* models.drift.DriftState, same fields in the same order. */
typedef struct {
    int64_t k;
    double s1, dc2, s3, dc3;
    double t1, q1, t3, q3; /* 3rd/4th-order sums: 0 for the letter's quadratic sensor */
} DriftState;

DriftState drift_initial_state(void);
/* ((k - 1) mean_prev + value) / k */
double drift_running_mean(double mean_prev, double value, int64_t k);
/* (x^2 + P, x^3 + 3 x P, x^4 + 6 x^2 P + 3 P^2): moments of N(x, P). */
void drift_posterior_moments(double x, double P, double *m2, double *m3, double *m4);
DriftState drift_update_general(DriftState state, double x_post, double P_post, double a2,
                                double a3, double a4);
DriftState drift_update(DriftState state, double x_post, double P_post, double a2);
/* (dc1, dc2, dc3) of a state. */
void drift_estimates_general(DriftState state, double a2, double a3, double a4, double *dc1,
                             double *dc2, double *dc3);
void drift_estimates(DriftState state, double a2, double *dc1, double *dc2, double *dc3);
/* dcs[estimator - 1] for estimator 1, 2 or 3; NaN otherwise (Python raises ValueError). */
double drift_select(const double dcs[3], int64_t estimator);

#endif
