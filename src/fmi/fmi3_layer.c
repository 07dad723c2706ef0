/* glider-cosim's FMI 3.0 co-simulation front end: the fmi3* functions over the layer.
 *
 * The same operations as FMI 2.0's front end (fmi_layer.c: one state machine, one error
 * contract): each function turns FMI 3.0's arguments into a layer operation. What FMI 3.0
 * adds and our models do not need is refused with a message: event mode, clocks,
 * configuration mode, early return, intermediate update, model exchange and scheduled
 * execution, and the types the models have none of (Float32, the other integers, Binary).
 * A stall is fmi3Discard with terminateSimulation true.
 * C99. Written from the FMI 3.0 standard and the FMI headers that fmpy ships.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "fmi_layer.h"

#define S(x) ((fmi3Status)(x))

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    return S(glider_op_set_debug_logging(instance, loggingOn, nCategories, categories));
}

static void orphan(fmi3InstanceEnvironment env, fmi3LogMessageCallback log, const char *name,
                   const char *what) {
    HostLogger logger = {1, NULL, NULL, NULL};
    logger.log3 = (Fmi3Logger)log;
    logger.env = env;
    glider_log_orphan(&logger, name, fmi3Error, what);
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    HostLogger logger = {1, NULL, NULL, NULL};
    char *resources;
    size_t n;
    void *inst;
    (void)instantiationToken, (void)earlyReturnAllowed, (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables, (void)intermediateUpdate;
    logger.log3 = (Fmi3Logger)logMessage;
    logger.env = instanceEnvironment;
    if (!instanceName || !instanceName[0]) {
        orphan(instanceEnvironment, logMessage, "?",
               "fmi3InstantiateCoSimulation: instanceName is NULL or empty");
        return NULL;
    }
    if (eventModeUsed) {
        orphan(instanceEnvironment, logMessage, instanceName,
               "fmi3InstantiateCoSimulation: eventModeUsed is invalid: this FMU has no event "
               "mode (hasEventMode = false)");
        return NULL;
    }
    /* a native path, usually with a trailing separator; NULL or empty: no resources */
    resources = glider_dup_text(resourcePath ? resourcePath : "");
    if (!resources) return NULL;
    n = strlen(resources);
    while (n > 1 && (resources[n - 1] == '/' || resources[n - 1] == '\\')) resources[--n] = '\0';
    inst = glider_op_instantiate(instanceName, resources, visible, loggingOn, &logger);
    free(resources);
    return inst;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    orphan(instanceEnvironment, logMessage, instanceName,
           "fmi3InstantiateModelExchange: this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    orphan(instanceEnvironment, logMessage, instanceName,
           "fmi3InstantiateScheduledExecution: this FMU supports co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { glider_op_free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    return S(glider_op_setup(instance, C_ENTER_INIT, toleranceDefined, tolerance, startTime,
                             stopTimeDefined, stopTime, 1));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    return S(glider_op_transition(instance, C_EXIT_INIT, S_STEP_COMPLETE));
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    return S(glider_op_transition(instance, C_TERMINATE, S_TERMINATED));
}

fmi3Status fmi3Reset(fmi3Instance instance) { return S(glider_op_reset(instance)); }

/* ------------------------------------------------------------------ values */
fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          fmi3Float64 values[], size_t nValues) {
    return S(glider_op_access(instance, C_GET_REAL, T_REAL, vr, nvr, nValues, NULL, values));
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues) {
    return S(glider_op_access(instance, C_SET_REAL, T_REAL, vr, nvr, nValues, values, NULL));
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Int32 values[], size_t nValues) {
    return S(glider_op_access(instance, C_GET_INTEGER, T_INTEGER, vr, nvr, nValues, NULL,
                              values));
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Int32 values[], size_t nValues) {
    return S(glider_op_access(instance, C_SET_INTEGER, T_INTEGER, vr, nvr, nValues, values,
                              NULL));
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         fmi3String values[], size_t nValues) {
    return S(glider_op_access(instance, C_GET_STRING, T_STRING, vr, nvr, nValues, NULL,
                              (void *)values));
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const fmi3String values[], size_t nValues) {
    return S(glider_op_access(instance, C_SET_STRING, T_STRING, vr, nvr, nValues,
                              (const void *)values, NULL));
}

/* fmi3Boolean is C's bool; the layer holds Booleans as int */
#define BOOL_BATCH 64
fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          fmi3Boolean values[], size_t nValues) {
    int buf[BOOL_BATCH];
    size_t done = 0, i;
    int st = 0;
    if (!vr || !values || nvr != nValues || nvr == 0) /* the layer says what is wrong */
        return S(glider_op_access(instance, C_GET_BOOLEAN, T_BOOLEAN, vr, nvr, nValues, NULL,
                                  values ? (void *)buf : NULL));
    while (done < nvr && st <= fmi3Warning) { /* in batches: no heap */
        size_t k = nvr - done < BOOL_BATCH ? nvr - done : BOOL_BATCH;
        st = glider_op_access(instance, C_GET_BOOLEAN, T_BOOLEAN, vr + done, k, k, NULL, buf);
        for (i = 0; st <= fmi3Warning && i < k; ++i) values[done + i] = buf[i] != 0;
        done += k;
    }
    return S(st);
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Boolean values[], size_t nValues) {
    int buf[BOOL_BATCH];
    size_t done = 0, i;
    int st = 0;
    if (!vr || !values || nvr != nValues || nvr == 0)
        return S(glider_op_access(instance, C_SET_BOOLEAN, T_BOOLEAN, vr, nvr, nValues,
                                  values ? (const void *)buf : NULL, NULL));
    while (done < nvr && st <= fmi3Warning) {
        size_t k = nvr - done < BOOL_BATCH ? nvr - done : BOOL_BATCH;
        for (i = 0; i < k; ++i) buf[i] = values[done + i] ? 1 : 0;
        st = glider_op_access(instance, C_SET_BOOLEAN, T_BOOLEAN, vr + done, k, k, buf, NULL);
        done += k;
    }
    return S(st);
}

/* The types the models have none of: any reference is refused (named, with its type). */
#define OTHER_TYPE(Type, code)                                                              \
    fmi3Status fmi3Get##Type(fmi3Instance instance, const fmi3ValueReference vr[],          \
                             size_t nvr, fmi3##Type values[], size_t nValues) {             \
        return S(glider_op_access(instance, C_GET_OTHER, code, vr, nvr, nValues, NULL,       \
                                  (void *)values));                                         \
    }                                                                                       \
    fmi3Status fmi3Set##Type(fmi3Instance instance, const fmi3ValueReference vr[],          \
                             size_t nvr, const fmi3##Type values[], size_t nValues) {       \
        return S(glider_op_access(instance, C_SET_OTHER, code, vr, nvr, nValues,             \
                                  (const void *)values, NULL));                             \
    }
OTHER_TYPE(Float32, 'f')
OTHER_TYPE(Int8, '1')
OTHER_TYPE(UInt8, '2')
OTHER_TYPE(Int16, '3')
OTHER_TYPE(UInt16, '4')
OTHER_TYPE(UInt32, '5')
OTHER_TYPE(Int64, '6')
OTHER_TYPE(UInt64, '7')
#undef OTHER_TYPE

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    (void)valueSizes;
    return S(glider_op_access(instance, C_GET_OTHER, 'y', vr, nvr, nValues, NULL,
                              (void *)values));
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)valueSizes;
    return S(glider_op_access(instance, C_SET_OTHER, 'y', vr, nvr, nValues,
                              (const void *)values, NULL));
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Clock values[]) {
    return S(glider_op_access(instance, C_GET_OTHER, 'c', vr, nvr, nvr, NULL, (void *)values));
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Clock values[]) {
    return S(glider_op_access(instance, C_SET_OTHER, 'c', vr, nvr, nvr, (const void *)values,
                              NULL));
}

/* ------------------------------------------------------------------ FMU state */
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    return S(glider_op_get_state(instance, FMUState));
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    return S(glider_op_set_state(instance, FMUState));
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    return S(glider_op_free_state(instance, FMUState));
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) {
    return S(glider_op_state_size(instance, FMUState, size));
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    return S(glider_op_serialize(instance, FMUState, (char *)serializedState, size));
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    return S(glider_op_deserialize(instance, (const char *)serializedState, size, FMUState));
}

/* ------------------------------------------------------------------ stepping */
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    int terminated = 0, st;
    double last = currentCommunicationPoint;
    (void)noSetFMUStatePriorToCurrentPoint;
    st = glider_op_do_step(instance, currentCommunicationPoint, communicationStepSize,
                           &terminated, &last);
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = terminated ? fmi3True : fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = last;
    return S(st);
}

/* ------------------------------------------------------------------ not provided */
#define NONE(call) return S(glider_op_unsupported(instance, call))

fmi3Status fmi3EnterEventMode(fmi3Instance instance) { NONE(C_FMI3_ONLY); }
fmi3Status fmi3EnterStepMode(fmi3Instance instance) { NONE(C_FMI3_ONLY); }
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { NONE(C_FMI3_ONLY); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { NONE(C_FMI3_ONLY); }
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { NONE(C_FMI3_ONLY); }
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { NONE(C_FMI3_ONLY); }

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                               fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference, (void)nDependencies;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent, (void)elementIndicesOfDependent, (void)independents;
    (void)elementIndicesOfIndependents, (void)dependencyKinds, (void)nDependencies;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                        size_t nUnknowns, const fmi3ValueReference knowns[],
                                        size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                        fmi3Float64 sensitivity[], size_t nSensitivity) {
    return S(glider_op_directional(instance, unknowns, nUnknowns, knowns, nKnowns, seed, nSeed,
                                   sensitivity, nSensitivity));
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                    size_t nUnknowns, const fmi3ValueReference knowns[],
                                    size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                    fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed;
    (void)sensitivity, (void)nSensitivity;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[],
                                  size_t nvr, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    (void)vr, (void)nvr, (void)intervals, (void)qualifiers;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[],
                                   size_t nvr, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions, (void)qualifiers;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)vr, (void)nvr, (void)shifts;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[],
                                size_t nvr, fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[],
                                  size_t nvr, const fmi3Float64 intervals[]) {
    (void)vr, (void)nvr, (void)intervals;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[],
                                   size_t nvr, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)vr, (void)nvr, (void)shifts;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[],
                                size_t nvr, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    (void)discreteStatesNeedUpdate, (void)terminateSimulation;
    (void)nominalsOfContinuousStatesChanged, (void)valuesOfContinuousStatesChanged;
    (void)nextEventTimeDefined, (void)nextEventTime;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives, (void)nContinuousStates;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) {
    (void)eventIndicators, (void)nEventIndicators;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals, (void)nContinuousStates;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    (void)nEventIndicators;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    (void)nContinuousStates;
    NONE(C_FMI3_ONLY);
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[],
                                    size_t nvr, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) {
    (void)vr, (void)nvr, (void)orders, (void)values, (void)nValues;
    NONE(C_GET_OUTPUT_DERIVATIVES);
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference, (void)activationTime;
    NONE(C_FMI3_ONLY);
}
