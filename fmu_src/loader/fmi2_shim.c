/*
 * fmi2_shim.c - the binaries/linux64/<Name>.so of a driftfmu FMU.
 *
 * pythonfmu's library (shipped beside this one as <Name>_pythonfmu.so) calls the Python C API but
 * does not link libpython, so a host that is not a Python process cannot load it.  This shim
 *
 *   1. makes sure the Python C API is in the process: if Py_IsInitialized is not found in the
 *      global scope, it dlopens a libpython with RTLD_NOW | RTLD_GLOBAL, trying in order
 *      $DRIFTFMU_LIBPYTHON, the soname of the Python the FMU was built with
 *      (DRIFTFMU_BUILD_LIBPYTHON), libpython3.13.so.1.0 ... libpython3.8.so.1.0 and libpython3.so;
 *   2. dlopens <Name>_pythonfmu.so (found beside this file via dladdr) with RTLD_LOCAL and
 *      forwards every FMI 2.0 co-simulation function to it;
 *   3. stands between pythonfmu and the host's logger.  pythonfmu passes a message to the
 *      logger only while debug logging is on, and turns a model that logged an error and gave up
 *      a step into fmi2Discard.  The shim therefore keeps pythonfmu's debug logging on, forwards
 *      warnings, errors and fatal messages to the host always (everything else only when the
 *      host switched logging on, filtered by its categories), and returns at least fmi2Error or
 *      fmi2Fatal from a call during which the model logged that status.
 *
 * If no libpython can be loaded, fmi2Instantiate logs what it tried and how to fix it and
 * returns NULL.  Neither library is ever unloaded: a Python interpreter cannot be finalised and
 * started again reliably within one process.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#ifndef DRIFTFMU_BUILD_LIBPYTHON
#define DRIFTFMU_BUILD_LIBPYTHON "libpython3.so"
#endif

#define INNER_SUFFIX "_pythonfmu.so"
#define ERROR_SIZE 4096

/* Every function of pythonfmu's library that the shim forwards to. */
#define FORWARDED(X)                                                                         \
    X(SetDebugLogging) X(Instantiate) X(FreeInstance) X(SetupExperiment)                     \
    X(EnterInitializationMode) X(ExitInitializationMode) X(Terminate) X(Reset)               \
    X(GetReal) X(GetInteger) X(GetBoolean) X(GetString)                                      \
    X(SetReal) X(SetInteger) X(SetBoolean) X(SetString)                                      \
    X(GetFMUstate) X(SetFMUstate) X(FreeFMUstate) X(SerializedFMUstateSize)                  \
    X(SerializeFMUstate) X(DeSerializeFMUstate) X(GetDirectionalDerivative)                  \
    X(SetRealInputDerivatives) X(GetRealOutputDerivatives) X(DoStep) X(CancelStep)           \
    X(GetStatus) X(GetRealStatus) X(GetIntegerStatus) X(GetBooleanStatus) X(GetStringStatus)

static struct {
#define DECLARE(name) fmi2##name##TYPE *name;
    FORWARDED(DECLARE)
#undef DECLARE
} inner;

static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;
static int loaded = 0;

/*
 * pythonfmu's library keeps its interpreter guard in a global std::shared_ptr and resets it
 * again from an __attribute__((destructor)).  At process exit the shared_ptr's own destructor
 * (an atexit handler) runs first, and the later reset releases the freed control block a second
 * time: a heap corruption that glibc reports as "corrupted double-linked list" (or not at all).
 * The shim registers, after loading that library, an exit handler that calls its exported
 * finalizePythonInterpreter() first: exit handlers run in reverse order of registration, so the
 * guard is released once, properly, and both later resets find it empty.
 */
static void (*inner_finalize)(void);

static void finalize_inner_at_exit(void)
{
    if (inner_finalize)
        inner_finalize();
}

/* One model instance: pythonfmu's component and what the shim needs to filter its messages. */
typedef struct {
    fmi2Component inner;
    fmi2CallbackFunctions host;     /* the host's callbacks, copied */
    fmi2CallbackFunctions to_inner; /* the host's, with the logger replaced by shim_logger */
    char *name;
    fmi2Boolean logging_on;
    size_t n_categories;
    char **categories;
    fmi2Status worst; /* worst of error and fatal logged during the current call */
} Instance;

/* Append a formatted line to the error text err (ERROR_SIZE bytes). */
static void append(char *err, const char *fmt, ...)
{
    size_t used = strlen(err);
    if (used + 1 >= ERROR_SIZE)
        return;
    va_list args;
    va_start(args, fmt);
    vsnprintf(err + used, ERROR_SIZE - used, fmt, args);
    va_end(args);
}

/* Try one libpython candidate; on failure add why to err. */
static int try_libpython(const char *path, char *err)
{
    if (dlopen(path, RTLD_NOW | RTLD_GLOBAL))
        return 1;
    const char *why = dlerror();
    append(err, "\n  %s", why ? why : path);
    return 0;
}

/*
 * Load a libpython unless the process has one.  On failure err says what was tried and how to
 * fix it; when $DRIFTFMU_LIBPYTHON failed but another libpython loaded, note says so.
 */
static int load_libpython(char *err, char *note)
{
    if (dlsym(RTLD_DEFAULT, "Py_IsInitialized"))
        return 1; /* a Python host, or libpython already loaded */
    append(err, "no Python in this process; tried to load libpython:");
    const char *explicit_path = getenv("DRIFTFMU_LIBPYTHON");
    int explicit_failed = 0;
    if (explicit_path && *explicit_path) {
        if (try_libpython(explicit_path, err))
            return 1;
        explicit_failed = 1;
    }
    char candidates[8][32];
    int n = 0;
    snprintf(candidates[n++], sizeof candidates[0], "%s", DRIFTFMU_BUILD_LIBPYTHON);
    for (int minor = 13; minor >= 8; minor--) {
        snprintf(candidates[n], sizeof candidates[0], "libpython3.%d.so.1.0", minor);
        if (strcmp(candidates[n], DRIFTFMU_BUILD_LIBPYTHON))
            n++;
    }
    snprintf(candidates[n++], sizeof candidates[0], "libpython3.so");
    for (int i = 0; i < n; i++) {
        if (try_libpython(candidates[i], err)) {
            if (explicit_failed)
                snprintf(note, ERROR_SIZE, "driftfmu: DRIFTFMU_LIBPYTHON=%s could not be "
                         "loaded; using %s instead", explicit_path, candidates[i]);
            return 1;
        }
    }
    append(err, "\n"
           "Set DRIFTFMU_LIBPYTHON to the full path of a libpython3.X.so.1.0, or add the "
           "directory that holds it to the library path (LD_LIBRARY_PATH or ldconfig); "
           "python3 -c \"import sysconfig; print(sysconfig.get_config_var('LIBDIR'))\" "
           "prints it for an installed Python.");
    return 0;
}

/* dlopen <dir of this file>/<stem>_pythonfmu.so and look up the forwarded functions. */
static int load_inner(char *err)
{
    Dl_info info;
    if (!dladdr((void *)&load_inner, &info) || !info.dli_fname) {
        append(err, "cannot find the path of the FMU's own binary");
        return 0;
    }
    const char *self = info.dli_fname;
    size_t stem = strlen(self);
    if (stem > 3 && !strcmp(self + stem - 3, ".so"))
        stem -= 3;
    char *path = malloc(stem + sizeof INNER_SUFFIX);
    if (!path) {
        append(err, "out of memory");
        return 0;
    }
    memcpy(path, self, stem);
    strcpy(path + stem, INNER_SUFFIX);
    void *handle = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char *why = dlerror();
        append(err, "cannot load pythonfmu's library: %s", why ? why : path);
        free(path);
        return 0;
    }
    free(path);
#define LOOKUP(name)                                                                         \
    inner.name = (fmi2##name##TYPE *)dlsym(handle, "fmi2" #name);                            \
    if (!inner.name) {                                                                       \
        append(err, "pythonfmu's library lacks fmi2" #name);                                 \
        return 0;                                                                            \
    }
    FORWARDED(LOOKUP)
#undef LOOKUP
    inner_finalize = (void (*)(void))dlsym(handle, "finalizePythonInterpreter");
    if (inner_finalize)
        atexit(finalize_inner_at_exit);
    /* Stay loaded until exit, like pythonfmu's library: the exit handler lives in this file. */
    dlopen(self, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
    return 1;
}

static int ensure_loaded(char *err, char *note)
{
    pthread_mutex_lock(&load_lock);
    if (!loaded)
        loaded = load_libpython(err, note) && load_inner(err);
    int ok = loaded;
    pthread_mutex_unlock(&load_lock);
    return ok;
}

static const char *status_category(fmi2Status status)
{
    switch (status) {
    case fmi2Warning: return "logStatusWarning";
    case fmi2Discard: return "logStatusDiscard";
    case fmi2Error: return "logStatusError";
    case fmi2Fatal: return "logStatusFatal";
    default: return "logAll";
    }
}

/* Pass a plain-text message to the host; '%' is escaped because the host treats it as a format. */
static void to_host(Instance *inst, fmi2Status status, const char *category, const char *message)
{
    if (!inst->host.logger)
        return;
    size_t n = strlen(message);
    char *escaped = malloc(2 * n + 1);
    if (!escaped)
        return;
    char *out = escaped;
    for (const char *p = message; *p; p++) {
        if (*p == '%')
            *out++ = '%';
        *out++ = *p;
    }
    *out = '\0';
    inst->host.logger(inst->host.componentEnvironment, inst->name, status,
                      category ? category : status_category(status), escaped);
    free(escaped);
}

static int wanted(const Instance *inst, fmi2Status status, const char *category)
{
    if (status == fmi2Warning || status == fmi2Error || status == fmi2Fatal)
        return 1;
    if (!inst->logging_on)
        return 0;
    if (inst->n_categories == 0)
        return 1;
    for (size_t i = 0; i < inst->n_categories; i++)
        if (category && !strcmp(category, inst->categories[i]))
            return 1;
    return 0;
}

/* The logger pythonfmu calls; its messages come without format arguments. */
static void shim_logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                        fmi2String category, fmi2String message, ...)
{
    (void)name;
    Instance *inst = (Instance *)env;
    if ((status == fmi2Error || status == fmi2Fatal) && status > inst->worst)
        inst->worst = status;
    if (message && wanted(inst, status, category))
        to_host(inst, status, category, message);
}

static void free_categories(Instance *inst)
{
    for (size_t i = 0; i < inst->n_categories; i++)
        free(inst->categories[i]);
    free(inst->categories);
    inst->categories = NULL;
    inst->n_categories = 0;
}

static void free_instance(Instance *inst)
{
    free_categories(inst);
    free(inst->name);
    free(inst);
}

static fmi2Status merged(Instance *inst, fmi2Status status)
{
    return (inst->worst > status && status != fmi2Pending) ? inst->worst : status;
}

/* Forward a call that returns fmi2Status, raising the status to what the model logged. */
#define FORWARD(c, name, ...)                                                                \
    Instance *inst = (Instance *)(c);                                                        \
    if (!inst)                                                                               \
        return fmi2Error;                                                                    \
    inst->worst = fmi2OK;                                                                    \
    return merged(inst, inner.name(inst->inner, __VA_ARGS__))

#define FORWARD0(c, name)                                                                    \
    Instance *inst = (Instance *)(c);                                                        \
    if (!inst)                                                                               \
        return fmi2Error;                                                                    \
    inst->worst = fmi2OK;                                                                    \
    return merged(inst, inner.name(inst->inner))

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    if (!functions)
        return NULL;
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst)
        return NULL;
    inst->host = *functions;
    inst->name = strdup(instanceName ? instanceName : "");
    inst->logging_on = loggingOn;
    char err[ERROR_SIZE] = "", note[ERROR_SIZE] = "";
    if (!inst->name || !ensure_loaded(err, note)) {
        char message[ERROR_SIZE + 128];
        snprintf(message, sizeof message, "driftfmu: cannot start the FMU's Python: %s",
                 inst->name ? err : "out of memory");
        to_host(inst, fmi2Error, "logStatusError", message);
        free_instance(inst);
        return NULL;
    }
    if (*note)
        to_host(inst, fmi2Warning, "logStatusWarning", note);
    inst->to_inner = inst->host;
    inst->to_inner.logger = shim_logger;
    inst->to_inner.componentEnvironment = inst;
    inst->inner = inner.Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation,
                                    &inst->to_inner, visible, fmi2True);
    if (!inst->inner) {
        free_instance(inst);
        return NULL;
    }
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst)
        return;
    inner.FreeInstance(inst->inner);
    free_instance(inst);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    Instance *inst = (Instance *)c;
    if (!inst)
        return fmi2Error;
    free_categories(inst);
    inst->logging_on = loggingOn;
    if (nCategories > 0) {
        inst->categories = calloc(nCategories, sizeof *inst->categories);
        if (!inst->categories)
            return fmi2Error;
        for (size_t i = 0; i < nCategories; i++) {
            inst->categories[i] = strdup(categories[i] ? categories[i] : "");
            if (!inst->categories[i])
                return fmi2Error;
            inst->n_categories = i + 1;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    FORWARD(c, SetupExperiment, toleranceDefined, tolerance, startTime, stopTimeDefined,
            stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { FORWARD0(c, EnterInitializationMode); }

fmi2Status fmi2ExitInitializationMode(fmi2Component c) { FORWARD0(c, ExitInitializationMode); }

fmi2Status fmi2Terminate(fmi2Component c) { FORWARD0(c, Terminate); }

fmi2Status fmi2Reset(fmi2Component c) { FORWARD0(c, Reset); }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    FORWARD(c, GetReal, vr, nvr, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[])
{
    FORWARD(c, GetInteger, vr, nvr, value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[])
{
    FORWARD(c, GetBoolean, vr, nvr, value);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[])
{
    FORWARD(c, GetString, vr, nvr, value);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    FORWARD(c, SetReal, vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    FORWARD(c, SetInteger, vr, nvr, value);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    FORWARD(c, SetBoolean, vr, nvr, value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[])
{
    FORWARD(c, SetString, vr, nvr, value);
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    FORWARD(c, GetFMUstate, state);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    FORWARD(c, SetFMUstate, state);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    FORWARD(c, FreeFMUstate, state);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    FORWARD(c, SerializedFMUstateSize, state, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte serializedState[],
                                 size_t size)
{
    FORWARD(c, SerializeFMUstate, state, serializedState, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *state)
{
    FORWARD(c, DeSerializeFMUstate, serializedState, size, state);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[])
{
    FORWARD(c, GetDirectionalDerivative, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown,
            dvUnknown);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[])
{
    FORWARD(c, SetRealInputDerivatives, vr, nvr, order, value);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[], fmi2Real value[])
{
    FORWARD(c, GetRealOutputDerivatives, vr, nvr, order, value);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    FORWARD(c, DoStep, currentCommunicationPoint, communicationStepSize,
            noSetFMUStatePriorToCurrentPoint);
}

fmi2Status fmi2CancelStep(fmi2Component c) { FORWARD0(c, CancelStep); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    FORWARD(c, GetStatus, s, value);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    FORWARD(c, GetRealStatus, s, value);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    FORWARD(c, GetIntegerStatus, s, value);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    FORWARD(c, GetBooleanStatus, s, value);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    FORWARD(c, GetStringStatus, s, value);
}
