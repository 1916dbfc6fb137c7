/* ekf: C port of models/ekf.py; see ekf.h. */
#include "ekf.h"
#include "sensor.h"

void ekf_predict_general(double x, double P, double A, double Q, double B, double u,
                         double *x_pred, double *P_pred)
{
    if (B == 0.0)
        *x_pred = A * x;
    else
        *x_pred = A * x + B * u;
    *P_pred = A * A * P + Q;
}

void ekf_predict(double x, double P, double A, double Q, double *x_pred, double *P_pred)
{
    ekf_predict_general(x, P, A, Q, 0.0, 0.0, x_pred, P_pred);
}

void ekf_update_general(double x_pred, double P_pred, double z, double a0, double a1, double a2,
                        double R, double a3, double a4, double *x, double *P)
{
    double H = sensor_dh_dx_general(x_pred, a1, a2, a3, a4);
    double S = H * H * P_pred + R;
    double K = P_pred * H / S;
    double one_minus_KH;
    *x = x_pred + K * (z - sensor_h_general(x_pred, a0, a1, a2, a3, a4));
    one_minus_KH = 1.0 - K * H;
    *P = one_minus_KH * one_minus_KH * P_pred + K * K * R;
}

void ekf_update(double x_pred, double P_pred, double z, double a0, double a1, double a2,
                double R, double *x, double *P)
{
    ekf_update_general(x_pred, P_pred, z, a0, a1, a2, R, 0.0, 0.0, x, P);
}

void ekf_step_general(double x, double P, double z, double a0, double a1, double a2, double A,
                      double Q, double R, double a3, double a4, double B, double u,
                      double *x_post, double *P_post)
{
    double x_pred, P_pred;
    ekf_predict_general(x, P, A, Q, B, u, &x_pred, &P_pred);
    ekf_update_general(x_pred, P_pred, z, a0, a1, a2, R, a3, a4, x_post, P_post);
}

void ekf_step(double x, double P, double z, double a0, double a1, double a2, double A,
              double Q, double R, double *x_post, double *P_post)
{
    ekf_step_general(x, P, z, a0, a1, a2, A, Q, R, 0.0, 0.0, 0.0, 0.0, x_post, P_post);
}
