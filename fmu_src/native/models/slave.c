/* slave: see slave.h. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"
#include "parameters.h"
#include "slave.h"

int slave_problem(ModelInstance *comp, const char *message)
{
    model_log_error(comp, "%s", message);
    return 1;
}

static double value_of(const ModelInstance *comp, int i)
{
    const char *base = (const char *)&comp->v + MODEL_VARIABLES[i].offset;
    if (MODEL_VARIABLES[i].type == TYPE_REAL) return *(const double *)base;
    return (double)*(const int *)base;
}

int slave_check_parameters(ModelInstance *comp, const SlaveRange *extra, int n_extra)
{
    char msg[PARAMETERS_MESSAGE_MAX];
    int i, j, n = 0;
    for (i = 0; i < N_VARIABLES; i++) {
        if (MODEL_VARIABLES[i].causality != CAUSALITY_PARAMETER) continue;
        if (parameters_problem(MODEL_VARIABLES[i].name, value_of(comp, i),
                               MODEL_VARIABLES[i].type == TYPE_INTEGER, msg, sizeof msg) == 1)
            n += slave_problem(comp, msg);
    }
    for (i = 0; i < N_VARIABLES; i++) {
        if (MODEL_VARIABLES[i].causality != CAUSALITY_PARAMETER) continue;
        for (j = 0; j < n_extra; j++) {
            double v = value_of(comp, i);
            if (strcmp(extra[j].name, MODEL_VARIABLES[i].name) != 0) continue;
            if (v < (double)extra[j].low || v > (double)extra[j].high) {
                snprintf(msg, sizeof msg, "%s = %.0f is out of range; allowed: %lld <= %s <= %lld",
                         extra[j].name, v, (long long)extra[j].low, extra[j].name,
                         (long long)extra[j].high);
                n += slave_problem(comp, msg);
            }
        }
    }
    return n;
}

int slave_check_nyquist(ModelInstance *comp, double f, double Ts)
{
    return slave_check_nyquist_named(comp, "f", f, Ts);
}

int slave_check_nyquist_named(ModelInstance *comp, const char *name, double f, double Ts)
{
    char msg[PARAMETERS_MESSAGE_MAX], rf[40], rn[40];
    double nyquist;
    if (!(Ts > 0.0)) return 0; /* Ts itself is refused by its range check */
    nyquist = 0.5 / Ts;
    if (!(f >= nyquist)) return 0;
    parameters_repr_float(f, rf, sizeof rf);
    parameters_repr_float(nyquist, rn, sizeof rn);
    snprintf(msg, sizeof msg, "%s = %s Hz is at or above the Nyquist rate 1/(2 Ts) = %s Hz; "
             "allowed: %s < %s Hz", name, rf, rn, name, rn);
    return slave_problem(comp, msg);
}

/* ---- checks of a restored hidden state ---------------------------------------------------- */

int slave_hidden_real(ModelInstance *comp, const char *name, double value, int nonnegative)
{
    char b[32];
    if (!isfinite(value)) {
        model_log_error(comp, "hidden %s = %s is not finite; allowed: a finite number", name,
                        (parameters_repr_float(value, b, sizeof b), b));
        return 1;
    }
    if (nonnegative && !(value >= 0.0)) {
        model_log_error(comp, "hidden %s = %s is a negative variance; allowed: %s >= 0", name,
                        (parameters_repr_float(value, b, sizeof b), b), name);
        return 1;
    }
    return 0;
}

int slave_hidden_real_of(ModelInstance *comp, const char *which, const char *field, double value,
                         int nonnegative)
{
    char name[64];
    snprintf(name, sizeof name, "%s.%s", which, field);
    return slave_hidden_real(comp, name, value, nonnegative);
}

int slave_hidden_flag(ModelInstance *comp, const char *name, int64_t value)
{
    if (value == 0 || value == 1)
        return 0;
    model_log_error(comp, "hidden %s = %lld is not a flag; allowed: 0 or 1", name,
                    (long long)value);
    return 1;
}

int slave_hidden_count(ModelInstance *comp, const char *name, int64_t value)
{
    if (value >= 0)
        return 0;
    model_log_error(comp, "hidden %s = %lld is not a count; allowed: %s >= 0", name,
                    (long long)value, name);
    return 1;
}

int slave_hidden_derived(ModelInstance *comp, const char *name, const void *a, const void *b,
                         size_t n)
{
    if (memcmp(a, b, n) == 0)
        return 0;
    model_log_error(comp, "hidden %s does not follow from the parameters; allowed: the values "
                    "the parameters of the state give", name);
    return 1;
}
