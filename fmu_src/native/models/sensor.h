/* sensor: C port of models/sensor.py (z = a0 + a1 x + a2 x^2 + v). */
#ifndef DRIFTFMU_SENSOR_H
#define DRIFTFMU_SENSOR_H

#include <stdint.h>

double sensor_h(double x, double a0, double a1, double a2);
double sensor_dh_dx(double x, double a1, double a2);
double sensor_measure(double x, double a0, double a1, double a2, double R, double v);
double sensor_measurement_noise(int64_t seed, int64_t k);
double sensor_drift(double a2, double variance);
/* a0 + a1 own + a2 own^2 + b own other (sensor_h + b own other, same bits at b = 0). */
double sensor_h_bilinear(double own, double other, double a0, double a1, double a2, double b);
double sensor_measure_bilinear(double own, double other, double a0, double a1, double a2,
                               double b, double R, double v);

#endif
