/* excitation: C port of models/excitation.py. */
#ifndef DRIFTFMU_EXCITATION_H
#define DRIFTFMU_EXCITATION_H

#include <stdint.h>

#define EXCITATION_GAUSSIAN 1
#define EXCITATION_SINUSOIDAL 2
/* Known input u (models.excitation.DRIVES): off, or the GAUSSIAN / SINUSOIDAL kinds above. */
#define EXCITATION_DRIVE_OFF 0

/* x_k = A x_{k-1} + B u + sqrt(Q) w (the B u term only when B != 0, as Python). */
double excitation_gauss_markov_general(double x_prev, double A, double Q, double w, double B,
                                       double u);
/* x_k = A x_{k-1} + sqrt(Q) w. */
double excitation_gauss_markov(double x_prev, double A, double Q, double w);
double excitation_gaussian_sample_general(double x_prev, double A, double Q, int64_t seed,
                                          int64_t k, double B, double u);
/* Sample k of the known input u (models.excitation.input_sample); NaN for an unknown drive
 * (Python raises). */
double excitation_input_sample(int64_t drive, int64_t seed, int64_t k, double Qu, double Xu,
                               double fu, double Ts);
/* Sample k of the Gauss-Markov excitation under seed (process-noise stream). */
double excitation_gaussian_sample(double x_prev, double A, double Q, int64_t seed, int64_t k);
/* Sample k of the 2-D Gauss-Markov excitation (models.excitation.gaussian_pair): (*x, *y). */
void excitation_gaussian_pair(double x_prev, double y_prev, double A, double Q, double Qy,
                              double rho, int64_t seed, int64_t k, double *x, double *y);
/* The same with the known input B u driving x. */
void excitation_gaussian_pair_general(double x_prev, double y_prev, double A, double Q,
                                      double Qy, double rho, int64_t seed, int64_t k, double B,
                                      double u, double *x, double *y);
/* The same from its two standard normal draws w1 (process noise) and w2 (second axis; not used
 * while Qy = 0) (models.excitation.correlated_pair). */
void excitation_correlated_pair(double x_prev, double y_prev, double A, double Q, double Qy,
                                double rho, double w1, double w2, double B, double u, double *x,
                                double *y);
/* Sample k of X sin(2 pi f t_k + phi), t_k = (k - 1) Ts. */
double excitation_sine(int64_t k, double X, double f, double Ts, double phi);
/* Q / (1 - A^2) (Gaussian) or X^2 / 2 (sinusoidal); NaN for another kind (Python raises). */
double excitation_stationary_variance(int64_t kind, double A, double Q, double X);

#endif
