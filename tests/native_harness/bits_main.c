/* The same computations on every platform, printed as hex bits (tests/test_native_models.py
 * compiles this with gcc and with x86_64-w64-mingw32-gcc, runs the second under wine and
 * compares the outputs line for line).  One program per model (the hooks have generic names):
 * the models/ math over a grid of inputs, then a run of the model's step logic with inputs and
 * steps drawn from SplitMix64 (whole-sample and fractional steps), then its parameter-check
 * messages for a bad parameter set. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"
#include "noise.h"
#include "ops.h"
#include "parameters.h"

ModelInstance *h_new(void);
int h_index(const char *name);
void h_set(ModelInstance *comp, int i, double value);
double h_get(const ModelInstance *comp, int i);
const char *h_log(void);

static void put(const char *what, double v)
{
    unsigned long long b;
    memcpy(&b, &v, sizeof b);
    printf("%s %016llx\n", what, b);
}

typedef struct {
    const char *name;
    double value;
} Start;

/* One parameter set per model (names a model does not have are skipped). */
static const Start RUN[] = {
    {"kind", 2}, {"X", 1.02}, {"f", 200.0}, {"phi", 1.3}, {"Xy", 0.51}, {"phiy", -0.7},
    {"seed", 11}, {"a0", 2.5}, {"a1", 1.0}, {"a2", 0.01}, {"a3", 0.002}, {"R", 1.2e-5},
    {"cross", 0.015}, {"fc", 1063.829787}, {"Vs", 5.0}, {"bits", 12}, {"density", 110e-6},
    {"axes", 2}, {"noise", 1}, {"process", 2}, {"Qh", 1e-8}, {"P0", 1.0}, {"Ts", 1e-4},
    {"A", 0.3}, {"Q", 0.02}, {"estimator", 1},
    {"bx", 0.02}, {"by", -0.015}, {"a2y", 0.008}, {"a0y", 0.3}, {"Ry", 2e-5}, {"Qy", 0.01},
    {"rho", 0.4}, {"P0y", 0.5},
    /* the Accelerometer's slow errors (models/errors.py), every one on */
    {"bias_on", 0.05}, {"random_walk", 0.02}, {"bias_gm", 0.03}, {"tau_gm", 0.02},
    {"flicker", 0.01}, {"tau_min", 0.003}, {"tau_max", 3.0}, {"d_inf", 0.04}, {"E_tau", 0.5},
    {"T0", 0.5}, {"kT_bias", 0.002}, {"kT_scale", -0.003}, {"range", 1.8}};
static const Start BAD[] = {{"Ts", 1e-12}, {"process", 2}, {"R", -1.0}, {"f", 7e3}, {"Vs", 2.0}, {"fc", 3e3},
                            {"seed", -3}, {"A", 1.0}, {"kind", 3}, {"estimator", 0},
                            {"noise", 2}, {"a1", 0.0}, {"Qh", -2.5e-9}, {"Ry", 0.0},
                            {"rho", 1.5}, {"flicker", 0.01}, {"tau_min", 4.0},
                            {"tau_max", 2.0}, {"bias_gm", -0.5}};

static void set_all(ModelInstance *comp, const Start *s, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        int j = h_index(s[i].name);
        if (j >= 0) h_set(comp, j, s[i].value);
    }
}

int main(void)
{
    int i;
    uint64_t r = 12345;
    ModelInstance *comp;
    double Ts, elapsed = 0.0;
    int64_t k = 1;
    int at = 1;
    /* the models/ math */
    for (i = 0; i < 300; i++) {
        double u = noise_uniform(7, 1, (uint64_t)i + 1);
        put("log", ops_log(ldexp(u, i * 7 - 1074 < -1074 ? -1074 : i * 7 - 1074)));
        put("exp", ops_exp(-745.0 + 1454.0 * u));
        put("sin2pi", ops_sin2pi((u - 0.5) * ldexp(1.0, i % 60)));
        put("sin", ops_sin((u - 0.5) * ldexp(1.0, i % 40)));
        put("normal", noise_normal((uint64_t)i, 2, UINT64_C(0xFFFFFFFFFFFFFFFF) - (uint64_t)i));
    }
    /* Python's repr of doubles (the messages), from random bit patterns and short decimals */
    for (i = 0; i < 2000; i++) {
        char buf[40];
        double v;
        r = noise_mix(r + 1);
        memcpy(&v, &r, sizeof v);
        if (i % 2) v = (double)(int64_t)(r >> 40) / ldexp(1.0, (int)(r % 30)) * 1e-3;
        parameters_repr_float(v, buf, sizeof buf);
        printf("repr %s\n", buf);
    }
    /* the step logic */
    comp = h_new();
    set_all(comp, RUN, sizeof RUN / sizeof RUN[0]);
    if (model_check(comp)) {
        printf("check failed: %s\n", h_log());
        return 1;
    }
    model_start(comp);
    Ts = comp->v.Ts;
    for (i = 0; i < 3000; i++) {
        StepPlan plan;
        double position, h;
        int64_t last, m;
        int v, first;
        for (v = 0; v < N_VARIABLES; v++) { /* inputs */
            if (MODEL_VARIABLES[v].causality == CAUSALITY_INPUT) {
                r = noise_mix(r + 1);
                h_set(comp, v, 3.0 * ((double)(r >> 11) * 0x1p-53) - 1.0);
            }
        }
        comp->k = k;
        if (MODEL_HAS_FEEDTHROUGH && at && model_compute(comp)) return 2;
        for (v = 0; v < N_VARIABLES; v++)
            if (MODEL_VARIABLES[v].causality == CAUSALITY_OUTPUT)
                put(MODEL_VARIABLES[v].name, h_get(comp, v));
        r = noise_mix(r + 1);
        h = Ts * (i % 3 == 2 ? 0.1 + 3.0 * ((double)(r >> 11) * 0x1p-53) : (double)(1 + r % 3));
        elapsed += h;
        position = elapsed / Ts;
        last = (int64_t)ceil(position - 1e-6);
        m = last + 1 - k > 0 ? last + 1 - k : 0;
        first = m > 0 && at;
        at = (double)last <= position + 1e-6;
        plan.k_first = k;
        plan.n = m;
        plan.first_pending = first;
        plan.end_pending = at;
        plan.k_end = k + m;
        if (model_advance(comp, &plan)) return 3;
        k += m;
    }
    /* the check messages */
    comp = h_new();
    set_all(comp, BAD, sizeof BAD / sizeof BAD[0]);
    printf("problems %d\n%s", model_check(comp), h_log());
    return 0;
}
