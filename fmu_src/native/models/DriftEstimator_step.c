/* DriftEstimator_step: the per-sample logic of fmu_src/DriftEstimator.py (prepare, sample, hold
 * and check_parameters) as the MODEL HOOKS of model.h; see DriftEstimator_step.h. */
#include <math.h>
#include <stdio.h>

#include "chain.h"
#include "covariance.h"
#include "drift.h"
#include "harmonic.h"
#include "model.h"
#include "slave.h"

static const SlaveRange EXTRA[] = {{"estimator", 1, 3}};

int model_check(ModelInstance *comp)
{
    const ModelVariables *v = &comp->v;
    int n;
    n = slave_check_parameters(comp, EXTRA, 1);
    if (v->process == HARMONIC_HARMONIC) n += slave_check_nyquist(comp, v->f, v->Ts);
    return n;
}

void model_start(ModelInstance *comp)
{
    ModelHidden *h = &comp->h;
    harmonic_rotation(comp->v.f, comp->v.Ts, &h->C, &h->S);
    h->state = harmonic_estimator_init(comp->v.process, comp->v.x0, comp->v.P0);
    h->pending = h->state;
}

/* DriftEstimator's COVARIANCE_NAMES and COVARIANCE_LISTING (the refusal of a step) and
 * STATE_COVARIANCE_NAMES (of a state being restored). */
static const char *const COVARIANCE_NAMES[] = {"P", "hidden state _state.P12",
                                               "hidden state _state.P22"};
static const char *const STATE_COVARIANCE_NAMES[] = {
    "hidden state _state.P", "hidden state _state.P12", "hidden state _state.P22"};
#define COVARIANCE_LISTING "the covariance (P, P12, P22) of hidden state _state"

/* DriftEstimator.covariance_refusal of the harmonic state s after sample k: comp->refusal. */
static const char *refuse_covariance(ModelInstance *comp, const HarmonicState *s, int64_t k)
{
    const double lower[3] = {s->P, s->P12, s->P22};
    covariance_refusal(2, lower, COVARIANCE_NAMES, COVARIANCE_LISTING, (long long)k,
                       comp->startTime + (double)(k - 1) * comp->v.Ts, comp->refusal,
                       sizeof comp->refusal);
    return comp->refusal;
}

/* DriftEstimator._outputs of the state s after sample k, and the first value that is not
 * finite, else the refusal of a covariance that is not valid (or NULL). */
static const char *outputs(ModelInstance *comp, const HarmonicState *s, int64_t k)
{
    ModelVariables *v = &comp->v;
    double dcs[3];
    drift_estimates_general(s->drift, v->a2, v->a3, v->a4, &dcs[0], &dcs[1], &dcs[2]);
    v->x_hat = s->x;
    v->P = s->P;
    v->dc_ekf1 = dcs[0];
    v->dc_ekf2 = dcs[1];
    v->dc_ekf3 = dcs[2];
    v->dc = drift_select(dcs, v->estimator);
    v->z_comp = chain_compensate(v->z, v->dc);
    if (!isfinite(v->x_hat)) return "x_hat";
    if (!isfinite(v->P)) return "P";
    if (!isfinite(v->dc_ekf1)) return "dc_ekf1";
    if (!isfinite(v->dc_ekf2)) return "dc_ekf2";
    if (!isfinite(v->dc_ekf3)) return "dc_ekf3";
    if (!isfinite(v->dc)) return "dc";
    if (!isfinite(v->z_comp)) return "z_comp";
    if (comp->v.process == HARMONIC_HARMONIC) {
        if (!isfinite(s->d)) return "hidden state _state.d";
        if (!isfinite(s->P12)) return "hidden state _state.P12";
        if (!isfinite(s->P22)) return "hidden state _state.P22";
    }
    if (!isfinite(s->drift.s1)) return "hidden state _state.drift.s1";
    if (!isfinite(s->drift.dc2)) return "hidden state _state.drift.dc2";
    if (!isfinite(s->drift.s3)) return "hidden state _state.drift.s3";
    if (!isfinite(s->drift.dc3)) return "hidden state _state.drift.dc3";
    if (comp->v.process == HARMONIC_HARMONIC && !covariance_valid2(s->P, s->P12, s->P22))
        return refuse_covariance(comp, s, k);
    return NULL;
}

/* DriftEstimator.hold: n >= 1 samples from k0; the first takes z as its measurement if
 * `first`, every other one is predict-only.  The harmonic state after each sample but the last
 * is refused when its covariance is not valid and finite (DriftEstimator._refuse_covariance);
 * the last is checked by outputs. */
static const char *hold(ModelInstance *comp, HarmonicState *s, int64_t k0, int64_t n,
                        int first)
{
    const ModelVariables *v = &comp->v;
    const ModelHidden *h = &comp->h;
    int64_t i;
    for (i = 0; i < n; i++) {
        if (i > 0 && v->process == HARMONIC_HARMONIC && !covariance_valid2(s->P, s->P12, s->P22)
            && isfinite(0.0 * s->P + 0.0 * s->P12 + 0.0 * s->P22))
            return refuse_covariance(comp, s, k0 + i - 1);
        if (first && i == 0)
            *s = harmonic_estimator_step_general(*s, v->z, v->a0, v->a1, v->a2, v->R, v->process,
                                                 v->A, v->Q, h->C, h->S, v->Qh, v->a3, v->a4,
                                                 v->B, v->u);
        else /* u held, as z */
            *s = harmonic_estimator_predict_general(*s, v->process, v->A, v->Q, h->C, h->S,
                                                    v->Qh, v->B, v->u);
    }
    return outputs(comp, s, k0 + n - 1);
}

const char *model_compute(ModelInstance *comp)
{
    comp->h.pending = comp->h.state;
    return hold(comp, &comp->h.pending, comp->k, 1, 1);
}

const char *model_advance(ModelInstance *comp, const StepPlan *plan)
{
    HarmonicState s = comp->h.state;
    if (plan->n > 0) {
        int64_t start = plan->k_first;
        int first = 1;
        if (plan->first_pending) { /* sample k: committed with the z set at t */
            s = comp->h.pending;
            start = plan->k_first + 1;
            first = 0;
        }
        if (plan->k_first + plan->n > start) { /* the other instants: z held from t */
            const char *bad = hold(comp, &s, start, plan->k_first + plan->n - start, first);
            if (bad) return bad;
        }
    }
    comp->h.state = s;
    return NULL; /* a pending sample at t + h: model_compute, from the z set there */
}

static int harmonic_state_problems(ModelInstance *comp, const char *which, const HarmonicState *s)
{
    char name[64];
    int n = 0;
    n += SLAVE_HIDDEN_REAL(comp, which, s, x, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, d, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, P, 1);
    n += SLAVE_HIDDEN_REAL(comp, which, s, P12, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, P22, 1);
    n += SLAVE_HIDDEN_REAL(comp, which, s, drift.s1, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, drift.dc2, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, drift.s3, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, drift.dc3, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, drift.t1, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, drift.q1, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, drift.t3, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, drift.q3, 0);
    snprintf(name, sizeof name, "%s.drift.k", which);
    n += slave_hidden_count(comp, name, s->drift.k);
    if (n == 0) { /* every field finite: the covariance (DriftEstimator.hidden_problems) */
        const double harmonic[3] = {s->P, s->P12, s->P22};
        char msg[MODEL_REFUSAL_MAX];
        if (comp->v.process == HARMONIC_HARMONIC
                ? covariance_state_problem(2, harmonic, STATE_COVARIANCE_NAMES,
                                           COVARIANCE_LISTING, msg, sizeof msg)
                : covariance_state_problem(1, harmonic, STATE_COVARIANCE_NAMES,
                                           COVARIANCE_LISTING, msg, sizeof msg))
            n += slave_problem(comp, msg);
    }
    return n;
}

int model_hidden_problems(ModelInstance *comp, const ModelHidden *fresh)
{
    const ModelHidden *h = &comp->h;
    return slave_hidden_derived(comp, "C", &h->C, &fresh->C, sizeof h->C) +
           slave_hidden_derived(comp, "S", &h->S, &fresh->S, sizeof h->S) +
           harmonic_state_problems(comp, "state", &h->state) +
           harmonic_state_problems(comp, "pending", &h->pending);
}
