/* toggle-cosim: the FMI 3.0 Co-Simulation layer of a sampled controller FMU over the instance
 * core (vsc_core.c). Every function of fmi3Functions.h is here: Co-Simulation without Event
 * Mode, early return or intermediate update; Float64 variables and the independent variable
 * time. Model Exchange and Scheduled Execution instantiate nothing (NULL); the other functions
 * are refused with fmi3Error and a log message, which leaves the instance as it was. */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "vsc_core.h"

typedef struct {
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log;
} layer_env;

static void emit3(const vsc_core *c, int status, const char *category, const char *message) {
    const layer_env *env = c->env;
    if (env->log != NULL) { env->log(env->environment, (fmi3Status)status, category, message); }
}

#define CORE(instance) ((vsc_core *)(instance))

static fmi3Status refused(fmi3Instance instance, const char *function) {
    if (instance == NULL) { return fmi3Error; }
    return (fmi3Status)vsc_log(CORE(instance), VSC_ERROR, "%s: not supported by this FMU (Co-Simulation "
                               "with Float64 variables, no Event Mode, clocks or derivatives)", function);
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    if (instance == NULL) { return fmi3Error; }
    return (fmi3Status)vsc_set_categories(CORE(instance), loggingOn, nCategories, categories);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    if (logMessage != NULL) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateModelExchange: " VSC_MODEL_IDENTIFIER " offers Co-Simulation only");
    }
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible,
                                               fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage != NULL) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: " VSC_MODEL_IDENTIFIER " offers Co-Simulation only");
    }
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    layer_env *env;
    vsc_core *c;
    const char *problem = NULL;
    (void)resourcePath; (void)visible; (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)intermediateUpdate;
    if (instanceName == NULL || instanceName[0] == '\0') {
        problem = "fmi3InstantiateCoSimulation: the instance needs a name";
    } else if (instantiationToken == NULL || strcmp(instantiationToken, VSC_TOKEN) != 0) {
        problem = "fmi3InstantiateCoSimulation: the instantiationToken is not this binary's " VSC_TOKEN
                  " (a modelDescription.xml of another build?)";
    } else if (eventModeUsed) {
        problem = "fmi3InstantiateCoSimulation: eventModeUsed = true, but this FMU has no Event Mode";
    } else if (nRequiredIntermediateVariables > 0) {
        problem = "fmi3InstantiateCoSimulation: no variable of this FMU has intermediate updates";
    }
    if (problem != NULL) {
        if (logMessage != NULL) { logMessage(instanceEnvironment, fmi3Error, "logStatusError", problem); }
        return NULL;
    }
    env = calloc(1, sizeof *env);
    if (env == NULL) { return NULL; }
    env->environment = instanceEnvironment;
    env->log = logMessage;
    c = vsc_new(instanceName, emit3, env, loggingOn);
    if (c == NULL) { free(env); return NULL; }
    c->has_time = 1;
    return c;
}

void fmi3FreeInstance(fmi3Instance instance) {
    if (instance == NULL) { return; }
    free((void *)CORE(instance)->env);
    vsc_free(CORE(instance));
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    int status;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (instance == NULL) { return fmi3Error; }
    status = vsc_check_mode(CORE(instance), "fmi3EnterInitializationMode", VSC_MODE_BIT(VSC_INSTANTIATED));
    if (status == VSC_OK) { status = vsc_set_start(CORE(instance), startTime); }
    if (status == VSC_OK) { status = vsc_enter_initialization(CORE(instance), "fmi3EnterInitializationMode"); }
    return (fmi3Status)status;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    if (instance == NULL) { return fmi3Error; }
    return (fmi3Status)vsc_exit_initialization(CORE(instance), "fmi3ExitInitializationMode");
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    if (instance == NULL) { return fmi3Error; }
    return (fmi3Status)vsc_terminate(CORE(instance), "fmi3Terminate");
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    if (instance == NULL) { return fmi3Error; }
    vsc_reset(CORE(instance));
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    if (instance == NULL) { return fmi3Error; }
    if (nValues != nValueReferences) {
        return (fmi3Status)vsc_log(CORE(instance), VSC_ERROR, "fmi3GetFloat64: %zu values for %zu scalar "
                                   "variables", nValues, nValueReferences);
    }
    return (fmi3Status)vsc_get(CORE(instance), "fmi3GetFloat64", valueReferences, nValueReferences, values);
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    if (instance == NULL) { return fmi3Error; }
    if (nValues != nValueReferences) {
        return (fmi3Status)vsc_log(CORE(instance), VSC_ERROR, "fmi3SetFloat64: %zu values for %zu scalar "
                                   "variables", nValues, nValueReferences);
    }
    return (fmi3Status)vsc_set(CORE(instance), "fmi3SetFloat64", valueReferences, nValueReferences, values);
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    if (instance == NULL) { return fmi3Error; }
    return (fmi3Status)vsc_get_state(CORE(instance), "fmi3GetFMUState", FMUState);
}
fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    if (instance == NULL) { return fmi3Error; }
    return (fmi3Status)vsc_set_state(CORE(instance), "fmi3SetFMUState", FMUState);
}
fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    if (instance == NULL) { return fmi3Error; }
    if (FMUState != NULL) { vsc_free_state(*FMUState); *FMUState = NULL; }
    return fmi3OK;
}
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    (void)FMUState;
    if (instance == NULL || size == NULL) { return fmi3Error; }
    *size = vsc_serialized_size();
    return fmi3OK;
}
fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    if (instance == NULL) { return fmi3Error; }
    return (fmi3Status)vsc_serialize(CORE(instance), "fmi3SerializeFMUState", FMUState, serializedState, size);
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    if (instance == NULL) { return fmi3Error; }
    return (fmi3Status)vsc_deserialize(CORE(instance), "fmi3DeserializeFMUState", serializedState, size, FMUState);
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    int status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (instance == NULL) { return fmi3Error; }
    status = vsc_do_step(CORE(instance), "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded != NULL) { *eventHandlingNeeded = fmi3False; }
    if (terminateSimulation != NULL) { *terminateSimulation = fmi3False; }
    if (earlyReturn != NULL) { *earlyReturn = fmi3False; }
    if (lastSuccessfulTime != NULL) { *lastSuccessfulTime = vsc_time(CORE(instance)); }
    return (fmi3Status)status;
}

/* ---- refused: what this FMU does not offer ---- */
fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    (void)instance;
    return refused(instance, "fmi3EnterEventMode");
}
fmi3Status fmi3GetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float32 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetFloat32");
}
fmi3Status fmi3GetInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int8 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetInt8");
}
fmi3Status fmi3GetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt8 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetUInt8");
}
fmi3Status fmi3GetInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int16 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetInt16");
}
fmi3Status fmi3GetUInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt16 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetUInt16");
}
fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int32 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetInt32");
}
fmi3Status fmi3GetUInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt32 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetUInt32");
}
fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int64 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetInt64");
}
fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetUInt64");
}
fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetBoolean");
}
fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3String values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3GetString");
}
fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)valueSizes; (void)values; (void)nValues;
    return refused(instance, "fmi3GetBinary");
}
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Clock values[]) {
    (void)valueReferences; (void)nValueReferences; (void)values;
    return refused(instance, "fmi3GetClock");
}
fmi3Status fmi3SetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float32 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetFloat32");
}
fmi3Status fmi3SetInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int8 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetInt8");
}
fmi3Status fmi3SetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt8 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetUInt8");
}
fmi3Status fmi3SetInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int16 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetInt16");
}
fmi3Status fmi3SetUInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt16 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetUInt16");
}
fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int32 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetInt32");
}
fmi3Status fmi3SetUInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt32 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetUInt32");
}
fmi3Status fmi3SetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int64 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetInt64");
}
fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetUInt64");
}
fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Boolean values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetBoolean");
}
fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3String values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)values; (void)nValues;
    return refused(instance, "fmi3SetString");
}
fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)valueSizes; (void)values; (void)nValues;
    return refused(instance, "fmi3SetBinary");
}
fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Clock values[]) {
    (void)valueReferences; (void)nValueReferences; (void)values;
    return refused(instance, "fmi3SetClock");
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity; (void)nSensitivity;
    return refused(instance, "fmi3GetDirectionalDerivative");
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity; (void)nSensitivity;
    return refused(instance, "fmi3GetAdjointDerivative");
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    (void)instance;
    return refused(instance, "fmi3EnterConfigurationMode");
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    (void)instance;
    return refused(instance, "fmi3ExitConfigurationMode");
}
fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences; (void)nValueReferences; (void)intervals; (void)qualifiers;
    return refused(instance, "fmi3GetIntervalDecimal");
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions; (void)qualifiers;
    return refused(instance, "fmi3GetIntervalFraction");
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float64 shifts[]) {
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return refused(instance, "fmi3GetShiftDecimal");
}
fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return refused(instance, "fmi3GetShiftFraction");
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float64 intervals[]) {
    (void)valueReferences; (void)nValueReferences; (void)intervals;
    return refused(instance, "fmi3SetIntervalDecimal");
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return refused(instance, "fmi3SetIntervalFraction");
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float64 shifts[]) {
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return refused(instance, "fmi3SetShiftDecimal");
}
fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return refused(instance, "fmi3SetShiftFraction");
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    (void)instance;
    return refused(instance, "fmi3EvaluateDiscreteStates");
}
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean* discreteStatesNeedUpdate, fmi3Boolean* terminateSimulation, fmi3Boolean* nominalsOfContinuousStatesChanged, fmi3Boolean* valuesOfContinuousStatesChanged, fmi3Boolean* nextEventTimeDefined, fmi3Float64* nextEventTime) {
    (void)discreteStatesNeedUpdate; (void)terminateSimulation; (void)nominalsOfContinuousStatesChanged; (void)valuesOfContinuousStatesChanged; (void)nextEventTimeDefined; (void)nextEventTime;
    return refused(instance, "fmi3UpdateDiscreteStates");
}
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    (void)instance;
    return refused(instance, "fmi3EnterContinuousTimeMode");
}
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean* enterEventMode, fmi3Boolean* terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint; (void)enterEventMode; (void)terminateSimulation;
    return refused(instance, "fmi3CompletedIntegratorStep");
}
fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    return refused(instance, "fmi3SetTime");
}
fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[], size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    return refused(instance, "fmi3SetContinuousStates");
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates) {
    (void)derivatives; (void)nContinuousStates;
    return refused(instance, "fmi3GetContinuousStateDerivatives");
}
fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    (void)eventIndicators; (void)nEventIndicators;
    return refused(instance, "fmi3GetEventIndicators");
}
fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    return refused(instance, "fmi3GetContinuousStates");
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates) {
    (void)nominals; (void)nContinuousStates;
    return refused(instance, "fmi3GetNominalsOfContinuousStates");
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t* nEventIndicators) {
    (void)nEventIndicators;
    return refused(instance, "fmi3GetNumberOfEventIndicators");
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t* nContinuousStates) {
    (void)nContinuousStates;
    return refused(instance, "fmi3GetNumberOfContinuousStates");
}
fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    (void)instance;
    return refused(instance, "fmi3EnterStepMode");
}
fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)orders; (void)values; (void)nValues;
    return refused(instance, "fmi3GetOutputDerivatives");
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference, fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    return refused(instance, "fmi3ActivateModelPartition");
}
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference, size_t* nDependencies) {
    (void)valueReference; (void)nDependencies;
    return refused(instance, "fmi3GetNumberOfVariableDependencies");
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent, size_t elementIndicesOfDependent[], fmi3ValueReference independents[], size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[], size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents; (void)dependencyKinds; (void)nDependencies;
    return refused(instance, "fmi3GetVariableDependencies");
}
