/* Accelerometer_step: the per-sample logic of fmu_src/Accelerometer.py (prepare, sample, hold and
 * check_parameters) as the MODEL HOOKS of model.h; see Accelerometer_step.h. */
#include <math.h>
#include <stdio.h>

#include "adxl203.h"
#include "dualaxis.h"
#include "model.h"
#include "slave.h"

static const SlaveRange EXTRA[] = {{"noise", 0, 1}};

static Config config_of(const ModelVariables *v)
{
    return adxl203_config_general(v->a0, v->a1, v->a2, v->R, v->a3, v->cross, v->fc, v->Vs,
                                  v->bits, v->density, v->Ts, v->a4);
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
}

/* Accelerometer._axis: one sample of an axis. */
static void axis_sample(const ModelInstance *comp, int64_t *set, double *lp, double own,
                        double other, int64_t k, int64_t axis, double *z)
{
    double v = comp->v.noise ? adxl203_noise(comp->v.seed, k, axis) : 0.0;
    adxl203_measure(*set, *lp, own, other, v, &comp->h.cfg, set, lp, z);
}

/* Accelerometer.sample over n >= 1 samples from k0 with the inputs held (Accelerometer.hold:
 * without a filter only the last leaves a trace); the outputs of the last.  Returns the name of
 * a value that is not finite, or NULL. */
static const char *hold(ModelInstance *comp, int64_t *lp_set, double *lp, int64_t *lpy_set,
                        double *lpy, int64_t k0, int64_t n)
{
    int64_t i;
    double z = comp->v.z, z_y = comp->v.z_y;
    if (!comp->h.cfg.has_alpha && n > 1) {
        k0 = k0 + n - 1;
        n = 1;
    }
    if (comp->v.dual) { /* Accelerometer._dual: no filter (dual = 1 needs fc = 0) */
        double vx = 0.0, vy = 0.0;
        int64_t k = k0 + n - 1;
        if (comp->v.noise) {
            vx = adxl203_noise(comp->v.seed, k, 1);
            vy = adxl203_noise(comp->v.seed, k, 2);
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
    for (i = 0; i < n; i++) {
        axis_sample(comp, lp_set, lp, comp->v.x, comp->v.y, k0 + i, 1, &z);
        if (comp->v.axes != 2) {
            *lpy_set = 0;
            *lpy = 0.0;
        } else {
            axis_sample(comp, lpy_set, lpy, comp->v.y, comp->v.x, k0 + i, 2, &z_y);
        }
    }
    comp->v.z = z;
    if (comp->v.axes == 2) comp->v.z_y = z_y;
    if (!isfinite(z)) return "z";
    if (comp->v.axes == 2 && !isfinite(z_y)) return "z_y";
    if (*lp_set && !isfinite(*lp)) return "hidden state _lp";
    if (*lpy_set && !isfinite(*lpy)) return "hidden state _lpy";
    return NULL;
}

const char *model_compute(ModelInstance *comp)
{
    ModelHidden *h = &comp->h;
    h->lp_pending_set = h->lp_set;
    h->lp_pending = h->lp;
    h->lpy_pending_set = h->lpy_set;
    h->lpy_pending = h->lpy;
    return hold(comp, &h->lp_pending_set, &h->lp_pending, &h->lpy_pending_set, &h->lpy_pending,
                comp->k, 1);
}

const char *model_advance(ModelInstance *comp, const StepPlan *plan)
{
    ModelHidden *h = &comp->h;
    int64_t lp_set = h->lp_set, lpy_set = h->lpy_set;
    double lp = h->lp, lpy = h->lpy;
    if (plan->n > 0) {
        int64_t start = plan->k_first;
        if (plan->first_pending) { /* sample k: committed with the inputs set at t */
            lp_set = h->lp_pending_set;
            lp = h->lp_pending;
            lpy_set = h->lpy_pending_set;
            lpy = h->lpy_pending;
            start = plan->k_first + 1;
        }
        if (plan->k_first + plan->n > start) { /* the other instants: inputs held from t */
            const char *bad = hold(comp, &lp_set, &lp, &lpy_set, &lpy, start,
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
           slave_hidden_real(comp, "lpy_pending", h->lpy_pending, 0);
}
