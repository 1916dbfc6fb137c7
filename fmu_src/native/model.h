/*
 * model.h - the contract between the FMI plumbing and a model (the way Reference-FMUs separates
 * model.c from fmi2Functions.c / fmi3Functions.c).
 *
 * The plumbing (cosimulation.c, fmi2Functions.c, fmi3Functions.c) is written once and shared by
 * the three models.  Each FMU is compiled from the plumbing of one FMI version, the model's step
 * logic and the models/ ports, with -I pointing at the FMU's generated config.h:
 *
 *   config.h   generated at build time by fmu_src/native_build.py from the slave's VARIABLES
 *              table: MODEL_NAME, INSTANTIATION_TOKEN, MODEL_VERSION, the struct ModelVariables
 *              (one field per variable, in VARIABLES order, named like the variable, double for
 *              Real and int for Integer), the value references vr_<name> (= table index, as in
 *              the Python FMU), the table MODEL_VARIABLES (name, type, causality, offset) and
 *              MODEL_START_VALUES; it includes MODEL_LOGIC_HEADER, which defines ModelHidden.
 *
 * The model provides (see the MODEL HOOKS below): model_check, model_start, model_compute and
 * model_advance, and the plain-data struct ModelHidden (no pointers: FMU states copy it with
 * memcpy and serialise its bytes).
 *
 * Timing (slave_base.STEP_RULE): sample k = 1, 2, ... sits at t_k = startTime + (k - 1) Ts.  The FMU
 * keeps its own time (startTime plus the sum of the accepted steps).  After initialisation it
 * is at sample 1, pending: its input-dependent outputs are computed from the inputs set at this
 * communication point.
 */
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
    size_t offset;          /* offsetof(ModelVariables, <name>) */
} VariableInfo;

#include "config.h"

/* FMI state machine, the FMI 3 names (FMI 2 maps onto them). */
typedef enum {
    STATE_INSTANTIATED = 1 << 0,
    STATE_INITIALIZATION = 1 << 1,
    STATE_STEP = 1 << 2,
    STATE_TERMINATED = 1 << 3,
    STATE_ERROR = 1 << 4,
    STATE_FATAL = 1 << 5
} ModelState;

/* Status codes shared by both FMI versions (numerically fmi2Status == fmi3Status). */
typedef enum { STATUS_OK = 0, STATUS_WARNING = 1, STATUS_DISCARD = 2, STATUS_ERROR = 3,
               STATUS_FATAL = 4 } Status;

struct ModelInstance;
/* Writes one finished log line to the host (FMI-version specific, set at instantiation). */
typedef void (*HostLogger)(struct ModelInstance *comp, Status status, const char *category,
                           const char *message);

/* The longest message a model writes into ModelInstance.refusal, NUL included. */
#define MODEL_REFUSAL_MAX 1024

/* The largest number of sample instants one doStep may process (slave_base.STEP_RULE). */
#define MAX_SAMPLES_PER_STEP 1000000LL
/* A sample instant is "at" a time within this fraction of a sample period. */
#define SAMPLE_TOLERANCE 1e-6

typedef struct ModelInstance {
    char *instanceName;
    ModelVariables v;           /* every variable, in VARIABLES order */
    ModelHidden h;              /* the model's hidden state */
    double startTime;
    double stopTime;            /* the defined stop time, or +inf (none defined): a step that
                                   would end after it is refused */
    double time;                /* startTime + the sum of the accepted step sizes */
    double elapsed, elapsed_c;  /* time - startTime as Neumaier's compensated sum, as the
                                   Python FMUs keep it (position = (elapsed + elapsed_c)/Ts) */
    int64_t k;                  /* the next sample to process (the pending one when pending) */
    int pending;                /* the current communication point is sample k's instant */
    int dirty;                  /* inputs set since the feedthrough outputs were computed */
    int initialised;            /* the parameters passed the checks at exit of initialisation */
    ModelState state;
    int loggingOn;
    HostLogger hostLog;
    void *hostData[4];          /* the host's callbacks and environment (FMI-version specific) */
    const char *logContext;     /* put before every error message while set (or NULL) */
    char refusal[MODEL_REFUSAL_MAX]; /* why model_compute or model_advance refused a result that
                                   is finite (model_refused), as the Python FMU words it */
} ModelInstance;

/* One doStep, planned by the plumbing from the FMU's time, start time and Ts. */
typedef struct {
    int64_t k_first;            /* first sample instant in [t, t + h) (valid when n > 0) */
    int64_t n;                  /* number of sample instants in [t, t + h) */
    int first_pending;          /* k_first is the pending sample of t: commit it with the inputs
                                   set at t (its outputs were computed by model_compute) */
    int end_pending;            /* t + h is the instant of sample k_end, which becomes pending */
    int64_t k_end;              /* the sample of t + h when end_pending */
} StepPlan;

/* ---- MODEL HOOKS (one set per model, provided by fmu_src/native/models/) ------------------ */

/* model_compute and model_advance change the outputs of comp->v and comp->h, nothing else: the
 * plumbing saves exactly those before it calls them, and puts them back when one fails.  A
 * model whose ModelHidden starts with constants that only model_start sets (derived from the
 * parameters) may define MODEL_HIDDEN_CHANGEABLE in its logic header, the offset where the
 * part the hooks change begins: the plumbing then saves that part only (default 0: all). */

/* Check the parameters at the end of initialisation: log every problem with model_log_error
 * (the same words as the Python FMU) and return their number (0: all good). */
int model_check(ModelInstance *comp);

/* Set the hidden state (and the outputs that depend on no input) for sample 1, after the
 * parameters are checked. */
void model_start(ModelInstance *comp);

/* Compute the input-dependent outputs of the pending sample comp->k from the inputs set now and
 * the committed hidden state (feedthrough); the result to commit stays in comp->h.  Returns NULL,
 * the name of an output or hidden value that came out non-finite, or comp->refusal after
 * writing there the whole message refusing a finite result (a filter's covariance that is not
 * positive semi-definite, models/covariance.py); the plumbing then restores the state as it
 * was before the call and returns an error naming it. */
const char *model_compute(ModelInstance *comp);

/* Process the sample instants of one step (slave_base.STEP_RULE): commit plan->k_first if
 * plan->first_pending, process the other instants with the inputs held from t (zero-order
 * hold), and, if plan->end_pending, make plan->k_end pending (outputs that depend on no input
 * computed; the others are computed by model_compute from the inputs set at t + h).  Otherwise
 * the outputs hold those of the last sample processed.  Returns NULL, the name of a value
 * that came out non-finite, or comp->refusal (as model_compute; the plumbing restores the state
 * from before the call). */
const char *model_advance(ModelInstance *comp, const StepPlan *plan);

/* Check the hidden state of an FMU state being restored (comp holds the state's variables,
 * sample index, pending flag and hidden state; its parameters passed model_check): every value
 * finite, in range (covariances P >= 0, flags 0 or 1, counts >= 0) and consistent (the
 * constants derived from the parameters equal `fresh`'s, which model_start computed from
 * them; a pending result matches the outputs).  Log each problem with model_log_error, naming
 * the field, and return their number (0: the state may be restored). */
int model_hidden_problems(ModelInstance *comp, const ModelHidden *fresh);

/* ---- services of the plumbing (cosimulation.c) -------------------------------------------- */

/* Log a message with status error (always forwarded to the host), prefixed with the instance
 * name as the Python FMUs do: "<instance>: <message>". */
void model_log_error(ModelInstance *comp, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* Log an informational message (forwarded only with debug logging on). */
void model_log_info(ModelInstance *comp, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* Python's repr() of a double (shortest string that reads back to the same bits: "0.001",
 * "1e-09", "nan", "inf", "-2.0"), for messages worded like the Python FMUs'.  buf >= 32. */
const char *repr_double(double value, char *buf);

#endif
