/* sensor: C port of models/sensor.py (z = a0 + a1 x + a2 x^2 + v). */
#ifndef DRIFTFMU_SENSOR_H
#define DRIFTFMU_SENSOR_H

#include <stdint.h>

double sensor_h(double x, double a0, double a1, double a2);
double sensor_dh_dx(double x, double a1, double a2);
double sensor_measure(double x, double a0, double a1, double a2, double R, double v);
double sensor_measurement_noise(int64_t seed, int64_t k);
double sensor_drift(double a2, double variance);

#endif
