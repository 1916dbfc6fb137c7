/* sensor: C port of models/sensor.py; see sensor.h. */
#include "noise.h"
#include "ops.h"
#include "sensor.h"

int sensor_higher(double a3, double a4) { return a3 != 0.0 || a4 != 0.0; }

double sensor_h_general(double x, double a0, double a1, double a2, double a3, double a4)
{
    double y = a0 + a1 * x + a2 * x * x, x2;
    if (sensor_higher(a3, a4)) {
        x2 = x * x;
        y = y + a3 * x2 * x + a4 * x2 * x2;
    }
    return y;
}

double sensor_h(double x, double a0, double a1, double a2)
{
    return sensor_h_general(x, a0, a1, a2, 0.0, 0.0);
}

double sensor_dh_dx_general(double x, double a1, double a2, double a3, double a4)
{
    double d = a1 + 2.0 * a2 * x, x2;
    if (sensor_higher(a3, a4)) {
        x2 = x * x;
        d = d + 3.0 * a3 * x2 + 4.0 * a4 * x2 * x;
    }
    return d;
}

double sensor_dh_dx(double x, double a1, double a2) { return sensor_dh_dx_general(x, a1, a2, 0.0, 0.0); }

double sensor_measure_general(double x, double a0, double a1, double a2, double R, double v,
                              double a3, double a4)
{
    return sensor_h_general(x, a0, a1, a2, a3, a4) + ops_sqrt(R) * v;
}

double sensor_measure(double x, double a0, double a1, double a2, double R, double v)
{
    return sensor_measure_general(x, a0, a1, a2, R, v, 0.0, 0.0);
}

double sensor_measurement_noise(int64_t seed, int64_t k)
{
    return noise_normal((uint64_t)seed, NOISE_STREAM_MEASUREMENT, (uint64_t)k);
}

double sensor_drift(double a2, double variance) { return a2 * variance; }

double sensor_drift_general(double a2, double variance, double a4, double m4)
{
    if (a4 == 0.0) return a2 * variance;
    return a2 * variance + a4 * m4;
}

double sensor_h_bilinear(double own, double other, double a0, double a1, double a2, double b)
{
    return sensor_h(own, a0, a1, a2) + b * own * other;
}

double sensor_measure_bilinear(double own, double other, double a0, double a1, double a2,
                               double b, double R, double v)
{
    return sensor_h_bilinear(own, other, a0, a1, a2, b) + ops_sqrt(R) * v;
}
