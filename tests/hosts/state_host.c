/*
 * state_host.c - a C host that gets, sets and frees FMU states from several threads at once, one
 * instance per thread (fmu_src/native/cosimulation.c keeps every live state of the library in
 * one list behind a spin lock, and issues each state handle, a serial number, under it).
 *
 * usage: state_host FMU_DIR MODEL_IDENTIFIER GUID THREADS ROUNDS [instances [RESOURCES_URI]]
 *
 * Each thread instantiates and initialises its instance, waits for the others (a barrier), then
 * ROUNDS times gets a state, sets it and frees it, recording every handle it got.  With
 * "instances" each thread instead waits for the others before its first instantiation, then
 * ROUNDS times instantiates (every thread under the same instance name and resources, at
 * RESOURCES_URI if given), initialises and frees an instance: the Python FMUs' loader shim
 * loads its libraries once under a lock, keeps freed instances in a pool under another, and
 * links a resources folder pythonfmu cannot read under a third (fmu_src/loader/fmi2_shim.c).
 * Printed:
 *
 *   FAILED <n>      calls that did not return fmi2OK (their log lines are printed too);
 *   HANDLES <n> <distinct>  handles got, and how many of them differ (a handle is issued once).
 *
 * Exit codes: 0 ok, 2 fmi2Instantiate returned NULL, 4 a library or function could not be
 * loaded.
 */
#include <pthread.h>
#include <stdint.h>
#include <string.h>

#include "fmi2Functions.h"
#include "host_common.h"

static fmi2InstantiateTYPE *instantiate;
static fmi2SetupExperimentTYPE *setup;
static fmi2EnterInitializationModeTYPE *enter;
static fmi2ExitInitializationModeTYPE *exit_init;
static fmi2GetFMUstateTYPE *get_state;
static fmi2SetFMUstateTYPE *set_state;
static fmi2FreeFMUstateTYPE *free_state;
static fmi2FreeInstanceTYPE *free_instance;
static const char *guid, *resources;
static int rounds, instances_mode;
static pthread_barrier_t barrier;
static pthread_mutex_t count_lock = PTHREAD_MUTEX_INITIALIZER;
static long failed;

typedef struct {
    int index;
    uintptr_t *handles;
} Work;

static void *work(void *arg)
{
    Work *w = arg;
    const fmi2CallbackFunctions callbacks = {host_logger2, calloc, free, NULL, NULL};
    char name[32];
    snprintf(name, sizeof name, "s%d", instances_mode ? 0 : w->index);
    long bad = 0;
    if (instances_mode) {
        pthread_barrier_wait(&barrier);
        for (int i = 0; i < rounds; i++) {
            fmi2Component c = instantiate(name, fmi2CoSimulation, guid, resources, &callbacks,
                                          fmi2False, fmi2False);
            if (!c) {
                bad++;
                continue;
            }
            w->handles[i] = (uintptr_t)i + 1 + (uintptr_t)w->index * (uintptr_t)rounds;
            bad += (setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK)
                + (enter(c) != fmi2OK) + (exit_init(c) != fmi2OK);
            free_instance(c);
        }
    } else {
        fmi2Component c = instantiate(name, fmi2CoSimulation, guid, resources, &callbacks,
                                      fmi2False, fmi2False);
        if (!c)
            exit(2);
        bad = (setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK)
            + (enter(c) != fmi2OK) + (exit_init(c) != fmi2OK);
        pthread_barrier_wait(&barrier);
        for (int i = 0; i < rounds; i++) {
            fmi2FMUstate s = NULL;
            bad += get_state(c, &s) != fmi2OK;
            w->handles[i] = (uintptr_t)s;
            bad += set_state(c, s) != fmi2OK;
            bad += free_state(c, &s) != fmi2OK;
        }
        free_instance(c);
    }
    pthread_mutex_lock(&count_lock);
    failed += bad;
    pthread_mutex_unlock(&count_lock);
    return NULL;
}

static int by_value(const void *a, const void *b)
{
    const uintptr_t x = *(const uintptr_t *)a, y = *(const uintptr_t *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    if (argc < 6 || argc > 8 || (argc > 6 && strcmp(argv[6], "instances"))) {
        fprintf(stderr, "usage: state_host FMU_DIR MODEL_IDENTIFIER GUID THREADS ROUNDS "
                "[instances [RESOURCES_URI]]\n");
        return 1;
    }
    instances_mode = argc > 6;
    const int threads = atoi(argv[4]);
    rounds = atoi(argv[5]);
    guid = argv[3];
    static char uri[8192];
    snprintf(uri, sizeof uri, "file://%s/resources", argv[1]);
    resources = argc > 7 ? argv[7] : uri;
    void *lib = host_open(argv[1], 2, argv[2]);
    instantiate = host_lookup(lib, "fmi2Instantiate");
    setup = host_lookup(lib, "fmi2SetupExperiment");
    enter = host_lookup(lib, "fmi2EnterInitializationMode");
    exit_init = host_lookup(lib, "fmi2ExitInitializationMode");
    get_state = host_lookup(lib, "fmi2GetFMUstate");
    set_state = host_lookup(lib, "fmi2SetFMUstate");
    free_state = host_lookup(lib, "fmi2FreeFMUstate");
    free_instance = host_lookup(lib, "fmi2FreeInstance");
    pthread_barrier_init(&barrier, NULL, (unsigned)threads);
    pthread_t *ids = calloc((size_t)threads, sizeof *ids);
    Work *works = calloc((size_t)threads, sizeof *works);
    uintptr_t *all = calloc((size_t)threads * (size_t)rounds, sizeof *all);
    for (int t = 0; t < threads; t++) {
        works[t].index = t;
        works[t].handles = all + (size_t)t * (size_t)rounds;
        pthread_create(&ids[t], NULL, work, &works[t]);
    }
    for (int t = 0; t < threads; t++)
        pthread_join(ids[t], NULL);
    const size_t n = (size_t)threads * (size_t)rounds;
    qsort(all, n, sizeof *all, by_value);
    size_t distinct = n ? 1 : 0;
    for (size_t i = 1; i < n; i++)
        distinct += all[i] != all[i - 1];
    printf("FAILED %ld\nHANDLES %zu %zu\n", failed, n, distinct);
    return 0;
}
