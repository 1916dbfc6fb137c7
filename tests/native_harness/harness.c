/* Test harness of one model's step logic (tests/test_native_models.py): what the plumbing
 * would do, reduced to calls the test drives through ctypes (or the wine test program).  The
 * log goes into a buffer, one message per line. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"

#if defined(_WIN32)
#define EXPORT __declspec(dllexport)
#else
#define EXPORT __attribute__((visibility("default")))
#endif

static char LOG[1 << 16];
static size_t LOG_LEN;

void model_log_error(ModelInstance *comp, const char *format, ...)
{
    va_list ap;
    int n;
    (void)comp;
    if (LOG_LEN >= sizeof LOG - 2) return;
    va_start(ap, format);
    n = vsnprintf(LOG + LOG_LEN, sizeof LOG - LOG_LEN - 1, format, ap);
    va_end(ap);
    if (n < 0) return;
    LOG_LEN += (size_t)n < sizeof LOG - LOG_LEN - 1 ? (size_t)n : sizeof LOG - LOG_LEN - 2;
    LOG[LOG_LEN++] = '\n';
    LOG[LOG_LEN] = '\0';
}

EXPORT const char *h_log(void) { return LOG; }

EXPORT void h_log_clear(void)
{
    LOG_LEN = 0;
    LOG[0] = '\0';
}

EXPORT ModelInstance *h_new(void)
{
    static const ModelVariables start = MODEL_START_VALUES;
    ModelInstance *comp = (ModelInstance *)calloc(1, sizeof(ModelInstance));
    comp->v = start;
    comp->k = 1;
    comp->pending = 1;
    comp->dirty = 1;
    return comp;
}

EXPORT void h_free(ModelInstance *comp) { free(comp); }

EXPORT size_t h_size(void) { return sizeof(ModelInstance); }

EXPORT void h_copy(ModelInstance *to, const ModelInstance *from) { memcpy(to, from, sizeof *to); }

EXPORT int h_index(const char *name)
{
    int i;
    for (i = 0; i < N_VARIABLES; i++)
        if (strcmp(MODEL_VARIABLES[i].name, name) == 0) return i;
    return -1;
}

EXPORT void h_set(ModelInstance *comp, int i, double value)
{
    char *p = (char *)&comp->v + MODEL_VARIABLES[i].offset;
    if (MODEL_VARIABLES[i].type == TYPE_REAL)
        *(double *)p = value;
    else
        *(int *)p = (int)value;
    comp->dirty = 1;
}

EXPORT double h_get(const ModelInstance *comp, int i)
{
    const char *p = (const char *)&comp->v + MODEL_VARIABLES[i].offset;
    if (MODEL_VARIABLES[i].type == TYPE_REAL) return *(const double *)p;
    return (double)*(const int *)p;
}

EXPORT void h_set_k(ModelInstance *comp, long long k) { comp->k = k; }

EXPORT int h_check(ModelInstance *comp) { return model_check(comp); }

EXPORT void h_start(ModelInstance *comp) { model_start(comp); }

EXPORT const char *h_compute(ModelInstance *comp) { return model_compute(comp); }

EXPORT const char *h_advance(ModelInstance *comp, long long k_first, long long n,
                             int first_pending, int end_pending, long long k_end)
{
    StepPlan plan;
    plan.k_first = k_first;
    plan.n = n;
    plan.first_pending = first_pending;
    plan.end_pending = end_pending;
    plan.k_end = k_end;
    return model_advance(comp, &plan);
}
