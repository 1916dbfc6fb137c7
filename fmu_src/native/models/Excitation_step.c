/* Excitation_step: the per-sample logic of fmu_src/Excitation.py (start, sample, hold and
 * check_parameters) as the MODEL HOOKS of model.h; see Excitation_step.h. */
#include <math.h>
#include <stdio.h>

#include "excitation.h"
#include "model.h"
#include "slave.h"

static const SlaveRange EXTRA[] = {{"kind", 1, 2}};

int model_check(ModelInstance *comp)
{
    const ModelVariables *v = &comp->v;
    int n;
    n = slave_check_parameters(comp, EXTRA, 1);
    if (v->kind == EXCITATION_SINUSOIDAL) n += slave_check_nyquist(comp, v->f, v->Ts);
    if (v->drive == EXCITATION_SINUSOIDAL) n += slave_check_nyquist_named(comp, "fu", v->fu, v->Ts);
    return n;
}

/* Excitation._u: sample k of the known input; drive 0: the host's u_in (0 unless set). */
static double sample_u(const ModelVariables *v, int64_t k)
{
    if (v->drive == EXCITATION_DRIVE_OFF) return v->u_in;
    return excitation_input_sample(v->drive, v->seed, k, v->Qu, v->Xu, v->fu, v->Ts);
}

/* Excitation._sample: sample k of (x, y) from (x_prev, y_prev). */
static void sample_xy(const ModelVariables *v, double x_prev, double y_prev, int64_t k,
                      double *x, double *y)
{
    if (v->kind == EXCITATION_GAUSSIAN) {
        excitation_gaussian_pair_general(x_prev, y_prev, v->A, v->Q, v->Qy, v->rho, v->seed, k,
                                         v->B, sample_u(v, k), x, y);
    } else {
        *x = excitation_sine(k, v->X, v->f, v->Ts, v->phi);
        *y = excitation_sine(k, v->Xy, v->f, v->Ts, v->phiy);
    }
}

/* Excitation.hold: n >= 1 samples from k0 (the sinusoid needs no history); the outputs of the
 * last.  Returns the name of a value that is not finite, or NULL. */
static const char *hold(ModelInstance *comp, double *x, double *y, int64_t k0, int64_t n)
{
    const ModelVariables *v = &comp->v;
    int64_t k;
    if (v->kind == EXCITATION_GAUSSIAN) {
        for (k = k0; k < k0 + n; k++) sample_xy(v, *x, *y, k, x, y);
    } else {
        sample_xy(v, *x, *y, k0 + n - 1, x, y);
    }
    comp->v.x = *x;
    comp->v.y = *y;
    comp->v.u = sample_u(v, k0 + n - 1);
    if (!isfinite(comp->v.x)) return "x";
    if (!isfinite(comp->v.y)) return "y";
    if (!isfinite(comp->v.u)) return "u";
    return NULL;
}

/* The outputs of the pending sample k from the committed (x, y) and the inputs set now. */
static const char *make_pending(ModelInstance *comp, int64_t k)
{
    double x = comp->h.x, y = comp->h.y;
    const char *bad = hold(comp, &x, &y, k, 1);
    comp->h.x_pending = x;
    comp->h.y_pending = y;
    comp->h.has_pending = 1;
    return bad;
}

void model_start(ModelInstance *comp)
{
    comp->h.x = comp->v.x0;
    comp->h.y = 0.0;
    const double x = comp->v.x, y = comp->v.y, u = comp->v.u;
    if (make_pending(comp, 1)) {
        /* sample 1 overflows (B u_in, say): nothing pending and the outputs as they were, as
         * in the Python FMU, which computes sample 1 when it is read and refuses it there; a
         * state got now must not hold the values that cannot be (a restore refuses them) */
        comp->v.x = x;
        comp->v.y = y;
        comp->v.u = u;
        comp->h.x_pending = comp->h.y_pending = 0.0;
        comp->h.has_pending = 0;
    }
}

const char *model_compute(ModelInstance *comp)
{
    /* feedthrough (x through B u_k, and u follow the host's u_in): the pending sample's
     * outputs from the inputs set at its communication point */
    return make_pending(comp, comp->k);
}

const char *model_advance(ModelInstance *comp, const StepPlan *plan)
{
    const char *bad = NULL;
    double x = comp->h.x, y = comp->h.y;
    if (plan->n > 0) {
        int64_t start = plan->k_first;
        if (plan->first_pending) { /* sample k: committed */
            if (comp->h.has_pending) {
                x = comp->h.x_pending;
                y = comp->h.y_pending;
            } else {
                bad = hold(comp, &x, &y, plan->k_first, 1);
                if (bad) return bad;
            }
            start = plan->k_first + 1;
        }
        if (plan->k_first + plan->n > start) { /* the other instants */
            bad = hold(comp, &x, &y, start, plan->k_first + plan->n - start);
            if (bad) return bad;
        }
    }
    comp->h.x = x;
    comp->h.y = y;
    comp->h.has_pending = 0;
    return NULL; /* a pending sample at t + h: model_compute, from the u_in set there */
}

int model_hidden_problems(ModelInstance *comp, const ModelHidden *fresh)
{
    (void)fresh;
    const ModelHidden *h = &comp->h;
    int n = slave_hidden_real(comp, "x", h->x, 0) + slave_hidden_real(comp, "y", h->y, 0) +
            slave_hidden_flag(comp, "has_pending", h->has_pending) +
            slave_hidden_real(comp, "x_pending", h->x_pending, 0) +
            slave_hidden_real(comp, "y_pending", h->y_pending, 0);
    if (n == 0 && h->has_pending && !comp->pending) {
        model_log_error(comp, "hidden has_pending = %d with pending = %d; allowed: "
                        "has_pending = 0 when no sample is pending", (int)h->has_pending,
                        comp->pending);
        n++;
    }
    if (n == 0 && h->has_pending && (h->x_pending != comp->v.x || h->y_pending != comp->v.y)) {
        model_log_error(comp, "hidden x_pending, y_pending are not the outputs x, y of the "
                        "pending sample; allowed: equal");
        n++;
    }
    return n;
}
