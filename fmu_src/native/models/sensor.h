/* sensor: C port of models/sensor.py (z = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4 + v).  C has no
 * default arguments: each function with the higher-order coefficients is *_general, and the
 * letter's function (a3 = a4 = 0) calls it with zeros, as the Python defaults do. */
#ifndef DRIFTFMU_SENSOR_H
#define DRIFTFMU_SENSOR_H

#include <stdint.h>

/* models.sensor.higher: 1 unless a3 and a4 are both 0. */
int sensor_higher(double a3, double a4);
double sensor_h_general(double x, double a0, double a1, double a2, double a3, double a4);
double sensor_h(double x, double a0, double a1, double a2);
double sensor_dh_dx_general(double x, double a1, double a2, double a3, double a4);
double sensor_dh_dx(double x, double a1, double a2);
double sensor_measure_general(double x, double a0, double a1, double a2, double R, double v,
                              double a3, double a4);
double sensor_measure(double x, double a0, double a1, double a2, double R, double v);
/* a2 variance + a4 m4 (a2 variance, same bits, at a4 = 0); the caller passes m4 (Python's
 * default m4 = 3 variance^2 is not ported). */
double sensor_drift_general(double a2, double variance, double a4, double m4);
double sensor_measurement_noise(int64_t seed, int64_t k);
double sensor_drift(double a2, double variance);
/* a0 + a1 own + a2 own^2 + b own other (sensor_h + b own other, same bits at b = 0). */
double sensor_h_bilinear(double own, double other, double a0, double a1, double a2, double b);
double sensor_measure_bilinear(double own, double other, double a0, double a1, double a2,
                               double b, double R, double v);

#endif
