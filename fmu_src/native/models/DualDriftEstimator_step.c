/* DualDriftEstimator_step: the per-sample logic of fmu_src/DualDriftEstimator.py (prepare,
 * sample, hold and check_parameters) as the MODEL HOOKS of model.h; see
 * DualDriftEstimator_step.h. */
#include <math.h>
#include <stdio.h>

#include "chain.h"
#include "covariance.h"
#include "drift.h"
#include "dualaxis.h"
#include "model.h"
#include "slave.h"

static const SlaveRange EXTRA[] = {{"estimator", 1, 3}};

int model_check(ModelInstance *comp)
{
    const ModelVariables *v = &comp->v;
    int n;
    n = slave_check_parameters(comp, EXTRA, 1);
    if (v->process == DUALAXIS_HARMONIC) n += slave_check_nyquist(comp, v->f, v->Ts);
    return n;
}

void model_start(ModelInstance *comp)
{
    ModelHidden *h = &comp->h;
    const ModelVariables *v = &comp->v;
    dualaxis_axes(v->a0, v->a1, v->a2, v->bx, v->R, v->a0y, v->a1y, v->a2y, v->by, v->Ry,
                  &h->ax, &h->ay);
    h->m = dualaxis_model(v->process, v->A, v->Q, v->Qy, v->rho, v->f, v->Ts, v->Qh);
    h->state = dualaxis_estimator_init(v->process, v->x0, v->y0, v->P0, v->P0y);
    h->pending = h->state;
}

/* DualDriftEstimator's COVARIANCE_NAMES, COVARIANCE_LISTING and STATE_COVARIANCE_NAMES of each
 * process model (index process - 1), packed as dualaxis_covariance_of packs the matrix. */
static const char *const COVARIANCE_NAMES[2][10] = {
    {"P_xx", "P_xy", "P_yy"},
    {"P_xx", "hidden state _state.P12", "hidden state _state.P22", "P_xy",
     "hidden state _state.P23", "P_yy", "hidden state _state.P14", "hidden state _state.P24",
     "hidden state _state.P34", "hidden state _state.P44"}};
static const char *const STATE_COVARIANCE_NAMES[2][10] = {
    {"hidden state _state.Pxx", "hidden state _state.Pxy", "hidden state _state.Pyy"},
    {"hidden state _state.P11", "hidden state _state.P12", "hidden state _state.P22",
     "hidden state _state.P13", "hidden state _state.P23", "hidden state _state.P33",
     "hidden state _state.P14", "hidden state _state.P24", "hidden state _state.P34",
     "hidden state _state.P44"}};
static const char *const COVARIANCE_LISTING[2] = {
    "the covariance (Pxx, Pxy, Pyy) of hidden state _state",
    "the covariance (P11, P12, P22, P13, P23, P33, P14, P24, P34, P44) of hidden state _state"};

/* DualDriftEstimator.covariance_refusal of the state s after sample k: comp->refusal. */
static const char *refuse_covariance(ModelInstance *comp, const DualEstimator *s, int64_t k)
{
    const int64_t process = comp->v.process;
    double lower[10];
    const int n = dualaxis_covariance_of(s, process, lower);
    covariance_refusal(n, lower, COVARIANCE_NAMES[process - 1], COVARIANCE_LISTING[process - 1],
                       (long long)k, comp->startTime + (double)(k - 1) * comp->v.Ts,
                       comp->refusal, sizeof comp->refusal);
    return comp->refusal;
}

/* Whether every entry of the covariance of s is finite. */
static int covariance_finite(const DualEstimator *s, int64_t process)
{
    double lower[10], zero = 0.0;
    const int n = dualaxis_covariance_of(s, process, lower);
    for (int i = 0; i < n * (n + 1) / 2; i++) zero += 0.0 * lower[i];
    return zero == 0.0;
}

#define CHECK(value, name) \
    do { \
        if (!isfinite(value)) return name; \
    } while (0)

/* DualDriftEstimator._outputs of the state after sample k, and the first value that is not
 * finite (the outputs in table order, then the hidden state: slave_base.hidden_valid's order),
 * else the refusal of a covariance that is not valid (or NULL). */
static const char *outputs(ModelInstance *comp, const DualEstimator *s, int64_t k)
{
    ModelVariables *v = &comp->v;
    const ModelHidden *h = &comp->h;
    double mom[5], dx[3], dy[3];
    DualDrift d = dualaxis_drift_of(s, v->process);
    dualaxis_moments(s, v->process, mom);
    dualaxis_estimates(d, h->ax, h->ay, dx, dy);
    v->x_hat = mom[0];
    v->y_hat = mom[1];
    v->P_xx = mom[2];
    v->P_xy = mom[3];
    v->P_yy = mom[4];
    v->dc_ekf1_x = dx[0];
    v->dc_ekf2_x = dx[1];
    v->dc_ekf3_x = dx[2];
    v->dc_ekf1_y = dy[0];
    v->dc_ekf2_y = dy[1];
    v->dc_ekf3_y = dy[2];
    v->dc_x = drift_select(dx, v->estimator);
    v->dc_y = drift_select(dy, v->estimator);
    v->z_comp_x = chain_compensate(v->z_x, v->dc_x);
    v->z_comp_y = chain_compensate(v->z_y, v->dc_y);
    CHECK(v->x_hat, "x_hat");
    CHECK(v->y_hat, "y_hat");
    CHECK(v->P_xx, "P_xx");
    CHECK(v->P_xy, "P_xy");
    CHECK(v->P_yy, "P_yy");
    CHECK(v->dc_ekf1_x, "dc_ekf1_x");
    CHECK(v->dc_ekf2_x, "dc_ekf2_x");
    CHECK(v->dc_ekf3_x, "dc_ekf3_x");
    CHECK(v->dc_ekf1_y, "dc_ekf1_y");
    CHECK(v->dc_ekf2_y, "dc_ekf2_y");
    CHECK(v->dc_ekf3_y, "dc_ekf3_y");
    CHECK(v->dc_x, "dc_x");
    CHECK(v->dc_y, "dc_y");
    CHECK(v->z_comp_x, "z_comp_x");
    CHECK(v->z_comp_y, "z_comp_y");
    if (v->process == DUALAXIS_GAUSS_MARKOV) {
        const DualState *g = &s->g;
        CHECK(g->x, "hidden state _state.x");
        CHECK(g->y, "hidden state _state.y");
        CHECK(g->Pxx, "hidden state _state.Pxx");
        CHECK(g->Pxy, "hidden state _state.Pxy");
        CHECK(g->Pyy, "hidden state _state.Pyy");
    } else {
        const DualHarmonicState *m = &s->h;
        CHECK(m->x, "hidden state _state.x");
        CHECK(m->dx, "hidden state _state.dx");
        CHECK(m->y, "hidden state _state.y");
        CHECK(m->dy, "hidden state _state.dy");
        CHECK(m->P11, "hidden state _state.P11");
        CHECK(m->P12, "hidden state _state.P12");
        CHECK(m->P22, "hidden state _state.P22");
        CHECK(m->P33, "hidden state _state.P33");
        CHECK(m->P34, "hidden state _state.P34");
        CHECK(m->P44, "hidden state _state.P44");
        CHECK(m->P13, "hidden state _state.P13");
        CHECK(m->P14, "hidden state _state.P14");
        CHECK(m->P23, "hidden state _state.P23");
        CHECK(m->P24, "hidden state _state.P24");
    }
    CHECK(d.s1xx, "hidden state _state.drift.s1xx");
    CHECK(d.s1xy, "hidden state _state.drift.s1xy");
    CHECK(d.s1yy, "hidden state _state.drift.s1yy");
    CHECK(d.dc2x, "hidden state _state.drift.dc2x");
    CHECK(d.dc2y, "hidden state _state.drift.dc2y");
    CHECK(d.s3xx, "hidden state _state.drift.s3xx");
    CHECK(d.s3xy, "hidden state _state.drift.s3xy");
    CHECK(d.s3yy, "hidden state _state.drift.s3yy");
    CHECK(d.dc3x, "hidden state _state.drift.dc3x");
    CHECK(d.dc3y, "hidden state _state.drift.dc3y");
    if (!dualaxis_valid(s, v->process)) return refuse_covariance(comp, s, k);
    return NULL;
}

/* DualDriftEstimator.hold: n >= 1 samples from k0; the first takes (z_x, z_y) as its
 * measurement if `first`, every other one is predict-only.  The state after each sample but
 * the last is refused when its covariance is not valid and finite
 * (DualDriftEstimator._refuse_covariance); the last is checked by outputs. */
static const char *hold(ModelInstance *comp, DualEstimator *s, int64_t k0, int64_t n,
                        int first)
{
    const ModelVariables *v = &comp->v;
    const ModelHidden *h = &comp->h;
    int64_t i;
    for (i = 0; i < n; i++) {
        if (i > 0 && !dualaxis_valid(s, v->process) && covariance_finite(s, v->process))
            return refuse_covariance(comp, s, k0 + i - 1);
        if (first && i == 0)
            *s = dualaxis_estimator_step(*s, v->z_x, v->z_y, h->ax, h->ay, &h->m);
        else
            *s = dualaxis_estimator_predict(*s, &h->m);
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
    DualEstimator s = comp->h.state;
    if (plan->n > 0) {
        int64_t start = plan->k_first;
        int first = 1;
        if (plan->first_pending) { /* sample k: committed with the (z_x, z_y) set at t */
            s = comp->h.pending;
            start = plan->k_first + 1;
            first = 0;
        }
        if (plan->k_first + plan->n > start) { /* the other instants: inputs held from t */
            const char *bad = hold(comp, &s, start, plan->k_first + plan->n - start, first);
            if (bad) return bad;
        }
    }
    comp->h.state = s;
    return NULL; /* a pending sample at t + h: model_compute, from the inputs set there */
}

static int dual_state_problems(ModelInstance *comp, const char *which, const DualEstimator *s)
{
    char name[64];
    int n = 0;
    n += SLAVE_HIDDEN_REAL(comp, which, s, g.x, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, g.y, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, g.Pxx, 1);
    n += SLAVE_HIDDEN_REAL(comp, which, s, g.Pxy, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, g.Pyy, 1);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.x, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.dx, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.y, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.dy, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P11, 1);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P12, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P22, 1);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P33, 1);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P34, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P44, 1);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P13, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P14, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P23, 0);
    n += SLAVE_HIDDEN_REAL(comp, which, s, h.P24, 0);
    const DualDrift *drifts[2] = {&s->g.drift, &s->h.drift};
    for (int i = 0; i < 2; i++) {
        const DualDrift *d = drifts[i];
        const double values[] = {d->s1xx, d->s1xy, d->s1yy, d->dc2x, d->dc2y, d->s3xx, d->s3xy,
                                 d->s3yy, d->dc3x, d->dc3y};
        static const char *names[] = {"s1xx", "s1xy", "s1yy", "dc2x", "dc2y", "s3xx", "s3xy",
                                      "s3yy", "dc3x", "dc3y"};
        for (size_t j = 0; j < sizeof values / sizeof values[0]; j++) {
            snprintf(name, sizeof name, "%s.%s.drift.%s", which, i ? "h" : "g", names[j]);
            n += slave_hidden_real(comp, name, values[j], 0);
        }
        snprintf(name, sizeof name, "%s.%s.drift.k", which, i ? "h" : "g");
        n += slave_hidden_count(comp, name, d->k);
    }
    if (n == 0 && (comp->v.process == DUALAXIS_GAUSS_MARKOV ||
                   comp->v.process == DUALAXIS_HARMONIC)) {
        /* every field finite: the covariance (DualDriftEstimator.hidden_problems) */
        const int64_t process = comp->v.process;
        double lower[10];
        char msg[MODEL_REFUSAL_MAX];
        const int size = dualaxis_covariance_of(s, process, lower);
        if (covariance_state_problem(size, lower, STATE_COVARIANCE_NAMES[process - 1],
                                     COVARIANCE_LISTING[process - 1], msg, sizeof msg))
            n += slave_problem(comp, msg);
    }
    return n;
}

int model_hidden_problems(ModelInstance *comp, const ModelHidden *fresh)
{
    const ModelHidden *h = &comp->h;
    return slave_hidden_derived(comp, "ax", &h->ax, &fresh->ax, sizeof h->ax) +
           slave_hidden_derived(comp, "ay", &h->ay, &fresh->ay, sizeof h->ay) +
           slave_hidden_derived(comp, "m", &h->m, &fresh->m, sizeof h->m) +
           dual_state_problems(comp, "state", &h->state) +
           dual_state_problems(comp, "pending", &h->pending);
}
