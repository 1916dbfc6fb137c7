/*
 * cosimulation.h - the FMI-version-independent half of the plumbing (cosimulation.c): the
 * lifecycle, the state machine, get/set by value reference, the step rule, FMU states.
 * fmi2Functions.c and fmi3Functions.c are thin adapters onto these calls.
 */
#ifndef DRIFTFMU_COSIMULATION_H
#define DRIFTFMU_COSIMULATION_H

#include "model.h"

/* A new instance in state Instantiated, or NULL (after logging why through `log`). */
ModelInstance *cs_instantiate(const char *instanceName, const char *token, int loggingOn,
                              HostLogger log, void *const hostData[4], const char *function);
void cs_free(ModelInstance *comp);

Status cs_set_debug_logging(ModelInstance *comp, int loggingOn);
/* The experiment: the start time, and the stop time when stopTimeDefined (finite, >= the start
 * time; a step that would end after it is refused, FMI 2.0 fmi2SetupExperiment and FMI 3.0
 * fmi3EnterInitializationMode). */
Status cs_setup(ModelInstance *comp, const char *function, double startTime,
                int stopTimeDefined, double stopTime);
Status cs_enter_initialization(ModelInstance *comp, const char *function);
Status cs_exit_initialization(ModelInstance *comp, const char *function);
Status cs_terminate(ModelInstance *comp, const char *function);
Status cs_reset(ModelInstance *comp, const char *function);

/* The most value references one get or set may name (the count rule, docs/native-hardening.md):
 * a larger count cannot be a list of this FMU's variables, and is refused before any element of
 * the arrays is read or written (a count such as SIZE_MAX or 2^31 with a short array would read
 * past it).  A count within the bound is taken at its word: only the host knows its arrays. */
#define MAX_VALUES_PER_CALL 65536u

/* Get/set `n` variables of `type` (TYPE_REAL: `reals`, TYPE_INTEGER: `ints`). A rejected call
 * changes nothing. */
Status cs_get(ModelInstance *comp, const char *function, VariableType type,
              const unsigned int vr[], size_t n, double reals[], int ints[]);
Status cs_set(ModelInstance *comp, const char *function, VariableType type,
              const unsigned int vr[], size_t n, const double reals[], const int ints[]);
/* A get/set of a type the model has no variable of (Boolean, String, ...). */
Status cs_no_such_type(ModelInstance *comp, const char *function, const char *type,
                       const unsigned int vr[], size_t n);

Status cs_do_step(ModelInstance *comp, const char *function, double currentTime, double h);

/* FMU states: opaque copies of the variables, hidden state, time, sample index and mode, listed
 * while live: a pointer that is not a live state is refused without being read; a restored
 * state is checked field by field (cosimulation.c, docs/native-hardening.md). */
Status cs_get_state(ModelInstance *comp, const char *function, void **state);
Status cs_set_state(ModelInstance *comp, const char *function, const void *state);
Status cs_free_state(ModelInstance *comp, const char *function, void **state);
Status cs_serialized_size(ModelInstance *comp, const char *function, const void *state,
                          size_t *size);
Status cs_serialize(ModelInstance *comp, const char *function, const void *state,
                    unsigned char *bytes, size_t size);
Status cs_deserialize(ModelInstance *comp, const char *function, const unsigned char *bytes,
                      size_t size, void **state);

/* Logs "<function> is not allowed in <mode>; allowed in: ..." and returns 0 (the slow path of
 * cs_allowed, out of line). */
int cs_refuse_mode(ModelInstance *comp, const char *function, int allowed);
/* "<function> is not allowed in <mode>; allowed in: ..." when the mode is not in `allowed` (a
 * mask of ModelState); returns nonzero when the call may go on.  Inline: every call of the
 * per-step path asks it, and the answer is one AND. */
static inline int cs_allowed(ModelInstance *comp, const char *function, int allowed)
{
    return (comp->state & allowed) ? 1 : cs_refuse_mode(comp, function, allowed);
}
/* 1 when a call's count of value references is within MAX_VALUES_PER_CALL; else 0, logged
 * (nothing of the call's arrays is read). */
int cs_count_ok(ModelInstance *comp, const char *function, size_t n);
/* A function the FMU does not support (Model Exchange, clocks, ...). */
Status cs_unsupported(ModelInstance *comp, const char *function);
void cs_log(ModelInstance *comp, Status status, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

#endif
