/* DriftEstimator_step: the per-sample logic of fmu_src/DriftEstimator.py, as the MODEL HOOKS of
 * fmu_src/native/model.h (model_check, model_start, model_compute, model_advance), compiled into
 * the DriftEstimator FMU.  This header is its MODEL_LOGIC_HEADER: it defines ModelHidden and
 * must not include model.h. */
#ifndef DRIFTFMU_DRIFTESTIMATOR_STEP_H
#define DRIFTFMU_DRIFTESTIMATOR_STEP_H

#include <stdint.h>

#include "bias.h"
#include "harmonic.h"

/* DriftEstimator.HIDDEN plus the derived process model (self._model's C, S and the bias
 * filter's F_b). */
typedef struct {
    double C, S;                  /* harmonic.rotation(f, Ts) */
    HarmonicState state;          /* _state: after the last sample processed (x0, P0 before
                                     the first); both process models, see harmonic.h */
    HarmonicState pending;        /* after the pending sample (computed by model_compute) */
    double Fb;                    /* bias.factor(tau_b, Ts) */
    Bias bias;                    /* _bias: the bias part with bias = 1 (b0, Pb0 before the
                                     first sample); all 0 with bias = 0 (Python's None) */
    Bias bias_pending;            /* after the pending sample */
} ModelHidden;

#endif
