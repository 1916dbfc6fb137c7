/*
 * fmi3Functions.c - the FMI 3.0 co-simulation interface onto cosimulation.c, shared by the
 * three models.  Float64 and Int32 variables (the Python FMUs' Real and Integer, same value
 * references); no event mode, no clocks, no intermediate update.
 */
#define __USE_MINGW_ANSI_STDIO 1
#include <stdio.h>
#include <string.h>

#include "fmi3Functions.h"
#include "cosimulation.h"

/* hostData: [0] the log callback, [1] the instance environment */
typedef struct {
    fmi3LogMessageCallback log;
} LogHolder;

static void host_log(ModelInstance *comp, Status status, const char *category,
                     const char *message)
{
    const LogHolder *holder = comp->hostData[0];
    if (holder && holder->log)
        holder->log(comp->hostData[1], (fmi3Status)status, category, message);
}

#define COMP ((ModelInstance *)instance)
#define GUARD                                                                              \
    if (!instance)                                                                         \
        return fmi3Error;

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                               size_t nCategories, const fmi3String categories[])
{
    GUARD;
    (void)nCategories, (void)categories;
    return (fmi3Status)cs_set_debug_logging(COMP, loggingOn);
}

static ModelInstance *refuse(const char *name, fmi3InstanceEnvironment env,
                             fmi3LogMessageCallback log, const char *why)
{
    if (log) {
        char message[512];
        snprintf(message, sizeof message, "%s: %s", name ? name : "", why);
        log(env, fmi3Error, "logStatusError", message);
    }
    return NULL;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    return refuse(instanceName, instanceEnvironment, logMessage, "fmi3InstantiateModelExchange:"
                  " this FMU supports co-simulation only; use fmi3InstantiateCoSimulation");
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn,
        (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    return refuse(instanceName, instanceEnvironment, logMessage,
                  "fmi3InstantiateScheduledExecution: this FMU supports co-simulation only; "
                  "use fmi3InstantiateCoSimulation");
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)resourcePath;   /* any form, or NULL: the model needs no resources */
    (void)visible, (void)earlyReturnAllowed, (void)requiredIntermediateVariables,
        (void)intermediateUpdate;
    if (eventModeUsed)
        return refuse(instanceName, instanceEnvironment, logMessage,
                      "fmi3InstantiateCoSimulation: eventModeUsed = true is not supported "
                      "(hasEventMode = false); allowed: eventModeUsed = false");
    if (nRequiredIntermediateVariables)
        return refuse(instanceName, instanceEnvironment, logMessage,
                      "fmi3InstantiateCoSimulation: intermediate variables are not supported "
                      "(providesIntermediateUpdate = false); allowed: none");
    LogHolder *holder = calloc(1, sizeof *holder);
    if (!holder)
        return NULL;
    holder->log = logMessage;
    void *host[4] = {holder, instanceEnvironment, NULL, NULL};
    ModelInstance *comp = cs_instantiate(instanceName, instantiationToken, loggingOn, host_log,
                                         host, "fmi3InstantiateCoSimulation");
    if (!comp)
        free(holder);
    return comp;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    if (!instance)
        return;
    void *holder = COMP->hostData[0];
    cs_free(COMP);
    free(holder);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    GUARD;
    (void)toleranceDefined, (void)tolerance;
    if (!cs_allowed(COMP, "fmi3EnterInitializationMode", STATE_INSTANTIATED))
        return fmi3Error;
    Status s = cs_setup(COMP, "fmi3EnterInitializationMode", startTime, stopTimeDefined,
                        stopTime);
    if (s != STATUS_OK)
        return (fmi3Status)s;
    return (fmi3Status)cs_enter_initialization(COMP, "fmi3EnterInitializationMode");
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    GUARD;
    return (fmi3Status)cs_exit_initialization(COMP, "fmi3ExitInitializationMode");
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    GUARD;
    return (fmi3Status)cs_terminate(COMP, "fmi3Terminate");
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    GUARD;
    return (fmi3Status)cs_reset(COMP, "fmi3Reset");
}

/* ---- variables ---------------------------------------------------------------------------- */

/* The counts of a get or set, checked before any element is read or written: nValues is the
 * sum of the variables' sizes (every variable of this FMU is a scalar: nValues == nvr), and
 * nvr is within MAX_VALUES_PER_CALL (cosimulation.h). */
static int counts_match(fmi3Instance instance, const char *function, size_t nvr, size_t nValues)
{
    if (nvr != nValues) {
        cs_log(COMP, STATUS_ERROR, "%s: %llu value references but %llu values; every variable "
               "is a scalar, allowed: as many values as value references", function,
               (unsigned long long)nvr, (unsigned long long)nValues);
        return 0;
    }
    return cs_count_ok(COMP, function, nvr);
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          fmi3Float64 values[], size_t nValues)
{
    GUARD;
    if (!counts_match(instance, "fmi3GetFloat64", nvr, nValues))
        return fmi3Error;
    return (fmi3Status)cs_get(COMP, "fmi3GetFloat64", TYPE_REAL, vr, nvr, values, NULL);
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues)
{
    GUARD;
    if (!counts_match(instance, "fmi3SetFloat64", nvr, nValues))
        return fmi3Error;
    return (fmi3Status)cs_set(COMP, "fmi3SetFloat64", TYPE_REAL, vr, nvr, values, NULL);
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Int32 values[], size_t nValues)
{
    GUARD;
    if (!counts_match(instance, "fmi3GetInt32", nvr, nValues))
        return fmi3Error;
    return (fmi3Status)cs_get(COMP, "fmi3GetInt32", TYPE_INTEGER, vr, nvr, NULL, (int *)values);
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Int32 values[], size_t nValues)
{
    GUARD;
    if (!counts_match(instance, "fmi3SetInt32", nvr, nValues))
        return fmi3Error;
    return (fmi3Status)cs_set(COMP, "fmi3SetInt32", TYPE_INTEGER, vr, nvr, NULL,
                              (const int *)values);
}

/* The types this FMU has no variable of: every value reference is an error (the counts are
 * checked first: nothing is read with a count no array can have). */
#define NO_TYPE(kind, ctype)                                                                \
    fmi3Status fmi3Get##kind(fmi3Instance instance, const fmi3ValueReference vr[],          \
                             size_t nvr, ctype values[], size_t nValues)                    \
    {                                                                                       \
        GUARD;                                                                              \
        (void)values;                                                                       \
        if (!counts_match(instance, "fmi3Get" #kind, nvr, nValues))                         \
            return fmi3Error;                                                               \
        return (fmi3Status)cs_no_such_type(COMP, "fmi3Get" #kind, #kind, vr, nvr);          \
    }                                                                                       \
    fmi3Status fmi3Set##kind(fmi3Instance instance, const fmi3ValueReference vr[],          \
                             size_t nvr, const ctype values[], size_t nValues)              \
    {                                                                                       \
        GUARD;                                                                              \
        (void)values;                                                                       \
        if (!counts_match(instance, "fmi3Set" #kind, nvr, nValues))                         \
            return fmi3Error;                                                               \
        return (fmi3Status)cs_no_such_type(COMP, "fmi3Set" #kind, #kind, vr, nvr);          \
    }

NO_TYPE(Float32, fmi3Float32)
NO_TYPE(Int8, fmi3Int8)
NO_TYPE(UInt8, fmi3UInt8)
NO_TYPE(Int16, fmi3Int16)
NO_TYPE(UInt16, fmi3UInt16)
NO_TYPE(UInt32, fmi3UInt32)
NO_TYPE(Int64, fmi3Int64)
NO_TYPE(UInt64, fmi3UInt64)
NO_TYPE(Boolean, fmi3Boolean)
NO_TYPE(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    GUARD;
    (void)valueSizes, (void)values;
    if (!counts_match(instance, "fmi3GetBinary", nvr, nValues))
        return fmi3Error;
    return (fmi3Status)cs_no_such_type(COMP, "fmi3GetBinary", "Binary", vr, nvr);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    GUARD;
    (void)valueSizes, (void)values;
    if (!counts_match(instance, "fmi3SetBinary", nvr, nValues))
        return fmi3Error;
    return (fmi3Status)cs_no_such_type(COMP, "fmi3SetBinary", "Binary", vr, nvr);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Clock values[])
{
    GUARD;
    (void)values;
    return (fmi3Status)cs_no_such_type(COMP, "fmi3GetClock", "Clock", vr, nvr);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Clock values[])
{
    GUARD;
    (void)values;
    return (fmi3Status)cs_no_such_type(COMP, "fmi3SetClock", "Clock", vr, nvr);
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr,
                                               size_t *nDependencies)
{
    GUARD;
    (void)vr, (void)nDependencies;
    return (fmi3Status)cs_unsupported(COMP, "fmi3GetNumberOfVariableDependencies (the model "
                                      "description lists them)");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies)
{
    GUARD;
    (void)dependent, (void)elementIndicesOfDependent, (void)independents,
        (void)elementIndicesOfIndependents, (void)dependencyKinds, (void)nDependencies;
    return (fmi3Status)cs_unsupported(COMP, "fmi3GetVariableDependencies (the model "
                                      "description lists them)");
}

/* ---- FMU states --------------------------------------------------------------------------- */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    GUARD;
    return (fmi3Status)cs_get_state(COMP, "fmi3GetFMUState", (void **)FMUState);
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    GUARD;
    return (fmi3Status)cs_set_state(COMP, "fmi3SetFMUState", FMUState);
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    GUARD;
    return (fmi3Status)cs_free_state(COMP, "fmi3FreeFMUState", (void **)FMUState);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    GUARD;
    return (fmi3Status)cs_serialized_size(COMP, "fmi3SerializedFMUStateSize", FMUState, size);
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size)
{
    GUARD;
    return (fmi3Status)cs_serialize(COMP, "fmi3SerializeFMUState", FMUState,
                                    (unsigned char *)serializedState, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState)
{
    GUARD;
    return (fmi3Status)cs_deserialize(COMP, "fmi3DeserializeFMUState",
                                      (const unsigned char *)serializedState, size,
                                      (void **)FMUState);
}

/* ---- co-simulation ------------------------------------------------------------------------ */

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    GUARD;
    return (fmi3Status)cs_unsupported(COMP, "fmi3EnterStepMode (no event mode: "
                                      "fmi3ExitInitializationMode enters step mode)");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    GUARD;
    (void)noSetFMUStatePriorToCurrentPoint;
    Status s = cs_do_step(COMP, "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded)
        *eventHandlingNeeded = fmi3False;
    if (terminateSimulation)
        *terminateSimulation = fmi3False;
    if (earlyReturn)
        *earlyReturn = fmi3False;
    if (lastSuccessfulTime)
        *lastSuccessfulTime = COMP->time;
    return (fmi3Status)s;
}

/* ---- not provided: derivatives, configuration, clocks, events, model exchange ------------- */

#define NOT_HERE(name, ...)                                                                 \
    fmi3Status name(fmi3Instance instance, ##__VA_ARGS__)                                   \
    {                                                                                       \
        GUARD;                                                                              \
        return (fmi3Status)cs_unsupported(COMP, #name);                                     \
    }

NOT_HERE(fmi3EnterEventMode)
NOT_HERE(fmi3GetDirectionalDerivative, const fmi3ValueReference unknowns[], size_t nUnknowns,
         const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
         size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
NOT_HERE(fmi3GetAdjointDerivative, const fmi3ValueReference unknowns[], size_t nUnknowns,
         const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
         size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
NOT_HERE(fmi3EnterConfigurationMode)
NOT_HERE(fmi3ExitConfigurationMode)
NOT_HERE(fmi3GetIntervalDecimal, const fmi3ValueReference vr[], size_t nvr,
         fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
NOT_HERE(fmi3GetIntervalFraction, const fmi3ValueReference vr[], size_t nvr,
         fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
NOT_HERE(fmi3GetShiftDecimal, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 shifts[])
NOT_HERE(fmi3GetShiftFraction, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 counters[],
         fmi3UInt64 resolutions[])
NOT_HERE(fmi3SetIntervalDecimal, const fmi3ValueReference vr[], size_t nvr,
         const fmi3Float64 intervals[])
NOT_HERE(fmi3SetIntervalFraction, const fmi3ValueReference vr[], size_t nvr,
         const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
NOT_HERE(fmi3SetShiftDecimal, const fmi3ValueReference vr[], size_t nvr,
         const fmi3Float64 shifts[])
NOT_HERE(fmi3SetShiftFraction, const fmi3ValueReference vr[], size_t nvr,
         const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
NOT_HERE(fmi3EvaluateDiscreteStates)
NOT_HERE(fmi3UpdateDiscreteStates, fmi3Boolean *discreteStatesNeedUpdate,
         fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
         fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
         fmi3Float64 *nextEventTime)
NOT_HERE(fmi3EnterContinuousTimeMode)
NOT_HERE(fmi3CompletedIntegratorStep, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
         fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
NOT_HERE(fmi3SetTime, fmi3Float64 time)
NOT_HERE(fmi3SetContinuousStates, const fmi3Float64 continuousStates[],
         size_t nContinuousStates)
NOT_HERE(fmi3GetContinuousStateDerivatives, fmi3Float64 derivatives[],
         size_t nContinuousStates)
NOT_HERE(fmi3GetEventIndicators, fmi3Float64 eventIndicators[], size_t nEventIndicators)
NOT_HERE(fmi3GetContinuousStates, fmi3Float64 continuousStates[], size_t nContinuousStates)
NOT_HERE(fmi3GetNominalsOfContinuousStates, fmi3Float64 nominals[], size_t nContinuousStates)
NOT_HERE(fmi3GetNumberOfEventIndicators, size_t *nEventIndicators)
NOT_HERE(fmi3GetNumberOfContinuousStates, size_t *nContinuousStates)
NOT_HERE(fmi3GetOutputDerivatives, const fmi3ValueReference vr[], size_t nvr,
         const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
NOT_HERE(fmi3ActivateModelPartition, fmi3ValueReference clockReference,
         fmi3Float64 activationTime)
