/* ekf: C port of models/ekf.py (scalar EKF, Joseph form).  Tuples come back through the
 * out-pointers, in the order of the Python tuple. */
#ifndef DRIFTFMU_EKF_H
#define DRIFTFMU_EKF_H

/* The *_general functions take the known input (B, u) and a3, a4 (models.ekf's keyword
 * arguments); the others are them at 0, as the Python defaults. */
void ekf_predict_general(double x, double P, double A, double Q, double B, double u,
                         double *x_pred, double *P_pred);
void ekf_update_general(double x_pred, double P_pred, double z, double a0, double a1, double a2,
                        double R, double a3, double a4, double *x, double *P);
void ekf_step_general(double x, double P, double z, double a0, double a1, double a2, double A,
                      double Q, double R, double a3, double a4, double B, double u,
                      double *x_post, double *P_post);
void ekf_predict(double x, double P, double A, double Q, double *x_pred, double *P_pred);
void ekf_update(double x_pred, double P_pred, double z, double a0, double a1, double a2,
                double R, double *x, double *P);
void ekf_step(double x, double P, double z, double a0, double a1, double a2, double A,
              double Q, double R, double *x_post, double *P_post);

#endif
