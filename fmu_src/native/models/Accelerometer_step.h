/* Accelerometer_step: the per-sample logic of fmu_src/Accelerometer.py, as the MODEL HOOKS of
 * fmu_src/native/model.h (model_check, model_start, model_compute, model_advance), compiled into
 * the Accelerometer FMU.  This header is its MODEL_LOGIC_HEADER: it defines ModelHidden and
 * must not include model.h. */
#ifndef DRIFTFMU_ACCELEROMETER_STEP_H
#define DRIFTFMU_ACCELEROMETER_STEP_H

#include <stdint.h>

#include "adxl203.h"

/* Accelerometer.HIDDEN plus the derived config; a *_set flag of 0 is Python's None. */
typedef struct {
    Config cfg;                       /* adxl203.config(**parameter_values()) (self._cfg) */
    int64_t lp_set, lp_pending_set;   /* x axis: committed and pending filter state */
    double lp, lp_pending;
    int64_t lpy_set, lpy_pending_set; /* y axis */
    double lpy, lpy_pending;
} ModelHidden;

#endif
