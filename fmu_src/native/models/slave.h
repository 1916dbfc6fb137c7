/* slave: what the three step-logic units share (the port of the checks and helpers of
 * fmu_src/slave_base.py), over the plumbing's fmu_src/native/model.h.  Compiled into every FMU
 * (slave.c); include after model.h. */
#ifndef DRIFTFMU_SLAVE_H
#define DRIFTFMU_SLAVE_H

#include <stdint.h>

/* The declared range of a parameter that models/parameters.py does not know (its VARIABLES row's
 * min and max, both integers: kind, noise, estimator). */
typedef struct {
    const char *name;
    int64_t low, high;
} SlaveRange;

/* SlaveBase.check_parameters: every parameter of MODEL_VARIABLES (table order) that
 * models.parameters knows, checked with its message, then those in `extra`; each problem is
 * logged with model_log_error.  Returns the number of problems. */
int slave_check_parameters(ModelInstance *comp, const SlaveRange *extra, int n_extra);

/* Log one problem (model_log_error(comp, "%s", message)) and return 1. */
int slave_problem(ModelInstance *comp, const char *message);

/* The Nyquist check of Excitation and DriftEstimator: 1 (logged) if f >= 0.5 / Ts (0 where Ts
 * is not positive: its own range check refuses it). */
int slave_check_nyquist(ModelInstance *comp, double f, double Ts);
/* The same check of the frequency parameter `name` (SlaveBase.nyquist_problems(name)). */
int slave_check_nyquist_named(ModelInstance *comp, const char *name, double f, double Ts);

/* Checks of a restored hidden state (model_hidden_problems), each logging one problem named
 * "hidden <name> = <value> ..." and returning 1 (0 when the value is good): a finite number
 * (>= 0 with nonnegative: a variance), a flag 0 or 1, a count >= 0, and a constant derived
 * from the parameters equal to the one model_start computes (n bytes at a and b). */
int slave_hidden_real(ModelInstance *comp, const char *name, double value, int nonnegative);
int slave_hidden_flag(ModelInstance *comp, const char *name, int64_t value);
int slave_hidden_count(ModelInstance *comp, const char *name, int64_t value);
int slave_hidden_derived(ModelInstance *comp, const char *name, const void *a, const void *b,
                         size_t n);

/* slave_hidden_real of a field of a restored struct, named "<which>.<field>" (e.g.
 * "state.drift.s1", at most 63 characters): the estimators' model_hidden_problems check their
 * filter states field by field with it, `SLAVE_HIDDEN_REAL(comp, "state", s, drift.s1, 0)`. */
int slave_hidden_real_of(ModelInstance *comp, const char *which, const char *field, double value,
                         int nonnegative);
#define SLAVE_HIDDEN_REAL(comp, which, s, field, nonnegative) \
    slave_hidden_real_of((comp), (which), #field, (s)->field, (nonnegative))

#endif
