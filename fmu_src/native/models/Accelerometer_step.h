/* Accelerometer_step: the per-sample logic of fmu_src/Accelerometer.py, as the MODEL HOOKS of
 * fmu_src/native/model.h (model_check, model_start, model_compute, model_advance), compiled into
 * the Accelerometer FMU.  This header is its MODEL_LOGIC_HEADER: it defines ModelHidden and
 * must not include model.h. */
#ifndef DRIFTFMU_ACCELEROMETER_STEP_H
#define DRIFTFMU_ACCELEROMETER_STEP_H

#include <stddef.h>
#include <stdint.h>

#include "adxl203.h"
#include "dualaxis.h"
#include "errors.h"

/* The keys of the noise streams under the seed (noise_key: the slow errors' random walk's,
 * Gauss-Markov bias's and flicker components', the measurement noise's of each axis), derived
 * once in model_start: the draws of a sample are noise_normal_keyed, the bits of noise_normal
 * (the Python slave keeps its draws in blocks instead). */
typedef struct {
    uint64_t rw, gm, fl[ERRORS_FLICKER_MAX], v, v_y;
} ErrorKeys;

/* Accelerometer.HIDDEN (_lp, _lpy: the output filters after the last sample processed; _err:
 * the slow errors' state, valid while ecfg.on, else 0.0 everywhere: Python's None), the same
 * after the pending sample (computed by model_compute), and the derived configs; a *_set flag
 * of 0 is Python's None. */
typedef struct {
    /* constants of the parameters (model_start sets them; a step leaves them) */
    Config cfg;                       /* adxl203.config(**parameter_values()) (self._cfg) */
    Axis ax, ay;                      /* dualaxis.axes(parameter_values()) (self._axes) */
    ErrorConfig ecfg;                 /* errors.config(**parameter_values()) (self._ecfg) */
    ErrorKeys keys;                   /* (self._n_rw, _n_gm, _n_fl: the draws' streams) */
    /* what a step changes */
    int64_t lp_set, lpy_set;
    double lp, lpy;
    int64_t lp_pending_set, lpy_pending_set;
    double lp_pending, lpy_pending;
    ErrorState err, err_pending;      /* _err */
    ErrorTilt tilt;                   /* the held tilt's sine (models.errors._TILT) */
} ModelHidden;
/* model.h: the part of ModelHidden a step changes begins here. */
#define MODEL_HIDDEN_CHANGEABLE offsetof(ModelHidden, lp_set)

#endif
