/* adxl203: C port of models/adxl203.py (the richer accelerometer), what the Accelerometer FMU
 * uses.  `None` of the Python is a flag field (has_alpha) or a flag argument (prev_set). */
#ifndef DRIFTFMU_ADXL203_H
#define DRIFTFMU_ADXL203_H

#include <stdint.h>

#include "errors.h"
#include "parameters.h"

#define ADXL203_VS_NOMINAL 5.0
#define ADXL203_SENSITIVITY_5V 1.000
#define ADXL203_SENSITIVITY_3V 0.560
#define ADXL203_VS_LOW 3.0
#define ADXL203_VS_HIGH 6.0
#define ADXL203_BANDWIDTH_RULE 5e-6
#define ADXL203_MAX_BANDWIDTH 2500.0
#define ADXL203_RANGE_G 1.7

/* models.adxl203.Config, same fields in the same order; alpha = None is has_alpha = 0. */
typedef struct {
    int64_t plain;
    double a0, a1, a2, a3, R, sigma, cross;
    int64_t has_alpha;
    double alpha;
    double lsb;
    int64_t levels;
    double a4;
    double lo; /* the ADC's lowest level (0.0 but over a measurement range) */
} Config;

double adxl203_bandwidth(double C);
double adxl203_sensitivity(double Vs);
double adxl203_noise_sigma(double density, double Ts);
Config adxl203_config(double a0, double a1, double a2, double R, double a3, double cross,
                      double fc, double Vs, int64_t bits, double density, double Ts);
/* With the 4th-order coefficient a4 (Python's keyword argument; the above is a4 = 0). */
Config adxl203_config_general(double a0, double a1, double a2, double R, double a3,
                              double cross, double fc, double Vs, int64_t bits, double density,
                              double Ts, double a4);
/* With the measurement range [g] (Python's keyword range; the above is range = 0). */
Config adxl203_config_ranged(double a0, double a1, double a2, double R, double a3,
                             double cross, double fc, double Vs, int64_t bits, double density,
                             double Ts, double a4, double range);
/* Measurement-noise draw of axis (1: x, 2: y) at sample k. */
double adxl203_noise(int64_t seed, int64_t k, int64_t axis);
double adxl203_sense(double own, double other, double v, const Config *cfg);
/* One filter step; prev_set = 0 is prev = None, cfg->has_alpha = 0 is alpha = None. */
double adxl203_lowpass(int64_t prev_set, double prev, double s, int64_t has_alpha, double alpha);
double adxl203_quantise(double V, const Config *cfg);
/* One sample of an axis: (*e_set, *e) is the filter state (e_set = 0: None), *z the output. */
void adxl203_measure(int64_t prev_set, double prev, double own, double other, double v,
                     const Config *cfg, int64_t *e_set, double *e, double *z);
/* One sample of the first axis with the slow errors (models.adxl203.measure_errors): the
 * filter state (*e_set, *e), the error state *state (advanced in place), the output *z;
 * draws: n_rw, n_gm and n_fl[ERRORS_FLICKER_MAX]; held: the sine of the held tilt
 * (errors_tilt; NULL: none). */
void adxl203_measure_errors(int64_t prev_set, double prev, ErrorState *state, double own,
                            double other, double v, double n_rw, double n_gm,
                            const double *n_fl, double theta, double T, const Config *cfg,
                            const ErrorConfig *ecfg, ErrorTilt *held, int64_t *e_set, double *e,
                            double *z);
/* Filter state after samples k0+1 .. k0+m-1 with the input held; a no-op without filter. */
void adxl203_hold(int64_t prev_set, double prev, double own, double other, int64_t seed,
                  int64_t k0, int64_t m, const Config *cfg, int64_t axis, int64_t noise_on,
                  int64_t *out_set, double *out);
/* Number of problems of the extra parameters (models.adxl203.problems), each message written
 * to report(ctx, message) in order. */
int adxl203_problems(double Vs, double fc, driftfmu_report report, void *ctx);

#endif
