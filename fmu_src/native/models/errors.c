/* errors: C port of models/errors.py; see errors.h.  Same operations in the same order. */
#include <stddef.h>
#include <stdio.h>

#include "errors.h"
#include "noise.h"
#include "ops.h"
#include "sensor.h"

/* models.errors.GM_SERIES: (-1)^n (4 - 2^n) / n! for n = 3 .. 22 (Python's repr). */
static const double GM_SERIES[20] = {
    0.6666666666666666, -0.5, 0.23333333333333334, -0.08333333333333333,
    0.024603174603174603, -0.00625, 0.0013999118165784832, -0.0002810846560846561,
    5.120650953984287e-05, -8.542768959435627e-06, 1.3149145093589538e-06,
    -1.8789081289081288e-07, 2.5055167250934446e-08, -3.1320870854601013e-09,
    3.684920794125587e-10, -4.0944189147451934e-11, 4.3099475296411905e-12,
    -4.3099639709116836e-13, 4.104735420520886e-14, -3.731581213735544e-15};

double errors_turn_on(double bias_on, int64_t seed)
{
    return bias_on * noise_ziggurat((uint64_t)seed, NOISE_STREAM_TURN_ON, 0);
}

double errors_random_walk(double b, double step, double n) { return b + step * n; }

void errors_gauss_markov_coefficients(double sigma, double tau, double Ts, double *a,
                                      double *c)
{
    *a = ops_exp(-Ts / tau);
    *c = sigma * ops_sqrt(1.0 - ops_exp(-2.0 * Ts / tau));
}

double errors_gauss_markov(double b, double a, double c, double n) { return a * b + c * n; }

int64_t errors_flicker_taus(double tau_min, double tau_max, double *taus)
{
    const double span = ops_log(tau_max / tau_min);
    const double decades = span / ERRORS_LN10;
    int64_t m = 1 + (int64_t)(-ops_floor(-(decades - 1e-9))), i;
    double step;
    if (m > ERRORS_FLICKER_MAX) m = ERRORS_FLICKER_MAX;
    if (m < 2) m = 2;
    step = span / (double)(m - 1);
    for (i = 0; i < m; i++)
        taus[i] = i == 0 ? tau_min : i == m - 1 ? tau_max : tau_min * ops_exp((double)i * step);
    return m;
}

double errors_allan_variance_gm(double variance, double tau, double T)
{
    const double r = T / tau;
    double f;
    if (r < 0.5) {
        double poly = GM_SERIES[19];
        int i;
        for (i = 18; i >= 0; i--)
            poly = poly * r + GM_SERIES[i];
        f = poly * r * r * r;
    } else {
        const double e = ops_exp(-r);
        f = ((2.0 * r - 3.0) + 4.0 * e) - e * e;
    }
    return variance * f / (r * r);
}

double errors_flicker_sigma(double flicker, const double *taus, int64_t m)
{
    const double centre = ops_sqrt(taus[0] * taus[m - 1]);
    double total = 0.0;
    int64_t i;
    for (i = 0; i < m; i++)
        total = total + errors_allan_variance_gm(1.0, taus[i], centre);
    return flicker / ops_sqrt(total);
}

double errors_flicker(const double *components, const double *a, const double *c,
                      const double *n, int64_t m, double *out)
{
    double total = 0.0;
    int64_t i;
    for (i = 0; i < m; i++) { /* (component i reads only components[i]: out may be them) */
        out[i] = errors_gauss_markov(components[i], a[i], c[i], n[i]);
        total = total + out[i];
    }
    return total;
}

double errors_exposure(double E, double x, double Ts, double d_inf, double E_tau, double *E_out)
{
    E = E + x * x * Ts;
    *E_out = E;
    return d_inf * (1.0 - ops_exp_estrin(-E / E_tau));
}

double errors_tilt(double x, double theta, ErrorTilt *held)
{
    ErrorTilt none = {0.0, 0.0};
    if (held == NULL) held = &none;
    if (held->theta != theta || theta == 0.0) { /* (-0.0 equals 0.0 but has its own sine) */
        held->theta = theta;
        held->sine = ops_sin(theta);
    }
    return x + held->sine;
}

void errors_temperature(double T, double T0, double kT_bias, double kT_scale, double *scale,
                        double *bias)
{
    const double dT = T - T0;
    *scale = 1.0 + kT_scale * dT;
    *bias = kT_bias * dT;
}

void errors_class2(double x, double theta, double T, double T0, double kT_bias, double kT_scale,
                   ErrorTilt *held, double *u, double *c)
{
    double scale;
    errors_temperature(T, T0, kT_bias, kT_scale, &scale, c);
    *u = x;
    if (theta != 0.0) *u = errors_tilt(*u, theta, held);
    if (kT_scale != 0.0) *u = scale * *u;
}

double errors_class2_offset(double theta, double T, double a1, double a2, double T0,
                            double kT_bias, double kT_scale, double a3, double a4)
{
    double g, c;
    errors_class2(0.0, theta, T, T0, kT_bias, kT_scale, NULL, &g, &c);
    return c + sensor_h_general(g, 0.0, a1, a2, a3, a4);
}

double errors_saturate(double u, double limit)
{
    u = u > limit ? limit : u;
    return u < -limit ? -limit : u;
}

ErrorConfig errors_config(int64_t seed, double Ts, double bias_on, double random_walk,
                          double bias_gm, double tau_gm, double flicker, double tau_min,
                          double tau_max, double d_inf, double E_tau, double T0,
                          double kT_bias, double kT_scale, double range)
{
    ErrorConfig c;
    int64_t i;
    for (i = 0; i < ERRORS_FLICKER_MAX; i++) c.fl_a[i] = c.fl_c[i] = 0.0;
    c.on = bias_on != 0.0 || random_walk != 0.0 || bias_gm != 0.0 || flicker != 0.0 ||
           d_inf != 0.0 || kT_bias != 0.0 || kT_scale != 0.0 || range != 0.0;
    c.bias_on = bias_on;
    c.b_on = bias_on != 0.0 ? errors_turn_on(bias_on, seed) : 0.0;
    c.rw = random_walk != 0.0 ? random_walk * ops_sqrt(Ts) : 0.0;
    c.gm_sigma = bias_gm;
    c.gm_a = c.gm_c = 0.0;
    if (bias_gm != 0.0) errors_gauss_markov_coefficients(bias_gm, tau_gm, Ts, &c.gm_a, &c.gm_c);
    c.fl_n = 0;
    c.fl_sigma = 0.0;
    if (flicker != 0.0) {
        double taus[ERRORS_FLICKER_MAX];
        c.fl_n = errors_flicker_taus(tau_min, tau_max, taus);
        c.fl_sigma = errors_flicker_sigma(flicker, taus, c.fl_n);
        for (i = 0; i < c.fl_n; i++)
            errors_gauss_markov_coefficients(c.fl_sigma, taus[i], Ts, &c.fl_a[i], &c.fl_c[i]);
    }
    c.d_inf = d_inf;
    c.E_tau = E_tau;
    c.Ts = Ts;
    c.T0 = T0;
    c.kT_bias = kT_bias;
    c.kT_scale = kT_scale;
    c.range = range;
    return c;
}

int errors_problems(double flicker, double tau_min, double tau_max, driftfmu_report report,
                    void *ctx)
{
    char msg[PARAMETERS_MESSAGE_MAX], r1[40], r2[40];
    if (flicker == 0.0) return 0;
    if (!(tau_min > 0.0 && tau_max > 0.0) || tau_min - tau_min != 0.0 ||
        tau_max - tau_max != 0.0)
        return 0; /* (their own range check says what is wrong) */
    parameters_repr_float(tau_min, r1, sizeof r1);
    parameters_repr_float(tau_max, r2, sizeof r2);
    if (!(tau_min < tau_max)) {
        snprintf(msg, sizeof msg, "tau_min = %s s and tau_max = %s s are not a band; allowed: "
                 "tau_min < tau_max (the correlation times of the flicker bias)", r1, r2);
        if (report) report(ctx, msg);
        return 1;
    }
    if (tau_max / tau_min > 1e7) { /* 10.0 ** FLICKER_DECADES_MAX */
        snprintf(msg, sizeof msg, "tau_min = %s s and tau_max = %s s span more than %d "
                 "decades; allowed: tau_max <= 1e%d tau_min (one flicker component per decade, "
                 "at most %d)", r1, r2, ERRORS_FLICKER_DECADES_MAX, ERRORS_FLICKER_DECADES_MAX,
                 ERRORS_FLICKER_MAX);
        if (report) report(ctx, msg);
        return 1;
    }
    return 0;
}

ErrorState errors_initial_state(int64_t seed, const ErrorConfig *ecfg)
{
    ErrorState s;
    int64_t i;
    s.rw = 0.0;
    s.gm = ecfg->gm_sigma != 0.0
           ? ecfg->gm_sigma * noise_ziggurat((uint64_t)seed, NOISE_STREAM_BIAS_GM, 0) : 0.0;
    s.E = 0.0;
    for (i = 0; i < ERRORS_FLICKER_MAX; i++)
        s.fl[i] = i < ecfg->fl_n
                  ? ecfg->fl_sigma * noise_ziggurat((uint64_t)seed,
                                                    (uint64_t)(NOISE_STREAM_FLICKER + i), 0)
                  : 0.0;
    return s;
}

void errors_draws(int64_t seed, int64_t k, const ErrorConfig *ecfg, double *n_rw,
                  double *n_gm, double *n_fl)
{
    int64_t i;
    *n_rw = ecfg->rw != 0.0
            ? noise_ziggurat((uint64_t)seed, NOISE_STREAM_RANDOM_WALK, (uint64_t)k) : 0.0;
    *n_gm = ecfg->gm_sigma != 0.0
            ? noise_ziggurat((uint64_t)seed, NOISE_STREAM_BIAS_GM, (uint64_t)k) : 0.0;
    for (i = 0; i < ecfg->fl_n; i++)
        n_fl[i] = noise_ziggurat((uint64_t)seed, (uint64_t)(NOISE_STREAM_FLICKER + i),
                                 (uint64_t)k);
}

void errors_advance(const ErrorState *state, double x, double n_rw, double n_gm,
                    const double *n_fl, const ErrorConfig *ecfg, ErrorState *out, double *b)
{
    double sum = 0.0, d = 0.0;
    if (out != state) *out = *state;
    /* the exposure first (its exponential is the longest chain of dependent operations of the
     * sample: begun before the other processes, which do not depend on it, it can run beside
     * them); added last, as in errors.advance (the same bits) */
    if (ecfg->d_inf != 0.0)
        d = errors_exposure(out->E, x, ecfg->Ts, ecfg->d_inf, ecfg->E_tau, &out->E);
    if (ecfg->bias_on != 0.0)
        sum = sum + ecfg->b_on;
    if (ecfg->rw != 0.0) {
        out->rw = errors_random_walk(out->rw, ecfg->rw, n_rw);
        sum = sum + out->rw;
    }
    if (ecfg->gm_sigma != 0.0) {
        out->gm = errors_gauss_markov(out->gm, ecfg->gm_a, ecfg->gm_c, n_gm);
        sum = sum + out->gm;
    }
    if (ecfg->fl_n)
        sum = sum + errors_flicker(out->fl, ecfg->fl_a, ecfg->fl_c, n_fl, ecfg->fl_n, out->fl);
    if (ecfg->d_inf != 0.0)
        sum = sum + d;
    *b = sum;
}

void errors_advance_state(ErrorState *state, double x, double n_rw, double n_gm,
                          const double *n_fl, const ErrorConfig *ecfg)
{
    int64_t i;
    if (ecfg->rw != 0.0) state->rw = errors_random_walk(state->rw, ecfg->rw, n_rw);
    if (ecfg->gm_sigma != 0.0)
        state->gm = errors_gauss_markov(state->gm, ecfg->gm_a, ecfg->gm_c, n_gm);
    for (i = 0; i < ecfg->fl_n; i++) /* (flicker's components, without their sum) */
        state->fl[i] = errors_gauss_markov(state->fl[i], ecfg->fl_a[i], ecfg->fl_c[i], n_fl[i]);
    if (ecfg->d_inf != 0.0) state->E = state->E + x * x * ecfg->Ts; /* (exposure's E) */
}

double errors_thermal_bias(double T, const ErrorConfig *ecfg)
{
    double scale, bias;
    if (ecfg->kT_bias == 0.0) return 0.0;
    errors_temperature(T, ecfg->T0, ecfg->kT_bias, ecfg->kT_scale, &scale, &bias);
    return bias;
}

double errors_sensed(double x, double theta, double T, const ErrorConfig *ecfg,
                     ErrorTilt *held)
{
    double u, c;
    errors_class2(x, theta, T, ecfg->T0, ecfg->kT_bias, ecfg->kT_scale, held, &u, &c);
    if (ecfg->range != 0.0) u = errors_saturate(u, ecfg->range);
    return u;
}

ErrorState errors_hold(ErrorState state, double x, int64_t seed, int64_t k0, int64_t m,
                       const ErrorConfig *ecfg)
{
    int64_t j;
    if (!(ecfg->rw != 0.0 || ecfg->gm_sigma != 0.0 || ecfg->d_inf != 0.0 || ecfg->fl_n))
        return state;
    for (j = 1; j < m; j++) {
        double n_rw, n_gm, n_fl[ERRORS_FLICKER_MAX];
        errors_draws(seed, k0 + j, ecfg, &n_rw, &n_gm, n_fl);
        errors_advance_state(&state, x, n_rw, n_gm, n_fl, ecfg);
    }
    return state;
}
