/* Excitation_step: the per-sample logic of fmu_src/Excitation.py, as the MODEL HOOKS of
 * fmu_src/native/model.h (model_check, model_start, model_compute, model_advance), compiled into
 * the Excitation FMU.  This header is its MODEL_LOGIC_HEADER: it defines ModelHidden and must
 * not include model.h (config.h includes this file before model.h defines ModelInstance). */
#ifndef DRIFTFMU_EXCITATION_STEP_H
#define DRIFTFMU_EXCITATION_STEP_H

#include <stdint.h>

/* No hidden state: x and y are the state (the Gauss-Markov recursion runs on the output x). */
typedef struct {
    int32_t unused;
} ModelHidden;

#endif
