/* chain: C port of the estimator part of models/chain.py (simulate is not ported). */
#ifndef DRIFTFMU_CHAIN_H
#define DRIFTFMU_CHAIN_H

#include "drift.h"

/* models.chain.EstimatorState, same fields in the same order. */
typedef struct {
    double x, P;
    DriftState drift;
} EstimatorState;

EstimatorState chain_estimator_init(double x0, double P0);
EstimatorState chain_estimator_step_general(EstimatorState state, double z, double a0,
                                            double a1, double a2, double A, double Q, double R,
                                            double a3, double a4, double B, double u);
EstimatorState chain_estimator_step(EstimatorState state, double z, double a0, double a1,
                                    double a2, double A, double Q, double R);
double chain_compensate(double z, double dc);

#endif
