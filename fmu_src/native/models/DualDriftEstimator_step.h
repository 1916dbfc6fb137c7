/* DualDriftEstimator_step: the per-sample logic of fmu_src/DualDriftEstimator.py, as the MODEL
 * HOOKS of fmu_src/native/model.h (model_check, model_start, model_compute, model_advance),
 * compiled into the DualDriftEstimator FMU.  This header is its MODEL_LOGIC_HEADER: it defines
 * ModelHidden and must not include model.h. */
#ifndef DRIFTFMU_DUALDRIFTESTIMATOR_STEP_H
#define DRIFTFMU_DUALDRIFTESTIMATOR_STEP_H

#include <stdint.h>

#include "dualaxis.h"

/* DualDriftEstimator.HIDDEN plus the derived constants (self._axes, self._model). */
typedef struct {
    Axis ax, ay;                  /* dualaxis.axes(parameter_values()) */
    DualModel m;                  /* dualaxis.model(process, ...) */
    DualEstimator state;          /* _state: after the last sample processed (x0, y0, P0, P0y
                                     before the first); both process models, see dualaxis.h */
    DualEstimator pending;        /* after the pending sample (computed by model_compute) */
} ModelHidden;

#endif
