/*
 * fmi2Functions.c - the FMI 2.0 co-simulation interface onto cosimulation.c, shared by the
 * three models (the way Reference-FMUs separates model.c from fmi2Functions.c).
 */
#define __USE_MINGW_ANSI_STDIO 1
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "cosimulation.h"

/* hostData: [0] the fmi2CallbackFunctions copy, [1] the component environment */
typedef struct {
    fmi2CallbackFunctions callbacks;
} Host2;

static void host_log(ModelInstance *comp, Status status, const char *category,
                     const char *message)
{
    const fmi2CallbackFunctions *cb = comp->hostData[0];
    if (!cb || !cb->logger)
        return;
    /* The message is the logger's format (hosts in languages without varargs, fmpy's among
     * them, print it as it is): every '%' doubled, so that printf-style hosts show it too. */
    char escaped[2048];
    size_t j = 0;
    for (size_t i = 0; message[i] && j + 2 < sizeof escaped; i++) {
        if (message[i] == '%')
            escaped[j++] = '%';
        escaped[j++] = message[i];
    }
    escaped[j] = 0;
    cb->logger(cb->componentEnvironment, comp->instanceName, (fmi2Status)status, category,
               escaped);
}

#define COMP ((ModelInstance *)c)
#define GUARD(name)                                                                        \
    if (!c)                                                                                \
        return fmi2Error;

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    GUARD("fmi2SetDebugLogging");
    (void)nCategories;
    (void)categories;
    return (fmi2Status)cs_set_debug_logging(COMP, loggingOn);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    (void)fmuResourceLocation;   /* any form, or NULL: the model needs no resources */
    (void)visible;
    if (!functions)
        return NULL;   /* no way to say why */
    /* without a logger (FMI 2.0 asks for one) the instance works and logs nowhere, as the
     * Python FMUs' loader shim does */
    fmi2CallbackFunctions *copy = functions->allocateMemory
        ? functions->allocateMemory(1, sizeof *copy) : calloc(1, sizeof *copy);
    if (!copy)
        return NULL;
    *copy = *functions;
    void *host[4] = {copy, NULL, NULL, NULL};
    if (fmuType != fmi2CoSimulation) {
        ModelInstance probe;
        memset(&probe, 0, sizeof probe);
        probe.instanceName = (char *)(instanceName ? instanceName : "");
        probe.hostLog = host_log;
        probe.hostData[0] = copy;
        cs_log(&probe, STATUS_ERROR, "fmi2Instantiate: fmuType %d is not supported; allowed: "
               "fmi2CoSimulation (%d)", (int)fmuType, (int)fmi2CoSimulation);
    } else {
        ModelInstance *comp = cs_instantiate(instanceName, fmuGUID, loggingOn, host_log, host,
                                             "fmi2Instantiate");
        if (comp)
            return comp;
    }
    if (copy->freeMemory)
        copy->freeMemory(copy);
    else
        free(copy);
    return NULL;
}

void fmi2FreeInstance(fmi2Component c)
{
    if (!c)
        return;
    fmi2CallbackFunctions *copy = COMP->hostData[0];
    cs_free(COMP);
    if (copy) {
        if (copy->freeMemory)
            copy->freeMemory(copy);
        else
            free(copy);
    }
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    GUARD("fmi2SetupExperiment");
    (void)toleranceDefined;
    (void)tolerance;
    return (fmi2Status)cs_setup(COMP, "fmi2SetupExperiment", startTime, stopTimeDefined,
                                stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    GUARD("");
    return (fmi2Status)cs_enter_initialization(COMP, "fmi2EnterInitializationMode");
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    GUARD("");
    return (fmi2Status)cs_exit_initialization(COMP, "fmi2ExitInitializationMode");
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    GUARD("");
    return (fmi2Status)cs_terminate(COMP, "fmi2Terminate");
}

fmi2Status fmi2Reset(fmi2Component c)
{
    GUARD("");
    return (fmi2Status)cs_reset(COMP, "fmi2Reset");
}

/* ---- variables ---------------------------------------------------------------------------- */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    GUARD("");
    return (fmi2Status)cs_get(COMP, "fmi2GetReal", TYPE_REAL, vr, nvr, value, NULL);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[])
{
    GUARD("");
    return (fmi2Status)cs_get(COMP, "fmi2GetInteger", TYPE_INTEGER, vr, nvr, NULL, value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[])
{
    GUARD("");
    (void)value;
    return (fmi2Status)cs_no_such_type(COMP, "fmi2GetBoolean", "Boolean", vr, nvr);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[])
{
    GUARD("");
    (void)value;
    return (fmi2Status)cs_no_such_type(COMP, "fmi2GetString", "String", vr, nvr);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    GUARD("");
    return (fmi2Status)cs_set(COMP, "fmi2SetReal", TYPE_REAL, vr, nvr, value, NULL);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    GUARD("");
    return (fmi2Status)cs_set(COMP, "fmi2SetInteger", TYPE_INTEGER, vr, nvr, NULL, value);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    GUARD("");
    (void)value;
    return (fmi2Status)cs_no_such_type(COMP, "fmi2SetBoolean", "Boolean", vr, nvr);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[])
{
    GUARD("");
    (void)value;
    return (fmi2Status)cs_no_such_type(COMP, "fmi2SetString", "String", vr, nvr);
}

/* ---- FMU states --------------------------------------------------------------------------- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    GUARD("");
    return (fmi2Status)cs_get_state(COMP, "fmi2GetFMUstate", (void **)FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    GUARD("");
    return (fmi2Status)cs_set_state(COMP, "fmi2SetFMUstate", FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    GUARD("");
    return (fmi2Status)cs_free_state(COMP, "fmi2FreeFMUstate", (void **)FMUstate);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    GUARD("");
    return (fmi2Status)cs_serialized_size(COMP, "fmi2SerializedFMUstateSize", FMUstate, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size)
{
    GUARD("");
    return (fmi2Status)cs_serialize(COMP, "fmi2SerializeFMUstate", FMUstate,
                                    (unsigned char *)serializedState, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate)
{
    GUARD("");
    return (fmi2Status)cs_deserialize(COMP, "fmi2DeSerializeFMUstate",
                                      (const unsigned char *)serializedState, size,
                                      (void **)FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[])
{
    GUARD("");
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown,
        (void)dvUnknown;
    return (fmi2Status)cs_unsupported(COMP, "fmi2GetDirectionalDerivative");
}

/* ---- co-simulation ------------------------------------------------------------------------ */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    GUARD("");
    (void)vr, (void)nvr, (void)order, (void)value;
    return (fmi2Status)cs_unsupported(COMP, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    GUARD("");
    (void)vr, (void)nvr, (void)order, (void)value;
    return (fmi2Status)cs_unsupported(COMP, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    GUARD("");
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)cs_do_step(COMP, "fmi2DoStep", currentCommunicationPoint,
                                  communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    GUARD("");
    return (fmi2Status)cs_unsupported(COMP, "fmi2CancelStep (every step completes)");
}

/* The status inquiries (as the loader shim answers them for the Python FMUs): fmi2DoStep never
 * returns fmi2Pending and never asks to terminate, so fmi2Terminated is false,
 * fmi2LastSuccessfulTime is the end of the last accepted step, and every other inquiry is
 * fmi2Discard, logged at that level, as the standard says. */
static const char *KINDS[] = {"fmi2DoStepStatus", "fmi2PendingStatus", "fmi2LastSuccessfulTime",
                              "fmi2Terminated"};

static int bad_kind(fmi2Component c, const char *function, fmi2StatusKind s, const void *value)
{
    if (!cs_allowed(COMP, function, STATE_STEP | STATE_TERMINATED))
        return 1;
    if (!value) {
        cs_log(COMP, STATUS_ERROR, "%s: value is NULL; allowed: a valid pointer", function);
        return 1;
    }
    if ((int)s < (int)fmi2DoStepStatus || (int)s > (int)fmi2Terminated) {
        cs_log(COMP, STATUS_ERROR, "%s: status kind %d does not exist; allowed: "
               "fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated",
               function, (int)s);
        return 1;
    }
    return 0;
}

static fmi2Status no_status(fmi2Component c, const char *function, fmi2StatusKind s)
{
    cs_log(COMP, STATUS_DISCARD, "%s(%s): no such status: fmi2DoStep never returns fmi2Pending "
           "(fmi2Discard)", function, KINDS[s]);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    GUARD("");
    if (bad_kind(c, "fmi2GetStatus", s, value))
        return fmi2Error;
    return no_status(c, "fmi2GetStatus", s);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    GUARD("");
    if (bad_kind(c, "fmi2GetRealStatus", s, value))
        return fmi2Error;
    if (s != fmi2LastSuccessfulTime)
        return no_status(c, "fmi2GetRealStatus", s);
    *value = COMP->time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    GUARD("");
    if (bad_kind(c, "fmi2GetIntegerStatus", s, value))
        return fmi2Error;
    return no_status(c, "fmi2GetIntegerStatus", s);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    GUARD("");
    if (bad_kind(c, "fmi2GetBooleanStatus", s, value))
        return fmi2Error;
    if (s != fmi2Terminated)
        return no_status(c, "fmi2GetBooleanStatus", s);
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    GUARD("");
    if (bad_kind(c, "fmi2GetStringStatus", s, value))
        return fmi2Error;
    return no_status(c, "fmi2GetStringStatus", s);
}

/* ---- model exchange: not provided ----------------------------------------------------------- */

#define NOT_ME(name, ...)                                                                   \
    fmi2Status name(__VA_ARGS__)                                                            \
    {                                                                                       \
        GUARD("");                                                                          \
        return (fmi2Status)cs_unsupported(COMP, #name);                                     \
    }

NOT_ME(fmi2EnterEventMode, fmi2Component c)
NOT_ME(fmi2NewDiscreteStates, fmi2Component c, fmi2EventInfo *eventInfo)
NOT_ME(fmi2EnterContinuousTimeMode, fmi2Component c)
NOT_ME(fmi2CompletedIntegratorStep, fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
NOT_ME(fmi2SetTime, fmi2Component c, fmi2Real time)
NOT_ME(fmi2SetContinuousStates, fmi2Component c, const fmi2Real x[], size_t nx)
NOT_ME(fmi2GetDerivatives, fmi2Component c, fmi2Real derivatives[], size_t nx)
NOT_ME(fmi2GetEventIndicators, fmi2Component c, fmi2Real eventIndicators[], size_t ni)
NOT_ME(fmi2GetContinuousStates, fmi2Component c, fmi2Real x[], size_t nx)
NOT_ME(fmi2GetNominalsOfContinuousStates, fmi2Component c, fmi2Real x_nominal[], size_t nx)
