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
 *   4. checks every call before pythonfmu sees it, and answers fmi2Error (NULL from
 *      fmi2Instantiate) with a log line naming what was given and what is allowed: the
 *      resource location (every file URI form FMI 2.0 allows, decoded here, since pythonfmu
 *      0.7.0 strips only "file://" and decodes only "%20", and crashes on a folder it cannot
 *      find), the GUID and the fmuType, the FMI 2.0 state machine, NULL pointers, counts no
 *      array can have, value references pythonfmu would pass on as negative numbers, FMU
 *      states that are not the calling instance's.  It answers the status inquiries itself,
 *      hands the model fmi2SetupExperiment's stop time (pythonfmu passes the start time only),
 *      has the model check a deserialised state before handing it out, and frees an
 *      instance's states with it;
 *   5. keeps freed instances, reset, for the next fmi2Instantiate of the same name (pythonfmu
 *      leaks about 1 kB for every instance it creates).
 *
 * If no libpython can be loaded, fmi2Instantiate logs what it tried and how to fix it and
 * returns NULL.  Neither library is ever unloaded: a Python interpreter cannot be finalised and
 * started again reliably within one process.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fmi2Functions.h"
#include "state_handles.h" /* fmu_src/native/, shared with the native plumbing */

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

/*
 * The FMI 2.0 co-simulation states the shim tracks (Reference-FMUs' masks).  A call that returned
 * fmi2Error leaves the instance where it was (the model guarantees a rejected call changes
 * nothing); a call that returned fmi2Fatal leaves it in FATAL, where only fmi2FreeInstance is
 * accepted.
 */
enum {
    INSTANTIATED = 1 << 0,
    INITIALIZATION_MODE = 1 << 1,
    STEP_COMPLETE = 1 << 2,
    TERMINATED = 1 << 3,
    FATAL = 1 << 4,
};
#define ANY_STATE (INSTANTIATED | INITIALIZATION_MODE | STEP_COMPLETE | TERMINATED)
#define GETTABLE (INITIALIZATION_MODE | STEP_COMPLETE | TERMINATED)
#define SETTABLE (INSTANTIATED | INITIALIZATION_MODE | STEP_COMPLETE)

/* One model instance: pythonfmu's component and what the shim needs to filter its messages. */
typedef struct Instance {
    fmi2Component inner;
    fmi2CallbackFunctions host;     /* the host's callbacks, copied */
    fmi2CallbackFunctions to_inner; /* the host's, with the logger replaced by shim_logger */
    char *name;
    fmi2Boolean logging_on;
    size_t n_categories;
    char **categories;
    fmi2Status worst; /* worst of error and fatal logged during the current call */
    int state;        /* one of the states above */
    char guid[128];   /* the FMU's GUID, checked at instantiation */
    int speaks;       /* the model understands SHIM_VR (the build record says so) */
    double start_time, time; /* from fmi2SetupExperiment; the end of the last accepted step */
    double elapsed, elapsed_c; /* time - start_time as the model keeps it: Neumaier's sum of the
                                  accepted step sizes (time = start_time + (elapsed + c)) */
    char *location;   /* the resource location pythonfmu got */
    fmi2Boolean visible;
    struct Instance *next_free; /* in the pool of freed instances */
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
    void *handle = dlopen(path, RTLD_NOW | RTLD_GLOBAL);
    if (!handle) {
        const char *why = dlerror();
        append(err, "\n  %s", why ? why : path);
        return 0;
    }
    if (!dlsym(handle, "Py_IsInitialized")) {
        append(err, "\n  %s: loads, but is not a libpython (it has no Py_IsInitialized)", path);
        dlclose(handle);
        return 0;
    }
    return 1;
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
    size_t explicit_at = strlen(err), explicit_end = explicit_at;
    if (explicit_path && *explicit_path) {
        if (try_libpython(explicit_path, err))
            return 1;
        explicit_failed = 1;
        explicit_end = strlen(err);
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
            if (explicit_failed) { /* its reason, without the list's line break */
                size_t skip = explicit_end - explicit_at > 3 ? 3 : 0;
                snprintf(note, ERROR_SIZE, "driftfmu: DRIFTFMU_LIBPYTHON=%s is not a usable "
                         "libpython (%.*s); using %s instead", explicit_path,
                         (int)(explicit_end - explicit_at - skip), err + explicit_at + skip,
                         candidates[i]);
            }
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
    if (status == fmi2Warning || status == fmi2Discard || status == fmi2Error ||
        status == fmi2Fatal)
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
    free(inst->location);
    free(inst);
}

static fmi2Status merged(Instance *inst, fmi2Status status)
{
    return (inst->worst > status && status != fmi2Pending) ? inst->worst : status;
}

/* A message of the shim itself, with the instance name in front as the model writes it. */
static void shim_log(Instance *inst, fmi2Status status, const char *fmt, ...)
{
    char message[ERROR_SIZE];
    int n = snprintf(message, sizeof message, "%s: ", inst->name ? inst->name : "");
    if (n < 0 || (size_t)n >= sizeof message)
        n = 0;
    va_list args;
    va_start(args, fmt);
    vsnprintf(message + n, sizeof message - n, fmt, args);
    va_end(args);
    to_host(inst, status, NULL, message);
}

static const char *state_name(int state)
{
    switch (state) {
    case INSTANTIATED: return "Instantiated";
    case INITIALIZATION_MODE: return "Initialization Mode";
    case STEP_COMPLETE: return "Step Complete";
    case TERMINATED: return "Terminated";
    default: return "Fatal";
    }
}

/* 1 if a call allowed in the states `states` may run now; otherwise log why and return 0. */
static int allowed(Instance *inst, const char *function, int states)
{
    if (inst->state & states)
        return 1;
    if (inst->state == FATAL) {
        shim_log(inst, fmi2Error, "%s refused: an earlier call failed with fmi2Fatal; only "
                 "fmi2FreeInstance is allowed now", function);
        return 0;
    }
    char list[256] = "";
    for (int bit = INSTANTIATED; bit <= TERMINATED; bit <<= 1)
        if (states & bit)
            snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", *list ? ", " : "",
                     state_name(bit));
    shim_log(inst, fmi2Error, "%s is not allowed in state %s (FMI 2.0 co-simulation); allowed "
             "in: %s", function, state_name(inst->state), list);
    return 0;
}

static fmi2Status after(Instance *inst, fmi2Status status)
{
    if (status == fmi2Fatal)
        inst->state = FATAL;
    return status;
}

/* The call's instance, or return fmi2Error from the function when it is NULL or not allowed. */
#define INSTANCE(c, function, states)                                                        \
    Instance *inst = (Instance *)(c);                                                        \
    if (!inst) {                                                                             \
        fprintf(stderr, "driftfmu: %s called with a NULL fmi2Component\n", function);       \
        return fmi2Error;                                                                    \
    }                                                                                        \
    if (!allowed(inst, function, states))                                                    \
        return fmi2Error

/*
 * One Python thread state per host thread, kept.  pythonfmu 0.7.0 starts Python in a thread of
 * its own (PyState's worker) and wraps every call in PyGILState_Ensure/Release.  A host thread
 * Python has never seen (any C host) has no thread state, so every call created one (with an
 * mmap'ed frame stack) and destroyed it again: about 10 us per FMI call, most of the C host's
 * step.  The first call of a thread once Python runs takes a thread state for that thread and
 * keeps it (PyGILState_Ensure, then PyEval_SaveThread: the GIL is released, the state stays);
 * pythonfmu's Ensure/Release then only take and release the GIL, as in a Python host.  A thread
 * Python knows already (fmpy's) is left alone.  When the thread ends, its state is cleared and
 * deleted under the GIL (not with PyGILState_Release: the C library may have cleared Python's
 * own thread-specific slot already by then).
 */
typedef int py_gil_state; /* PyGILState_STATE, an enum */
static struct {
    int (*is_initialized)(void);
    void *(*this_thread_state)(void);
    py_gil_state (*ensure)(void);
    void *(*save_thread)(void);
    void (*restore_thread)(void *);
    void (*clear)(void *);
    void (*delete_current)(void);
} py;
static pthread_once_t py_once = PTHREAD_ONCE_INIT;
static pthread_key_t pinned_key;
static __thread int pinned;

static void unpin_thread_state(void *tstate)
{
    if (py.is_initialized()) {
        py.restore_thread(tstate);
        py.clear(tstate);
        py.delete_current(); /* and releases the GIL */
    }
}

static void resolve_python(void)
{
    py.is_initialized = (int (*)(void))dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    py.this_thread_state = (void *(*)(void))dlsym(RTLD_DEFAULT, "PyGILState_GetThisThreadState");
    py.ensure = (py_gil_state (*)(void))dlsym(RTLD_DEFAULT, "PyGILState_Ensure");
    py.save_thread = (void *(*)(void))dlsym(RTLD_DEFAULT, "PyEval_SaveThread");
    py.restore_thread = (void (*)(void *))dlsym(RTLD_DEFAULT, "PyEval_RestoreThread");
    py.clear = (void (*)(void *))dlsym(RTLD_DEFAULT, "PyThreadState_Clear");
    py.delete_current = (void (*)(void))dlsym(RTLD_DEFAULT, "PyThreadState_DeleteCurrent");
    if (!(py.is_initialized && py.this_thread_state && py.ensure && py.save_thread &&
          py.restore_thread && py.clear && py.delete_current) ||
        pthread_key_create(&pinned_key, unpin_thread_state))
        py.is_initialized = NULL; /* not found: every call keeps pythonfmu's own way */
}

static void pin_thread_state(void)
{
    if (pinned)
        return;
    pthread_once(&py_once, resolve_python);
    if (!py.is_initialized) {
        pinned = 1;
        return;
    }
    if (!py.is_initialized())
        return; /* before pythonfmu started Python: the next call pins */
    pinned = 1;
    if (py.this_thread_state())
        return;
    py.ensure();
    pthread_setspecific(pinned_key, py.save_thread());
}

/* Forward to pythonfmu, raising the status to what the model logged. */
#define CALL(expr) (pin_thread_state(), inst->worst = fmi2OK, after(inst, merged(inst, (expr))))

static int null_argument(Instance *inst, const char *function, const char *name, const void *p)
{
    if (p)
        return 0;
    shim_log(inst, fmi2Error, "%s: %s is NULL; allowed: a valid pointer", function, name);
    return 1;
}

/* 1 (logged) if an array of n > 0 elements is NULL. */
static int null_count_array(Instance *inst, const char *function, const char *name,
                            const char *count, size_t n, const void *p)
{
    if (n == 0 || p)
        return 0;
    shim_log(inst, fmi2Error, "%s: %s is NULL with %s = %zu; allowed: an array of %s "
             "elements (or %s = 0)", function, name, count, n, count, count);
    return 1;
}

static int null_array(Instance *inst, const char *function, const char *name, size_t n,
                      const void *p)
{
    return null_count_array(inst, function, name, "nvr", n, p);
}

/*
 * The value reference through which the shim tells the model what pythonfmu 0.7.0 does not pass
 * on (slave_base.SHIM_VR; no variable has it): set to [startTime, stopTimeDefined, stopTime] it
 * is fmi2SetupExperiment (pythonfmu passes the model the start time only); set to [1] it makes
 * the next fmi2SetFMUstate the check of a state fresh from fmi2DeSerializeFMUstate.
 */
#define SHIM_VR 0x7fffffffu

/*
 * 1 (logged) if a value reference cannot be one of this FMU's.  pythonfmu passes value
 * references to Python as signed ints, so 2^31 and above would reach the model as negative
 * numbers; the shim refuses them itself and prints them unsigned, and SHIM_VR too.
 */
static int bad_references(Instance *inst, const char *function, const fmi2ValueReference vr[],
                          size_t nvr)
{
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= SHIM_VR) {
            shim_log(inst, fmi2Error, "%s: value reference %u does not exist; the model "
                     "description lists the value references of this FMU", function,
                     (unsigned)vr[i]);
            return 1;
        }
    }
    return 0;
}

/*
 * The count rule: a get or set names at most MAX_VALUES_PER_CALL value references (as the native
 * FMUs, cosimulation.h).  A larger count cannot be a list of this FMU's variables; it is refused
 * before any element of the host's arrays is read (pythonfmu would read nvr of each, and the
 * shim's own checks too: SIZE_MAX or 2^31 with a short array reads past it).  A count within
 * the bound is taken at its word: only the host knows its arrays.
 */
#define MAX_VALUES_PER_CALL 65536u

static int too_many(Instance *inst, const char *function, const char *what, size_t n)
{
    if (n <= MAX_VALUES_PER_CALL)
        return 0;
    shim_log(inst, fmi2Error, "%s: %s = %zu; allowed: at most %u per call (a larger count "
             "cannot list this FMU's variables); nothing was read and nothing was changed",
             function, what, n, MAX_VALUES_PER_CALL);
    return 1;
}

#define CHECK_ARRAYS(function, vr, nvr, value)                                               \
    if (too_many(inst, function, "nvr", nvr) || null_array(inst, function, "vr", nvr, vr) ||  \
        null_array(inst, function, "value", nvr, value) ||                                   \
        bad_references(inst, function, vr, nvr))                                             \
    return fmi2Error

/* -- the resource location ----------------------------------------------------------------- */

#define ALLOWED_LOCATIONS                                                                    \
    "allowed: a file URI of this FMU's resources folder (file:///abs/path, file:/abs/path or " \
    "file://localhost/abs/path, percent-encoded as RFC 3986 allows) or an absolute path"

static int hex_digit(int c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

/* The percent-decoded copy of s (malloc'd), or NULL for a malformed escape or %00. */
static char *percent_decoded(const char *s)
{
    char *out = malloc(strlen(s) + 1), *o = out;
    if (!out)
        return NULL;
    for (const char *p = s; *p; p++) {
        if (*p != '%') {
            *o++ = *p;
            continue;
        }
        int hi = hex_digit((unsigned char)p[1]), lo = hi < 0 ? -1 : hex_digit((unsigned char)p[2]);
        if (lo < 0 || (hi == 0 && lo == 0)) {
            free(out);
            return NULL;
        }
        *o++ = (char)(hi * 16 + lo);
        p += 2;
    }
    *o = '\0';
    return out;
}

static int is_directory(const char *path)
{
    struct stat st;
    return path && stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

static void strip_trailing_slashes(char *path)
{
    size_t n = strlen(path);
    while (n > 1 && path[n - 1] == '/')
        path[--n] = '\0';
}

/*
 * The absolute folder a resource location names (malloc'd), or NULL with the reason in why.
 * Accepted: file:///abs, file:/abs, file://localhost/abs (scheme and host case-insensitive),
 * percent-decoded; a plain absolute path as some hosts pass it.  When the decoded folder does
 * not exist but the undecoded one does (a host that did not encode a '%'), that one is used.
 */
static char *resource_folder(const char *location, char *why)
{
    if (!location) {
        snprintf(why, ERROR_SIZE, "fmuResourceLocation is NULL; " ALLOWED_LOCATIONS);
        return NULL;
    }
    const char *path = NULL;
    char *decoded = NULL;
    if (location[0] == '/') {
        path = location;
    } else if (!strncasecmp(location, "file:", 5)) {
        const char *rest = location + 5;
        if (rest[0] == '/' && rest[1] == '/') {
            const char *authority = rest + 2, *slash = strchr(authority, '/');
            size_t n = slash ? (size_t)(slash - authority) : strlen(authority);
            if (!slash || !(n == 0 || (n == 9 && !strncasecmp(authority, "localhost", 9)))) {
                snprintf(why, ERROR_SIZE, "fmuResourceLocation \"%s\" names %s; "
                         ALLOWED_LOCATIONS, location,
                         slash ? "a file on another host" : "no absolute path");
                return NULL;
            }
            path = slash;
        } else if (rest[0] == '/') {
            path = rest;
        } else {
            snprintf(why, ERROR_SIZE, "fmuResourceLocation \"%s\" is a relative file URI; "
                     ALLOWED_LOCATIONS, location);
            return NULL;
        }
        decoded = percent_decoded(path);
    } else {
        snprintf(why, ERROR_SIZE, "fmuResourceLocation \"%s\" is neither a file URI nor an "
                 "absolute path; " ALLOWED_LOCATIONS, location);
        return NULL;
    }
    char *folder = NULL;
    if (decoded && is_directory(decoded)) {
        folder = decoded;
        decoded = NULL;
    } else if (is_directory(path)) {
        folder = strdup(path);
    }
    free(decoded);
    if (!folder) {
        snprintf(why, ERROR_SIZE, "fmuResourceLocation \"%s\": no such folder; " ALLOWED_LOCATIONS,
                 location);
        return NULL;
    }
    strip_trailing_slashes(folder);
    return folder;
}

/* Read the first n - 1 bytes of a file as a string; 0 if it cannot be read. */
static int read_text(const char *path, char *text, size_t n)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0;
    size_t got = fread(text, 1, n - 1, f);
    text[got] = '\0';
    fclose(f);
    return 1;
}

/* Copy the value after `key` up to `end` in text into out (n bytes); 0 if not found. */
static int value_after(const char *text, const char *key, char end, char *out, size_t n)
{
    const char *p = strstr(text, key);
    if (!p)
        return 0;
    p += strlen(key);
    const char *q = strchr(p, end);
    if (!q || (size_t)(q - p) >= n)
        return 0;
    memcpy(out, p, q - p);
    out[q - p] = '\0';
    return 1;
}

/*
 * The FMU's GUID: from resources/driftfmu_build.json (the builder writes it there), else from
 * the modelDescription.xml beside the resources folder.  *speaks: the build record says that
 * the model understands SHIM_VR (a driftfmu slave: "shim_vr": true).
 */
static int fmu_guid(const char *folder, char *guid, size_t n, int *speaks)
{
    size_t len = strlen(folder) + 64;
    char *path = malloc(len), *text = malloc(1 << 16);
    int found = 0;
    *speaks = 0;
    if (path && text) {
        snprintf(path, len, "%s/driftfmu_build.json", folder);
        found = read_text(path, text, 1 << 16) && value_after(text, "\"guid\": \"", '"', guid, n);
        *speaks = found && strstr(text, "\"shim_vr\": true") != NULL;
        if (!found) {
            snprintf(path, len, "%s/../modelDescription.xml", folder);
            found = read_text(path, text, 1 << 16) && value_after(text, " guid=\"", '"', guid, n);
        }
    }
    free(path);
    free(text);
    return found;
}

static int valid_utf8(const unsigned char *s)
{
    while (*s) {
        int extra = *s < 0x80 ? 0 : (*s >> 5) == 6 ? 1 : (*s >> 4) == 14 ? 2 : (*s >> 3) == 30 ? 3
                                                                                          : -1;
        if (extra < 0)
            return 0;
        s++;
        for (int i = 0; i < extra; i++, s++)
            if ((*s >> 6) != 2)
                return 0;
    }
    return 1;
}

/*
 * pythonfmu 0.7.0 turns every "%20" of the location into a space and hands the path to Python
 * as UTF-8.  A folder whose name has "%20" in it, or is not UTF-8, is therefore reached through
 * a symbolic link in a private temporary folder of this process (one per folder, removed at
 * exit).
 */
#define MAX_ALIASES 256
static pthread_mutex_t alias_lock = PTHREAD_MUTEX_INITIALIZER;
static char alias_root[4096];
static char *alias_of[MAX_ALIASES][2]; /* folder, link */
static int n_aliases;

static void remove_aliases(void)
{
    for (int i = 0; i < n_aliases; i++)
        unlink(alias_of[i][1]);
    if (*alias_root)
        rmdir(alias_root);
}

static int safe_for_pythonfmu(const char *path)
{
    return !strstr(path, "%20") && valid_utf8((const unsigned char *)path);
}

/* The path to hand to pythonfmu for folder (malloc'd "file://..."), or NULL with why. */
static char *pythonfmu_location(const char *folder, char *why)
{
    const char *path = folder;
    char *location = NULL;
    pthread_mutex_lock(&alias_lock);
    if (!safe_for_pythonfmu(folder)) {
        path = NULL;
        for (int i = 0; i < n_aliases && !path; i++)
            if (!strcmp(alias_of[i][0], folder))
                path = alias_of[i][1];
        if (!path && !*alias_root) {
            const char *tmp = getenv("TMPDIR");
            if (!tmp || tmp[0] != '/' || !safe_for_pythonfmu(tmp) || strlen(tmp) > 4000)
                tmp = "/tmp";
            snprintf(alias_root, sizeof alias_root, "%s/driftfmu-XXXXXX", tmp);
            if (mkdtemp(alias_root))
                atexit(remove_aliases);
            else
                *alias_root = '\0';
        }
        if (!path && *alias_root && n_aliases < MAX_ALIASES) {
            char link[4200];
            snprintf(link, sizeof link, "%s/r%d", alias_root, n_aliases);
            char *f = strdup(folder), *l = strdup(link);
            if (f && l && symlink(folder, link) == 0) {
                alias_of[n_aliases][0] = f;
                alias_of[n_aliases][1] = l;
                path = alias_of[n_aliases++][1];
            } else {
                free(f);
                free(l);
            }
        }
    }
    if (path) {
        location = malloc(strlen(path) + 8);
        if (location)
            sprintf(location, "file://%s", path);
    }
    pthread_mutex_unlock(&alias_lock);
    if (!location)
        snprintf(why, ERROR_SIZE, "the resources folder \"%s\" has a name pythonfmu cannot "
                 "read (\"%%20\" or not UTF-8) and no link to it could be made in the temporary "
                 "folder (TMPDIR or /tmp)", folder);
    return location;
}

/* -- the pool of freed instances ---------------------------------------------------------- */

/*
 * Creating a pythonfmu 0.7.0 instance leaks about 1 kB that nothing outside pythonfmu can free
 * (a copy of the resources path, the slave class's mro() list and the str() of every class in
 * it, made and dropped inside its fmi2Instantiate).  fmi2FreeInstance therefore resets the
 * instance (pythonfmu's fmi2Reset makes a fresh Python slave object) and keeps up to POOL_SIZE
 * of them; an fmi2Instantiate with the same instance name, resources and visibility gets one
 * back, in the state a new instance has, without a new pythonfmu instance.
 */
#define POOL_SIZE 8
static pthread_mutex_t pool_lock = PTHREAD_MUTEX_INITIALIZER;
static Instance *pool;
static int pooled;

static Instance *from_pool(const char *name, const char *location, fmi2Boolean visible)
{
    Instance *found = NULL;
    pthread_mutex_lock(&pool_lock);
    for (Instance **p = &pool; *p; p = &(*p)->next_free) {
        Instance *i = *p;
        if (!strcmp(i->name, name) && !strcmp(i->location, location) &&
            !i->visible == !visible) {
            *p = i->next_free;
            i->next_free = NULL;
            pooled--;
            found = i;
            break;
        }
    }
    pthread_mutex_unlock(&pool_lock);
    return found;
}

/* Reset inst and keep it for a later fmi2Instantiate; 0 when it cannot be kept. */
static int to_pool(Instance *inst)
{
    pthread_mutex_lock(&pool_lock);
    int room = pooled < POOL_SIZE;
    pthread_mutex_unlock(&pool_lock);
    if (!room || !inst->location)
        return 0;
    inst->host.logger = NULL; /* the host is gone: nothing it gave may be called */
    inst->logging_on = fmi2False;
    free_categories(inst);
    if (CALL(inner.Reset(inst->inner)) > fmi2Warning)
        return 0;
    pthread_mutex_lock(&pool_lock);
    inst->next_free = pool;
    pool = inst;
    pooled++;
    pthread_mutex_unlock(&pool_lock);
    return 1;
}

/* -- instantiation ------------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

/* Check what the host passed; the location to give pythonfmu, or NULL after logging why. */
static char *checked_arguments(Instance *inst, fmi2String instanceName, fmi2Type fmuType,
                               fmi2String fmuGUID, fmi2String fmuResourceLocation)
{
    char why[ERROR_SIZE] = "";
    char *folder = NULL, *location = NULL;
    if (!instanceName || !*instanceName) {
        snprintf(why, sizeof why, "instanceName is %s; allowed: a non-empty string",
                 instanceName ? "empty" : "NULL");
    } else if (fmuType != fmi2CoSimulation) {
        snprintf(why, sizeof why, "fmuType = %d (%s) is not supported; allowed: "
                 "fmi2CoSimulation (%d): this FMU implements co-simulation only", (int)fmuType,
                 fmuType == fmi2ModelExchange ? "fmi2ModelExchange" : "unknown",
                 (int)fmi2CoSimulation);
    } else if ((folder = resource_folder(fmuResourceLocation, why))) {
        size_t n = strlen(folder) + 32;
        char *marker = malloc(n), guid[128];
        if (marker)
            snprintf(marker, n, "%s/slavemodule.txt", folder);
        if (!marker || access(marker, R_OK) != 0) {
            snprintf(why, sizeof why, "fmuResourceLocation \"%s\" is the folder \"%s\", which is "
                     "not the resources folder of this FMU (it has no slavemodule.txt); "
                     ALLOWED_LOCATIONS, fmuResourceLocation, folder);
        } else if (!fmu_guid(folder, guid, sizeof guid, &inst->speaks)) {
            snprintf(why, sizeof why, "cannot read this FMU's GUID from %s/driftfmu_build.json "
                     "or %s/../modelDescription.xml", folder, folder);
        } else if (!fmuGUID || strcmp(fmuGUID, guid)) {
            snprintf(why, sizeof why, "fmuGUID %s%s%s does not match this FMU; allowed: the "
                     "guid of its modelDescription.xml, %s", fmuGUID ? "\"" : "",
                     fmuGUID ? fmuGUID : "NULL", fmuGUID ? "\"" : "", guid);
        } else {
            snprintf(inst->guid, sizeof inst->guid, "%s", guid);
            location = pythonfmu_location(folder, why);
        }
        free(marker);
    }
    free(folder);
    if (!location)
        shim_log(inst, fmi2Error, "fmi2Instantiate: %s", why);
    return location;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    if (!functions) {
        fprintf(stderr, "driftfmu: fmi2Instantiate: functions is NULL; allowed: the host's "
                "fmi2CallbackFunctions\n");
        return NULL;
    }
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst)
        return NULL;
    inst->host = *functions;
    inst->name = strdup(instanceName ? instanceName : "");
    inst->logging_on = loggingOn;
    inst->state = INSTANTIATED;
    if (!inst->name) {
        free_instance(inst);
        return NULL;
    }
    char *location = checked_arguments(inst, instanceName, fmuType, fmuGUID,
                                       fmuResourceLocation);
    if (!location) {
        free_instance(inst);
        return NULL;
    }
    char err[ERROR_SIZE] = "", note[ERROR_SIZE] = "";
    if (!ensure_loaded(err, note)) {
        shim_log(inst, fmi2Error, "driftfmu: cannot start the FMU's Python: %s", err);
        free(location);
        free_instance(inst);
        return NULL;
    }
    if (*note)
        to_host(inst, fmi2Warning, "logStatusWarning", note);
    inst->to_inner = inst->host;
    inst->to_inner.logger = shim_logger;
    inst->to_inner.componentEnvironment = inst;
    if (!inst->to_inner.allocateMemory || !inst->to_inner.freeMemory) {
        inst->to_inner.allocateMemory = calloc;
        inst->to_inner.freeMemory = free;
    }
    Instance *reused = from_pool(inst->name, location, visible);
    if (reused) {
        reused->host = inst->host;
        reused->logging_on = loggingOn;
        reused->state = INSTANTIATED;
        reused->start_time = reused->time = reused->elapsed = reused->elapsed_c = 0.0;
        reused->worst = fmi2OK;
        free(location);
        free_instance(inst);
        return reused;
    }
    inst->location = location;
    inst->visible = visible;
    inst->inner = inner.Instantiate(instanceName, fmuType, fmuGUID, location, &inst->to_inner,
                                    visible, fmi2True);
    if (!inst->inner) {
        free_instance(inst);
        return NULL;
    }
    return inst;
}

static void free_states_of(Instance *inst);

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst)
        return;
    free_states_of(inst); /* every state the instance got or deserialised dies with it */
    if (inst->state != FATAL && to_pool(inst))
        return;
    /* After a fatal error pythonfmu 0.7.0 has released the instance's Python objects already,
       and releasing them again would crash: the instance is left to the process then. */
    if (inst->state != FATAL)
        inner.FreeInstance(inst->inner);
    free_instance(inst);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    INSTANCE(c, "fmi2SetDebugLogging", ANY_STATE);
    if (too_many(inst, "fmi2SetDebugLogging", "nCategories", nCategories) ||
        null_count_array(inst, "fmi2SetDebugLogging", "categories", "nCategories", nCategories,
                         categories))
        return fmi2Error;
    /* the new list is made first: out of memory leaves the old one in place (calloc checks
       nCategories * size for overflow) */
    char **list = nCategories > 0 ? calloc(nCategories, sizeof *list) : NULL;
    for (size_t i = 0; list && i < nCategories; i++) {
        list[i] = strdup(categories[i] ? categories[i] : "");
        if (!list[i]) {
            while (i > 0)
                free(list[--i]);
            free(list);
            list = NULL;
        }
    }
    if (nCategories > 0 && !list) {
        shim_log(inst, fmi2Error, "fmi2SetDebugLogging: out of memory for %zu categories; "
                 "nothing was changed", nCategories);
        return fmi2Error;
    }
    free_categories(inst);
    inst->logging_on = loggingOn;
    inst->categories = list;
    inst->n_categories = nCategories;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    INSTANCE(c, "fmi2SetupExperiment", INSTANTIATED);
    if (!isfinite(startTime)) {
        shim_log(inst, fmi2Error, "fmi2SetupExperiment: startTime = %g; allowed: a finite "
                 "time", startTime);
        return fmi2Error;
    }
    /* a driftfmu model gets the stop time too, checks it and refuses a step past it */
    const fmi2ValueReference vr[3] = {SHIM_VR, SHIM_VR, SHIM_VR};
    const fmi2Real experiment[3] = {startTime, stopTimeDefined ? 1.0 : 0.0,
                                    stopTimeDefined ? stopTime : 0.0};
    fmi2Status status = inst->speaks
        ? CALL(inner.SetReal(inst->inner, vr, 3, experiment))
        : CALL(inner.SetupExperiment(inst->inner, toleranceDefined, tolerance, startTime,
                                     stopTimeDefined, stopTime));
    if (status <= fmi2Warning) {
        inst->start_time = inst->time = startTime;
        inst->elapsed = inst->elapsed_c = 0.0;
    }
    return status;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    INSTANCE(c, "fmi2EnterInitializationMode", INSTANTIATED);
    fmi2Status status = CALL(inner.EnterInitializationMode(inst->inner));
    if (status <= fmi2Warning)
        inst->state = INITIALIZATION_MODE;
    return status;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    INSTANCE(c, "fmi2ExitInitializationMode", INITIALIZATION_MODE);
    fmi2Status status = CALL(inner.ExitInitializationMode(inst->inner));
    if (status <= fmi2Warning) {
        inst->state = STEP_COMPLETE;
        inst->time = inst->start_time;
        inst->elapsed = inst->elapsed_c = 0.0;
    }
    return status;
}

/* Accepted in Step Complete (the standard) and in Initialization Mode (a master that gives up
   after a refused fmi2ExitInitializationMode ends the instance cleanly); refused, as by the
   native FMUs, before initialisation and a second time. */
fmi2Status fmi2Terminate(fmi2Component c)
{
    INSTANCE(c, "fmi2Terminate", INITIALIZATION_MODE | STEP_COMPLETE);
    fmi2Status status = CALL(inner.Terminate(inst->inner));
    if (status <= fmi2Warning)
        inst->state = TERMINATED;
    return status;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    INSTANCE(c, "fmi2Reset", ANY_STATE);
    fmi2Status status = CALL(inner.Reset(inst->inner));
    if (status <= fmi2Warning) {
        inst->state = INSTANTIATED;
        inst->start_time = inst->time = inst->elapsed = inst->elapsed_c = 0.0;
    }
    return status;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    INSTANCE(c, "fmi2GetReal", GETTABLE);
    CHECK_ARRAYS("fmi2GetReal", vr, nvr, value);
    return CALL(inner.GetReal(inst->inner, vr, nvr, value));
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[])
{
    INSTANCE(c, "fmi2GetInteger", GETTABLE);
    CHECK_ARRAYS("fmi2GetInteger", vr, nvr, value);
    return CALL(inner.GetInteger(inst->inner, vr, nvr, value));
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[])
{
    INSTANCE(c, "fmi2GetBoolean", GETTABLE);
    CHECK_ARRAYS("fmi2GetBoolean", vr, nvr, value);
    return CALL(inner.GetBoolean(inst->inner, vr, nvr, value));
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[])
{
    INSTANCE(c, "fmi2GetString", GETTABLE);
    CHECK_ARRAYS("fmi2GetString", vr, nvr, value);
    return CALL(inner.GetString(inst->inner, vr, nvr, value));
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    INSTANCE(c, "fmi2SetReal", SETTABLE);
    CHECK_ARRAYS("fmi2SetReal", vr, nvr, value);
    return CALL(inner.SetReal(inst->inner, vr, nvr, value));
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    INSTANCE(c, "fmi2SetInteger", SETTABLE);
    CHECK_ARRAYS("fmi2SetInteger", vr, nvr, value);
    return CALL(inner.SetInteger(inst->inner, vr, nvr, value));
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    INSTANCE(c, "fmi2SetBoolean", SETTABLE);
    CHECK_ARRAYS("fmi2SetBoolean", vr, nvr, value);
    return CALL(inner.SetBoolean(inst->inner, vr, nvr, value));
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[])
{
    INSTANCE(c, "fmi2SetString", SETTABLE);
    CHECK_ARRAYS("fmi2SetString", vr, nvr, value);
    for (size_t i = 0; i < nvr; i++)
        if (null_argument(inst, "fmi2SetString", "value[i]", value[i]))
            return fmi2Error;
    return CALL(inner.SetString(inst->inner, vr, nvr, value));
}

/* -- FMU states ---------------------------------------------------------------------------- */

/*
 * An FMU state is a shim record around pythonfmu's (a Python object): the model's GUID, the
 * instance that owns it and the instance's FMI state and time go with it.  The host holds a
 * handle, not the record's address: a number the shim issues once (a serial number, with a tag
 * of this loaded copy of the library in the high bits and a bit that makes it a non-canonical
 * address on x86-64), so a freed state's handle never comes back as a live state when memory is
 * reused.  Every live record is listed: a handle that is not a live state of the calling
 * instance (garbage, freed, freed with its instance, another instance's, another FMU's or
 * another loaded copy's) is refused, naming which, without reading anything.  A state belongs
 * to the instance that got or deserialised it, and fmi2FreeInstance frees every state of the
 * instance (FMI 2.0: it frees all memory the FMU's functions allocated).  Serialised, a state
 * is the model's bytes (JSON with the model's name, GUID and version, which the model checks,
 * with every other field, when the bytes are deserialised and again when the state is set).
 */

typedef struct State {
    struct State *next;
    uintptr_t handle;
    const Instance *owner;
    fmi2FMUstate inner;
    char guid[128];
    int state;
    double start_time, time, elapsed, elapsed_c;
} State;

static pthread_mutex_t states_lock = PTHREAD_MUTEX_INITIALIZER;
static State *live_states;
static uint64_t issued; /* handles issued so far (the last serial number) */

/* The live record of handle h, or NULL (the caller holds the lock). */
static State *find_locked(const void *h)
{
    for (State *s = live_states; s; s = s->next)
        if ((const void *)s->handle == h)
            return s;
    return NULL;
}

/* Issue a handle for s, owned by inst, and list it. */
static void add_live(State *s, const Instance *inst)
{
    pthread_mutex_lock(&states_lock);
    issued = state_next_serial(issued);
    s->handle = state_handle(&issued, issued);
    s->owner = inst;
    s->next = live_states;
    live_states = s;
    pthread_mutex_unlock(&states_lock);
}

static void remove_live(State *s)
{
    pthread_mutex_lock(&states_lock);
    for (State **p = &live_states; *p; p = &(*p)->next)
        if (*p == s) {
            *p = s->next;
            break;
        }
    pthread_mutex_unlock(&states_lock);
}

/* Free every state inst owns: pythonfmu's states too while the instance can still free them
   (after an fmi2Fatal pythonfmu's instance is left alone, as fmi2FreeInstance leaves it). */
static void free_states_of(Instance *inst)
{
    State *mine = NULL;
    pthread_mutex_lock(&states_lock);
    for (State **p = &live_states; *p;) {
        State *s = *p;
        if (s->owner == inst) {
            *p = s->next;
            s->next = mine;
            mine = s;
        } else {
            p = &s->next;
        }
    }
    pthread_mutex_unlock(&states_lock);
    while (mine) {
        State *s = mine;
        mine = s->next;
        if (inst->state != FATAL)
            CALL(inner.FreeFMUstate(inst->inner, &s->inner));
        free(s);
    }
}

/* What a handle that is not a live state of inst is: 1 another instance's, 2 issued by this
   library and freed since, 0 anything else (never issued here: garbage, another library's);
   -1 (and *mine set) when it is a live state of inst. */
static int stranger(const Instance *inst, const void *h, State **mine)
{
    pthread_mutex_lock(&states_lock); /* (read under the lock: another instance may free it) */
    State *s = find_locked(h);
    const int owned = s && s->owner == inst;
    const uint64_t last = issued;
    pthread_mutex_unlock(&states_lock);
    *mine = owned ? s : NULL;
    if (s)
        return owned ? -1 : 1;
    return state_issued_here(&issued, h, last) ? 2 : 0;
}

/* The record behind a state the host passed when it is a live state of inst, or NULL
   (logged, naming what the handle is). */
static State *known_state(Instance *inst, const char *function, fmi2FMUstate state)
{
    if (!state) {
        shim_log(inst, fmi2Error, "%s: FMUstate is NULL; allowed: a state from "
                 "fmi2GetFMUstate or fmi2DeSerializeFMUstate of this instance", function);
        return NULL;
    }
    State *s;
    switch (stranger(inst, state, &s)) {
    case -1:
        break;
    case 1:
        shim_log(inst, fmi2Error, "%s: FMUstate %p belongs to another instance of this FMU "
                 "(GUID %s), not to this one: a state is valid only in the instance that made "
                 "it (to move a state between instances, serialise it and deserialise it in "
                 "the other); allowed: a live state of this instance", function, state,
                 inst->guid);
        return NULL;
    case 2:
        shim_log(inst, fmi2Error, "%s: FMUstate %p is freed: by fmi2FreeFMUstate, or with the "
                 "instance that made it (fmi2FreeInstance frees every state of the instance); "
                 "allowed: a live state of this instance", function, state);
        return NULL;
    default:
        shim_log(inst, fmi2Error, "%s: FMUstate %p is not a live state of this loaded copy of "
                 "the FMU (GUID %s): not made by its fmi2GetFMUstate or "
                 "fmi2DeSerializeFMUstate (a state pointer is valid only in the library and the "
                 "instance that made it; to move a state between copies of an FMU, serialise "
                 "it); allowed: a live state of this instance", function, state, inst->guid);
        return NULL;
    }
    if (strcmp(s->guid, inst->guid)) { /* (cannot happen: the owner is this instance) */
        shim_log(inst, fmi2Error, "%s: FMUstate %p is a state of the FMU with GUID %s, not of "
                 "this one (GUID %s); allowed: a live state of this FMU", function, state,
                 s->guid, inst->guid);
        return NULL;
    }
    return s;
}

/*
 * Put pythonfmu's state `fresh` into *FMUstate: into the record already there when it is a live
 * state of inst (whose old state is freed), or into a new one.
 */
static fmi2Status store_state(Instance *inst, fmi2FMUstate fresh, fmi2FMUstate *FMUstate,
                              const State *fields)
{
    State *s = NULL;
    if (*FMUstate && stranger(inst, *FMUstate, &s) == -1) {
        fmi2FMUstate old = s->inner;
        inner.FreeFMUstate(inst->inner, &old);
    } else {
        s = calloc(1, sizeof *s);
        if (!s) {
            inner.FreeFMUstate(inst->inner, &fresh);
            shim_log(inst, fmi2Error, "out of memory for an FMU state");
            return fmi2Error;
        }
        add_live(s, inst);
    }
    s->inner = fresh;
    snprintf(s->guid, sizeof s->guid, "%s", inst->guid);
    s->state = fields->state;
    s->start_time = fields->start_time;
    s->time = fields->time;
    s->elapsed = fields->elapsed;
    s->elapsed_c = fields->elapsed_c;
    *FMUstate = (fmi2FMUstate)s->handle;
    return fmi2OK;
}

/* A non-NULL *FMUstate that is not a live state of inst: said in a warning, and left alone. */
static fmi2Status check_target(Instance *inst, const char *function, fmi2FMUstate *FMUstate)
{
    State *s;
    if (*FMUstate && stranger(inst, *FMUstate, &s) != -1) {
        shim_log(inst, fmi2Warning, "%s: *FMUstate = %p is not a live FMU state of this "
                 "instance; a new state is returned and the old pointer is left alone",
                 function, *FMUstate);
        *FMUstate = NULL;
        return fmi2Warning;
    }
    return fmi2OK;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    INSTANCE(c, "fmi2GetFMUstate", ANY_STATE);
    if (null_argument(inst, "fmi2GetFMUstate", "FMUstate", FMUstate))
        return fmi2Error;
    fmi2FMUstate target = *FMUstate;
    fmi2Status warning = check_target(inst, "fmi2GetFMUstate", &target);
    fmi2FMUstate fresh = NULL;
    fmi2Status status = CALL(inner.GetFMUstate(inst->inner, &fresh));
    if (status > fmi2Warning)
        return status;
    if (!fresh) {
        shim_log(inst, fmi2Error, "fmi2GetFMUstate: the model returned no state");
        return fmi2Error;
    }
    State fields = {.state = inst->state, .start_time = inst->start_time, .time = inst->time,
                    .elapsed = inst->elapsed, .elapsed_c = inst->elapsed_c};
    fmi2Status stored = store_state(inst, fresh, &target, &fields);
    if (stored == fmi2OK)
        *FMUstate = target;
    return stored > status ? stored : status > warning ? status : warning;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    INSTANCE(c, "fmi2SetFMUstate", ANY_STATE);
    State *s = known_state(inst, "fmi2SetFMUstate", FMUstate);
    if (!s)
        return fmi2Error;
    fmi2Status status = CALL(inner.SetFMUstate(inst->inner, s->inner));
    if (status <= fmi2Warning) {
        inst->state = s->state;
        inst->start_time = s->start_time;
        inst->time = s->time;
        inst->elapsed = s->elapsed;
        inst->elapsed_c = s->elapsed_c;
    }
    return status;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    INSTANCE(c, "fmi2FreeFMUstate", ANY_STATE | FATAL);
    if (!FMUstate || !*FMUstate)
        return fmi2OK; /* nothing to free */
    State *s = known_state(inst, "fmi2FreeFMUstate", *FMUstate);
    if (!s)
        return fmi2Error;
    remove_live(s);
    if (inst->state != FATAL)
        inner.FreeFMUstate(inst->inner, &s->inner);
    free(s);
    *FMUstate = NULL;
    return fmi2OK;
}

/* Size of pythonfmu's serialisation of s, or (size_t)-1 after an error. */
static size_t inner_size(Instance *inst, State *s, fmi2Status *status)
{
    size_t n = 0;
    *status = CALL(inner.SerializedFMUstateSize(inst->inner, s->inner, &n));
    return *status > fmi2Warning ? (size_t)-1 : n;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    INSTANCE(c, "fmi2SerializedFMUstateSize", ANY_STATE);
    if (null_argument(inst, "fmi2SerializedFMUstateSize", "size", size))
        return fmi2Error;
    State *s = known_state(inst, "fmi2SerializedFMUstateSize", FMUstate);
    if (!s)
        return fmi2Error;
    fmi2Status status;
    size_t n = inner_size(inst, s, &status);
    if (n != (size_t)-1)
        *size = n;
    return status;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size)
{
    INSTANCE(c, "fmi2SerializeFMUstate", ANY_STATE);
    if (null_argument(inst, "fmi2SerializeFMUstate", "serializedState", serializedState))
        return fmi2Error;
    State *s = known_state(inst, "fmi2SerializeFMUstate", FMUstate);
    if (!s)
        return fmi2Error;
    fmi2Status status;
    size_t n = inner_size(inst, s, &status);
    if (n == (size_t)-1)
        return status;
    if (size < n) { /* pythonfmu would copy n bytes into the smaller buffer */
        shim_log(inst, fmi2Error, "fmi2SerializeFMUstate: size = %zu is too small; allowed: "
                 "the size fmi2SerializedFMUstateSize returns, %zu", size, n);
        return fmi2Error;
    }
    fmi2Status inner_status = CALL(inner.SerializeFMUstate(inst->inner, s->inner,
                                                           serializedState, n));
    return inner_status > status ? inner_status : status;
}

/* The largest serialised state the shim takes from a host (a state of these models is a few
   kilobytes of JSON): a larger size is refused before any arithmetic or allocation with it. */
#define SERIALIZED_LIMIT ((size_t)1 << 26)

/* 1 if `what` occurs in text before end. */
static int occurs(const char *text, const char *end, const char *what)
{
    const char *p = strstr(text, what);
    return p && p < end;
}

/*
 * The FMI state and time a serialised state describes, from the model's "flags" and "time"
 * (the model writes them, and checks the GUID, the model and every field when the state is
 * set).  Bytes without them get the instance's own: the model refuses such bytes anyway.
 */
static void state_of_bytes(Instance *inst, const fmi2Byte *bytes, size_t size, State *fields)
{
    fields->state = inst->state;
    fields->start_time = inst->start_time;
    fields->time = inst->time;
    fields->elapsed = inst->elapsed;
    fields->elapsed_c = inst->elapsed_c;
    /* size comes from the host: size + 1 must not wrap (the bytes themselves were checked to
       be there by the caller only as far as a pointer goes; a size this large is refused) */
    if (size >= SERIALIZED_LIMIT)
        return;
    char *text = malloc(size + 1);
    if (!text)
        return;
    memcpy(text, bytes, size);
    text[size] = '\0';
    const char *flags = strstr(text, "\"flags\": {"), *end = flags ? strchr(flags, '}') : NULL;
    if (end) {
        fields->state = occurs(flags, end, "\"terminated\": true") ? TERMINATED
                        : occurs(flags, end, "\"initialised\": true") ? STEP_COMPLETE
                        : occurs(flags, end, "\"in_init\": true") ? INITIALIZATION_MODE
                                                                    : INSTANTIATED;
    }
    const char *time = strstr(text, "\"time\": [");
    double start, elapsed, c;
    if (time && sscanf(time + 9, "%lf, %lf, %lf", &start, &elapsed, &c) == 3 &&
        isfinite(start) && isfinite(elapsed) && isfinite(c)) {
        fields->start_time = start;
        fields->elapsed = elapsed;
        fields->elapsed_c = c;
        fields->time = start + (elapsed + c);
    }
    free(text);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate)
{
    INSTANCE(c, "fmi2DeSerializeFMUstate", ANY_STATE);
    if (null_count_array(inst, "fmi2DeSerializeFMUstate", "serializedState", "size", size,
                         serializedState) ||
        null_argument(inst, "fmi2DeSerializeFMUstate", "FMUstate", FMUstate))
        return fmi2Error;
    if (size >= SERIALIZED_LIMIT) {
        shim_log(inst, fmi2Error, "fmi2DeSerializeFMUstate: size = %zu bytes; allowed: a "
                 "serialised state of this FMU, fewer than %zu bytes (the size "
                 "fmi2SerializedFMUstateSize returned)", size, (size_t)SERIALIZED_LIMIT);
        return fmi2Error;
    }
    State fields;
    state_of_bytes(inst, size ? serializedState : "", size, &fields);
    fmi2FMUstate target = *FMUstate;
    fmi2Status warning = check_target(inst, "fmi2DeSerializeFMUstate", &target);
    fmi2FMUstate fresh = NULL;
    fmi2Status status = CALL(inner.DeSerializeFMUstate(inst->inner, size ? serializedState : "",
                                                       size, &fresh));
    if (status > fmi2Warning)
        return status;
    if (!fresh) {
        shim_log(inst, fmi2Error, "fmi2DeSerializeFMUstate: the model returned no state");
        return fmi2Error;
    }
    /* the model checks what it read, every field as fmi2SetFMUstate will, and changes nothing
       (SHIM_VR set to [1]: the next fmi2SetFMUstate is that check), so bad bytes are refused
       here, with the reason */
    const fmi2ValueReference check_vr[1] = {SHIM_VR};
    const fmi2Real check_next[1] = {1.0};
    fmi2Status checked = inst->speaks ? CALL(inner.SetReal(inst->inner, check_vr, 1, check_next))
                                      : fmi2OK;
    if (inst->speaks && checked <= fmi2Warning)
        checked = CALL(inner.SetFMUstate(inst->inner, fresh));
    if (checked > fmi2Warning) {
        if (inst->state != FATAL)
            inner.FreeFMUstate(inst->inner, &fresh);
        return checked;
    }
    if (checked > status)
        status = checked;
    fmi2Status stored = store_state(inst, fresh, &target, &fields);
    if (stored == fmi2OK)
        *FMUstate = target;
    return stored > status ? stored : status > warning ? status : warning;
}

/* -- what the FMU does not provide --------------------------------------------------------- */

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[])
{
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown,
        (void)dvUnknown;
    INSTANCE(c, "fmi2GetDirectionalDerivative", GETTABLE);
    shim_log(inst, fmi2Error, "fmi2GetDirectionalDerivative: not provided "
             "(providesDirectionalDerivative is false)");
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[])
{
    (void)vr, (void)nvr, (void)order, (void)value;
    INSTANCE(c, "fmi2SetRealInputDerivatives", SETTABLE);
    shim_log(inst, fmi2Error, "fmi2SetRealInputDerivatives: not provided (canInterpolateInputs "
             "is false: inputs are held over a step)");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[], fmi2Real value[])
{
    (void)vr, (void)nvr, (void)order, (void)value;
    INSTANCE(c, "fmi2GetRealOutputDerivatives", STEP_COMPLETE | TERMINATED);
    shim_log(inst, fmi2Error, "fmi2GetRealOutputDerivatives: not provided "
             "(maxOutputDerivativeOrder is 0)");
    return fmi2Error;
}

/* -- stepping ------------------------------------------------------------------------------ */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    INSTANCE(c, "fmi2DoStep", STEP_COMPLETE);
    if (!isfinite(currentCommunicationPoint)) {
        shim_log(inst, fmi2Error, "fmi2DoStep: currentCommunicationPoint = %g s; allowed: a "
                 "finite time (the FMU keeps its own time and steps from %.17g s, the end of "
                 "the previous step)", currentCommunicationPoint, inst->time);
        return fmi2Error;
    }
    fmi2Status status = CALL(inner.DoStep(inst->inner, currentCommunicationPoint,
                                          communicationStepSize,
                                          noSetFMUStatePriorToCurrentPoint));
    if (status <= fmi2Warning) { /* the model's own time (slave_base._step), bit for bit */
        double e = inst->elapsed, h = communicationStepSize, t = e + h;
        inst->elapsed_c += fabs(e) >= fabs(h) ? (e - t) + h : (h - t) + e;
        inst->elapsed = t;
        inst->time = inst->start_time + (inst->elapsed + inst->elapsed_c);
    }
    return status;
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    INSTANCE(c, "fmi2CancelStep", STEP_COMPLETE);
    shim_log(inst, fmi2Error, "fmi2CancelStep: no step is in progress (fmi2DoStep never "
             "returns fmi2Pending)");
    return fmi2Error;
}

/*
 * The status inquiries, answered by the shim: fmi2DoStep never returns fmi2Pending and never
 * asks to terminate, so fmi2Terminated is false, fmi2LastSuccessfulTime is the end of the last
 * accepted step, and every other inquiry is fmi2Discard, as the standard says.
 */
#define STATUS_STATES (STEP_COMPLETE | TERMINATED)

static int bad_kind(Instance *inst, const char *function, fmi2StatusKind s, const void *value)
{
    if (null_argument(inst, function, "value", value))
        return 1;
    if (s < fmi2DoStepStatus || s > fmi2Terminated) {
        shim_log(inst, fmi2Error, "%s: status kind %d does not exist; allowed: fmi2DoStepStatus, "
                 "fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated", function, (int)s);
        return 1;
    }
    return 0;
}

static fmi2Status discard(Instance *inst, const char *function, fmi2StatusKind s)
{
    static const char *kinds[] = {"fmi2DoStepStatus", "fmi2PendingStatus",
                                  "fmi2LastSuccessfulTime", "fmi2Terminated"};
    shim_log(inst, fmi2Discard, "%s(%s): no such status: fmi2DoStep never returns fmi2Pending "
             "(fmi2Discard)", function, kinds[s]);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    INSTANCE(c, "fmi2GetStatus", STATUS_STATES);
    if (bad_kind(inst, "fmi2GetStatus", s, value))
        return fmi2Error;
    return discard(inst, "fmi2GetStatus", s);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    INSTANCE(c, "fmi2GetRealStatus", STATUS_STATES);
    if (bad_kind(inst, "fmi2GetRealStatus", s, value))
        return fmi2Error;
    if (s != fmi2LastSuccessfulTime)
        return discard(inst, "fmi2GetRealStatus", s);
    *value = inst->time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    INSTANCE(c, "fmi2GetIntegerStatus", STATUS_STATES);
    if (bad_kind(inst, "fmi2GetIntegerStatus", s, value))
        return fmi2Error;
    return discard(inst, "fmi2GetIntegerStatus", s);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    INSTANCE(c, "fmi2GetBooleanStatus", STATUS_STATES);
    if (bad_kind(inst, "fmi2GetBooleanStatus", s, value))
        return fmi2Error;
    if (s != fmi2Terminated)
        return discard(inst, "fmi2GetBooleanStatus", s);
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    INSTANCE(c, "fmi2GetStringStatus", STATUS_STATES);
    if (bad_kind(inst, "fmi2GetStringStatus", s, value))
        return fmi2Error;
    return discard(inst, "fmi2GetStringStatus", s);
}
