/*
 * cosimulation.c - lifecycle, state machine, variable access, the step rule and FMU states,
 * shared by the FMI 2.0 and FMI 3.0 adapters and by the three models.
 *
 * Behaviour mirrors fmu_src/slave_base.py (the Python FMUs): errors are logged with status
 * error, naming what was wrong and what is allowed, and a rejected call changes nothing; error
 * lines reach the host's logger even with debug logging off.
 */
#define __USE_MINGW_ANSI_STDIO 1
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cosimulation.h"
#include "state_handles.h"

#define MESSAGE_SIZE 1024

/* The per-step path (cs_set, cs_get, cs_do_step) keeps its checks inline and cheap; what it
 * says when a check fails is written out of line (NOINLINE), so that the common case carries no
 * message buffers and no formatting.  ALL_VARIABLES unrolls a loop over the constant table
 * MODEL_VARIABLES completely: the compiler then folds each row's type and causality, and a loop
 * "for every real output" becomes one statement per real output. */
#if defined(__GNUC__)
#define NOINLINE __attribute__((noinline))
#define LIKELY(x) __builtin_expect(!!(x), 1)
#define ALL_VARIABLES _Pragma("GCC unroll 4096")
#else
#define NOINLINE
#define LIKELY(x) (x)
#define ALL_VARIABLES
#endif

static const char *CATEGORY[] = {"logStatusOK", "logStatusWarning", "logStatusDiscard",
                                 "logStatusError", "logStatusFatal"};

/* ---- logging -------------------------------------------------------------------------------- */

static void vlog(ModelInstance *comp, Status status, const char *format, va_list args)
{
    if (!comp || !comp->hostLog)
        return;
    if (status < STATUS_WARNING && !comp->loggingOn)
        return;
    char message[MESSAGE_SIZE];
    int used = snprintf(message, sizeof message, "%s: %s",
                        comp->instanceName ? comp->instanceName : "",
                        status >= STATUS_WARNING && comp->logContext ? comp->logContext : "");
    if (used < 0 || (size_t)used >= sizeof message)
        used = 0;
    vsnprintf(message + used, sizeof message - (size_t)used, format, args);
    comp->hostLog(comp, status, CATEGORY[status], message);
}

void cs_log(ModelInstance *comp, Status status, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vlog(comp, status, format, args);
    va_end(args);
}

void model_log_error(ModelInstance *comp, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vlog(comp, STATUS_ERROR, format, args);
    va_end(args);
}

void model_log_info(ModelInstance *comp, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vlog(comp, STATUS_OK, format, args);
    va_end(args);
}

const char *repr_double(double value, char *buf)
{
    if (isnan(value)) {
        strcpy(buf, "nan");
        return buf;
    }
    if (isinf(value)) {
        strcpy(buf, value > 0 ? "inf" : "-inf");
        return buf;
    }
    if (value == 0.0) {
        strcpy(buf, signbit(value) ? "-0.0" : "0.0");
        return buf;
    }
    /* shortest "%.{p-1}e" that reads back to the same double */
    char sci[40];
    int p;
    for (p = 1; p <= 17; p++) {
        snprintf(sci, sizeof sci, "%.*e", p - 1, value);
        if (strtod(sci, NULL) == value)
            break;
    }
    /* split into sign, digits and decimal exponent */
    char digits[24];
    int nd = 0, neg = 0;
    const char *s = sci;
    if (*s == '-') {
        neg = 1;
        s++;
    }
    for (; *s && *s != 'e'; s++)
        if (*s >= '0' && *s <= '9')
            digits[nd++] = *s;
    digits[nd] = 0;
    int e = atoi(s + 1);
    while (nd > 1 && digits[nd - 1] == '0')
        digits[--nd] = 0;
    char *o = buf;
    if (neg)
        *o++ = '-';
    if (e >= -4 && e < 16) {   /* Python's repr: fixed notation */
        if (e < 0) {
            *o++ = '0';
            *o++ = '.';
            for (int i = 0; i < -e - 1; i++)
                *o++ = '0';
            for (int i = 0; i < nd; i++)
                *o++ = digits[i];
        } else {
            for (int i = 0; i <= e; i++)
                *o++ = i < nd ? digits[i] : '0';
            *o++ = '.';
            if (nd > e + 1)
                for (int i = e + 1; i < nd; i++)
                    *o++ = digits[i];
            else
                *o++ = '0';
        }
        *o = 0;
    } else {
        *o++ = digits[0];
        if (nd > 1) {
            *o++ = '.';
            for (int i = 1; i < nd; i++)
                *o++ = digits[i];
        }
        sprintf(o, "e%c%02d", e < 0 ? '-' : '+', e < 0 ? -e : e);
    }
    return buf;
}

/* ---- the state machine ------------------------------------------------------------------ */

static const char *mode_name(ModelState state)
{
    switch (state) {
    case STATE_INSTANTIATED: return "the instantiated mode";
    case STATE_INITIALIZATION: return "initialisation mode";
    case STATE_STEP: return "step mode";
    case STATE_TERMINATED: return "the terminated mode";
    case STATE_ERROR: return "the error mode";
    default: return "the fatal mode";
    }
}

int cs_refuse_mode(ModelInstance *comp, const char *function, int allowed)
{
    char modes[256] = "";
    const ModelState all[] = {STATE_INSTANTIATED, STATE_INITIALIZATION, STATE_STEP,
                              STATE_TERMINATED};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) {
        if (allowed & all[i]) {
            if (modes[0])
                strcat(modes, ", ");
            strcat(modes, mode_name(all[i]));
        }
    }
    cs_log(comp, STATUS_ERROR, "%s is not allowed in %s; allowed in: %s", function,
           mode_name(comp->state), modes);
    return 0;
}

Status cs_unsupported(ModelInstance *comp, const char *function)
{
    cs_log(comp, STATUS_ERROR, "%s is not supported: this is a co-simulation FMU without "
           "events, clocks or derivatives", function);
    return STATUS_ERROR;
}

/* ---- lifecycle -------------------------------------------------------------------------- */

static const ModelVariables START = MODEL_START_VALUES;

static void to_start(ModelInstance *comp)
{
    comp->v = START;
    memset(&comp->h, 0, sizeof comp->h);
    comp->startTime = 0.0;
    comp->stopTime = INFINITY;
    comp->time = 0.0;
    comp->elapsed = comp->elapsed_c = 0.0;
    comp->logContext = NULL;
    comp->k = 1;
    comp->pending = 1;
    comp->dirty = 1;
    comp->initialised = 0;
    comp->state = STATE_INSTANTIATED;
}

ModelInstance *cs_instantiate(const char *instanceName, const char *token, int loggingOn,
                              HostLogger log, void *const hostData[4], const char *function)
{
    ModelInstance probe;   /* logs the reason a NULL comes back */
    memset(&probe, 0, sizeof probe);
    probe.instanceName = (char *)(instanceName ? instanceName : "");
    probe.hostLog = log;
    for (int i = 0; i < 4; i++)
        probe.hostData[i] = hostData[i];
    if (!instanceName) {
        cs_log(&probe, STATUS_ERROR, "%s: instanceName is NULL; allowed: a string", function);
        return NULL;
    }
    if (!token || strcmp(token, INSTANTIATION_TOKEN) != 0) {
        cs_log(&probe, STATUS_ERROR, "%s: %s %s does not match %s of this FMU (%s %s); "
               "the model description and the binary are from different builds", function,
               MODEL_TOKEN_NAME, token ? token : "NULL", MODEL_TOKEN_NAME, MODEL_NAME,
               INSTANTIATION_TOKEN);
        return NULL;
    }
    ModelInstance *comp = calloc(1, sizeof *comp);
    char *name = comp ? malloc(strlen(instanceName) + 1) : NULL;
    if (!name) {
        free(comp);
        cs_log(&probe, STATUS_ERROR, "%s: out of memory", function);
        return NULL;
    }
    strcpy(name, instanceName);
    *comp = probe;
    comp->instanceName = name;
    comp->loggingOn = loggingOn;
    to_start(comp);
    model_log_info(comp, "%s: instantiated %s %s", function, MODEL_NAME, MODEL_VERSION);
    return comp;
}

static void free_states_of(const ModelInstance *comp);

void cs_free(ModelInstance *comp)
{
    if (!comp)
        return;
    free_states_of(comp);   /* every state the instance got or deserialised dies with it */
    free(comp->instanceName);
    free(comp);
}

Status cs_set_debug_logging(ModelInstance *comp, int loggingOn)
{
    comp->loggingOn = loggingOn;
    return STATUS_OK;
}

Status cs_setup(ModelInstance *comp, const char *function, double startTime,
                int stopTimeDefined, double stopTime)
{
    if (!cs_allowed(comp, function, STATE_INSTANTIATED))
        return STATUS_ERROR;
    char b[32], b2[32];
    if (!isfinite(startTime)) {
        cs_log(comp, STATUS_ERROR, "%s: start time %s is not finite; allowed: a finite time",
               function, repr_double(startTime, b));
        return STATUS_ERROR;
    }
    if (stopTimeDefined && !(isfinite(stopTime) && stopTime >= startTime)) {
        cs_log(comp, STATUS_ERROR, "%s: stopTime = %s s with startTime = %s s; allowed: a "
               "finite stop time >= startTime, or stopTimeDefined = false (nothing was "
               "changed)", function, repr_double(stopTime, b), repr_double(startTime, b2));
        return STATUS_ERROR;
    }
    comp->startTime = startTime;
    comp->stopTime = stopTimeDefined ? stopTime : INFINITY;
    comp->time = startTime;
    comp->dirty = 1;
    return STATUS_OK;
}

Status cs_enter_initialization(ModelInstance *comp, const char *function)
{
    if (!cs_allowed(comp, function, STATE_INSTANTIATED))
        return STATUS_ERROR;
    comp->state = STATE_INITIALIZATION;
    comp->dirty = 1;
    return STATUS_OK;
}

Status cs_exit_initialization(ModelInstance *comp, const char *function)
{
    if (!cs_allowed(comp, function, STATE_INITIALIZATION))
        return STATUS_ERROR;
    /* every check first: a refused exit leaves the instance in Initialization Mode, unchanged,
     * so that the host can correct a parameter and call again (as the Python FMUs) */
    if (model_check(comp) > 0)
        return STATUS_ERROR;
    comp->state = STATE_STEP;
    comp->time = comp->startTime;
    comp->elapsed = comp->elapsed_c = 0.0;
    comp->k = 1;
    comp->pending = 1;
    model_start(comp);
    comp->dirty = 1;
    comp->initialised = 1;
    return STATUS_OK;
}

Status cs_terminate(ModelInstance *comp, const char *function)
{
    if (!cs_allowed(comp, function, STATE_INITIALIZATION | STATE_STEP))
        return STATUS_ERROR;
    comp->state = STATE_TERMINATED;
    return STATUS_OK;
}

Status cs_reset(ModelInstance *comp, const char *function)
{
    (void)function;
    to_start(comp);
    return STATUS_OK;
}

/* ---- variables -------------------------------------------------------------------------- */

#define REAL_AT(comp, i) ((double *)((char *)&(comp)->v + MODEL_VARIABLES[i].offset))
#define INT_AT(comp, i) ((int *)((char *)&(comp)->v + MODEL_VARIABLES[i].offset))

static const char *TYPE_NAME[] = {FMI_VERSION == 2 ? "Real" : "Float64",
                                  FMI_VERSION == 2 ? "Integer" : "Int32"};
static const char *CAUSALITY_NAME[] = {"parameter", "input", "output"};

typedef struct {
    ModelVariables v;
    ModelHidden h;
} Backup;

#define IS_REAL_OUTPUT(i) \
    (MODEL_VARIABLES[i].causality == CAUSALITY_OUTPUT && MODEL_VARIABLES[i].type == TYPE_REAL)
#define VALUE_AT(v, i) ((char *)&(v) + MODEL_VARIABLES[i].offset)
#define VALUE_SIZE(i) (MODEL_VARIABLES[i].type == TYPE_REAL ? sizeof(double) : sizeof(int))

/* The part of ModelHidden a hook may change: from MODEL_HIDDEN_CHANGEABLE (model.h; a model
 * whose hidden state starts with constants its parameters give may say where they end) to the
 * end, by default all of it. */
#ifndef MODEL_HIDDEN_CHANGEABLE
#define MODEL_HIDDEN_CHANGEABLE 0
#endif
#define HIDDEN_TAIL(h) ((char *)&(h) + MODEL_HIDDEN_CHANGEABLE)
#define HIDDEN_TAIL_SIZE (sizeof(ModelHidden) - MODEL_HIDDEN_CHANGEABLE)

/* What a model hook may change (model.h: the outputs and the hidden state), saved before it
 * runs so that a failed step or refresh can be undone: the outputs one by one (the unrolled
 * loop copies exactly them) and the hidden state from MODEL_HIDDEN_CHANGEABLE on. */
static inline void save_changeable(Backup *b, const ModelInstance *comp)
{
    ALL_VARIABLES
    for (int i = 0; i < N_VARIABLES; i++)
        if (MODEL_VARIABLES[i].causality == CAUSALITY_OUTPUT)
            memcpy(VALUE_AT(b->v, i), VALUE_AT(comp->v, i), VALUE_SIZE(i));
    memcpy(HIDDEN_TAIL(b->h), HIDDEN_TAIL(comp->h), HIDDEN_TAIL_SIZE);
}

static NOINLINE void restore_changeable(ModelInstance *comp, const Backup *b)
{
    for (int i = 0; i < N_VARIABLES; i++)
        if (MODEL_VARIABLES[i].causality == CAUSALITY_OUTPUT)
            memcpy(VALUE_AT(comp->v, i), VALUE_AT(b->v, i), VALUE_SIZE(i));
    memcpy(HIDDEN_TAIL(comp->h), HIDDEN_TAIL(b->h), HIDDEN_TAIL_SIZE);
}

/* The output guard: the name of the first real output of `v` that is not finite, or NULL. */
static inline const char *nonfinite_output(const ModelVariables *v)
{
    ALL_VARIABLES
    for (int i = 0; i < N_VARIABLES; i++)
        if (IS_REAL_OUTPUT(i) && !isfinite(*(const double *)VALUE_AT(*v, i)))
            return MODEL_VARIABLES[i].name;
    return NULL;
}

/* The outputs of sample 1 read in Initialization Mode, from the start values and inputs set so
 * far (as the Python FMUs and the InitialUnknowns say): checked, computed on a copy, and only
 * the outputs kept. */
static Status initialisation_outputs(ModelInstance *comp, const char *function)
{
    Backup backup = {comp->v, comp->h};
    comp->logContext = "cannot compute the outputs in Initialization Mode: ";
    int problems = model_check(comp);
    comp->logContext = NULL;
    if (problems)
        return STATUS_ERROR;
    const int64_t k = comp->k;
    comp->k = 1;
    model_start(comp);
    const char *bad = MODEL_HAS_FEEDTHROUGH ? model_compute(comp) : NULL;
    ModelVariables computed = comp->v;
    comp->v = backup.v;
    comp->h = backup.h;
    comp->k = k;
    for (int i = 0; !bad && i < N_VARIABLES; i++)
        if (MODEL_VARIABLES[i].causality == CAUSALITY_OUTPUT &&
            MODEL_VARIABLES[i].type == TYPE_REAL &&
            !isfinite(*(double *)((char *)&computed + MODEL_VARIABLES[i].offset)))
            bad = MODEL_VARIABLES[i].name;
    if (bad == comp->refusal) { /* the model's own words (a covariance), as the Python FMU's */
        cs_log(comp, STATUS_ERROR, "%s", bad);
        return STATUS_ERROR;
    }
    if (bad) {
        char bt[32];
        cs_log(comp, STATUS_ERROR, "%s: %s would not be finite at sample 1 (t = %s s): the "
               "start values overflow the model; allowed: values whose outputs stay finite "
               "(nothing was changed)", function, bad, repr_double(comp->startTime, bt));
        return STATUS_ERROR;
    }
    for (int i = 0; i < N_VARIABLES; i++)
        if (MODEL_VARIABLES[i].causality == CAUSALITY_OUTPUT)
            memcpy((char *)&comp->v + MODEL_VARIABLES[i].offset,
                   (char *)&computed + MODEL_VARIABLES[i].offset,
                   MODEL_VARIABLES[i].type == TYPE_REAL ? sizeof(double) : sizeof(int));
    comp->dirty = 0;
    return STATUS_OK;
}

static NOINLINE Status refused_refresh(ModelInstance *comp, const char *function,
                                       const char *bad)
{
    char b[32];
    if (bad == comp->refusal) { /* the model's own words (a covariance), as the Python FMU's */
        cs_log(comp, STATUS_ERROR, "%s", bad);
        return STATUS_ERROR;
    }
    cs_log(comp, STATUS_ERROR, "%s: %s would not be finite at sample %lld (t = %s s): the "
           "inputs and parameters overflow the model; allowed: values whose outputs and "
           "state stay finite (nothing was changed)", function, bad, (long long)comp->k,
           repr_double(comp->startTime + (double)(comp->k - 1) * comp->v.Ts, b));
    return STATUS_ERROR;
}

/* The feedthrough outputs of the pending sample, computed when inputs changed. The state is
 * restored and an error returned when a value comes out non-finite. */
static NOINLINE Status compute_dirty(ModelInstance *comp, const char *function)
{
    /* not initialised (Initialization Mode, or terminated from there): the outputs of sample 1
     * from the start values and inputs, as the Python FMUs compute them */
    if (!comp->initialised &&
        (comp->state == STATE_INITIALIZATION || comp->state == STATE_TERMINATED))
        return initialisation_outputs(comp, function);
    if (!(MODEL_HAS_FEEDTHROUGH && comp->initialised && comp->pending))
        return STATUS_OK;
    Backup backup;
    save_changeable(&backup, comp);
    const char *bad = model_compute(comp);
    if (bad) {
        restore_changeable(comp, &backup);
        return refused_refresh(comp, function, bad);
    }
    comp->dirty = 0;
    return STATUS_OK;
}

/* Nothing to do unless inputs or parameters changed since the outputs were computed. */
static inline Status refresh(ModelInstance *comp, const char *function)
{
    return comp->dirty ? compute_dirty(comp, function) : STATUS_OK;
}

/* FMI 3.0: the independent variable time has the value reference after the table's. */
#define VR_TIME ((unsigned int)N_VARIABLES)
#define IS_TIME(vr) (FMI_VERSION == 3 && (vr) == VR_TIME)

static int bad_reference(unsigned int vr, VariableType type, int reading)
{
    if (IS_TIME(vr))
        return !(type == TYPE_REAL && reading);
    return vr >= N_VARIABLES || MODEL_VARIABLES[vr].type != (VariableType)type;
}

/* What is wrong with the value references of a call on `type` variables, worded as the Python
 * FMUs word it: "value reference 999 does not exist; allowed: the Real value references of
 * modelDescription.xml (0, 1, ...)". */
static void bad_references(char *out, size_t size, const unsigned int vr[], size_t n,
                           const char *type, int type_code, int reading)
{
    size_t used = 0;
    out[0] = 0;
#define PUT(...)                                                                           \
    do {                                                                                   \
        if (used < size) {                                                                 \
            int w = snprintf(out + used, size - used, __VA_ARGS__);                        \
            used += w > 0 ? (size_t)w : 0;                                                 \
        }                                                                                  \
    } while (0)
    int first = 1;
    for (size_t i = 0; i < n; i++) {
        if (type_code >= 0 && !bad_reference(vr[i], (VariableType)type_code, reading))
            continue;
        if (!first)
            PUT(", ");
        first = 0;
        if (IS_TIME(vr[i]))
            PUT("value reference %u is time, the independent variable: a Float64 that can be "
                "read, not set", vr[i]);
        else if (vr[i] >= N_VARIABLES)
            PUT("value reference %u does not exist", vr[i]);
        else
            PUT("value reference %u is %s, %s %s variable, not %s %s variable", vr[i],
                MODEL_VARIABLES[vr[i]].name,
                MODEL_VARIABLES[vr[i]].type == TYPE_REAL ? "a" : "an",
                TYPE_NAME[MODEL_VARIABLES[vr[i]].type],
                (type[0] == 'I' || type[0] == 'U') ? "an" : "a", type);
    }
    PUT("; allowed: the %s value references of modelDescription.xml (", type);
    int any = 0;
    for (int i = 0; type_code >= 0 && i < N_VARIABLES; i++)
        if ((int)MODEL_VARIABLES[i].type == type_code) {
            PUT(any ? ", %d" : "%d", i);
            any = 1;
        }
    if (FMI_VERSION == 3 && type_code == TYPE_REAL && reading) {
        PUT(any ? ", %d" : "%d", N_VARIABLES);
        any = 1;
    }
    PUT("%s)", any ? "" : "none");
#undef PUT
}

int cs_count_ok(ModelInstance *comp, const char *function, size_t n)
{
    if (LIKELY(n <= MAX_VALUES_PER_CALL))
        return 1;
    cs_log(comp, STATUS_ERROR, "%s: %llu value references in one call; allowed: at most %u "
           "(a larger count cannot list this FMU's %d variables); nothing was read and nothing "
           "was changed", function, (unsigned long long)n, MAX_VALUES_PER_CALL, N_VARIABLES);
    return 0;
}

static NOINLINE Status refused_null(ModelInstance *comp, const char *function, size_t n)
{
    cs_log(comp, STATUS_ERROR, "%s: a NULL array for %lu values", function, (unsigned long)n);
    return STATUS_ERROR;
}

static NOINLINE Status refused_references(ModelInstance *comp, const char *function,
                                          VariableType type, const unsigned int vr[], size_t n)
{
    char text[MESSAGE_SIZE];
    bad_references(text, sizeof text, vr, n, TYPE_NAME[type], type, 1);
    cs_log(comp, STATUS_ERROR, "%s: %s", function, text);
    return STATUS_ERROR;
}

Status cs_get(ModelInstance *comp, const char *function, VariableType type,
              const unsigned int vr[], size_t n, double reals[], int ints[])
{
    /* FMI 2.0 and 3.0 alike: no getter before Initialization Mode (as the Python FMUs) */
    if (!cs_allowed(comp, function, STATE_INITIALIZATION | STATE_STEP | STATE_TERMINATED) ||
        !cs_count_ok(comp, function, n))
        return STATUS_ERROR;
    if (n && (!vr || (type == TYPE_REAL ? !reals : !ints)))
        return refused_null(comp, function, n);
    for (size_t i = 0; i < n; i++)
        if (bad_reference(vr[i], type, 1))
            return refused_references(comp, function, type, vr, n);
    if (refresh(comp, function) != STATUS_OK)
        return STATUS_ERROR;
    if (type == TYPE_REAL) {
        for (size_t i = 0; i < n; i++)
            reals[i] = IS_TIME(vr[i]) ? comp->time : *REAL_AT(comp, vr[i]);
    } else {
        for (size_t i = 0; i < n; i++)
            ints[i] = *INT_AT(comp, vr[i]);
    }
    return STATUS_OK;
}

/* A set with at least one problem: every problem of the call (all but the last logged, the
 * last with the error); nothing is set. */
static NOINLINE Status refused_set(ModelInstance *comp, const char *function, VariableType type,
                                   const unsigned int vr[], size_t n, const double reals[])
{
    char problems[8][MESSAGE_SIZE];
    int np = 0;
    if (comp->state == STATE_TERMINATED)
        snprintf(problems[np++], MESSAGE_SIZE, "the instance is terminated (%s); allowed: %s, "
                 "%s, the get functions and %s", FMI_VERSION == 2 ? "fmi2Terminate" :
                 "fmi3Terminate", FMI_VERSION == 2 ? "fmi2Reset" : "fmi3Reset",
                 FMI_VERSION == 2 ? "fmi2FreeInstance" : "fmi3FreeInstance",
                 FMI_VERSION == 2 ? "fmi2SetFMUstate" : "fmi3SetFMUState");
    for (size_t i = 0; i < n; i++)
        if (bad_reference(vr[i], type, 0)) {
            bad_references(problems[np++], MESSAGE_SIZE, vr, n, TYPE_NAME[type], type, 0);
            break;
        }
    for (size_t i = 0; i < n && np < 8; i++) {
        if (bad_reference(vr[i], type, 0))
            continue;
        const VariableInfo *info = &MODEL_VARIABLES[vr[i]];
        char b[32];
        if (info->causality == CAUSALITY_OUTPUT)
            snprintf(problems[np++], MESSAGE_SIZE, "%s is an output; only parameters and "
                     "inputs can be set", info->name);
        else if (type == TYPE_REAL && !isfinite(reals[i]))
            snprintf(problems[np++], MESSAGE_SIZE, "%s = %s is not finite; %s accepts finite "
                     "values only", info->name, repr_double(reals[i], b),
                     CAUSALITY_NAME[info->causality]);
        else if (info->causality == CAUSALITY_PARAMETER && comp->initialised)
            snprintf(problems[np++], MESSAGE_SIZE, "%s is a fixed parameter and cannot be "
                     "changed after initialisation (it stays %s)", info->name,
                     info->type == TYPE_REAL ? repr_double(*REAL_AT(comp, vr[i]), b)
                     : (snprintf(b, sizeof b, "%d", *INT_AT(comp, vr[i])), b));
    }
    for (int i = 0; i < np - 1; i++)
        cs_log(comp, STATUS_ERROR, "%s: %s", function, problems[i]);
    cs_log(comp, STATUS_ERROR, "%s: %s%s", function, problems[np - 1],
           n > 1 ? "; nothing was set" : "");
    return STATUS_ERROR;
}

Status cs_set(ModelInstance *comp, const char *function, VariableType type,
              const unsigned int vr[], size_t n, const double reals[], const int ints[])
{
    if (!cs_allowed(comp, function, STATE_INSTANTIATED | STATE_INITIALIZATION | STATE_STEP |
                    STATE_TERMINATED) || !cs_count_ok(comp, function, n))
        return STATUS_ERROR;
    if (n && (!vr || (type == TYPE_REAL ? !reals : !ints)))
        return refused_null(comp, function, n);
    /* every check of refused_set first, without words: a rejected call changes nothing */
    int ok = comp->state != STATE_TERMINATED;
    for (size_t i = 0; ok && i < n; i++) {
        const unsigned int r = vr[i];
        ok = !bad_reference(r, type, 0) && MODEL_VARIABLES[r].causality != CAUSALITY_OUTPUT &&
             (type != TYPE_REAL || isfinite(reals[i])) &&
             !(MODEL_VARIABLES[r].causality == CAUSALITY_PARAMETER && comp->initialised);
    }
    if (!LIKELY(ok))
        return refused_set(comp, function, type, vr, n, reals);
    if (type == TYPE_REAL) {
        for (size_t i = 0; i < n; i++)
            *REAL_AT(comp, vr[i]) = reals[i];
    } else {
        for (size_t i = 0; i < n; i++)
            *INT_AT(comp, vr[i]) = ints[i];
    }
    if (n)
        comp->dirty = 1;
    return STATUS_OK;
}

Status cs_no_such_type(ModelInstance *comp, const char *function, const char *type,
                       const unsigned int vr[], size_t n)
{
    if (n == 0)
        return STATUS_OK;
    if (!cs_count_ok(comp, function, n))
        return STATUS_ERROR;
    if (!vr) {
        cs_log(comp, STATUS_ERROR, "%s: a NULL array for %lu values", function,
               (unsigned long)n);
        return STATUS_ERROR;
    }
    char text[MESSAGE_SIZE];
    bad_references(text, sizeof text, vr, n, type, -1, 0);
    cs_log(comp, STATUS_ERROR, "%s: %s", function, text);
    return STATUS_ERROR;
}

/* ---- the step rule (slave_base.STEP_RULE), as fmu_src/slave_base.py keeps it ---------------------- */

/* Neumaier's compensated sum of the step sizes (slave_base._add). */
static void add_step(double *s, double *c, double x)
{
    double t = *s + x;
    if (fabs(*s) >= fabs(x))
        *c += (*s - t) + x;
    else
        *c += (x - t) + *s;
    *s = t;
}

/* A step refused before it is planned: the checks of cs_do_step in their order, each with
 * its message (called only when one of them fails). */
static NOINLINE Status refused_step(ModelInstance *comp, const char *function,
                                    double currentTime, double h)
{
    char bh[32], bt[32], bl[32];
    if (comp->state == STATE_TERMINATED) {
        cs_log(comp, STATUS_ERROR, "cannot step: the instance is terminated (%s); allowed: %s, "
               "then initialise again", FMI_VERSION == 2 ? "fmi2Terminate" : "fmi3Terminate",
               FMI_VERSION == 2 ? "fmi2Reset" : "fmi3Reset");
        return STATUS_ERROR;
    }
    if (!cs_allowed(comp, function, STATE_STEP))
        return STATUS_ERROR;
    if (!comp->initialised) {
        cs_log(comp, STATUS_ERROR, "cannot step: initialisation did not complete (see the "
               "errors above)");
        return STATUS_ERROR;
    }
    if (!isfinite(currentTime)) {   /* any finite value: the FMU keeps its own time */
        cs_log(comp, STATUS_ERROR, "%s: currentCommunicationPoint = %s s; allowed: a finite "
               "time (the FMU keeps its own time and steps from %s s, the end of the previous "
               "step)", function, repr_double(currentTime, bt), repr_double(comp->time, bl));
        return STATUS_ERROR;
    }
    cs_log(comp, STATUS_ERROR, "communication step h = %s s; allowed: a finite h > 0",
           repr_double(h, bh));
    return STATUS_ERROR;
}

/* A step that spans too many sample instants, or whose end is no finite number of them. */
static NOINLINE Status refused_span(ModelInstance *comp, double h, double position)
{
    char bh[32], bt[32], bl[32];
    const double Ts = comp->v.Ts, limit = (double)MAX_SAMPLES_PER_STEP;
    /* the room left before the limit, in seconds: finite whenever Ts is (an overflow of
     * limit * Ts or of the time itself is said as such) */
    const double room = (limit + (double)comp->k - 1.0) * Ts - (comp->elapsed + comp->elapsed_c);
    if (!isfinite(position) || !isfinite(room))
        cs_log(comp, STATUS_ERROR, "communication step h = %s s from t = %s s with Ts = %s "
               "s: the time in sample periods, (t + h - startTime)/Ts, is not a finite "
               "number; allowed: steps whose end is a finite number of sample periods "
               "after the start", repr_double(h, bh), repr_double(comp->time, bt),
               repr_double(Ts, bl));
    else
        cs_log(comp, STATUS_ERROR, "communication step h = %s s spans more than %lld "
               "sample instants of Ts = %s s; allowed: at most MAX_SAMPLES_PER_STEP = %lld "
               "sample instants per step, h <= about %s s", repr_double(h, bh),
               (long long)MAX_SAMPLES_PER_STEP, repr_double(Ts, bt),
               (long long)MAX_SAMPLES_PER_STEP, repr_double(room, bl));
    return STATUS_ERROR;
}

/* A step that would end after the defined stop time by more than the tolerance of the sample
 * instants (FMI 2.0 and 3.0: an FMU asked to compute past the stop time returns an error). */
static NOINLINE Status refused_stop(ModelInstance *comp, double h, double elapsed)
{
    char bh[32], bt[32], be[32], bs[32];
    cs_log(comp, STATUS_ERROR, "communication step h = %s s from t = %s s ends at t = %s s, "
           "after the stop time %s s (%s); allowed: steps that end at or before the stop time "
           "(within a millionth of a sample period); nothing was changed", repr_double(h, bh),
           repr_double(comp->time, bt), repr_double(comp->startTime + elapsed, be),
           repr_double(comp->stopTime, bs),
           FMI_VERSION == 2 ? "fmi2SetupExperiment" : "fmi3EnterInitializationMode");
    return STATUS_ERROR;
}

/* A step whose outputs or state came out non-finite (the instance is restored already). */
static NOINLINE Status refused_result(ModelInstance *comp, const char *bad, double h)
{
    char bh[32], bt[32];
    if (bad == comp->refusal) { /* the model's own words (a covariance), as the Python FMU's */
        cs_log(comp, STATUS_ERROR, "%s", bad);
        return STATUS_ERROR;
    }
    cs_log(comp, STATUS_ERROR, "%s would not be finite in the step from t = %s s by h = %s "
           "s: the inputs and parameters overflow the model; allowed: values whose outputs "
           "and state stay finite (nothing was changed)", bad, repr_double(comp->time, bt),
           repr_double(h, bh));
    return STATUS_ERROR;
}

/* (int64_t)ceil(x) for the x of a planned step (finite, and below MAX_SAMPLES_PER_STEP plus the
 * sample index, far inside the range of int64_t) without a call into libm: the truncation
 * toward zero, plus one when it lies below x. */
static inline int64_t ceil_int(double x)
{
    const int64_t i = (int64_t)x;
    return (double)i < x ? i + 1 : i;
}

Status cs_do_step(ModelInstance *comp, const char *function, double currentTime, double h)
{
    /* the checks of refused_step, at once: any finite currentTime (the FMU keeps its own time),
     * a finite h > 0, in step mode after a completed initialisation */
    if (!LIKELY(comp->state == STATE_STEP && comp->initialised && isfinite(currentTime) &&
                isfinite(h) && h > 0.0))
        return refused_step(comp, function, currentTime, h);
    const double Ts = comp->v.Ts, tol = SAMPLE_TOLERANCE;
    const int64_t k = comp->k;
    double elapsed = comp->elapsed, elapsed_c = comp->elapsed_c;
    add_step(&elapsed, &elapsed_c, h);
    const double position = (elapsed + elapsed_c) / Ts;   /* t + h in sample periods */
    const double limit = (double)MAX_SAMPLES_PER_STEP;
    if (!LIKELY(position - tol <= limit + (double)k - 1.0))
        return refused_span(comp, h, position);
    if (!LIKELY(position - tol <= (comp->stopTime - comp->startTime) / Ts))
        return refused_stop(comp, h, elapsed + elapsed_c);
    const int64_t last = ceil_int(position - tol);   /* first instant at or after t + h */
    const int64_t m = last + 1 - k > 0 ? last + 1 - k : 0;   /* instants in [t, t + h) */
    StepPlan plan;
    plan.k_first = k;
    plan.n = m;
    plan.first_pending = comp->pending && m > 0;
    plan.end_pending = (double)last <= position + tol;
    plan.k_end = k + m;

    Backup backup;
    save_changeable(&backup, comp);
    const int dirty = comp->dirty;   /* a refresh below marks the outputs current */
    if (plan.first_pending && refresh(comp, function) != STATUS_OK)
        return STATUS_ERROR;
    const char *bad = model_advance(comp, &plan);
    if (!bad)
        bad = nonfinite_output(&comp->v);   /* the output guard */
    if (bad) {
        restore_changeable(comp, &backup);
        comp->dirty = dirty;   /* the outputs put back are due again if they were */
        return refused_result(comp, bad, h);
    }
    comp->elapsed = elapsed;
    comp->elapsed_c = elapsed_c;
    comp->time = comp->startTime + (elapsed + elapsed_c);
    comp->k = k + m;
    comp->pending = plan.end_pending;
    comp->dirty = 1;
    return STATUS_OK;
}

/* ---- FMU states ------------------------------------------------------------------------- */

/*
 * A state is a Snapshot: a header naming the model, build and layout, a checksum of the whole
 * (catches bytes corrupted in storage or transit), then the instance's fields.  A state from
 * outside (fmi2DeSerializeFMUstate / fmi3DeserializeFMUState) and a state pointer a host hands
 * back (fmi2SetFMUstate / fmi3SetFMUState) pass the same checks as the values a host sets
 * through the API (crafted values have a valid checksum: the checks catch them), and the
 * state is refused as a whole, naming the field, otherwise.  See docs/native-hardening.md.
 */
#define STATE_MAGIC "driftfmu-state-3"

typedef struct {
    char magic[24];             /* STATE_MAGIC */
    char model[32];             /* MODEL_NAME */
    char token[64];             /* INSTANTIATION_TOKEN */
    char version[24];           /* MODEL_VERSION */
    uint64_t size;              /* sizeof(Snapshot) */
} StateHeader;

typedef struct {
    StateHeader header;
    uint64_t checksum;          /* FNV-1a 64 of the snapshot with this field 0 */
    ModelVariables v;
    ModelHidden h;
    double startTime, time, elapsed, elapsed_c;
    double stopTime;            /* +inf: none defined */
    int64_t k;
    int32_t pending, dirty, initialised, state;
} Snapshot;

static uint64_t checksum_of(const Snapshot *s)
{
    const unsigned char *bytes = (const unsigned char *)s;
    const size_t at = offsetof(Snapshot, checksum), end = at + sizeof s->checksum;
    uint64_t hash = 14695981039346656037ULL;
    for (size_t i = 0; i < sizeof *s; i++) {
        hash ^= (i >= at && i < end) ? 0u : bytes[i];
        hash *= 1099511628211ULL;
    }
    return hash;
}

static void fill_header(StateHeader *header)
{
    memset(header, 0, sizeof *header);
    strncpy(header->magic, STATE_MAGIC, sizeof header->magic - 1);
    strncpy(header->model, MODEL_NAME, sizeof header->model - 1);
    strncpy(header->token, INSTANTIATION_TOKEN, sizeof header->token - 1);
    strncpy(header->version, MODEL_VERSION, sizeof header->version - 1);
    header->size = sizeof(Snapshot);
}

/* A header's text field as a printable string (at most n bytes, non-printable bytes as '?'). */
static void printable(char *out, const char *field, size_t n)
{
    size_t i;
    for (i = 0; i < n && field[i]; i++)
        out[i] = (field[i] >= 32 && field[i] < 127) ? field[i] : '?';
    out[i] = 0;
}

static int header_ok(ModelInstance *comp, const char *function, const StateHeader *header)
{
    StateHeader mine;
    fill_header(&mine);
    if (memcmp(header, &mine, sizeof mine) == 0)
        return 1;
    if (strncmp(header->magic, STATE_MAGIC, sizeof header->magic) != 0) {
        cs_log(comp, STATUS_ERROR, "%s: not an FMU state of %s: no %s header; allowed: a state "
               "that this FMU (%s %s) produced", function, MODEL_NAME, STATE_MAGIC, MODEL_NAME,
               MODEL_VERSION);
    } else {
        char model[33], token[65], version[25];
        printable(model, header->model, sizeof header->model);
        printable(token, header->token, sizeof header->token);
        printable(version, header->version, sizeof header->version);
        if (strcmp(model, MODEL_NAME) || strcmp(token, INSTANTIATION_TOKEN) ||
            strcmp(version, MODEL_VERSION))
            cs_log(comp, STATUS_ERROR, "%s: not an FMU state of %s %s (%s): it is a state of "
                   "%s %s (%s); allowed: a state of this very FMU (same build and version)",
                   function, MODEL_NAME, MODEL_VERSION, INSTANTIATION_TOKEN, model, version,
                   token);
        else
            cs_log(comp, STATUS_ERROR, "%s: the FMU state header of %s is damaged (size field "
                   "%llu, a state has %lu bytes, or bytes after the names); the state is "
                   "refused", function, MODEL_NAME, (unsigned long long)header->size,
                   (unsigned long)sizeof(Snapshot));
    }
    return 0;
}

static int state_allowed(ModelInstance *comp, const char *function)
{
    return cs_allowed(comp, function, STATE_INSTANTIATED | STATE_INITIALIZATION | STATE_STEP |
                      STATE_TERMINATED);
}

/* Logs one problem of a state (all but the last are logged as they are found; the caller
 * adds the verdict to the last).  Returns the new count. */
#define STATE_PROBLEM(...)                                                                 \
    do {                                                                                   \
        if (n_problems)                                                                    \
            cs_log(comp, STATUS_ERROR, "%s: %s", function, last);                          \
        snprintf(last, sizeof last, __VA_ARGS__);                                          \
        n_problems++;                                                                      \
    } while (0)

/* The number of problems of snapshot s (0: it may be restored), each logged with status error
 * and naming the field.  A state is refused as a whole: nothing is changed here. */
static int snapshot_problems(ModelInstance *comp, const char *function, const Snapshot *s)
{
    if (!header_ok(comp, function, &s->header))
        return 1;
    char last[MESSAGE_SIZE] = "", b1[32], b2[32], b3[32];
    int n_problems = 0;
    const uint64_t sum = checksum_of(s);
    if (sum != s->checksum) {
        cs_log(comp, STATUS_ERROR, "%s: the FMU state of %s is corrupted: its checksum is "
               "%016llx, its bytes give %016llx; the state is refused and nothing was changed",
               function, MODEL_NAME, (unsigned long long)s->checksum, (unsigned long long)sum);
        return 1;
    }
    const int32_t mode = s->state;
    if (mode != STATE_INSTANTIATED && mode != STATE_INITIALIZATION && mode != STATE_STEP &&
        mode != STATE_TERMINATED)
        STATE_PROBLEM("mode = %d is not a mode; allowed: %d (instantiated), %d "
                      "(initialisation), %d (step), %d (terminated)", (int)mode,
                      STATE_INSTANTIATED, STATE_INITIALIZATION, STATE_STEP, STATE_TERMINATED);
    const struct { const char *name; int32_t value; } flags[] = {
        {"pending", s->pending}, {"dirty", s->dirty}, {"initialised", s->initialised}};
    for (size_t i = 0; i < sizeof flags / sizeof flags[0]; i++)
        if (flags[i].value != 0 && flags[i].value != 1)
            STATE_PROBLEM("%s = %d is not a flag; allowed: 0 or 1", flags[i].name,
                          (int)flags[i].value);
    if (s->initialised == 1 && (mode == STATE_INSTANTIATED || mode == STATE_INITIALIZATION))
        STATE_PROBLEM("initialised = 1 in mode %d; allowed: initialised = 0 before the exit "
                      "of initialisation", (int)mode);
    if (s->initialised == 0 && mode == STATE_STEP)
        STATE_PROBLEM("initialised = 0 in step mode; allowed: initialised = 1 in step mode");
    const struct { const char *name; double value; } times[] = {
        {"startTime", s->startTime}, {"time", s->time}, {"elapsed", s->elapsed},
        {"elapsed_c", s->elapsed_c}};
    int times_ok = 1;
    for (size_t i = 0; i < sizeof times / sizeof times[0]; i++)
        if (!isfinite(times[i].value)) {
            STATE_PROBLEM("%s = %s is not finite; allowed: finite times", times[i].name,
                          repr_double(times[i].value, b1));
            times_ok = 0;
        }
    if (times_ok && !(s->elapsed >= 0.0))
        STATE_PROBLEM("elapsed = %s s; allowed: elapsed >= 0", repr_double(s->elapsed, b1));
    else if (times_ok && s->time != s->startTime + (s->elapsed + s->elapsed_c))
        STATE_PROBLEM("time = %s s is not startTime + elapsed = %s s; allowed: the time the "
                      "steps of the state add up to", repr_double(s->time, b1),
                      repr_double(s->startTime + (s->elapsed + s->elapsed_c), b2));
    if (times_ok && !(s->stopTime >= s->startTime))
        STATE_PROBLEM("stopTime = %s s with startTime = %s s; allowed: a stop time >= "
                      "startTime, or inf (none defined)", repr_double(s->stopTime, b1),
                      repr_double(s->startTime, b2));
    if (s->k < 1)
        STATE_PROBLEM("k = %lld is not a sample index; allowed: k >= 1", (long long)s->k);
    for (int i = 0; i < N_VARIABLES; i++) {
        const VariableInfo *info = &MODEL_VARIABLES[i];
        if (info->type == TYPE_REAL) {
            const double value = *(const double *)((const char *)&s->v + info->offset);
            if (!isfinite(value))
                STATE_PROBLEM("%s = %s is not finite; allowed: finite values only", info->name,
                              repr_double(value, b1));
        }
    }
    if (n_problems)
        goto verdict;
    if (!s->initialised) {
        /* before initialisation the hidden state is empty and the FMU at sample 1 */
        static const ModelHidden empty;
        if (memcmp(&s->h, &empty, sizeof empty) != 0)
            STATE_PROBLEM("the hidden state is set although initialised = 0; allowed: an "
                          "empty hidden state before initialisation");
        if (s->k != 1 || s->pending != 1)
            STATE_PROBLEM("k = %lld, pending = %d before initialisation; allowed: k = 1, "
                          "pending = 1", (long long)s->k, (int)s->pending);
        if (s->elapsed != 0.0 || s->elapsed_c != 0.0)
            STATE_PROBLEM("elapsed = %s s before initialisation; allowed: 0.0",
                          repr_double(s->elapsed + s->elapsed_c, b1));
        goto verdict;
    }
    {
        /* the parameters pass the checks of fmi2ExitInitializationMode, and the hidden state
         * is one they allow: on a scratch copy, logging through this instance */
        ModelInstance scratch = *comp;
        scratch.v = s->v;
        char context[160];
        snprintf(context, sizeof context, "%s: the FMU state is not valid: ", function);
        scratch.logContext = context;
        int bad = model_check(&scratch);
        if (bad) {
            n_problems += bad;
            cs_log(comp, STATUS_ERROR, "%s: the FMU state of %s is refused (its parameters "
                   "are not valid, see above) and nothing was changed", function, MODEL_NAME);
            return n_problems + 1;
        }
        /* the sample index and the pending flag follow from the time (slave_base) */
        const double Ts = s->v.Ts, tol = SAMPLE_TOLERANCE;
        const double position = (s->elapsed + s->elapsed_c) / Ts;
        if (!isfinite(position) || position > 9.0e15) {
            STATE_PROBLEM("the time %s s after the start is not a finite number of sample "
                          "periods Ts = %s s", repr_double(s->elapsed + s->elapsed_c, b1),
                          repr_double(Ts, b2));
        } else {
            const double first = ceil(position - tol);
            const int at = first <= position + tol;
            if ((double)(s->k - 1) != first || s->pending != at)
                STATE_PROBLEM("k = %lld and pending = %d do not match the time %s s after "
                              "the start (the next sample there is k = %s, pending = %d)",
                              (long long)s->k, (int)s->pending,
                              repr_double(s->elapsed + s->elapsed_c, b1),
                              repr_double(first + 1.0, b3), at);
            if (!(position - tol <= (s->stopTime - s->startTime) / Ts))
                STATE_PROBLEM("the time %s s after the start is after the stop time %s s; "
                              "allowed: a time at or before the stop time",
                              repr_double(s->elapsed + s->elapsed_c, b1),
                              repr_double(s->stopTime, b2));
        }
        ModelInstance fresh = scratch;
        fresh.logContext = NULL;
        model_start(&fresh);
        scratch.h = s->h;
        scratch.k = s->k;
        scratch.pending = s->pending;
        bad = model_hidden_problems(&scratch, &fresh.h);
        if (bad) {
            if (n_problems)
                cs_log(comp, STATUS_ERROR, "%s: %s", function, last);
            cs_log(comp, STATUS_ERROR, "%s: the FMU state of %s is refused (its hidden state "
                   "is not valid, see above) and nothing was changed", function, MODEL_NAME);
            return n_problems + bad + 1;
        }
    }
verdict:
    if (n_problems)
        cs_log(comp, STATUS_ERROR, "%s: the FMU state of %s is not valid: %s; the state is "
               "refused and nothing was changed", function, MODEL_NAME, last);
    return n_problems;
}
#undef STATE_PROBLEM

/* ---- the live states: a state handle a host passes is looked up before anything is read ---- */

/*
 * A state handed to the host is a StateNode: the Snapshot, the instance that owns it, and the
 * handle the host holds (state_handles.h: a number issued once, never an address, so a freed
 * state's handle cannot come back as a live state when the memory is reused).
 *
 * Every live state of the library is in one list, guarded by a spin lock (GCC/Clang atomics: no
 * thread library, so the Windows binaries keep needing only system DLLs).  A state belongs to
 * the instance that got or deserialised it: the instance's free frees all its states (FMI 2.0
 * and 3.0: fmi2FreeInstance/fmi3FreeInstance free all memory the FMU's functions allocated),
 * and a handle that is not a live state of the calling instance (garbage, freed, freed with its
 * instance, another instance's, another library's) is refused, naming which, without being
 * read.  To move a state between instances, a host serialises it.
 */
typedef struct StateNode {
    struct StateNode *next;
    uintptr_t handle;
    const ModelInstance *owner;
    Snapshot s;
} StateNode;

static StateNode *live_states;
static uint64_t issued;   /* handles issued so far (the last serial number) */
static char live_lock;

static void lock_states(void)
{
    while (__atomic_test_and_set(&live_lock, __ATOMIC_ACQUIRE))
        ;
}

static void unlock_states(void)
{
    __atomic_clear(&live_lock, __ATOMIC_RELEASE);
}

/* The live node of handle h, or NULL (the caller holds the lock). */
static StateNode *find_locked(const void *h)
{
    for (StateNode *n = live_states; n; n = n->next)
        if ((const void *)n->handle == h)
            return n;
    return NULL;
}

/* Issue a handle for node, owned by comp, and list it. */
static void add_live(StateNode *node, const ModelInstance *comp)
{
    lock_states();
    issued = state_next_serial(issued);
    node->handle = state_handle(&issued, issued);
    node->owner = comp;
    node->next = live_states;
    live_states = node;
    unlock_states();
}

static void remove_live(StateNode *node)
{
    lock_states();
    for (StateNode **p = &live_states; *p; p = &(*p)->next)
        if (*p == node) {
            *p = node->next;
            break;
        }
    unlock_states();
}

/* Free every state comp owns (its free: nothing the instance's calls allocated outlives it). */
static void free_states_of(const ModelInstance *comp)
{
    lock_states();
    for (StateNode **p = &live_states; *p;) {
        StateNode *n = *p;
        if (n->owner == comp) {
            *p = n->next;
            free(n);
        } else {
            p = &n->next;
        }
    }
    unlock_states();
}

/* What a handle that is not a live state of comp is: 1 another instance's, 2 issued by this
 * library and freed since, 0 anything else (never issued here: garbage, another library's). */
static int stranger(const ModelInstance *comp, const void *h, StateNode **mine)
{
    lock_states();   /* (the node is read under the lock: another instance may free it) */
    StateNode *n = find_locked(h);
    const int owned = n && n->owner == comp;
    const uint64_t last = issued;
    unlock_states();
    *mine = owned ? n : NULL;
    if (n)
        return owned ? -1 : 1;
    return state_issued_here(&issued, h, last) ? 2 : 0;
}

/* The node behind a state handle a host passed when it is a live state of comp, or NULL
 * (logged, naming what the handle is). */
static StateNode *known_state(ModelInstance *comp, const char *function, const void *state)
{
    if (!state) {
        cs_log(comp, STATUS_ERROR, "%s: the FMU state is NULL; allowed: a state from this "
               "instance's get or deserialise call", function);
        return NULL;
    }
    StateNode *node;
    switch (stranger(comp, state, &node)) {
    case -1:
        return node;
    case 1:
        cs_log(comp, STATUS_ERROR, "%s: FMU state %p belongs to another instance of %s, not to "
               "this one: a state is valid only in the instance that made it (to move a state "
               "between instances, serialise it and deserialise it in the other); allowed: a "
               "live state of this instance", function, state, MODEL_NAME);
        return NULL;
    case 2:
        cs_log(comp, STATUS_ERROR, "%s: FMU state %p is freed: by %s, or with the instance "
               "that made it (%s frees every state of the instance); allowed: a live state of "
               "this instance", function, state,
               FMI_VERSION == 2 ? "fmi2FreeFMUstate" : "fmi3FreeFMUState",
               FMI_VERSION == 2 ? "fmi2FreeInstance" : "fmi3FreeInstance");
        return NULL;
    default:
        cs_log(comp, STATUS_ERROR, "%s: FMU state %p is not a live state of this loaded copy "
               "of %s: not made by its get or deserialise call (a state pointer is valid only "
               "in the library and the instance that made it; to move a state between copies, "
               "serialise it); allowed: a live state of this instance", function, state,
               MODEL_NAME);
        return NULL;
    }
}

static void snapshot_of(const ModelInstance *comp, Snapshot *s)
{
    memset(s, 0, sizeof *s);   /* padding too: equal states serialise to equal bytes */
    fill_header(&s->header);
    s->v = comp->v;
    s->h = comp->h;
    s->startTime = comp->startTime;
    s->time = comp->time;
    s->elapsed = comp->elapsed;
    s->elapsed_c = comp->elapsed_c;
    s->stopTime = comp->stopTime;
    s->k = comp->k;
    s->pending = comp->pending;
    s->dirty = comp->dirty;
    s->initialised = comp->initialised;
    s->state = (int32_t)comp->state;
    s->checksum = checksum_of(s);
}

/* The state a host hands in to be written (get, deserialise): its node when it is a live state
 * of comp, else NULL (a new one is made), with a warning for a handle that is not one (left
 * alone: another instance's state stays as it is). */
static StateNode *reusable_state(ModelInstance *comp, const char *function, void *handle,
                                 Status *status)
{
    if (!handle)
        return NULL;
    StateNode *node;
    if (stranger(comp, handle, &node) == -1)
        return node;
    cs_log(comp, STATUS_WARNING, "%s: *FMUstate = %p is not a live FMU state of this instance; "
           "a new state is returned and the old pointer is left alone", function, handle);
    *status = STATUS_WARNING;
    return NULL;
}

Status cs_get_state(ModelInstance *comp, const char *function, void **state)
{
    if (!state_allowed(comp, function))
        return STATUS_ERROR;
    if (!state) {
        cs_log(comp, STATUS_ERROR, "%s: the FMU state pointer is NULL; allowed: a pointer to "
               "NULL or to a live state of this instance", function);
        return STATUS_ERROR;
    }
    Status status = STATUS_OK;
    StateNode *node = reusable_state(comp, function, *state, &status);
    if (!node) {
        node = malloc(sizeof *node);
        if (!node) {
            cs_log(comp, STATUS_ERROR, "%s: out of memory (%lu bytes for an FMU state)",
                   function, (unsigned long)sizeof *node);
            return STATUS_ERROR;
        }
        snapshot_of(comp, &node->s);
        add_live(node, comp);
    } else {
        snapshot_of(comp, &node->s);
    }
    *state = (void *)node->handle;
    return status;
}

Status cs_set_state(ModelInstance *comp, const char *function, const void *state)
{
    if (!state_allowed(comp, function))
        return STATUS_ERROR;
    const StateNode *node = known_state(comp, function, state);
    if (!node)
        return STATUS_ERROR;
    const Snapshot *s = &node->s;
    if (snapshot_problems(comp, function, s))
        return STATUS_ERROR;
    comp->v = s->v;
    comp->h = s->h;
    comp->startTime = s->startTime;
    comp->stopTime = s->stopTime;
    comp->time = s->time;
    comp->elapsed = s->elapsed;
    comp->elapsed_c = s->elapsed_c;
    comp->k = s->k;
    comp->pending = s->pending;
    comp->dirty = 1;   /* the pending outputs are computed anew (as the Python FMUs do) */
    comp->initialised = s->initialised;
    comp->state = (ModelState)s->state;
    return STATUS_OK;
}

Status cs_free_state(ModelInstance *comp, const char *function, void **state)
{
    if (!state || !*state)
        return STATUS_OK;   /* nothing to free */
    StateNode *node = known_state(comp, function, *state);
    if (!node)
        return STATUS_ERROR;
    remove_live(node);
    free(node);
    *state = NULL;
    return STATUS_OK;
}

Status cs_serialized_size(ModelInstance *comp, const char *function, const void *state,
                          size_t *size)
{
    if (!size) {
        cs_log(comp, STATUS_ERROR, "%s: size is NULL; allowed: a valid pointer", function);
        return STATUS_ERROR;
    }
    if (!known_state(comp, function, state))
        return STATUS_ERROR;
    *size = sizeof(Snapshot);
    return STATUS_OK;
}

Status cs_serialize(ModelInstance *comp, const char *function, const void *state,
                    unsigned char *bytes, size_t size)
{
    const StateNode *node = known_state(comp, function, state);
    if (!node)
        return STATUS_ERROR;
    if (!bytes || size < sizeof node->s) {
        cs_log(comp, STATUS_ERROR, "%s: a buffer of %lu bytes%s; allowed: a buffer of at least "
               "%lu bytes (the serialised size of a state of %s)", function,
               (unsigned long)size, bytes ? "" : " at NULL", (unsigned long)sizeof node->s,
               MODEL_NAME);
        return STATUS_ERROR;
    }
    memcpy(bytes, &node->s, sizeof node->s);
    return STATUS_OK;
}

Status cs_deserialize(ModelInstance *comp, const char *function, const unsigned char *bytes,
                      size_t size, void **state)
{
    if (!state || (!bytes && size)) {
        cs_log(comp, STATUS_ERROR, "%s: %s is NULL; allowed: a valid pointer", function,
               !state ? "the FMU state pointer" : "the serialised state");
        return STATUS_ERROR;
    }
    /* the size a host passes is compared, never used in arithmetic or to allocate */
    if (size != sizeof(Snapshot)) {
        /* the header is read only from a size a state could have (a host that says SIZE_MAX
         * for a short buffer is not taken at its word) */
        if (size >= sizeof(StateHeader) && size <= 16 * sizeof(Snapshot)) {
            StateHeader header;
            memcpy(&header, bytes, sizeof header);
            if (!header_ok(comp, function, &header))
                return STATUS_ERROR;
        }
        cs_log(comp, STATUS_ERROR, "%s: not an FMU state of %s: %lu bytes; allowed: the %lu "
               "bytes of a serialised state", function, MODEL_NAME, (unsigned long)size,
               (unsigned long)sizeof(Snapshot));
        return STATUS_ERROR;
    }
    Snapshot s;   /* checked as a whole before it replaces anything */
    memcpy(&s, bytes, sizeof s);
    if (snapshot_problems(comp, function, &s))
        return STATUS_ERROR;
    /* into the live state *state is (as the loader shim does), else into a new one: a host
     * that deserialises into one state again and again allocates nothing */
    Status status = STATUS_OK;
    StateNode *node = reusable_state(comp, function, *state, &status);
    if (!node) {
        node = malloc(sizeof *node);
        if (!node) {
            cs_log(comp, STATUS_ERROR, "%s: out of memory (%lu bytes for an FMU state)",
                   function, (unsigned long)sizeof *node);
            return STATUS_ERROR;
        }
        node->s = s;
        add_live(node, comp);
    } else {
        node->s = s;
    }
    *state = (void *)node->handle;
    return status;
}
