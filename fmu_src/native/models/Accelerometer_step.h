/* Accelerometer_step: the per-sample logic of fmu_src/Accelerometer.py, as the MODEL HOOKS of
 * fmu_src/native/model.h (model_check, model_start, model_compute, model_advance), compiled into
 * the Accelerometer FMU.  This header is its MODEL_LOGIC_HEADER: it defines ModelHidden and
 * must not include model.h. */
#ifndef DRIFTFMU_ACCELEROMETER_STEP_H
#define DRIFTFMU_ACCELEROMETER_STEP_H

#include <stdint.h>

#include "adxl203.h"
#include "dualaxis.h"
#include "errors.h"

/* Accelerometer.HIDDEN (_lp, _lpy: the output filters after the last sample processed; _err:
 * the slow errors' state, valid while ecfg.on, else 0.0 everywhere: Python's None), the same
 * after the pending sample (computed by model_compute), and the derived configs; a *_set flag
 * of 0 is Python's None. */
typedef struct {
    Config cfg;                       /* adxl203.config(**parameter_values()) (self._cfg) */
    Axis ax, ay;                      /* dualaxis.axes(parameter_values()) (self._axes) */
    int64_t lp_set, lpy_set;
    double lp, lpy;
    int64_t lp_pending_set, lpy_pending_set;
    double lp_pending, lpy_pending;
    ErrorConfig ecfg;                 /* errors.config(**parameter_values()) (self._ecfg) */
    ErrorState err, err_pending;      /* _err */
} ModelHidden;

#endif
