/* Excitation_step: the per-sample logic of fmu_src/Excitation.py, as the MODEL HOOKS of
 * fmu_src/native/model.h (model_check, model_start, model_compute, model_advance), compiled into
 * the Excitation FMU.  This header is its MODEL_LOGIC_HEADER: it defines ModelHidden and must
 * not include model.h (config.h includes this file before model.h defines ModelInstance). */
#ifndef DRIFTFMU_EXCITATION_STEP_H
#define DRIFTFMU_EXCITATION_STEP_H

#include <stdint.h>

/* Excitation.HIDDEN (_x, _y: the excitation after the last sample processed, x0 and 0 before
 * sample 1) and the state after the pending sample (Python's _pending), computed by
 * model_compute from the inputs set at its communication point (has_pending 0 until then). */
typedef struct {
    double x, y;
    int32_t has_pending;
    double x_pending, y_pending;
} ModelHidden;

#endif
