/* sensor: C port of models/sensor.py; see sensor.h. */
#include "noise.h"
#include "ops.h"
#include "sensor.h"

double sensor_h(double x, double a0, double a1, double a2) { return a0 + a1 * x + a2 * x * x; }

double sensor_dh_dx(double x, double a1, double a2) { return a1 + 2.0 * a2 * x; }

double sensor_measure(double x, double a0, double a1, double a2, double R, double v)
{
    return sensor_h(x, a0, a1, a2) + ops_sqrt(R) * v;
}

double sensor_measurement_noise(int64_t seed, int64_t k)
{
    return noise_normal((uint64_t)seed, NOISE_STREAM_MEASUREMENT, (uint64_t)k);
}

double sensor_drift(double a2, double variance) { return a2 * variance; }

double sensor_h_bilinear(double own, double other, double a0, double a1, double a2, double b)
{
    return sensor_h(own, a0, a1, a2) + b * own * other;
}

double sensor_measure_bilinear(double own, double other, double a0, double a1, double a2,
                               double b, double R, double v)
{
    return sensor_h_bilinear(own, other, a0, a1, a2, b) + ops_sqrt(R) * v;
}
