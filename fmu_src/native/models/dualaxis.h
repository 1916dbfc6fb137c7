/* dualaxis: C port of models/dualaxis.py (the dual-axis sensor with a bilinear cross term, the
 * EKF over both axes and the generalised drift estimators).  Only what the FMUs use (the
 * closed forms cross_moment, expected_drift, scale and the chain simulate are not ported).
 *
 * The estimator functions take and return a DualEstimator, which holds a state of either
 * process model: under DUALAXIS_GAUSS_MARKOV its field g (models.dualaxis.DualState), under
 * DUALAXIS_HARMONIC its field h (DualHarmonicState); the other is untouched. */
#ifndef DRIFTFMU_DUALAXIS_H
#define DRIFTFMU_DUALAXIS_H

#include <stdint.h>

#include "parameters.h"

#define DUALAXIS_GAUSS_MARKOV 1
#define DUALAXIS_HARMONIC 2

/* models.dualaxis.Axis, same fields in the same order. */
typedef struct {
    double a0, a1, a2, b, R;
} Axis;

/* models.dualaxis.DualDrift, same fields in the same order. */
typedef struct {
    int64_t k;
    double s1xx, s1xy, s1yy, dc2x, dc2y, s3xx, s3xy, s3yy, dc3x, dc3y;
} DualDrift;

/* models.dualaxis.DualState. */
typedef struct {
    double x, y, Pxx, Pxy, Pyy;
    DualDrift drift;
} DualState;

/* models.dualaxis.DualHarmonicState. */
typedef struct {
    double x, dx, y, dy, P11, P12, P22, P33, P34, P44, P13, P14, P23, P24;
    DualDrift drift;
} DualHarmonicState;

/* Either state (see above). */
typedef struct {
    DualState g;
    DualHarmonicState h;
} DualEstimator;

/* models.dualaxis.model's dict. */
typedef struct {
    int64_t process;
    double A, Q, Qy, Qxy, C, S, Qh;
} DualModel;

void dualaxis_axes(double a0, double a1, double a2, double bx, double R, double a0y, double a1y,
                   double a2y, double by, double Ry, Axis *ax, Axis *ay);
void dualaxis_measure(double x, double y, Axis ax, Axis ay, double vx, double vy, double *zx,
                      double *zy);
void dualaxis_noise(int64_t seed, int64_t k, double *vx, double *vy);
/* Number of problems of models.dualaxis.sensor_problems (dual and the six extras; bits is an
 * Integer), each written to report(ctx, message). */
int dualaxis_sensor_problems(int64_t dual, double a3, double cross, double fc, double Vs,
                             int64_t bits, double density, driftfmu_report report, void *ctx);

/* _row2: returns (o, t, Poo, Pot, Ptt) through the out-pointers. */
void dualaxis__row2(double o, double t, double Poo, double Pot, double Ptt, double H, double G,
                    double e, double R, double *o_post, double *t_post, double *poo,
                    double *pot, double *ptt);
/* _row4: P and out in the order (P11, P12, P22, P13, P14, P23, P24, P33, P34, P44). */
void dualaxis__row4(double o, double od, double t, double td, const double P[10], double H,
                    double G, double e, double R, double *o_post, double *od_post,
                    double *t_post, double *td_post, double out[10]);
void dualaxis_jacobian(double x, double y, Axis ax, Axis ay, double *Hxx, double *Hxy,
                       double *Hyx, double *Hyy);
void dualaxis_innovations(double x, double y, double zx, double zy, Axis ax, Axis ay,
                          double *ex, double *ey);
/* s: (x, y, Pxx, Pxy, Pyy) in and out (s_post). */
void dualaxis_update2(const double s[5], double zx, double zy, Axis ax, Axis ay,
                      double s_post[5]);
void dualaxis_predict2(double x, double y, double Pxx, double Pxy, double Pyy, double A,
                       double Q, double Qy, double Qxy, double out[5]);
/* out: (x, dx, y, dy, P11, P12, P22, P33, P34, P44, P13, P14, P23, P24). */
void dualaxis_predict4(DualHarmonicState st, double C, double S, double Qh, double out[14]);
void dualaxis_update4(const double s[14], double zx, double zy, Axis ax, Axis ay,
                      double out[14]);

DualDrift dualaxis_drift_init(void);
DualDrift dualaxis_drift_update(DualDrift d, double x, double y, double Pxx, double Pxy,
                                double Pyy, Axis ax, Axis ay);
/* dx = (dc1, dc2, dc3) of x, dy of y. */
void dualaxis_estimates(DualDrift d, Axis ax, Axis ay, double dx[3], double dy[3]);

DualModel dualaxis_model(int64_t process, double A, double Q, double Qy, double rho, double f,
                         double Ts, double Qh);
/* All fields NaN for an unknown process (Python raises ValueError). */
DualEstimator dualaxis_estimator_init(int64_t process, double x0, double y0, double P0,
                                      double P0y);
/* (x+, y+, Pxx, Pxy, Pyy) of the state of `process`. */
void dualaxis_moments(const DualEstimator *st, int64_t process, double out[5]);
/* The state's drift (of `process`). */
DualDrift dualaxis_drift_of(const DualEstimator *st, int64_t process);
/* models.dualaxis.covariance_of: the lower triangle of the filter's covariance packed by rows
 * into lower ((Pxx, Pxy, Pyy), or (P11, P12, P22, P13, P23, P33, P14, P24, P34, P44)); returns
 * its size n, 2 or 4. */
int dualaxis_covariance_of(const DualEstimator *st, int64_t process, double lower[10]);
/* models.dualaxis.valid: 1 if the filter's covariance is valid (models/covariance.py). */
int dualaxis_valid(const DualEstimator *st, int64_t process);
DualEstimator dualaxis_estimator_predict(DualEstimator st, const DualModel *m);
DualEstimator dualaxis_estimator_step(DualEstimator st, double zx, double zy, Axis ax, Axis ay,
                                      const DualModel *m);

#endif
