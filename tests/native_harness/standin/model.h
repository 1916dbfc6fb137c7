/* A stand-in for fmu_src/native/model.h (the plumbing's contract) with only what
 * the step-logic units use: the tests of fmu_src/native/models compile against it when the real
 * header is not in the tree (tests/test_native_models.py uses the real one when it is).  Field
 * and type names are those of the real header. */
#ifndef DRIFTFMU_MODEL_H
#define DRIFTFMU_MODEL_H

#include <stddef.h>
#include <stdint.h>

typedef enum { TYPE_REAL = 0, TYPE_INTEGER = 1 } VariableType;
typedef enum { CAUSALITY_PARAMETER = 0, CAUSALITY_INPUT = 1, CAUSALITY_OUTPUT = 2 } Causality;

typedef struct {
    const char *name;
    VariableType type;
    Causality causality;
    size_t offset;
} VariableInfo;

#include "config.h"

typedef struct ModelInstance {
    char *instanceName;
    ModelVariables v;
    ModelHidden h;
    double startTime;
    double time;
    int64_t k;
    int pending;
    int dirty;
    int initialised;
} ModelInstance;

typedef struct {
    int64_t k_first;
    int64_t n;
    int first_pending;
    int end_pending;
    int64_t k_end;
} StepPlan;

int model_check(ModelInstance *comp);
void model_start(ModelInstance *comp);
const char *model_compute(ModelInstance *comp);
const char *model_advance(ModelInstance *comp, const StepPlan *plan);

void model_log_error(ModelInstance *comp, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

#endif
