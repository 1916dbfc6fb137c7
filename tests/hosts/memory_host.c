/*
 * memory_host.c - the resident memory of an FMI 2.0 or FMI 3.0 co-simulation FMU over many
 * calls of one kind, from a C host (no Python in the process unless the FMU brings it).
 *
 * usage: memory_host FMI DIR MODEL_IDENTIFIER TOKEN WHAT N EVERY [LEAK]
 *
 *   FMI     2 or 3: the FMU's library is DIR/binaries/linux64/ID.so (FMI 2.0) or
 *           DIR/binaries/x86_64-linux/ID.so (FMI 3.0)
 *   TOKEN   the GUID (FMI 2.0) or instantiation token (FMI 3.0)
 *   WHAT    cycles   N times: instantiate, (setup,) enter and exit initialisation, one step of
 *                    1 ms, terminate, free
 *           states   one instance, initialised, one step; then N get-state calls into one
 *                    state pointer (the FMU may reuse the state it handed out)
 *           serdes   as states, then N times: serialise the state into one buffer and
 *                    deserialise that buffer into the same state pointer
 *           orphans  N times: instantiate, (setup,) enter and exit initialisation, one step
 *                    of 1 ms, get a state, free the instance without freeing the state (FMI
 *                    2.0 and 3.0: the free frees every state of the instance); every 1000th
 *                    cycle the last orphaned state is also passed to the next instance's
 *                    set-state, which must refuse it (else "ORPHAN ACCEPTED i" is printed)
 *   EVERY   print "RSS WHAT i bytes" after every EVERY-th call (i counts from 1)
 *   LEAK    (tests of the measurement) the host itself leaks LEAK bytes per call
 *
 * Every call's status is checked: a call that returns an error or worse prints "CALL name
 * returned status" and exits 3.  Log messages print as "LOG status category: message".  "END"
 * and exit code 0 when all N calls ran; 1 bad arguments, 2 instantiation failed, 4 the library
 * or a function could not be loaded.
 */
#include <stdint.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmi3Functions.h"
#include "host_common.h"

static int fmi;
static void *lib;
static char resources[8192];
static const char *token;
static size_t leak;
static void *leaked; /* the host's own planted leak, kept in a list */

static void check(const char *call, int status)
{
    if (status > 1) { /* fmi2Warning == fmi3Warning == 1 */
        printf("CALL %s returned %d\n", call, status);
        exit(3);
    }
}

/* The calls, by FMI version: looked up once. */
static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2DoStepTYPE *step;
    fmi2TerminateTYPE *terminate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
} f2;

static struct {
    fmi3InstantiateCoSimulationTYPE *instantiate;
    fmi3EnterInitializationModeTYPE *enter;
    fmi3ExitInitializationModeTYPE *exit_init;
    fmi3DoStepTYPE *step;
    fmi3TerminateTYPE *terminate;
    fmi3FreeInstanceTYPE *free_instance;
    fmi3GetFMUStateTYPE *get_state;
    fmi3SetFMUStateTYPE *set_state;
    fmi3FreeFMUStateTYPE *free_state;
    fmi3SerializedFMUStateSizeTYPE *size;
    fmi3SerializeFMUStateTYPE *serialize;
    fmi3DeserializeFMUStateTYPE *deserialize;
} f3;

static fmi2CallbackFunctions callbacks2 = {host_logger2, calloc, free, NULL, NULL};

static void look_up(const char *dir, const char *id)
{
    lib = host_open(dir, fmi, id);
    if (fmi == 2) {
        snprintf(resources, sizeof resources, "file://%s/resources", dir);
#define LOOK(field, name) f2.field = (fmi2##name##TYPE *)host_lookup(lib, "fmi2" #name);
        LOOK(instantiate, Instantiate) LOOK(setup, SetupExperiment)
        LOOK(enter, EnterInitializationMode) LOOK(exit_init, ExitInitializationMode)
        LOOK(step, DoStep) LOOK(terminate, Terminate) LOOK(free_instance, FreeInstance)
        LOOK(get_state, GetFMUstate) LOOK(set_state, SetFMUstate) LOOK(free_state, FreeFMUstate)
        LOOK(size, SerializedFMUstateSize) LOOK(serialize, SerializeFMUstate)
        LOOK(deserialize, DeSerializeFMUstate)
#undef LOOK
    } else {
        snprintf(resources, sizeof resources, "%s/resources/", dir);
#define LOOK(field, name) f3.field = (fmi3##name##TYPE *)host_lookup(lib, "fmi3" #name);
        LOOK(instantiate, InstantiateCoSimulation)
        LOOK(enter, EnterInitializationMode) LOOK(exit_init, ExitInitializationMode)
        LOOK(step, DoStep) LOOK(terminate, Terminate) LOOK(free_instance, FreeInstance)
        LOOK(get_state, GetFMUState) LOOK(set_state, SetFMUState) LOOK(free_state, FreeFMUState)
        LOOK(size, SerializedFMUStateSize) LOOK(serialize, SerializeFMUState)
        LOOK(deserialize, DeserializeFMUState)
#undef LOOK
    }
}

/* An instance in Step Mode after one step of 1 ms. */
static void *start(void)
{
    void *c;
    if (fmi == 2) {
        c = f2.instantiate("memory", fmi2CoSimulation, token, resources, &callbacks2,
                           fmi2False, fmi2False);
        if (!c) {
            printf("INSTANTIATE FAILED\n");
            exit(2);
        }
        check("fmi2SetupExperiment", f2.setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
        check("fmi2EnterInitializationMode", f2.enter(c));
        check("fmi2ExitInitializationMode", f2.exit_init(c));
        check("fmi2DoStep", f2.step(c, 0.0, 1e-3, fmi2True));
    } else {
        c = f3.instantiate("memory", token, resources, fmi3False, fmi3False, fmi3False,
                           fmi3False, NULL, 0, NULL, host_logger3, NULL);
        if (!c) {
            printf("INSTANTIATE FAILED\n");
            exit(2);
        }
        fmi3Boolean event, terminate, early;
        fmi3Float64 last;
        check("fmi3EnterInitializationMode",
              f3.enter(c, fmi3False, 0.0, 0.0, fmi3False, 0.0));
        check("fmi3ExitInitializationMode", f3.exit_init(c));
        check("fmi3DoStep", f3.step(c, 0.0, 1e-3, fmi3True, &event, &terminate, &early, &last));
    }
    return c;
}

static void stop(void *c)
{
    if (fmi == 2) {
        check("fmi2Terminate", f2.terminate(c));
        f2.free_instance(c);
    } else {
        check("fmi3Terminate", f3.terminate(c));
        f3.free_instance(c);
    }
}

static void free_instance(void *c)
{
    if (fmi == 2)
        f2.free_instance(c);
    else
        f3.free_instance(c);
}

/* 1 when the instance accepts a state of a freed instance (it must refuse it: an error). */
static int refuse_orphan(void *c, void *orphan)
{
    int quiet = host_quiet, status;
    host_quiet = 1;
    status = fmi == 2 ? (int)f2.set_state(c, orphan) : (int)f3.set_state(c, orphan);
    host_quiet = quiet;
    return status < 3; /* fmi2Error == fmi3Error == 3 */
}

static void get_state(void *c, void **state)
{
    if (fmi == 2)
        check("fmi2GetFMUstate", f2.get_state(c, state));
    else
        check("fmi3GetFMUState", f3.get_state(c, state));
}

static void free_state(void *c, void **state)
{
    if (fmi == 2)
        check("fmi2FreeFMUstate", f2.free_state(c, state));
    else
        check("fmi3FreeFMUState", f3.free_state(c, state));
}

/* Serialise *state into *buffer (grown to the size the FMU says), deserialise it into *state. */
static void serdes(void *c, void **state, char **buffer, size_t *capacity)
{
    size_t size = 0;
    if (fmi == 2)
        check("fmi2SerializedFMUstateSize", f2.size(c, *state, &size));
    else
        check("fmi3SerializedFMUStateSize", f3.size(c, *state, &size));
    if (size > *capacity) {
        free(*buffer);
        *buffer = malloc(size);
        *capacity = size;
        if (!*buffer) {
            printf("OUT OF MEMORY\n");
            exit(3);
        }
    }
    if (fmi == 2) {
        check("fmi2SerializeFMUstate", f2.serialize(c, *state, *buffer, size));
        check("fmi2DeSerializeFMUstate", f2.deserialize(c, *buffer, size, state));
    } else {
        check("fmi3SerializeFMUState", f3.serialize(c, *state, (fmi3Byte *)*buffer, size));
        check("fmi3DeserializeFMUState",
              f3.deserialize(c, (const fmi3Byte *)*buffer, size, state));
    }
}

static void plant_leak(void)
{
    if (leak >= sizeof(void *)) {
        void **p = malloc(leak);
        if (!p)
            return;
        memset(p, 0x5a, leak);
        *p = leaked;
        leaked = p;
    }
}

int main(int argc, char **argv)
{
    if (argc != 8 && argc != 9) {
        fprintf(stderr, "usage: %s FMI DIR MODEL_IDENTIFIER TOKEN WHAT N EVERY [LEAK]\n",
                argv[0]);
        return 1;
    }
    fmi = atoi(argv[1]);
    token = argv[4];
    const char *what = argv[5];
    long n = strtol(argv[6], NULL, 10), every = strtol(argv[7], NULL, 10);
    leak = argc == 9 ? (size_t)strtoul(argv[8], NULL, 10) : 0;
    if ((fmi != 2 && fmi != 3) || n < 0 || every < 1 ||
        (strcmp(what, "cycles") && strcmp(what, "states") && strcmp(what, "serdes") &&
         strcmp(what, "orphans"))) {
        fprintf(stderr, "memory_host: FMI is 2 or 3, WHAT cycles, states, serdes or orphans, "
                        "N >= 0, EVERY >= 1\n");
        return 1;
    }
    setvbuf(stdout, NULL, _IOLBF, 0);
    look_up(argv[2], argv[3]);
    if (!strcmp(what, "cycles")) {
        for (long i = 0; i < n; i++) {
            stop(start());
            plant_leak();
            host_measure(what, i, every);
        }
    } else if (!strcmp(what, "orphans")) {
        void *orphan = NULL;
        for (long i = 0; i < n; i++) {
            void *c = start(), *state = NULL;
            if (orphan && i % 1000 == 0 && refuse_orphan(c, orphan))
                printf("ORPHAN ACCEPTED %ld\n", i);
            get_state(c, &state);
            free_instance(c);
            orphan = state;
            plant_leak();
            host_measure(what, i, every);
        }
    } else {
        void *c = start(), *state = NULL;
        char *buffer = NULL;
        size_t capacity = 0;
        get_state(c, &state);
        for (long i = 0; i < n; i++) {
            if (!strcmp(what, "states"))
                get_state(c, &state);
            else
                serdes(c, &state, &buffer, &capacity);
            plant_leak();
            host_measure(what, i, every);
        }
        free_state(c, &state);
        free(buffer);
        stop(c);
    }
    printf("END\n");
    return 0;
}
