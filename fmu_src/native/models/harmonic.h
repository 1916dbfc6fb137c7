/* harmonic: C port of models/harmonic.py (2-state EKF at a known frequency, and the estimator
 * over either process model).
 *
 * The estimator functions take and return a HarmonicState for both process models: under
 * GAUSS_MARKOV its fields x, P, drift are those of models.chain.EstimatorState and d, P12, P22
 * are 0 and untouched. */
#ifndef DRIFTFMU_HARMONIC_H
#define DRIFTFMU_HARMONIC_H

#include <stdint.h>

#include "drift.h"

#define HARMONIC_GAUSS_MARKOV 1
#define HARMONIC_HARMONIC 2

/* models.harmonic.HarmonicState, same fields in the same order. */
typedef struct {
    double x, d, P, P12, P22;
    DriftState drift;
} HarmonicState;

/* (C, S) = (cos 2 pi f Ts, sin 2 pi f Ts). */
void harmonic_rotation(double f, double Ts, double *C, double *S);
void harmonic_predict(double x, double d, double P11, double P12, double P22, double C,
                      double S, double Qh, double *xp, double *dp, double *p11, double *p12,
                      double *p22);
void harmonic_update(double x, double d, double P11, double P12, double P22, double z,
                     double a0, double a1, double a2, double R, double *x_post,
                     double *d_post, double *p11, double *p12, double *p22);
void harmonic_update_general(double x, double d, double P11, double P12, double P22, double z,
                             double a0, double a1, double a2, double R, double a3, double a4,
                             double *x_post, double *d_post, double *p11, double *p12,
                             double *p22);
void harmonic_step_general(double x, double d, double P11, double P12, double P22, double z,
                           double a0, double a1, double a2, double C, double S, double Qh,
                           double R, double a3, double a4, double *x_post, double *d_post,
                           double *p11, double *p12, double *p22);
void harmonic_step(double x, double d, double P11, double P12, double P22, double z, double a0,
                   double a1, double a2, double C, double S, double Qh, double R,
                   double *x_post, double *d_post, double *p11, double *p12, double *p22);

/* Filter state before the first sample; all fields NaN for an unknown process (Python
 * raises ValueError). */
HarmonicState harmonic_estimator_init(int64_t process, double x0, double P0);
HarmonicState harmonic_estimator_step(HarmonicState state, double z, double a0, double a1,
                                      double a2, double R, int64_t process, double A, double Q,
                                      double C, double S, double Qh);
HarmonicState harmonic_estimator_predict(HarmonicState state, int64_t process, double A,
                                         double Q, double C, double S, double Qh);
/* With a3, a4 and the known input (B, u) of the Gauss-Markov model (the harmonic model has no
 * input; B, u are ignored there, as in Python). */
HarmonicState harmonic_estimator_step_general(HarmonicState state, double z, double a0,
                                              double a1, double a2, double R, int64_t process,
                                              double A, double Q, double C, double S, double Qh,
                                              double a3, double a4, double B, double u);
HarmonicState harmonic_estimator_predict_general(HarmonicState state, int64_t process, double A,
                                                 double Q, double C, double S, double Qh,
                                                 double B, double u);

#endif
