/* ekf: C port of models/ekf.py; see ekf.h. */
#include "ekf.h"
#include "sensor.h"

void ekf_predict(double x, double P, double A, double Q, double *x_pred, double *P_pred)
{
    *x_pred = A * x;
    *P_pred = A * A * P + Q;
}

void ekf_update(double x_pred, double P_pred, double z, double a0, double a1, double a2,
                double R, double *x, double *P)
{
    double H = sensor_dh_dx(x_pred, a1, a2);
    double S = H * H * P_pred + R;
    double K = P_pred * H / S;
    double one_minus_KH;
    *x = x_pred + K * (z - sensor_h(x_pred, a0, a1, a2));
    one_minus_KH = 1.0 - K * H;
    *P = one_minus_KH * one_minus_KH * P_pred + K * K * R;
}

void ekf_step(double x, double P, double z, double a0, double a1, double a2, double A,
              double Q, double R, double *x_post, double *P_post)
{
    double x_pred, P_pred;
    ekf_predict(x, P, A, Q, &x_pred, &P_pred);
    ekf_update(x_pred, P_pred, z, a0, a1, a2, R, x_post, P_post);
}
