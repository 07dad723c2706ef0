/* glider-cosim's FMI 2.0 co-simulation front end: the fmi2* functions over the layer.
 *
 * Each function only turns FMI 2.0's arguments into a layer operation (fmi_layer.c),
 * which checks the instance and the state machine, runs the back end and reports: the
 * state machine and the error contract are written once, for FMI 2.0 and 3.0 alike.
 * C99. Written from the FMI 2.0.4 standard and the FMI headers that fmpy ships.
 */
#include <stdio.h>
#include <stdlib.h>

#include "fmi2Functions.h"
#include "fmi_layer.h"

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    return (fmi2Status)glider_op_set_debug_logging(c, loggingOn != fmi2False, nCategories,
                                                   categories);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    HostLogger logger = {0, NULL, NULL, NULL};
    char text[600];
    char *resources;
    void *inst;
    (void)fmuGUID;
    if (functions) {
        logger.log2 = (Fmi2Logger)functions->logger;
        logger.env = functions->componentEnvironment;
    }
    if (!instanceName || !instanceName[0]) {
        glider_log_orphan(&logger, "?", fmi2Error, "fmi2Instantiate: instanceName is NULL or empty");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        snprintf(text, sizeof text, "fmi2Instantiate: %s supports co-simulation only",
                 GLIDER_BACKEND.model_identifier());
        glider_log_orphan(&logger, instanceName, fmi2Error, text);
        return NULL;
    }
    resources = fmuResourceLocation ? glider_resource_path(fmuResourceLocation) : NULL;
    if (!resources) {
        snprintf(text, sizeof text,
                 "fmi2Instantiate: fmuResourceLocation '%.200s' is invalid: expected a file: URI",
                 fmuResourceLocation ? fmuResourceLocation : "(null)");
        glider_log_orphan(&logger, instanceName, fmi2Error, text);
        return NULL;
    }
    inst = glider_op_instantiate(instanceName, resources, visible != fmi2False,
                                 loggingOn != fmi2False, &logger);
    free(resources);
    return inst;
}

void fmi2FreeInstance(fmi2Component c) { glider_op_free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    return (fmi2Status)glider_op_setup(c, C_SETUP_EXPERIMENT, toleranceDefined != fmi2False,
                                       tolerance, startTime, stopTimeDefined != fmi2False,
                                       stopTime, 0);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    return (fmi2Status)glider_op_transition(c, C_ENTER_INIT, S_INIT);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return (fmi2Status)glider_op_transition(c, C_EXIT_INIT, S_STEP_COMPLETE);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    return (fmi2Status)glider_op_transition(c, C_TERMINATE, S_TERMINATED);
}

fmi2Status fmi2Reset(fmi2Component c) { return (fmi2Status)glider_op_reset(c); }

/* fmi2Get<Type> and fmi2Set<Type> for the four types */
#define VALUE_ACCESS(Type, TYPE)                                                           \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,   \
                             fmi2##Type value[]) {                                         \
        return (fmi2Status)glider_op_access(c, C_GET_##TYPE, T_##TYPE, vr, nvr, nvr, NULL,  \
                                            (void *)value);                                \
    }                                                                                      \
    fmi2Status fmi2Set##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,   \
                             const fmi2##Type value[]) {                                   \
        return (fmi2Status)glider_op_access(c, C_SET_##TYPE, T_##TYPE, vr, nvr, nvr,        \
                                            (const void *)value, NULL);                    \
    }
VALUE_ACCESS(Real, REAL)
VALUE_ACCESS(Integer, INTEGER)
VALUE_ACCESS(Boolean, BOOLEAN)
VALUE_ACCESS(String, STRING)
#undef VALUE_ACCESS

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    return (fmi2Status)glider_op_get_state(c, FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    return (fmi2Status)glider_op_set_state(c, FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    return (fmi2Status)glider_op_free_state(c, FMUstate);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    return (fmi2Status)glider_op_state_size(c, FMUstate, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte buffer[],
                                 size_t size) {
    return (fmi2Status)glider_op_serialize(c, FMUstate, buffer, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    return (fmi2Status)glider_op_deserialize(c, serializedState, size, FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    return (fmi2Status)glider_op_directional(c, vUnknown_ref, nUnknown, vKnown_ref, nKnown,
                                             dvKnown, nKnown, dvUnknown, nUnknown);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return (fmi2Status)glider_op_unsupported(c, C_SET_INPUT_DERIVATIVES);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return (fmi2Status)glider_op_unsupported(c, C_GET_OUTPUT_DERIVATIVES);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return (fmi2Status)glider_op_unsupported(c, C_CANCEL_STEP);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)glider_op_do_step(c, currentCommunicationPoint, communicationStepSize,
                                         NULL, NULL);
}

static void store_step_status(const Instance *i, void *v) {
    *(fmi2Status *)v = i->state == S_STEP_FAILED ? fmi2Discard : fmi2OK;
}
static void store_last_time(const Instance *i, void *v) { *(fmi2Real *)v = i->time; }
static void store_terminated(const Instance *i, void *v) {
    *(fmi2Boolean *)v = i->terminated ? fmi2True : fmi2False;
}
static void store_pending(const Instance *i, void *v) {
    (void)i;
    *(fmi2String *)v = "no asynchronous step is pending";
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    return (fmi2Status)glider_op_query(c, C_GET_STATUS, (int)s, fmi2DoStepStatus,
                                       store_step_status, value);
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    return (fmi2Status)glider_op_query(c, C_GET_REAL_STATUS, (int)s, fmi2LastSuccessfulTime,
                                       store_last_time, value);
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    return (fmi2Status)glider_op_query(c, C_GET_INTEGER_STATUS, (int)s, fmi2DoStepStatus, NULL,
                                       value);
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    return (fmi2Status)glider_op_query(c, C_GET_BOOLEAN_STATUS, (int)s, fmi2Terminated,
                                       store_terminated, value);
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    return (fmi2Status)glider_op_query(c, C_GET_STRING_STATUS, (int)s, fmi2PendingStatus,
                                       store_pending, value);
}
