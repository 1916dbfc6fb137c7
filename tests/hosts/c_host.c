/*
 * c_host.c - a minimal FMI 2.0 co-simulation host that is not a Python process.
 *
 * usage: c_host FMU_DIR MODEL_IDENTIFIER GUID VALUE_REFERENCE STEPS STEP_SIZE
 *
 * Loads FMU_DIR/binaries/linux64/MODEL_IDENTIFIER.so, instantiates it with debug logging off,
 * sets up at t = 0, initialises, does STEPS steps of STEP_SIZE and prints the Real
 * VALUE_REFERENCE as "VALUE <number>".  Log messages are printed as "LOG <status> <category>:
 * <message>".  Exit codes: 0 ok, 2 fmi2Instantiate returned NULL, 3 a call failed, 4 the
 * library or a function could not be loaded.
 */
#include "fmi2Functions.h"
#include "host_common.h"

static void check(const char *call, fmi2Status status)
{
    if (status > fmi2Warning) {
        printf("CALL %s returned %d\n", call, (int)status);
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
    fmi2ValueReference vr = (fmi2ValueReference)strtoul(argv[4], NULL, 10);
    int steps = atoi(argv[5]);
    double h = strtod(argv[6], NULL);

    char resources[4096];
    snprintf(resources, sizeof resources, "file://%s/resources", dir);
    void *lib = host_open(dir, 2, id);
    fmi2InstantiateTYPE *instantiate = host_lookup(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = host_lookup(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter = host_lookup(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init = host_lookup(lib, "fmi2ExitInitializationMode");
    fmi2DoStepTYPE *do_step = host_lookup(lib, "fmi2DoStep");
    fmi2GetRealTYPE *get_real = host_lookup(lib, "fmi2GetReal");
    fmi2TerminateTYPE *terminate = host_lookup(lib, "fmi2Terminate");
    fmi2FreeInstanceTYPE *free_instance = host_lookup(lib, "fmi2FreeInstance");

    fmi2CallbackFunctions callbacks = {host_logger2, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("c_host", fmi2CoSimulation, guid, resources, &callbacks,
                                  fmi2False, fmi2False);
    if (!c) {
        printf("INSTANTIATE FAILED\n");
        return 2;
    }
    check("fmi2SetupExperiment", setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    check("fmi2EnterInitializationMode", enter(c));
    check("fmi2ExitInitializationMode", exit_init(c));
    double t = 0.0;
    for (int i = 0; i < steps; i++) {
        check("fmi2DoStep", do_step(c, t, h, fmi2True));
        t += h;
    }
    fmi2Real value;
    check("fmi2GetReal", get_real(c, &vr, 1, &value));
    printf("VALUE %.17g\n", value);
    check("fmi2Terminate", terminate(c));
    free_instance(c);
    return 0;
}
