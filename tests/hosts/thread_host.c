/*
 * thread_host.c - a C host (no Python in the process) that calls a Python FMU from two threads
 * one after the other, and reports what the Python thread states did.
 *
 * usage: thread_host FMU_DIR MODEL_IDENTIFIER GUID VALUE_REFERENCE STEPS STEP_SIZE
 *
 * The main thread instantiates and initialises the FMU; thread A does the first half of the
 * STEPS steps and ends; thread B does the rest and reads the Real VALUE_REFERENCE; the main
 * thread terminates and frees it.  Printed:
 *
 *   STATE <thread> <same>  whether the thread had one Python thread state after every one of its
 *                          calls (1) or none / a different one after some call (0): the loader
 *                          shim keeps one per thread instead of a new one per call;
 *   THREADS <when> <n>     Python thread states alive (the main thread's and pythonfmu's own
 *                          count, and the one of this count itself): after A ended, A's state
 *                          must be gone;
 *   VALUE <number>         the output after STEPS steps (as c_host.c prints it).
 *
 * Exit codes: 0 ok, 2 fmi2Instantiate returned NULL, 3 a call failed, 4 a library or function
 * could not be loaded.  Log messages are printed as "LOG <status> <category>: <message>".
 */
#include <pthread.h>

#include "fmi2Functions.h"
#include "host_common.h"

static void check(const char *call, fmi2Status status)
{
    if (status > fmi2Warning) {
        printf("CALL %s returned %d\n", call, (int)status);
        exit(3);
    }
}

/* The Python C API, from the libpython the FMU's loader brought into the process. */
static void *(*this_thread_state)(void);
static int (*gil_ensure)(void);
static void (*gil_release)(int);
static void *(*main_interpreter)(void);
static void *(*thread_head)(void *);
static void *(*thread_next)(void *);

static fmi2DoStepTYPE *do_step;
static fmi2GetRealTYPE *get_real;
static fmi2Component component;
static fmi2ValueReference vr;
static double h;
static int steps, done;

/* Python thread states of the interpreter, counted under the GIL. */
static int count_thread_states(void)
{
    int gil = gil_ensure();
    int n = 0;
    for (void *t = thread_head(main_interpreter()); t; t = thread_next(t))
        n++;
    gil_release(gil);
    return n;
}

static void *stepper(void *name)
{
    void *first = NULL;
    int same = 1;
    int last = *(const char *)name == 'B';
    int until = last ? steps : steps / 2;
    for (; done < until; done++) {
        check("fmi2DoStep", do_step(component, done * h, h, fmi2True));
        void *now = this_thread_state();
        if (!first)
            first = now;
        same = same && now && now == first;
    }
    if (last) {
        fmi2Real value;
        check("fmi2GetReal", get_real(component, &vr, 1, &value));
        same = same && this_thread_state() == first;
        printf("VALUE %.17g\n", value);
    }
    printf("STATE %s %d\n", (const char *)name, same);
    return NULL;
}

static void in_thread(const char *name)
{
    pthread_t thread;
    if (pthread_create(&thread, NULL, stepper, (void *)name) || pthread_join(thread, NULL)) {
        printf("THREAD %s could not run\n", name);
        exit(3);
    }
}

int main(int argc, char **argv)
{
    if (argc != 7) {
        fprintf(stderr, "usage: %s FMU_DIR MODEL_IDENTIFIER GUID VR STEPS STEP_SIZE\n", argv[0]);
        return 1;
    }
    const char *dir = argv[1], *id = argv[2], *guid = argv[3];
    vr = (fmi2ValueReference)strtoul(argv[4], NULL, 10);
    steps = atoi(argv[5]);
    h = strtod(argv[6], NULL);

    char resources[4096];
    snprintf(resources, sizeof resources, "file://%s/resources", dir);
    void *lib = host_open(dir, 2, id);
    fmi2InstantiateTYPE *instantiate = host_lookup(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = host_lookup(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter = host_lookup(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init = host_lookup(lib, "fmi2ExitInitializationMode");
    fmi2TerminateTYPE *terminate = host_lookup(lib, "fmi2Terminate");
    fmi2FreeInstanceTYPE *free_instance = host_lookup(lib, "fmi2FreeInstance");
    do_step = host_lookup(lib, "fmi2DoStep");
    get_real = host_lookup(lib, "fmi2GetReal");

    fmi2CallbackFunctions callbacks = {host_logger2, calloc, free, NULL, NULL};
    component = instantiate("thread_host", fmi2CoSimulation, guid, resources, &callbacks,
                            fmi2False, fmi2False);
    if (!component) {
        printf("INSTANTIATE FAILED\n");
        return 2;
    }
    this_thread_state = host_lookup(RTLD_DEFAULT, "PyGILState_GetThisThreadState");
    gil_ensure = (int (*)(void))host_lookup(RTLD_DEFAULT, "PyGILState_Ensure");
    gil_release = (void (*)(int))host_lookup(RTLD_DEFAULT, "PyGILState_Release");
    main_interpreter = host_lookup(RTLD_DEFAULT, "PyInterpreterState_Main");
    thread_head = (void *(*)(void *))host_lookup(RTLD_DEFAULT, "PyInterpreterState_ThreadHead");
    thread_next = (void *(*)(void *))host_lookup(RTLD_DEFAULT, "PyThreadState_Next");

    check("fmi2SetupExperiment", setup(component, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    check("fmi2EnterInitializationMode", enter(component));
    check("fmi2ExitInitializationMode", exit_init(component));
    printf("THREADS before %d\n", count_thread_states());
    in_thread("A");
    printf("THREADS after-A %d\n", count_thread_states());
    in_thread("B");
    printf("THREADS after-B %d\n", count_thread_states());
    check("fmi2Terminate", terminate(component));
    free_instance(component);
    return 0;
}
