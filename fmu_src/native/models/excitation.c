/* excitation: C port of models/excitation.py; see excitation.h. */
#include <math.h>

#include "excitation.h"
#include "noise.h"
#include "ops.h"

double excitation_gauss_markov_general(double x_prev, double A, double Q, double w, double B,
                                       double u)
{
    if (B == 0.0) return A * x_prev + ops_sqrt(Q) * w;
    return A * x_prev + B * u + ops_sqrt(Q) * w;
}

double excitation_gauss_markov(double x_prev, double A, double Q, double w)
{
    return excitation_gauss_markov_general(x_prev, A, Q, w, 0.0, 0.0);
}

double excitation_gaussian_sample_general(double x_prev, double A, double Q, int64_t seed,
                                          int64_t k, double B, double u)
{
    return excitation_gauss_markov_general(
        x_prev, A, Q, noise_normal((uint64_t)seed, NOISE_STREAM_PROCESS, (uint64_t)k), B, u);
}

double excitation_input_sample(int64_t drive, int64_t seed, int64_t k, double Qu, double Xu,
                               double fu, double Ts)
{
    if (drive == EXCITATION_GAUSSIAN)
        return ops_sqrt(Qu) * noise_normal((uint64_t)seed, NOISE_STREAM_INPUT, (uint64_t)k);
    if (drive == EXCITATION_SINUSOIDAL) return excitation_sine(k, Xu, fu, Ts, 0.0);
    if (drive == EXCITATION_DRIVE_OFF) return 0.0;
    return NAN;
}

double excitation_gaussian_sample(double x_prev, double A, double Q, int64_t seed, int64_t k)
{
    return excitation_gauss_markov(
        x_prev, A, Q, noise_normal((uint64_t)seed, NOISE_STREAM_PROCESS, (uint64_t)k));
}

void excitation_gaussian_pair(double x_prev, double y_prev, double A, double Q, double Qy,
                              double rho, int64_t seed, int64_t k, double *x, double *y)
{
    excitation_gaussian_pair_general(x_prev, y_prev, A, Q, Qy, rho, seed, k, 0.0, 0.0, x, y);
}

void excitation_gaussian_pair_general(double x_prev, double y_prev, double A, double Q,
                                      double Qy, double rho, int64_t seed, int64_t k, double B,
                                      double u, double *x, double *y)
{
    double w1 = noise_normal((uint64_t)seed, NOISE_STREAM_PROCESS, (uint64_t)k);
    if (Qy == 0.0) {
        excitation_correlated_pair(x_prev, y_prev, A, Q, Qy, rho, w1, 0.0, B, u, x, y);
        return;
    }
    excitation_correlated_pair(x_prev, y_prev, A, Q, Qy, rho, w1,
                               noise_normal((uint64_t)seed, NOISE_STREAM_SENSOR_Y, (uint64_t)k),
                               B, u, x, y);
}

void excitation_correlated_pair(double x_prev, double y_prev, double A, double Q, double Qy,
                                double rho, double w1, double w2, double B, double u, double *x,
                                double *y)
{
    *x = excitation_gauss_markov_general(x_prev, A, Q, w1, B, u);
    if (Qy == 0.0) {
        *y = 0.0;
        return;
    }
    *y = A * y_prev + ops_sqrt(Qy) * (rho * w1 + ops_sqrt(1.0 - rho * rho) * w2);
}

double excitation_sine(int64_t k, double X, double f, double Ts, double phi)
{
    return X * ops_sin2pi(f * Ts * (double)(k - 1) + phi / (2.0 * OPS_PI));
}

double excitation_stationary_variance(int64_t kind, double A, double Q, double X)
{
    if (kind == EXCITATION_GAUSSIAN) return Q / (1.0 - A * A);
    if (kind == EXCITATION_SINUSOIDAL) return X * X / 2.0;
    return NAN;
}
