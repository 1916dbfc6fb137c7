/* adxl203: C port of models/adxl203.py (what the Accelerometer FMU uses); see adxl203.h. */
#include <math.h>
#include <stdio.h>

#include "adxl203.h"
#include "noise.h"
#include "ops.h"
#include "sensor.h"

double adxl203_bandwidth(double C) { return ADXL203_BANDWIDTH_RULE / C; }

double adxl203_sensitivity(double Vs)
{
    return ADXL203_SENSITIVITY_3V
           + (ADXL203_SENSITIVITY_5V - ADXL203_SENSITIVITY_3V) * (Vs - 3.0) / 2.0;
}

double adxl203_noise_sigma(double density, double Ts) { return density * ops_sqrt(0.5 / Ts); }

Config adxl203_config(double a0, double a1, double a2, double R, double a3, double cross,
                      double fc, double Vs, int64_t bits, double density, double Ts)
{
    return adxl203_config_general(a0, a1, a2, R, a3, cross, fc, Vs, bits, density, Ts, 0.0);
}

Config adxl203_config_general(double a0, double a1, double a2, double R, double a3,
                              double cross, double fc, double Vs, int64_t bits, double density,
                              double Ts, double a4)
{
    return adxl203_config_ranged(a0, a1, a2, R, a3, cross, fc, Vs, bits, density, Ts, a4, 0.0);
}

Config adxl203_config_ranged(double a0, double a1, double a2, double R, double a3,
                             double cross, double fc, double Vs, int64_t bits, double density,
                             double Ts, double a4, double range)
{
    Config c;
    double scale, z0;
    c.plain = (cross == 0.0 && fc == 0.0 && Vs == 0.0 && bits == 0 && density == 0.0);
    scale = Vs > 0.0 ? adxl203_sensitivity(Vs) / adxl203_sensitivity(ADXL203_VS_NOMINAL) : 1.0;
    z0 = Vs > 0.0 ? Vs / 2.0 : a0;
    c.a0 = z0;
    c.a1 = a1 * scale;
    c.a2 = a2 * scale;
    c.a3 = a3 * scale;
    c.a4 = a4 * scale;
    c.R = R;
    c.sigma = density > 0.0 ? c.a1 * adxl203_noise_sigma(density, Ts) : ops_sqrt(R);
    c.cross = cross;
    c.has_alpha = fc > 0.0;
    c.alpha = fc > 0.0 ? ops_exp(-2.0 * OPS_PI * fc * Ts) : 0.0;
    /* 2 ** bits; the parameter check allows bits <= 24 (saturated at 2^62 beyond) */
    c.levels = bits > 0 ? (int64_t)1 << (bits < 62 ? bits : 62) : 0;
    c.lo = 0.0;
    if (c.levels && Vs <= 0.0 && range > 0.0) { /* over a0 +- |a1| range */
        const double span = fabs(c.a1) * range;
        c.lo = z0 - span;
        c.lsb = 2.0 * span / (double)c.levels;
    } else {
        c.lsb = c.levels ? (Vs > 0.0 ? Vs : ADXL203_VS_NOMINAL) / (double)c.levels : 0.0;
    }
    return c;
}

double adxl203_noise(int64_t seed, int64_t k, int64_t axis)
{
    return noise_normal((uint64_t)seed,
                        axis == 1 ? NOISE_STREAM_MEASUREMENT : NOISE_STREAM_MEASUREMENT_Y,
                        (uint64_t)k);
}

double adxl203_sense(double own, double other, double v, const Config *cfg)
{
    double u = own + cfg->cross * other;
    double u2 = u * u;
    if (cfg->a4 == 0.0) return cfg->a1 * u + cfg->a2 * u2 + cfg->a3 * u2 * u + cfg->sigma * v;
    return cfg->a1 * u + cfg->a2 * u2 + cfg->a3 * u2 * u + cfg->a4 * u2 * u2 + cfg->sigma * v;
}

double adxl203_lowpass(int64_t prev_set, double prev, double s, int64_t has_alpha, double alpha)
{
    if (!has_alpha || !prev_set) return s;
    return alpha * prev + (1.0 - alpha) * s;
}

double adxl203_quantise(double V, const Config *cfg)
{
    double code, top;
    if (!cfg->levels) return V;
    if (!(V - V == 0.0)) return V; /* non-finite: named by the FMU, not clipped */
    if (cfg->lo == 0.0)
        code = ops_floor(V / cfg->lsb + 0.5);
    else
        code = ops_floor((V - cfg->lo) / cfg->lsb + 0.5);
    code = code < 0.0 ? 0.0 : code;
    top = (double)cfg->levels - 1.0;
    code = code > top ? top : code;
    if (cfg->lo == 0.0) return code * cfg->lsb;
    return cfg->lo + code * cfg->lsb;
}

void adxl203_measure(int64_t prev_set, double prev, double own, double other, double v,
                     const Config *cfg, int64_t *e_set, double *e, double *z)
{
    if (cfg->plain) {
        *e_set = 0;
        *e = 0.0;
        *z = sensor_measure_general(own, cfg->a0, cfg->a1, cfg->a2, cfg->R, v, cfg->a3, cfg->a4);
        return;
    }
    *e = adxl203_lowpass(prev_set, prev, adxl203_sense(own, other, v, cfg), cfg->has_alpha,
                         cfg->alpha);
    *e_set = 1;
    *z = adxl203_quantise(cfg->a0 + *e, cfg);
}

void adxl203_measure_errors(int64_t prev_set, double prev, ErrorState *state, double own,
                            double other, double v, double n_rw, double n_gm,
                            const double *n_fl, double theta, double T, const Config *cfg,
                            const ErrorConfig *ecfg, ErrorTilt *held, int64_t *e_set, double *e,
                            double *z)
{
    double b, u, V;
    errors_advance(state, own, n_rw, n_gm, n_fl, ecfg, state, &b);
    u = errors_sensed(own, theta, T, ecfg, held);
    if (cfg->plain) {
        *e_set = 0;
        *e = 0.0;
        V = sensor_measure_general(u, cfg->a0, cfg->a1, cfg->a2, cfg->R, v, cfg->a3, cfg->a4);
    } else {
        *e = adxl203_lowpass(prev_set, prev, adxl203_sense(u, other, v, cfg), cfg->has_alpha,
                             cfg->alpha);
        *e_set = 1;
        V = cfg->a0 + *e;
    }
    V = V + b;
    if (ecfg->kT_bias != 0.0) V = V + errors_thermal_bias(T, ecfg);
    *z = adxl203_quantise(V, cfg);
}

void adxl203_hold(int64_t prev_set, double prev, double own, double other, int64_t seed,
                  int64_t k0, int64_t m, const Config *cfg, int64_t axis, int64_t noise_on,
                  int64_t *out_set, double *out)
{
    int64_t j;
    if (!cfg->has_alpha) {
        *out_set = prev_set;
        *out = prev;
        return;
    }
    for (j = 1; j < m; j++) {
        double v = noise_on ? adxl203_noise(seed, k0 + j, axis) : 0.0;
        prev = adxl203_lowpass(prev_set, prev, adxl203_sense(own, other, v, cfg), 1, cfg->alpha);
        prev_set = 1;
    }
    *out_set = prev_set;
    *out = prev;
}

int adxl203_problems(double Vs, double fc, driftfmu_report report, void *ctx)
{
    char msg[PARAMETERS_MESSAGE_MAX], r[40];
    int n = 0;
    if (Vs != 0.0 && !(ADXL203_VS_LOW <= Vs && Vs <= ADXL203_VS_HIGH)) {
        parameters_repr_float(Vs, r, sizeof r);
        snprintf(msg, sizeof msg, "Vs = %s V is not allowed; allowed: Vs = 0 (ratiometric "
                 "output off) or %g <= Vs <= %g", r, ADXL203_VS_LOW, ADXL203_VS_HIGH);
        if (report) report(ctx, msg);
        n++;
    }
    if (fc > ADXL203_MAX_BANDWIDTH) {
        parameters_repr_float(fc, r, sizeof r);
        snprintf(msg, sizeof msg, "fc = %s Hz is not allowed; allowed: fc = 0 (low-pass off) or "
                 "0 < fc <= %g Hz (datasheet maximum)", r, ADXL203_MAX_BANDWIDTH);
        if (report) report(ctx, msg);
        n++;
    }
    return n;
}
