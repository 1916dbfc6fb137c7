/* DriftEstimator_step: the per-sample logic of fmu_src/DriftEstimator.py (prepare, sample, hold
 * and check_parameters) as the MODEL HOOKS of model.h; see DriftEstimator_step.h. */
#include <math.h>
#include <stdio.h>

#include "bias.h"
#include "chain.h"
#include "covariance.h"
#include "drift.h"
#include "errors.h"
#include "harmonic.h"
#include "model.h"
#include "parameters.h"
#include "sensor.h"
#include "slave.h"

static const SlaveRange EXTRA[] = {{"estimator", 1, 3}};

int model_check(ModelInstance *comp)
{
    const ModelVariables *v = &comp->v;
    int n;
    n = slave_check_parameters(comp, EXTRA, 1);
    if (v->process == HARMONIC_HARMONIC) n += slave_check_nyquist(comp, v->f, v->Ts);
    if (v->bias == 1 && v->process == HARMONIC_HARMONIC) {
        /* DriftEstimator.BIAS_WITH_HARMONIC */
        model_log_error(comp, "bias = %d is not allowed with process = %d; allowed: bias = 1 "
                        "with process = 1 (the harmonic filter has no bias state), or bias = 0",
                        v->bias, v->process);
        n++;
    }
    return n;
}

void model_start(ModelInstance *comp)
{
    ModelHidden *h = &comp->h;
    const Bias none = {0.0, 0.0, 0.0};
    harmonic_rotation(comp->v.f, comp->v.Ts, &h->C, &h->S);
    h->state = harmonic_estimator_init(comp->v.process, comp->v.x0, comp->v.P0);
    h->pending = h->state;
    h->Fb = bias_factor(comp->v.tau_b, comp->v.Ts);
    h->bias = comp->v.bias == 1 ? bias_init(comp->v.b0, comp->v.Pb0) : none;
    h->bias_pending = h->bias;
}

/* The bias state (DriftEstimator._bias), or a class-2 coefficient (_kT). */
static int bias_on(const ModelVariables *v) { return v->bias == 1; }
static int kT_on(const ModelVariables *v) { return v->kT_bias != 0.0 || v->kT_scale != 0.0; }

/* DriftEstimator._general_sample's offset: models.errors.class2_offset with a tilt or a temperature
 * coefficient, else 0 (then z - 0.0 is z: the letter's sample, the same bits). */
static double class2_offset(const ModelVariables *v)
{
    if (v->theta != 0.0 || kT_on(v))
        return errors_class2_offset(v->theta, v->T, v->a1, v->a2, v->T0, v->kT_bias, v->kT_scale,
                                    v->a3, v->a4);
    return 0.0;
}

/* DriftEstimator's COVARIANCE_NAMES and COVARIANCE_LISTING (the refusal of a step) and
 * STATE_COVARIANCE_NAMES (of a state being restored). */
static const char *const COVARIANCE_NAMES[] = {"P", "hidden state _state.P12",
                                               "hidden state _state.P22"};
static const char *const STATE_COVARIANCE_NAMES[] = {
    "hidden state _state.P", "hidden state _state.P12", "hidden state _state.P22"};
#define COVARIANCE_LISTING "the covariance (P, P12, P22) of hidden state _state"

/* The bias filter's (models.bias.COVARIANCE_NAMES; the listing from the names) and, in a state
 * being restored, DriftEstimator.BIAS_STATE_COVARIANCE_NAMES and BIAS_STATE_LISTING. */
static const char *const BIAS_COVARIANCE_NAMES[] = {"P", "P_xb", "P_bb"};
static const char *const BIAS_STATE_COVARIANCE_NAMES[] = {
    "hidden state _state.P", "hidden state _bias.Pxb", "hidden state _bias.Pbb"};
#define BIAS_STATE_LISTING "the covariance (P, Pxb, Pbb) of hidden states _state and _bias"

/* DriftEstimator.covariance_refusal of the harmonic state s after sample k: comp->refusal. */
static const char *refuse_covariance(ModelInstance *comp, const HarmonicState *s, int64_t k)
{
    const double lower[3] = {s->P, s->P12, s->P22};
    covariance_refusal(2, lower, COVARIANCE_NAMES, COVARIANCE_LISTING, (long long)k,
                       comp->startTime + (double)(k - 1) * comp->v.Ts, comp->refusal,
                       sizeof comp->refusal);
    return comp->refusal;
}

/* The same for the bias filter's covariance (P, P_xb, P_bb). */
static const char *refuse_bias_covariance(ModelInstance *comp, const HarmonicState *s,
                                          const Bias *b, int64_t k)
{
    const double lower[3] = {s->P, b->Pxb, b->Pbb};
    covariance_refusal(2, lower, BIAS_COVARIANCE_NAMES, NULL, (long long)k,
                       comp->startTime + (double)(k - 1) * comp->v.Ts, comp->refusal,
                       sizeof comp->refusal);
    return comp->refusal;
}

/* DriftEstimator._outputs / _general_outputs of the state s (and bias part b) after sample k
 * with the measurement z (the offset removed), and the first value that is not finite, else the
 * refusal of a covariance that is not valid (or NULL). */
static const char *outputs(ModelInstance *comp, const HarmonicState *s, const Bias *b, double z,
                           double offset, int64_t k)
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
    if (bias_on(v)) {
        v->z_comp = bias_compensate(z, v->dc, b->b);
        v->b_hat = b->b;
        v->P_bb = b->Pbb;
        v->P_xb = b->Pxb;
    } else {
        v->z_comp = chain_compensate(z, v->dc);
        v->b_hat = v->P_bb = v->P_xb = 0.0;
    }
    v->dc_class2 = offset;
    if (!isfinite(v->x_hat)) return "x_hat";
    if (!isfinite(v->P)) return "P";
    if (!isfinite(v->dc_ekf1)) return "dc_ekf1";
    if (!isfinite(v->dc_ekf2)) return "dc_ekf2";
    if (!isfinite(v->dc_ekf3)) return "dc_ekf3";
    if (!isfinite(v->dc)) return "dc";
    if (!isfinite(v->z_comp)) return "z_comp";
    if (!isfinite(v->b_hat)) return "b_hat";
    if (!isfinite(v->P_bb)) return "P_bb";
    if (!isfinite(v->P_xb)) return "P_xb";
    if (!isfinite(v->dc_class2)) return "dc_class2";
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
    if (bias_on(v) && !covariance_valid2(s->P, b->Pxb, b->Pbb))
        return refuse_bias_covariance(comp, s, b, k);
    return NULL;
}

/* models.bias.estimator_step / estimator_predict on the Gauss-Markov fields of s. */
static void bias_sample(const ModelVariables *v, const ModelHidden *h, HarmonicState *s, Bias *b,
                        double z, int update)
{
    EstimatorState e;
    e.x = s->x;
    e.P = s->P;
    e.drift = s->drift;
    if (update)
        e = bias_estimator_step(e, b, z, v->a0, v->a1, v->a2, v->A, v->Q, v->R, h->Fb, v->Qb,
                                v->a3, v->a4, v->B, v->u);
    else
        e = bias_estimator_predict(e, b, v->A, v->Q, h->Fb, v->Qb, v->B, v->u);
    s->x = e.x;
    s->P = e.P;
    s->drift = e.drift;
}

/* DriftEstimator.hold: n >= 1 samples from k0; the first takes z as its measurement if
 * `first`, every other one is predict-only.  The harmonic state after each sample but the last
 * is refused when its covariance is not valid and finite (DriftEstimator._refuse_covariance);
 * the last is checked by outputs. */
static const char *hold(ModelInstance *comp, HarmonicState *s, Bias *b, int64_t k0, int64_t n,
                        int first)
{
    const ModelVariables *v = &comp->v;
    const ModelHidden *h = &comp->h;
    const double offset = class2_offset(v), z = v->z - offset;
    int64_t i;
    for (i = 0; i < n; i++) {
        if (i > 0 && v->process == HARMONIC_HARMONIC && !covariance_valid2(s->P, s->P12, s->P22)
            && isfinite(0.0 * s->P + 0.0 * s->P12 + 0.0 * s->P22))
            return refuse_covariance(comp, s, k0 + i - 1);
        if (i > 0 && bias_on(v) && !covariance_valid2(s->P, b->Pxb, b->Pbb)
            && isfinite(0.0 * s->P + 0.0 * b->Pxb + 0.0 * b->Pbb))
            return refuse_bias_covariance(comp, s, b, k0 + i - 1);
        if (bias_on(v))
            bias_sample(v, h, s, b, z, first && i == 0);
        else if (first && i == 0)
            *s = harmonic_estimator_step_general(*s, z, v->a0, v->a1, v->a2, v->R, v->process,
                                                 v->A, v->Q, h->C, h->S, v->Qh, v->a3, v->a4,
                                                 v->B, v->u);
        else /* u held, as z */
            *s = harmonic_estimator_predict_general(*s, v->process, v->A, v->Q, h->C, h->S,
                                                    v->Qh, v->B, v->u);
    }
    return outputs(comp, s, b, z, offset, k0 + n - 1);
}

const char *model_compute(ModelInstance *comp)
{
    comp->h.pending = comp->h.state;
    comp->h.bias_pending = comp->h.bias;
    return hold(comp, &comp->h.pending, &comp->h.bias_pending, comp->k, 1, 1);
}

const char *model_advance(ModelInstance *comp, const StepPlan *plan)
{
    HarmonicState s = comp->h.state;
    Bias b = comp->h.bias;
    if (plan->n > 0) {
        int64_t start = plan->k_first;
        int first = 1;
        if (plan->first_pending) { /* sample k: committed with the z set at t */
            s = comp->h.pending;
            b = comp->h.bias_pending;
            start = plan->k_first + 1;
            first = 0;
        }
        if (plan->k_first + plan->n > start) { /* the other instants: z held from t */
            const char *bad = hold(comp, &s, &b, start, plan->k_first + plan->n - start, first);
            if (bad) return bad;
        }
    }
    comp->h.state = s;
    comp->h.bias = b;
    return NULL; /* a pending sample at t + h: model_compute, from the z set there */
}

static int harmonic_state_problems(ModelInstance *comp, const char *which, const HarmonicState *s,
                                   const char *bias_which, const Bias *b)
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
    n += SLAVE_HIDDEN_REAL(comp, bias_which, b, b, 0);
    n += SLAVE_HIDDEN_REAL(comp, bias_which, b, Pxb, 0);
    n += SLAVE_HIDDEN_REAL(comp, bias_which, b, Pbb, 1);
    if (n == 0 && !bias_on(&comp->v) && (b->b != 0.0 || b->Pxb != 0.0 || b->Pbb != 0.0)) {
        /* DriftEstimator.hidden_problems: a bias part that does not belong to bias = 0 */
        char vb[32], vx[32], vp[32];
        parameters_repr_float(b->b, vb, sizeof vb);
        parameters_repr_float(b->Pxb, vx, sizeof vx);
        parameters_repr_float(b->Pbb, vp, sizeof vp);
        model_log_error(comp, "hidden %s = (%s, %s, %s) does not belong to bias = %d; allowed: "
                        "(0.0, 0.0, 0.0) with bias = 0 (no bias state)", bias_which, vb, vx, vp,
                        comp->v.bias);
        n++;
    }
    if (n == 0) { /* every field finite: the covariance (DriftEstimator.hidden_problems) */
        const double harmonic[3] = {s->P, s->P12, s->P22}, with_bias[3] = {s->P, b->Pxb, b->Pbb};
        char msg[MODEL_REFUSAL_MAX];
        if (bias_on(&comp->v)
                ? covariance_state_problem(2, with_bias, BIAS_STATE_COVARIANCE_NAMES,
                                           BIAS_STATE_LISTING, msg, sizeof msg)
                : comp->v.process == HARMONIC_HARMONIC
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
           slave_hidden_derived(comp, "Fb", &h->Fb, &fresh->Fb, sizeof h->Fb) +
           harmonic_state_problems(comp, "state", &h->state, "bias", &h->bias) +
           harmonic_state_problems(comp, "pending", &h->pending, "bias_pending",
                                   &h->bias_pending);
}
