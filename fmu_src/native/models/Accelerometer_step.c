/* Accelerometer_step: the per-sample logic of fmu_src/Accelerometer.py (prepare, sample, hold and
 * check_parameters) as the MODEL HOOKS of model.h; see Accelerometer_step.h. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "adxl203.h"
#include "dualaxis.h"
#include "model.h"
#include "noise.h"
#include "ops.h"
#include "slave.h"

static const SlaveRange EXTRA[] = {{"noise", 0, 1}};

static Config config_of(const ModelVariables *v)
{
    return adxl203_config_ranged(v->a0, v->a1, v->a2, v->R, v->a3, v->cross, v->fc, v->Vs,
                                 v->bits, v->density, v->Ts, v->a4, v->range);
}

static ErrorConfig ecfg_of(const ModelVariables *v)
{
    return errors_config(v->seed, v->Ts, v->bias_on, v->random_walk, v->bias_gm, v->tau_gm,
                         v->flicker, v->tau_min, v->tau_max, v->d_inf, v->E_tau, v->T0,
                         v->kT_bias, v->kT_scale, v->range);
}

/* Accelerometer.ERROR_SWITCHES: the parameters that switch a slow error on. */
#define N_SWITCHES 8
static const char *const SWITCHES[N_SWITCHES] = {"bias_on", "random_walk", "bias_gm", "flicker",
                                                 "d_inf", "kT_bias", "kT_scale", "range"};

static void switch_values(const ModelVariables *v, double *out)
{
    out[0] = v->bias_on;
    out[1] = v->random_walk;
    out[2] = v->bias_gm;
    out[3] = v->flicker;
    out[4] = v->d_inf;
    out[5] = v->kT_bias;
    out[6] = v->kT_scale;
    out[7] = v->range;
}

/* The dual-axis sensor with a slow error on (Accelerometer.check_parameters). */
static int dual_errors_problem(ModelInstance *comp)
{
    char msg[PARAMETERS_MESSAGE_MAX], on[PARAMETERS_MESSAGE_MAX] = "", r[40];
    double values[N_SWITCHES];
    size_t used = 0;
    int i, any = 0;
    switch_values(&comp->v, values);
    for (i = 0; i < N_SWITCHES; i++) {
        if (values[i] == 0.0) continue;
        parameters_repr_float(values[i], r, sizeof r);
        used += (size_t)snprintf(on + used, sizeof on - used, "%s%s = %s", any ? ", " : "",
                                 SWITCHES[i], r);
        if (used >= sizeof on) used = sizeof on - 1;
        any = 1;
    }
    if (!any) return 0;
    snprintf(msg, sizeof msg, "dual = 1 is not allowed with %s; allowed: dual = 1 with bias_on, "
             "random_walk, bias_gm, flicker, d_inf, kT_bias, kT_scale, range = 0 (the slow errors "
             "and the range act on the single-axis sensor)", on);
    return slave_problem(comp, msg);
}

static void report(void *ctx, const char *message) { slave_problem((ModelInstance *)ctx, message); }

int model_check(ModelInstance *comp)
{
    const ModelVariables *v = &comp->v;
    int n = slave_check_parameters(comp, EXTRA, 1);
    n += adxl203_problems(v->Vs, v->fc, report, comp);
    n += dualaxis_sensor_problems(v->dual, v->a3, v->cross, v->fc, v->Vs, v->bits, v->density,
                                  report, comp);
    if (v->dual && v->a4 != 0.0) {
        char msg[PARAMETERS_MESSAGE_MAX], r[40];
        parameters_repr_float(v->a4, r, sizeof r);
        snprintf(msg, sizeof msg, "dual = 1 is not allowed with a4 = %s; allowed: dual = 1 "
                 "with a4 = 0 (the bilinear sensor is of 2nd order)", r);
        n += slave_problem(comp, msg);
    }
    n += errors_problems(v->flicker, v->tau_min, v->tau_max, report, comp);
    if (v->dual) n += dual_errors_problem(comp);
    if (n == 0) { /* the effective values of the config must be finite */
        Config cfg = config_of(v);
        const char *names[6] = {"a0", "a1", "a2", "a3", "sigma", "a4"};
        double values[6];
        int i;
        values[0] = cfg.a0;
        values[1] = cfg.a1;
        values[2] = cfg.a2;
        values[3] = cfg.a3;
        values[4] = cfg.sigma;
        values[5] = cfg.a4;
        for (i = 0; i < 6; i++) {
            if (!isfinite(values[i])) {
                char msg[PARAMETERS_MESSAGE_MAX], r[40];
                parameters_repr_float(values[i], r, sizeof r);
                snprintf(msg, sizeof msg, "the parameters give the effective %s = %s (a1, a2, a3, a4 "
                         "and the noise are scaled by S(Vs)/S(5 V) and density by "
                         "sqrt(1/(2 Ts))); allowed: parameters whose effective values are "
                         "finite", names[i], r);
                n += slave_problem(comp, msg);
            }
        }
        {
            const char *adc[2] = {"lo", "lsb"};
            double adc_values[2];
            adc_values[0] = cfg.lo;
            adc_values[1] = cfg.lsb;
            for (i = 0; i < 2; i++) {
                if (!isfinite(adc_values[i])) {
                    char msg[PARAMETERS_MESSAGE_MAX], r[40];
                    parameters_repr_float(adc_values[i], r, sizeof r);
                    snprintf(msg, sizeof msg, "the ADC over a0 +- |a1| range gives %s = %s; "
                             "allowed: a0, a1 and range whose span is finite", adc[i], r);
                    n += slave_problem(comp, msg);
                }
            }
        }
        {
            const ErrorConfig ecfg = ecfg_of(v);
            const char *slow[4] = {"b_on", "rw", "gm_c", "fl_sigma"};
            double slow_values[4];
            slow_values[0] = ecfg.b_on;
            slow_values[1] = ecfg.rw;
            slow_values[2] = ecfg.gm_c;
            slow_values[3] = ecfg.fl_sigma;
            for (i = 0; i < 4; i++) {
                if (!isfinite(slow_values[i])) {
                    char msg[PARAMETERS_MESSAGE_MAX], r[40];
                    parameters_repr_float(slow_values[i], r, sizeof r);
                    snprintf(msg, sizeof msg, "the parameters give the slow errors' %s = %s "
                             "(b_on = bias_on n_0, rw = random_walk sqrt(Ts), gm_c = bias_gm "
                             "sqrt(1 - exp(-2 Ts/tau_gm)), fl_sigma = flicker over the Allan "
                             "deviation of the unit components); allowed: parameters whose "
                             "effective values are finite", slow[i], r);
                    n += slave_problem(comp, msg);
                }
            }
        }
    }
    return n;
}

void model_start(ModelInstance *comp)
{
    comp->h.cfg = config_of(&comp->v);
    dualaxis_axes(comp->v.a0, comp->v.a1, comp->v.a2, comp->v.bx, comp->v.R, comp->v.a0y,
                  comp->v.a1y, comp->v.a2y, comp->v.by, comp->v.Ry, &comp->h.ax, &comp->h.ay);
    comp->h.lp_set = comp->h.lpy_set = 0;
    comp->h.lp = comp->h.lpy = 0.0;
    comp->h.lp_pending_set = comp->h.lpy_pending_set = 0;
    comp->h.lp_pending = comp->h.lpy_pending = 0.0;
    comp->h.ecfg = ecfg_of(&comp->v);
    comp->h.keys.rw = noise_key((uint64_t)comp->v.seed, NOISE_STREAM_RANDOM_WALK);
    comp->h.keys.gm = noise_key((uint64_t)comp->v.seed, NOISE_STREAM_BIAS_GM);
    {
        int i;
        for (i = 0; i < ERRORS_FLICKER_MAX; i++)
            comp->h.keys.fl[i] = noise_key((uint64_t)comp->v.seed,
                                           (uint64_t)(NOISE_STREAM_FLICKER + i));
    }
    comp->h.keys.v = noise_key((uint64_t)comp->v.seed, NOISE_STREAM_MEASUREMENT);
    comp->h.keys.v_y = noise_key((uint64_t)comp->v.seed, NOISE_STREAM_MEASUREMENT_Y);
    comp->h.tilt.theta = comp->h.tilt.sine = 0.0;
    memset(&comp->h.err, 0, sizeof comp->h.err);
    if (comp->h.ecfg.on) comp->h.err = errors_initial_state(comp->v.seed, &comp->h.ecfg);
    comp->h.err_pending = comp->h.err;
}

/* adxl203.noise(seed, k, axis), from the stream's key. */
static double measurement_noise(const ModelInstance *comp, int64_t k, int64_t axis)
{
    return noise_normal_keyed(axis == 1 ? comp->h.keys.v : comp->h.keys.v_y, (uint64_t)k);
}

/* errors_draws(seed, k, ...), from the streams' keys (Accelerometer._draws). */
static void keyed_draws(const ModelInstance *comp, int64_t k, double *n_rw, double *n_gm,
                        double *n_fl)
{
    const ErrorConfig *ecfg = &comp->h.ecfg;
    const ErrorKeys *keys = &comp->h.keys;
    int64_t i;
    *n_rw = ecfg->rw != 0.0 ? noise_ziggurat_keyed(keys->rw, (uint64_t)k) : 0.0;
    *n_gm = ecfg->gm_sigma != 0.0 ? noise_ziggurat_keyed(keys->gm, (uint64_t)k) : 0.0;
    for (i = 0; i < ecfg->fl_n; i++)
        n_fl[i] = noise_ziggurat_keyed(keys->fl[i], (uint64_t)k);
}

/* Accelerometer._axis_errors: the first axis with the slow errors. */
static void axis_errors_sample(ModelInstance *comp, int64_t *set, double *lp, ErrorState *err,
                               int64_t k, double *z)
{
    const ErrorConfig *ecfg = &comp->h.ecfg;
    double v, n_rw, n_gm, n_fl[ERRORS_FLICKER_MAX];
    /* the draws, then the measurement noise, then the sample (the exposure first): the noise's
     * logarithm and the exposure's exponential, the two longest chains of dependent operations
     * of the sample, close enough for the CPU to run them side by side (with the draws between
     * them, they ran one after the other) */
    keyed_draws(comp, k, &n_rw, &n_gm, n_fl);
    v = comp->v.noise ? measurement_noise(comp, k, 1) : 0.0;
    /* (every process off: the state stays 0.0, Python's None) */
    adxl203_measure_errors(*set, *lp, err, comp->v.x, comp->v.y, v, n_rw, n_gm, n_fl,
                           comp->v.theta, comp->v.T, &comp->h.cfg, ecfg, &comp->h.tilt, set, lp,
                           z);
}

/* Accelerometer._errors_valid: the exposure, the one number of the error state that can
 * overflow while z stays finite (the walk, the Gauss-Markov and flicker biases reach z as they
 * are, and z is checked first); its name when it is not finite. */
static const char *errors_not_finite(const ErrorState *err)
{
    return isfinite(err->E) ? NULL : "hidden state _err.E";
}

/* Accelerometer._axis: one sample of an axis. */
static void axis_sample(const ModelInstance *comp, int64_t *set, double *lp, double own,
                        double other, int64_t k, int64_t axis, double *z)
{
    double v = comp->v.noise ? measurement_noise(comp, k, axis) : 0.0;
    adxl203_measure(*set, *lp, own, other, v, &comp->h.cfg, set, lp, z);
}

/* Accelerometer.hold over n >= 1 samples from k0 with the inputs held: the samples before the
 * last change only the error state (errors_advance_state, as errors_hold, with the draws from
 * the streams' keys) and the output filters (adxl203_hold, of what the sensor senses: the slow
 * errors' class 2 and range, where on); the last is Accelerometer.sample.  Its outputs; returns
 * the name of a value that is not finite, or NULL. */
static const char *hold(ModelInstance *comp, int64_t *lp_set, double *lp, int64_t *lpy_set,
                        double *lpy, ErrorState *err, int64_t k0, int64_t n)
{
    int64_t i;
    double z = comp->v.z, z_y = comp->v.z_y;
    const int errors = comp->h.ecfg.on || comp->v.theta != 0.0;
    if (n > 1) {
        const Config *cfg = &comp->h.cfg;
        if (comp->h.ecfg.on) {
            for (i = k0; i < k0 + n - 1; i++) {
                double n_rw, n_gm, n_fl[ERRORS_FLICKER_MAX];
                keyed_draws(comp, i, &n_rw, &n_gm, n_fl);
                errors_advance_state(err, comp->v.x, n_rw, n_gm, n_fl, &comp->h.ecfg);
            }
        }
        if (cfg->has_alpha) {
            const double own = errors ? errors_sensed(comp->v.x, comp->v.theta, comp->v.T,
                                                      &comp->h.ecfg, &comp->h.tilt)
                                      : comp->v.x;
            adxl203_hold(*lp_set, *lp, own, comp->v.y, comp->v.seed, k0 - 1, n, cfg, 1,
                         comp->v.noise, lp_set, lp);
            if (comp->v.axes == 2)
                adxl203_hold(*lpy_set, *lpy, comp->v.y, comp->v.x, comp->v.seed, k0 - 1, n, cfg,
                             2, comp->v.noise, lpy_set, lpy);
        }
        k0 = k0 + n - 1;
        n = 1;
    }
    if (comp->v.dual) { /* Accelerometer._dual: no filter (dual = 1 needs fc = 0) */
        double vx = 0.0, vy = 0.0;
        if (comp->v.noise) {
            vx = measurement_noise(comp, k0, 1);
            vy = measurement_noise(comp, k0, 2);
        }
        dualaxis_measure(comp->v.x, comp->v.y, comp->h.ax, comp->h.ay, vx, vy, &z, &z_y);
        *lp_set = *lpy_set = 0;
        *lp = *lpy = 0.0;
        comp->v.z = z;
        comp->v.z_y = z_y;
        if (!isfinite(z)) return "z";
        if (!isfinite(z_y)) return "z_y";
        return NULL;
    }
    if (errors) /* Accelerometer.sample: the last */
        axis_errors_sample(comp, lp_set, lp, err, k0, &z);
    else
        axis_sample(comp, lp_set, lp, comp->v.x, comp->v.y, k0, 1, &z);
    if (comp->v.axes != 2) {
        *lpy_set = 0;
        *lpy = 0.0;
    } else {
        axis_sample(comp, lpy_set, lpy, comp->v.y, comp->v.x, k0, 2, &z_y);
    }
    comp->v.z = z;
    if (comp->v.axes == 2) comp->v.z_y = z_y;
    if (!isfinite(z)) return "z";
    if (comp->v.axes == 2 && !isfinite(z_y)) return "z_y";
    if (*lp_set && !isfinite(*lp)) return "hidden state _lp";
    if (*lpy_set && !isfinite(*lpy)) return "hidden state _lpy";
    if (comp->h.ecfg.on) return errors_not_finite(err);
    return NULL;
}

const char *model_compute(ModelInstance *comp)
{
    ModelHidden *h = &comp->h;
    h->lp_pending_set = h->lp_set;
    h->lp_pending = h->lp;
    h->lpy_pending_set = h->lpy_set;
    h->lpy_pending = h->lpy;
    if (h->ecfg.on) h->err_pending = h->err;
    return hold(comp, &h->lp_pending_set, &h->lp_pending, &h->lpy_pending_set, &h->lpy_pending,
                &h->err_pending, comp->k, 1);
}

const char *model_advance(ModelInstance *comp, const StepPlan *plan)
{
    ModelHidden *h = &comp->h;
    int64_t lp_set = h->lp_set, lpy_set = h->lpy_set;
    double lp = h->lp, lpy = h->lpy;
    /* (the error state is advanced in place: the plumbing puts back what a refused step
     * changed, model.h) */
    if (plan->n > 0) {
        int64_t start = plan->k_first;
        if (plan->first_pending) { /* sample k: committed with the inputs set at t */
            lp_set = h->lp_pending_set;
            lp = h->lp_pending;
            lpy_set = h->lpy_pending_set;
            lpy = h->lpy_pending;
            if (h->ecfg.on) h->err = h->err_pending;
            start = plan->k_first + 1;
        }
        if (plan->k_first + plan->n > start) { /* the other instants: inputs held from t */
            const char *bad = hold(comp, &lp_set, &lp, &lpy_set, &lpy, &h->err, start,
                                   plan->k_first + plan->n - start);
            if (bad) return bad;
        }
    }
    h->lp_set = lp_set;
    h->lp = lp;
    h->lpy_set = lpy_set;
    h->lpy = lpy;
    return NULL; /* a pending sample at t + h: model_compute, from the inputs set there */
}

/* models.errors.state_problems of an error state of the restored hidden state (`which`: err
 * or err_pending), the C form: while every slow error is off the state is all 0.0 (Python's
 * None); otherwise every number is finite, the exposure E >= 0, a process that is off has 0.0,
 * the components beyond the flicker bias's fl_n are 0.0. */
static int error_state_problems(ModelInstance *comp, const char *which, const ErrorState *s,
                                const ErrorConfig *ecfg)
{
    static const ErrorState zero;
    char name[64], b[32];
    int n = 0;
    int64_t i;
    if (!ecfg->on) {
        const double *values = &s->rw; /* rw, gm, E, fl[0 ..]: the struct's doubles in order */
        const char *names[3] = {"rw", "gm", "E"};
        if (memcmp(s, &zero, sizeof zero) == 0) return 0;
        for (i = 0; i < 3 + ERRORS_FLICKER_MAX; i++)
            if (memcmp(&values[i], &zero.rw, sizeof(double)) != 0) break;
        if (i < 3)
            snprintf(name, sizeof name, "%s.%s", which, names[i]);
        else
            snprintf(name, sizeof name, "%s.fl[%d]", which, (int)(i - 3));
        model_log_error(comp, "hidden %s = %s although every slow error is off (bias_on, "
                        "random_walk, bias_gm, flicker, d_inf, kT_bias, kT_scale, range = 0); "
                        "allowed: 0.0", name,
                        (parameters_repr_float(values[i < 3 + ERRORS_FLICKER_MAX ? i : 0], b,
                                               sizeof b), b));
        return 1;
    }
    n += SLAVE_HIDDEN_REAL(comp, which, s, rw, 0) + SLAVE_HIDDEN_REAL(comp, which, s, gm, 0);
    snprintf(name, sizeof name, "%s.E", which);
    if (!isfinite(s->E)) {
        n += slave_hidden_real(comp, name, s->E, 0);
    } else if (!(s->E >= 0.0)) {
        model_log_error(comp, "hidden %s = %s is a negative exposure; allowed: E >= 0 (a sum "
                        "of x^2 Ts)", name, (parameters_repr_float(s->E, b, sizeof b), b));
        n++;
    }
    {
        const struct { const char *field, *what; int on; double value; } off[3] = {
            {"rw", "random_walk", ecfg->rw != 0.0, s->rw},
            {"gm", "bias_gm", ecfg->gm_sigma != 0.0, s->gm},
            {"E", "d_inf", ecfg->d_inf != 0.0, s->E}};
        for (i = 0; i < 3; i++) {
            if (off[i].on || off[i].value == 0.0 || !isfinite(off[i].value)) continue;
            model_log_error(comp, "hidden %s.%s = %s although %s = 0 (off); allowed: %s.%s = "
                            "0.0", which, off[i].field,
                            (parameters_repr_float(off[i].value, b, sizeof b), b), off[i].what,
                            which, off[i].field);
            n++;
        }
    }
    for (i = 0; i < ERRORS_FLICKER_MAX; i++) {
        snprintf(name, sizeof name, "%s.fl[%d]", which, (int)i);
        if (!isfinite(s->fl[i])) {
            n += slave_hidden_real(comp, name, s->fl[i], 0);
        } else if (i >= ecfg->fl_n && s->fl[i] != 0.0) {
            model_log_error(comp, "hidden %s = %s is a flicker component the parameters do not "
                            "have (%d of them); allowed: 0.0", name,
                            (parameters_repr_float(s->fl[i], b, sizeof b), b), (int)ecfg->fl_n);
            n++;
        }
    }
    return n;
}

/* The held tilt's sine of a restored hidden state: theta finite and the sine its ops_sin, bit
 * for bit (a cache: any held theta will do, but not a sine of another). */
static int tilt_problems(ModelInstance *comp, const ErrorTilt *t)
{
    char b1[32], b2[32];
    double sine;
    if (!isfinite(t->theta)) return slave_hidden_real(comp, "tilt.theta", t->theta, 0);
    sine = ops_sin(t->theta);
    if (memcmp(&sine, &t->sine, sizeof sine) == 0) return 0;
    model_log_error(comp, "hidden tilt.sine = %s is not the sine of tilt.theta = %s; allowed: "
                    "sin(tilt.theta) (the held tilt's sine)",
                    (parameters_repr_float(t->sine, b1, sizeof b1), b1),
                    (parameters_repr_float(t->theta, b2, sizeof b2), b2));
    return 1;
}

int model_hidden_problems(ModelInstance *comp, const ModelHidden *fresh)
{
    const ModelHidden *h = &comp->h;
    return slave_hidden_derived(comp, "cfg", &h->cfg, &fresh->cfg, sizeof h->cfg) +
           slave_hidden_derived(comp, "ax", &h->ax, &fresh->ax, sizeof h->ax) +
           slave_hidden_derived(comp, "ay", &h->ay, &fresh->ay, sizeof h->ay) +
           slave_hidden_flag(comp, "lp_set", h->lp_set) +
           slave_hidden_flag(comp, "lpy_set", h->lpy_set) +
           slave_hidden_flag(comp, "lp_pending_set", h->lp_pending_set) +
           slave_hidden_flag(comp, "lpy_pending_set", h->lpy_pending_set) +
           slave_hidden_real(comp, "lp", h->lp, 0) + slave_hidden_real(comp, "lpy", h->lpy, 0) +
           slave_hidden_real(comp, "lp_pending", h->lp_pending, 0) +
           slave_hidden_real(comp, "lpy_pending", h->lpy_pending, 0) +
           slave_hidden_derived(comp, "ecfg", &h->ecfg, &fresh->ecfg, sizeof h->ecfg) +
           slave_hidden_derived(comp, "keys", &h->keys, &fresh->keys, sizeof h->keys) +
           error_state_problems(comp, "err", &h->err, &fresh->ecfg) +
           error_state_problems(comp, "err_pending", &h->err_pending, &fresh->ecfg) +
           tilt_problems(comp, &h->tilt);
}
