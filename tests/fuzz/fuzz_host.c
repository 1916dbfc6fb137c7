/*
 * fuzz_host.c - an FMI 2.0 co-simulation host that runs a script of calls, for tests/fuzz.
 *
 * usage: fuzz_host < SCRIPT
 *
 * One call a line, words separated by spaces; I is an instance slot, L a library slot, S a
 * state slot, B a byte-buffer slot (0..63 each).  Numbers are read with strtod/strtoul, so
 * "nan", "inf" and "1e300" work.  A word "NULL" stands for a NULL string; "\s" in a word is
 * a space, "\\" a backslash.
 *
 *   load L DIR MODEL_IDENTIFIER        dlopen DIR/binaries/linux64/MODEL_IDENTIFIER.so
 *   inst I L NAME TYPE GUID URI        fmi2Instantiate; GUID/URI "NULL"; URI "DEFAULT" is
 *                                      file://DIR/resources; prints "INST I ok|null"
 *   instcb I L NAME GUID KIND          fmi2Instantiate with callbacks without a logger
 *                                      (nolog), without memory functions (noalloc), or NULL
 *   reals I N VR...                    the Real value references of I (snapshots, finiteness)
 *   free I | setup I T [STOP] | enter I | exit I | term I | reset I
 *                                      (setup: with STOP, stopTimeDefined and that stop time)
 *   setr I N VR V ...  | seti I N VR V ... | setb I N VR V ...
 *   getr I N VR ...    | geti I N VR ...   | getb I N VR ...
 *   copy I VR J VR2                    set Real VR2 of instance J to Real VR of instance I
 *   step I T H
 *   count I KIND N                     a get or set (KIND: getr setr geti seti getb setb) of N
 *                                      value references with one-element arrays (N: any
 *                                      size_t, e.g. 18446744073709551615)
 *   gst I S | sst I S | fst I S        get into / set from / free state slot S
 *   ser I S B | des I B S              serialise state S into buffer B / deserialise B into S
 *   raw B TEXT                         buffer B := TEXT (a hand-made "serialised state"; \n
 *                                      and \s in TEXT are a newline and a space)
 *   alias S T                          state slot S := the pointer in slot T
 *   dump B                             print buffer B ("DUMP B text", newlines as '|')
 *   craft B NEWB KEY JSON              NEWB := B with "KEY": JSON added to its JSON object
 *                                      (the driftfmu header's length is fixed up)
 *   garbage S                          state slot S := a pointer to 64 bytes of junk
 *   null I WHAT                        a call with a NULL where a pointer belongs (see below)
 *   status I KIND TYPE                 fmi2Get<TYPE>Status (TYPE: s r i b str); prints the
 *                                      value (not for str) when the call succeeds
 *   cycles L N EVERY                   N instantiate..free cycles, "RSS i bytes" every EVERY
 *   stateloop I S N EVERY              N fmi2GetFMUstate into slot S, RSS every EVERY
 *   errloop I N EVERY                  N rejected fmi2SetReal (NaN into vr 0), RSS every EVERY
 *   check on|off                       around every later call: snapshot before and after;
 *                                      a call that returned fmi2Error or worse must leave the
 *                                      snapshot unchanged (else "CHANGED line")
 *
 * Every call prints "S line name status".  Getters print "V line value..." too.  After a
 * call returning fmi2OK or fmi2Warning the Real variables (from "reals") are read back; a
 * non-finite one prints "NONFINITE line vr value".  Log messages print as "LOG status
 * category: message".  The exit code is 0 when the script ran to its end.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "fmi2Functions.h"
#include "../hosts/host_common.h"

#define SLOTS 64
#define MAX_WORDS 4096

typedef struct {
    void *handle;
    char dir[4096];
#define FIELD(name) fmi2##name##TYPE *name;
    FIELD(Instantiate) FIELD(FreeInstance) FIELD(SetupExperiment)
    FIELD(EnterInitializationMode) FIELD(ExitInitializationMode) FIELD(Terminate) FIELD(Reset)
    FIELD(GetReal) FIELD(GetInteger) FIELD(GetBoolean) FIELD(SetReal) FIELD(SetInteger)
    FIELD(SetBoolean) FIELD(GetFMUstate) FIELD(SetFMUstate) FIELD(FreeFMUstate)
    FIELD(SerializedFMUstateSize) FIELD(SerializeFMUstate) FIELD(DeSerializeFMUstate)
    FIELD(DoStep) FIELD(GetStatus) FIELD(GetRealStatus) FIELD(GetIntegerStatus)
    FIELD(GetBooleanStatus) FIELD(GetStringStatus)
#undef FIELD
} Library;

typedef struct {
    Library *lib;
    fmi2Component c;
    size_t n_reals;
    fmi2ValueReference reals[256];
} Slot;

static Library libs[SLOTS];
static Slot insts[SLOTS];
static fmi2FMUstate states[SLOTS];
static char *buffers[SLOTS];
static size_t buffer_sizes[SLOTS];
static int line_no, checking;
static char junk[SLOTS][64];

static fmi2CallbackFunctions callbacks = {host_logger2, calloc, free, NULL, NULL};

static void fail(const char *what)
{
    printf("SCRIPT line %d: %s\n", line_no, what);
    fflush(stdout);
    exit(5);
}

static int slot(const char *word)
{
    char *end;
    long i = word ? strtol(word, &end, 10) : -1;
    if (!word || *end || i < 0 || i >= SLOTS)
        fail("bad slot");
    return (int)i;
}

static Slot *instance(const char *word)
{
    Slot *s = &insts[slot(word)];
    if (!s->lib)
        fail("no such instance");
    return s;
}

static double number(const char *word)
{
    if (!word)
        fail("missing number");
    return strtod(word, NULL);
}

static fmi2ValueReference reference(const char *word)
{
    if (!word)
        fail("missing value reference");
    return (fmi2ValueReference)strtoull(word, NULL, 10);
}

static const char *string_or_null(const char *word)
{
    return word && strcmp(word, "NULL") ? word : NULL;
}

static void load(int l, const char *dir, const char *id)
{
    Library *lib = &libs[l];
    snprintf(lib->dir, sizeof lib->dir, "%s", dir);
    lib->handle = host_open(dir, 2, id);
#define LOOK(name) lib->name = (fmi2##name##TYPE *)host_lookup(lib->handle, "fmi2" #name);
    LOOK(Instantiate) LOOK(FreeInstance) LOOK(SetupExperiment) LOOK(EnterInitializationMode)
    LOOK(ExitInitializationMode) LOOK(Terminate) LOOK(Reset) LOOK(GetReal) LOOK(GetInteger)
    LOOK(GetBoolean) LOOK(SetReal) LOOK(SetInteger) LOOK(SetBoolean) LOOK(GetFMUstate)
    LOOK(SetFMUstate) LOOK(FreeFMUstate) LOOK(SerializedFMUstateSize) LOOK(SerializeFMUstate)
    LOOK(DeSerializeFMUstate) LOOK(DoStep) LOOK(GetStatus) LOOK(GetRealStatus)
    LOOK(GetIntegerStatus) LOOK(GetBooleanStatus) LOOK(GetStringStatus)
#undef LOOK
}

/* -- snapshots: every Real, and the serialised FMU state -------------------------------- */

typedef struct {
    fmi2Status real_status, state_status;
    double reals[256];
    char *bytes;
    size_t size;
} Snapshot;

static void snapshot(Slot *s, Snapshot *snap)
{
    int was_quiet = host_quiet;
    host_quiet = 1;
    memset(snap, 0, sizeof *snap);
    snap->real_status = s->n_reals ? s->lib->GetReal(s->c, s->reals, s->n_reals, snap->reals)
                                   : fmi2OK;
    fmi2FMUstate state = NULL;
    snap->state_status = s->lib->GetFMUstate(s->c, &state);
    if (snap->state_status <= fmi2Warning &&
        s->lib->SerializedFMUstateSize(s->c, state, &snap->size) <= fmi2Warning) {
        snap->bytes = malloc(snap->size ? snap->size : 1);
        if (s->lib->SerializeFMUstate(s->c, state, (fmi2Byte *)snap->bytes, snap->size) >
            fmi2Warning)
            snap->size = 0;
    }
    if (state)
        s->lib->FreeFMUstate(s->c, &state);
    host_quiet = was_quiet;
}

static int same(const Snapshot *a, const Snapshot *b, size_t n_reals)
{
    if (a->real_status != b->real_status || a->state_status != b->state_status ||
        a->size != b->size)
        return 0;
    for (size_t i = 0; i < n_reals; i++)
        if (memcmp(&a->reals[i], &b->reals[i], sizeof(double)))
            return 0;
    return a->size == 0 || !memcmp(a->bytes, b->bytes, a->size);
}

/* After an accepted call: every Real variable must be finite. */
static void check_finite(Slot *s)
{
    double values[256];
    int was_quiet = host_quiet;
    host_quiet = 1;
    fmi2Status status = s->lib->GetReal(s->c, s->reals, s->n_reals, values);
    host_quiet = was_quiet;
    if (status > fmi2Warning)
        return;
    for (size_t i = 0; i < s->n_reals; i++)
        if (!isfinite(values[i]))
            printf("NONFINITE %d %u %.17g\n", line_no, (unsigned)s->reals[i], values[i]);
}

/* -- the calls -------------------------------------------------------------------------- */

static void print_reals(const double *v, size_t n)
{
    printf("V %d", line_no);
    for (size_t i = 0; i < n; i++)
        printf(" %.17g", v[i]);
    printf("\n");
}

/* craft: insert `"key": json, ` after the first '{' of the JSON part of buffer b. */
static void craft(int b, int nb, const char *key, const char *json)
{
    if (!buffers[b])
        fail("empty buffer");
    const char *start = memchr(buffers[b], '{', buffer_sizes[b]);
    if (!start)
        fail("no JSON object in the buffer");
    size_t head = (size_t)(start - buffers[b]) + 1;
    size_t extra = strlen(key) + strlen(json) + 8;
    size_t size = buffer_sizes[b] + extra + 32;
    char *out = calloc(1, size);
    /* the header's last line ends with the length of what follows it */
    size_t payload = buffer_sizes[b] - (size_t)(start - buffers[b]);
    char *header_end = memchr(buffers[b], '{', buffer_sizes[b]);
    size_t header_len = (size_t)(header_end - buffers[b]);
    size_t n = 0;
    if (header_len > 0) {
        /* rewrite "... <length>\n": drop the old number, print the new one */
        const char *last = header_end - 1; /* the '\n' */
        const char *p = last;
        while (p > buffers[b] && p[-1] != ' ')
            p--;
        n = (size_t)(p - buffers[b]);
        memcpy(out, buffers[b], n);
        n += (size_t)sprintf(out + n, "%zu\n", payload + strlen(key) + strlen(json) + 6);
    }
    memcpy(out + n, start, 1);
    n += 1;
    n += (size_t)sprintf(out + n, "\"%s\": %s, ", key, json);
    memcpy(out + n, buffers[b] + head, buffer_sizes[b] - head);
    n += buffer_sizes[b] - head;
    free(buffers[nb]);
    buffers[nb] = out;
    buffer_sizes[nb] = n;
}

static fmi2Status null_call(Slot *s, const char *what)
{
    fmi2ValueReference vr = 0;
    double v = 0.0;
    size_t size = 0;
    Library *l = s->lib;
    if (!strcmp(what, "getr_vr")) return l->GetReal(s->c, NULL, 1, &v);
    if (!strcmp(what, "getr_value")) return l->GetReal(s->c, &vr, 1, NULL);
    if (!strcmp(what, "setr_vr")) return l->SetReal(s->c, NULL, 1, &v);
    if (!strcmp(what, "setr_value")) return l->SetReal(s->c, &vr, 1, NULL);
    if (!strcmp(what, "geti_value")) return l->GetInteger(s->c, &vr, 1, NULL);
    if (!strcmp(what, "gst")) return l->GetFMUstate(s->c, NULL);
    if (!strcmp(what, "sst")) return l->SetFMUstate(s->c, NULL);
    if (!strcmp(what, "fst")) return l->FreeFMUstate(s->c, NULL);
    if (!strcmp(what, "fst_inner")) {
        fmi2FMUstate none = NULL;
        return l->FreeFMUstate(s->c, &none);
    }
    if (!strcmp(what, "size")) return l->SerializedFMUstateSize(s->c, NULL, &size);
    if (!strcmp(what, "size_out")) {
        fmi2FMUstate state = NULL;
        fmi2Status got = l->GetFMUstate(s->c, &state);
        fmi2Status status = l->SerializedFMUstateSize(s->c, state, NULL);
        if (got <= fmi2Warning)
            l->FreeFMUstate(s->c, &state);
        return status;
    }
    if (!strcmp(what, "des_bytes")) {
        fmi2FMUstate state = NULL;
        return l->DeSerializeFMUstate(s->c, NULL, 10, &state);
    }
    if (!strcmp(what, "des_state")) return l->DeSerializeFMUstate(s->c, "x", 1, NULL);
    if (!strcmp(what, "status_value")) return l->GetStatus(s->c, fmi2DoStepStatus, NULL);
    if (!strcmp(what, "component")) return l->DoStep(NULL, 0.0, 1e-3, fmi2True);
    if (!strcmp(what, "component_get")) return l->GetReal(NULL, &vr, 1, &v);
    fail("unknown null case");
    return fmi2Fatal;
}

static fmi2Status set_values(Slot *s, char **w, int n_words, int kind)
{
    size_t n = (size_t)number(w[2]);
    if (n > 256 || (int)(3 + 2 * n) > n_words)
        fail("bad value list");
    fmi2ValueReference vr[256];
    double r[256];
    fmi2Integer i[256];
    fmi2Boolean b[256];
    for (size_t k = 0; k < n; k++) {
        vr[k] = reference(w[3 + 2 * k]);
        r[k] = number(w[4 + 2 * k]);
        i[k] = (fmi2Integer)strtol(w[4 + 2 * k], NULL, 10);
        b[k] = i[k] != 0;
    }
    if (kind == 'r') return s->lib->SetReal(s->c, vr, n, r);
    if (kind == 'i') return s->lib->SetInteger(s->c, vr, n, i);
    return s->lib->SetBoolean(s->c, vr, n, b);
}

static fmi2Status get_values(Slot *s, char **w, int n_words, int kind)
{
    size_t n = (size_t)number(w[2]);
    if (n > 256 || (int)(3 + n) > n_words)
        fail("bad reference list");
    fmi2ValueReference vr[256];
    double r[256];
    fmi2Integer i[256];
    fmi2Boolean b[256];
    for (size_t k = 0; k < n; k++)
        vr[k] = reference(w[3 + k]);
    fmi2Status status;
    if (kind == 'r') {
        status = s->lib->GetReal(s->c, vr, n, r);
    } else if (kind == 'i') {
        status = s->lib->GetInteger(s->c, vr, n, i);
        for (size_t k = 0; k < n; k++)
            r[k] = i[k];
    } else {
        status = s->lib->GetBoolean(s->c, vr, n, b);
        for (size_t k = 0; k < n; k++)
            r[k] = b[k];
    }
    if (status <= fmi2Warning)
        print_reals(r, n);
    if (kind == 'r' && status <= fmi2Warning)
        for (size_t k = 0; k < n; k++)
            if (!isfinite(r[k]))
                printf("NONFINITE %d %u %.17g\n", line_no, (unsigned)vr[k], r[k]);
    return status;
}

/* Run one call; returns its status (fmi2OK for calls without one). */
static fmi2Status run(char **w, int n)
{
    const char *op = w[0];
    if (!strcmp(op, "load")) {
        if (n < 4) fail("load L DIR ID");
        load(slot(w[1]), w[2], w[3]);
        return fmi2OK;
    }
    if (!strcmp(op, "instcb")) { /* inst with odd callbacks: nolog, noalloc or null */
        if (n < 6) fail("instcb I L NAME GUID KIND");
        Slot *s = &insts[slot(w[1])];
        Library *lib = &libs[slot(w[2])];
        if (!lib->handle) fail("no such library");
        char uri[8192];
        snprintf(uri, sizeof uri, "file://%s/resources", lib->dir);
        static fmi2CallbackFunctions nolog = {NULL, calloc, free, NULL, NULL};
        static fmi2CallbackFunctions noalloc = {host_logger2, NULL, NULL, NULL, NULL};
        const fmi2CallbackFunctions *cb = !strcmp(w[5], "nolog") ? &nolog
                                          : !strcmp(w[5], "noalloc") ? &noalloc : NULL;
        s->lib = lib;
        s->c = lib->Instantiate(w[3], fmi2CoSimulation, w[4], uri, cb, fmi2False, fmi2False);
        printf("INST %s %s\n", w[1], s->c ? "ok" : "null");
        if (!s->c)
            s->lib = NULL;
        return s->c ? fmi2OK : fmi2Error;
    }
    if (!strcmp(op, "inst")) {
        if (n < 7) fail("inst I L NAME TYPE GUID URI");
        Slot *s = &insts[slot(w[1])];
        Library *lib = &libs[slot(w[2])];
        if (!lib->handle) fail("no such library");
        char uri[8192];
        const char *location = string_or_null(w[6]);
        if (location && !strcmp(location, "DEFAULT")) {
            snprintf(uri, sizeof uri, "file://%s/resources", lib->dir);
            location = uri;
        }
        s->lib = lib;
        s->c = lib->Instantiate(string_or_null(w[3]), (fmi2Type)atoi(w[4]), string_or_null(w[5]),
                                location, &callbacks, fmi2False, fmi2False);
        printf("INST %s %s\n", w[1], s->c ? "ok" : "null");
        if (!s->c)
            s->lib = NULL;
        return s->c ? fmi2OK : fmi2Error;
    }
    if (!strcmp(op, "raw")) {
        int b = slot(w[1]);
        const char *text = n > 2 ? w[2] : "";
        char *out = malloc(strlen(text) + 1), *o = out;
        for (const char *p = text; *p; p++) {
            if (p[0] == '\\' && (p[1] == 'n' || p[1] == 's')) {
                *o++ = p[1] == 'n' ? '\n' : ' ';
                p++;
            } else {
                *o++ = *p;
            }
        }
        free(buffers[b]);
        buffers[b] = out;
        buffer_sizes[b] = (size_t)(o - out);
        return fmi2OK;
    }
    if (!strcmp(op, "dump")) {
        int b = slot(w[1]);
        printf("DUMP %d ", b);
        for (size_t i = 0; i < buffer_sizes[b]; i++)
            putchar(buffers[b][i] == '\n' ? '|' : buffers[b][i]);
        printf("\n");
        return fmi2OK;
    }
    if (!strcmp(op, "alias")) {
        states[slot(w[1])] = states[slot(w[2])];
        return fmi2OK;
    }
    if (!strcmp(op, "craft")) {
        if (n < 5) fail("craft B NEWB KEY JSON");
        craft(slot(w[1]), slot(w[2]), w[3], w[4]);
        return fmi2OK;
    }
    if (!strcmp(op, "garbage")) {
        int k = slot(w[1]);
        for (int i = 0; i < 64; i++)
            junk[k][i] = (char)(0x5a ^ (i * 37));
        states[k] = junk[k];
        return fmi2OK;
    }
    if (!strcmp(op, "check")) {
        checking = n > 1 && !strcmp(w[1], "on");
        return fmi2OK;
    }
    if (!strcmp(op, "cycles")) {
        Library *lib = &libs[slot(w[1])];
        long count = (long)number(w[2]), every = (long)number(w[3]);
        char uri[8192], guid[256] = "";
        snprintf(uri, sizeof uri, "file://%s/resources", lib->dir);
        if (n > 4) snprintf(guid, sizeof guid, "%s", w[4]);
        for (long i = 0; i < count; i++) {
            fmi2Component c = lib->Instantiate("cycle", fmi2CoSimulation, guid, uri, &callbacks,
                                               fmi2False, fmi2False);
            if (!c) fail("instantiation failed in cycles");
            lib->SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
            lib->EnterInitializationMode(c);
            lib->ExitInitializationMode(c);
            lib->DoStep(c, 0.0, 1e-3, fmi2True);
            lib->Terminate(c);
            lib->FreeInstance(c);
            host_measure("cycles", i, every);
        }
        return fmi2OK;
    }
    if (!strcmp(op, "stateloop")) {
        Slot *s = instance(w[1]);
        int k = slot(w[2]);
        long count = (long)number(w[3]), every = (long)number(w[4]);
        for (long i = 0; i < count; i++) {
            if (s->lib->GetFMUstate(s->c, &states[k]) > fmi2Warning) fail("get state failed");
            host_measure("states", i, every);
        }
        return fmi2OK;
    }
    if (!strcmp(op, "errloop")) {
        Slot *s = instance(w[1]);
        long count = (long)number(w[2]), every = (long)number(w[3]);
        fmi2ValueReference vr = s->n_reals ? s->reals[s->n_reals - 1] : 0;
        double v = NAN;
        host_quiet = 1;
        for (long i = 0; i < count; i++) {
            s->lib->SetReal(s->c, &vr, 1, &v);
            host_measure("errors", i, every);
        }
        host_quiet = 0;
        return fmi2OK;
    }
    if (!strcmp(op, "reals")) {
        Slot *s = instance(w[1]);
        s->n_reals = (size_t)number(w[2]);
        if (s->n_reals > 256 || (int)(3 + s->n_reals) > n) fail("bad reals");
        for (size_t k = 0; k < s->n_reals; k++)
            s->reals[k] = reference(w[3 + k]);
        return fmi2OK;
    }
    if (n < 2) fail("missing instance");
    Slot *s = instance(w[1]);
    Library *l = s->lib;
    if (!strcmp(op, "free")) {
        l->FreeInstance(s->c);
        s->lib = NULL;
        s->c = NULL;
        return fmi2OK;
    }
    if (!strcmp(op, "setup"))
        return l->SetupExperiment(s->c, fmi2False, 0.0, number(w[2]), n > 3 ? fmi2True : fmi2False,
                                  n > 3 ? number(w[3]) : 0.0);
    if (!strcmp(op, "count")) {
        if (n < 4) fail("count I KIND N");
        size_t count = (size_t)strtoull(w[3], NULL, 10);
        fmi2ValueReference vr[1] = {0};
        fmi2Real r[1] = {0.0};
        fmi2Integer i[1] = {0};
        fmi2Boolean b[1] = {0};
        const char *kind = w[2];
        if (!strcmp(kind, "getr")) return l->GetReal(s->c, vr, count, r);
        if (!strcmp(kind, "setr")) return l->SetReal(s->c, vr, count, r);
        if (!strcmp(kind, "geti")) return l->GetInteger(s->c, vr, count, i);
        if (!strcmp(kind, "seti")) return l->SetInteger(s->c, vr, count, i);
        if (!strcmp(kind, "getb")) return l->GetBoolean(s->c, vr, count, b);
        if (!strcmp(kind, "setb")) return l->SetBoolean(s->c, vr, count, b);
        fail("count: unknown kind");
    }
    if (!strcmp(op, "enter")) return l->EnterInitializationMode(s->c);
    if (!strcmp(op, "exit")) return l->ExitInitializationMode(s->c);
    if (!strcmp(op, "term")) return l->Terminate(s->c);
    if (!strcmp(op, "reset")) return l->Reset(s->c);
    if (!strcmp(op, "setr")) return set_values(s, w, n, 'r');
    if (!strcmp(op, "seti")) return set_values(s, w, n, 'i');
    if (!strcmp(op, "setb")) return set_values(s, w, n, 'b');
    if (!strcmp(op, "getr")) return get_values(s, w, n, 'r');
    if (!strcmp(op, "geti")) return get_values(s, w, n, 'i');
    if (!strcmp(op, "getb")) return get_values(s, w, n, 'b');
    if (!strcmp(op, "copy")) {
        if (n < 5) fail("copy I VR J VR2");
        Slot *d = instance(w[3]);
        fmi2ValueReference from = reference(w[2]), to = reference(w[4]);
        double v;
        fmi2Status status = l->GetReal(s->c, &from, 1, &v);
        if (status > fmi2Warning) return status;
        return d->lib->SetReal(d->c, &to, 1, &v);
    }
    if (!strcmp(op, "step")) {
        if (n < 4) fail("step I T H");
        return l->DoStep(s->c, number(w[2]), number(w[3]), fmi2True);
    }
    if (!strcmp(op, "gst")) return l->GetFMUstate(s->c, &states[slot(w[2])]);
    if (!strcmp(op, "sst")) return l->SetFMUstate(s->c, states[slot(w[2])]);
    if (!strcmp(op, "fst")) return l->FreeFMUstate(s->c, &states[slot(w[2])]);
    if (!strcmp(op, "ser")) {
        int k = slot(w[2]), b = slot(w[3]);
        size_t size = 0;
        fmi2Status status = l->SerializedFMUstateSize(s->c, states[k], &size);
        if (status > fmi2Warning) return status;
        free(buffers[b]);
        buffers[b] = malloc(size ? size : 1);
        buffer_sizes[b] = size;
        return l->SerializeFMUstate(s->c, states[k], (fmi2Byte *)buffers[b], size);
    }
    if (!strcmp(op, "des")) {
        int b = slot(w[2]), k = slot(w[3]);
        return l->DeSerializeFMUstate(s->c, buffers[b] ? buffers[b] : "", buffer_sizes[b],
                                      &states[k]);
    }
    if (!strcmp(op, "null")) return null_call(s, n > 2 ? w[2] : "");
    if (!strcmp(op, "status")) {
        if (n < 4) fail("status I KIND TYPE");
        fmi2StatusKind kind = (fmi2StatusKind)atoi(w[2]);
        const char *t = w[3];
        fmi2Status sv;
        fmi2Real rv;
        fmi2Integer iv;
        fmi2Boolean bv;
        fmi2String strv;
        fmi2Status status;
        double printed;
        if (!strcmp(t, "s")) {
            status = l->GetStatus(s->c, kind, &sv);
            printed = sv;
        } else if (!strcmp(t, "r")) {
            status = l->GetRealStatus(s->c, kind, &rv);
            printed = rv;
        } else if (!strcmp(t, "i")) {
            status = l->GetIntegerStatus(s->c, kind, &iv);
            printed = iv;
        } else if (!strcmp(t, "b")) {
            status = l->GetBooleanStatus(s->c, kind, &bv);
            printed = bv;
        } else {
            return l->GetStringStatus(s->c, kind, &strv);
        }
        if (status <= fmi2Warning)
            print_reals(&printed, 1);
        return status;
    }
    fail("unknown call");
    return fmi2Fatal;
}

/* "\s" in a word is a space (paths and URIs with spaces), "\\" a backslash. */
static void unescape(char *word)
{
    char *o = word;
    for (char *p = word; *p; p++) {
        if (p[0] == '\\' && (p[1] == 's' || p[1] == '\\')) {
            *o++ = p[1] == 's' ? ' ' : '\\';
            p++;
        } else {
            *o++ = *p;
        }
    }
    *o = '\0';
}

int main(void)
{
    static char line[1 << 16];
    setvbuf(stdout, NULL, _IOLBF, 0);
    while (fgets(line, sizeof line, stdin)) {
        line_no++;
        char *w[MAX_WORDS];
        int n = 0;
        for (char *t = strtok(line, " \t\r\n"); t && n < MAX_WORDS; t = strtok(NULL, " \t\r\n"))
            w[n++] = t;
        for (int k = 0; k < n && strcmp(w[0], "raw"); k++)
            unescape(w[k]);
        if (n == 0 || w[0][0] == '#')
            continue;
        /* snapshot around calls on an instance, when checking */
        int on_instance = strcmp(w[0], "load") && strcmp(w[0], "inst") && strcmp(w[0], "raw") &&
                          strcmp(w[0], "instcb") &&
                          strcmp(w[0], "craft") && strcmp(w[0], "garbage") &&
                          strcmp(w[0], "check") && strcmp(w[0], "reals") &&
                          strcmp(w[0], "alias") && strcmp(w[0], "dump") &&
                          strcmp(w[0], "free") && strcmp(w[0], "cycles") && n > 1;
        Slot *s = on_instance ? &insts[slot(w[1])] : NULL;
        if (s && !s->lib)
            s = NULL;
        Snapshot before, after;
        int snap = checking && s;
        if (snap)
            snapshot(s, &before);
        fmi2Status status = run(w, n);
        printf("S %d %s %d\n", line_no, w[0], (int)status);
        if (snap) {
            snapshot(s, &after);
            if (status >= fmi2Error && !same(&before, &after, s->n_reals))
                printf("CHANGED %d %s\n", line_no, w[0]);
            free(before.bytes);
            free(after.bytes);
        }
        if (s && status <= fmi2Warning && s->n_reals && strcmp(w[0], "null"))
            check_finite(s);
        fflush(stdout);
    }
    printf("END\n");
    return 0;
}
