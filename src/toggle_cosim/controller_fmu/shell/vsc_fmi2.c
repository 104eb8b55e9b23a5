/* toggle-cosim: the FMI 2.0 Co-Simulation layer of a sampled controller FMU over the instance
 * core (vsc_core.c). Every function of fmi2Functions.h is here; Model Exchange, Integer,
 * Boolean and String variables, directional derivatives and asynchronous steps are refused
 * with fmi2Error and a log message. */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "vsc_core.h"

typedef struct {
    fmi2CallbackFunctions callbacks;
} layer_env;

/* The standard's logger takes a printf format: the message goes as the format with every '%'
   doubled, so that loggers that format it and loggers that print it (FMPy) both show it. */
static void emit2(const vsc_core *c, int status, const char *category, const char *message) {
    const layer_env *env = c->env;
    char format[2048];
    size_t i = 0;
    for (; *message != '\0' && i + 2 < sizeof format; message++) {
        if (*message == '%') { format[i++] = '%'; }
        format[i++] = *message;
    }
    format[i] = '\0';
    if (env->callbacks.logger != NULL) {
        env->callbacks.logger(env->callbacks.componentEnvironment, c->name, (fmi2Status)status, category, format);
    }
}

#define CORE(component) ((vsc_core *)(component))
#define CHECK(component, function)                                                       \
    do {                                                                                 \
        if ((component) == NULL) { return fmi2Error; }                                   \
    } while (0)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    CHECK(c, "fmi2SetDebugLogging");
    return (fmi2Status)vsc_set_categories(CORE(c), loggingOn, nCategories, categories);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    layer_env *env;
    vsc_core *c;
    (void)fmuResourceLocation;
    (void)visible;
    if (functions == NULL || functions->logger == NULL) { return NULL; }
    if (instanceName == NULL || instanceName[0] == '\0') {
        functions->logger(functions->componentEnvironment, "", fmi2Error, "logStatusError",
                          "fmi2Instantiate: the instance needs a name");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                          "fmi2Instantiate: %s offers Co-Simulation only", VSC_MODEL_IDENTIFIER);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, VSC_TOKEN) != 0) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                          "fmi2Instantiate: the GUID %s is not this binary's %s (a modelDescription.xml "
                          "of another build?)", fmuGUID ? fmuGUID : "(null)", VSC_TOKEN);
        return NULL;
    }
    env = calloc(1, sizeof *env);
    if (env == NULL) { return NULL; }
    env->callbacks = *functions;
    c = vsc_new(instanceName, emit2, env, loggingOn);
    if (c == NULL) { free(env); return NULL; }
    return c;
}

void fmi2FreeInstance(fmi2Component c) {
    if (c == NULL) { return; }
    free((void *)CORE(c)->env);
    vsc_free(CORE(c));
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    int status;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    CHECK(c, "fmi2SetupExperiment");
    status = vsc_check_mode(CORE(c), "fmi2SetupExperiment", VSC_MODE_BIT(VSC_INSTANTIATED));
    if (status != VSC_OK) { return (fmi2Status)status; }
    return (fmi2Status)vsc_set_start(CORE(c), startTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    CHECK(c, "fmi2EnterInitializationMode");
    return (fmi2Status)vsc_enter_initialization(CORE(c), "fmi2EnterInitializationMode");
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CHECK(c, "fmi2ExitInitializationMode");
    return (fmi2Status)vsc_exit_initialization(CORE(c), "fmi2ExitInitializationMode");
}

fmi2Status fmi2Terminate(fmi2Component c) {
    CHECK(c, "fmi2Terminate");
    return (fmi2Status)vsc_terminate(CORE(c), "fmi2Terminate");
}

fmi2Status fmi2Reset(fmi2Component c) {
    CHECK(c, "fmi2Reset");
    vsc_reset(CORE(c));
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    CHECK(c, "fmi2GetReal");
    return (fmi2Status)vsc_get(CORE(c), "fmi2GetReal", vr, nvr, value);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    CHECK(c, "fmi2SetReal");
    return (fmi2Status)vsc_set(CORE(c), "fmi2SetReal", vr, nvr, value);
}

static fmi2Status no_variables(fmi2Component c, const char *function, size_t nvr) {
    CHECK(c, function);
    if (nvr == 0) { return fmi2OK; }
    return (fmi2Status)vsc_log(CORE(c), VSC_ERROR, "%s: this FMU has Real variables only", function);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)vr; (void)value;
    return no_variables(c, "fmi2GetInteger", nvr);
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)vr; (void)value;
    return no_variables(c, "fmi2GetBoolean", nvr);
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)vr; (void)value;
    return no_variables(c, "fmi2GetString", nvr);
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)vr; (void)value;
    return no_variables(c, "fmi2SetInteger", nvr);
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)vr; (void)value;
    return no_variables(c, "fmi2SetBoolean", nvr);
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)vr; (void)value;
    return no_variables(c, "fmi2SetString", nvr);
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2GetFMUstate");
    return (fmi2Status)vsc_get_state(CORE(c), "fmi2GetFMUstate", FMUstate);
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    CHECK(c, "fmi2SetFMUstate");
    return (fmi2Status)vsc_set_state(CORE(c), "fmi2SetFMUstate", FMUstate);
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2FreeFMUstate");
    if (FMUstate != NULL) { vsc_free_state(*FMUstate); *FMUstate = NULL; }
    return fmi2OK;
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate;
    CHECK(c, "fmi2SerializedFMUstateSize");
    *size = vsc_serialized_size();
    return fmi2OK;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    CHECK(c, "fmi2SerializeFMUstate");
    return (fmi2Status)vsc_serialize(CORE(c), "fmi2SerializeFMUstate", FMUstate, (unsigned char *)serializedState, size);
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2DeSerializeFMUstate");
    return (fmi2Status)vsc_deserialize(CORE(c), "fmi2DeSerializeFMUstate", (const unsigned char *)serializedState,
                                       size, FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    CHECK(c, "fmi2GetDirectionalDerivative");
    return (fmi2Status)vsc_log(CORE(c), VSC_ERROR, "fmi2GetDirectionalDerivative: not provided "
                               "(providesDirectionalDerivative=\"false\")");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    CHECK(c, "fmi2SetRealInputDerivatives");
    return (fmi2Status)vsc_log(CORE(c), VSC_ERROR, "fmi2SetRealInputDerivatives: the controller samples its "
                               "inputs and cannot interpolate them (canInterpolateInputs=\"false\")");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    CHECK(c, "fmi2GetRealOutputDerivatives");
    return (fmi2Status)vsc_log(CORE(c), VSC_ERROR, "fmi2GetRealOutputDerivatives: not provided "
                               "(maxOutputDerivativeOrder=\"0\")");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK(c, "fmi2DoStep");
    return (fmi2Status)vsc_do_step(CORE(c), "fmi2DoStep", currentCommunicationPoint, communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    CHECK(c, "fmi2CancelStep");
    return (fmi2Status)vsc_log(CORE(c), VSC_ERROR, "fmi2CancelStep: every step completes at once "
                               "(canRunAsynchronuously=\"false\")");
}

static fmi2Status no_status(fmi2Component c, const char *function) {
    CHECK(c, function);
    return (fmi2Status)vsc_log(CORE(c), VSC_DISCARD, "%s: every step completes at once; there is no "
                               "pending status", function);
}
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s; (void)value;
    return no_status(c, "fmi2GetStatus");
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (c != NULL && s == fmi2LastSuccessfulTime && value != NULL) {
        *value = vsc_time(CORE(c));
        return fmi2OK;
    }
    return no_status(c, "fmi2GetRealStatus");
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s; (void)value;
    return no_status(c, "fmi2GetIntegerStatus");
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (c != NULL && s == fmi2Terminated && value != NULL) {
        *value = fmi2False;
        return fmi2OK;
    }
    return no_status(c, "fmi2GetBooleanStatus");
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s; (void)value;
    return no_status(c, "fmi2GetStringStatus");
}

/* Model Exchange: not offered */
#define NO_ME(call, args)                                                                                 \
    fmi2Status call args {                                                                                \
        return c == NULL ? fmi2Error                                                                      \
                         : (fmi2Status)vsc_log(CORE(c), VSC_ERROR, #call ": this FMU offers Co-Simulation only"); \
    }
NO_ME(fmi2EnterEventMode, (fmi2Component c))
NO_ME(fmi2NewDiscreteStates, (fmi2Component c, fmi2EventInfo *info))
NO_ME(fmi2EnterContinuousTimeMode, (fmi2Component c))
NO_ME(fmi2CompletedIntegratorStep, (fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                     fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation))
NO_ME(fmi2SetTime, (fmi2Component c, fmi2Real time))
NO_ME(fmi2SetContinuousStates, (fmi2Component c, const fmi2Real x[], size_t nx))
NO_ME(fmi2GetDerivatives, (fmi2Component c, fmi2Real derivatives[], size_t nx))
NO_ME(fmi2GetEventIndicators, (fmi2Component c, fmi2Real eventIndicators[], size_t ni))
NO_ME(fmi2GetContinuousStates, (fmi2Component c, fmi2Real x[], size_t nx))
NO_ME(fmi2GetNominalsOfContinuousStates, (fmi2Component c, fmi2Real x_nominal[], size_t nx))
