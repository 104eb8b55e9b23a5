/* FMI 2.0 Co-Simulation and Model Exchange entry points for a generated model (md_model.h):
 * a thin layer over the generic shell (instance.c, the logic fmi3.c shares) and the solver
 * core (solver.c). fmi2Instantiate accepts the interface types modelDescription.xml offers
 * (MD_INFO.interfaces); a Model Exchange instance is integrated by the importer, through
 * the same model evaluations and the same event handling as the shell's own integrator.
 *
 * Model Exchange state machine (sec. 3.2.1): instantiated -> initialisationMode ->
 * eventMode <-> continuousTimeMode -> terminated. fmi2NewDiscreteStates handles every event
 * at the present point with event iteration, so one call settles it
 * (newDiscreteStatesNeeded is always false); there are no time events.
 *
 * Section references are to the FMI 2.0 standard (2.0.x).
 *
 * Value references: 0 .. nvars-1 are the model's variables (MD_INFO tables), Real or Boolean
 * (a Boolean lives as 0.0 / 1.0 in the same arrays, so both fmi2Get/SetReal and
 * fmi2Get/SetBoolean reach it); nvars + MD_SETTING_* are the solver settings of
 * MD_SHELL_SETTINGS, Real parameters. There are no Integer or String variables.
 *
 * State machine (sec. 4.3.1, Co-Simulation calling sequence), collapsed to what a
 * synchronous slave needs: instantiated -> initialisationMode -> stepComplete ("step")
 * -> terminated, plus error and fatal. A doStep that fails leaves the instance in `error`:
 * further doStep calls return fmi2Error; the variables can still be read (diagnostics),
 * fmi2GetRealStatus(fmi2LastSuccessfulTime) says where it stopped, and fmi2SetFMUstate
 * (sec. 2.1.3) or fmi2Reset can bring it back. Misuse that does not damage the instance
 * (a wrong value reference, a non-settable variable, a non-finite value, a call in the
 * wrong state, bad doStep arguments) returns fmi2Error and leaves the state unchanged.
 * fmi2Fatal is sticky: every call then returns fmi2Fatal except fmi2FreeInstance.
 *
 * What is FMI 2.0's own, and so lives here rather than in instance.c:
 *   - the memory callbacks of fmi2CallbackFunctions (the shell allocates through them) and
 *     the variadic logger, which takes the instance name and treats its message as a format;
 *   - log categories logEvents, logStatusError (warnings go there too), logAll; with
 *     loggingOn false, logStatusError stays on;
 *   - fmi2SetupExperiment (start, stop time and tolerance come before initialisation mode);
 *     variables cannot be read before fmi2EnterInitializationMode; the solver settings are
 *     tunable parameters, as in FMI 3.0;
 *   - Integer and String calls, status queries (sec. 4.2.3) and the last doStep status.
 */
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "instance.h"
#include "instance.h" /* the generic shell (instance.c), compiled as a unit of its own */

/* ---------------------------------------------------------------------------------------
 * Instance and layer description
 * ------------------------------------------------------------------------------------- */

typedef struct {
    md_instance base;          /* first: an fmi2Component is also an md_instance * */
    fmi2CallbackFunctions cb;  /* a copy: the environment's struct need not outlive the call */
    fmi2Status last_step_status;
} Instance;

/* Variables can be read from initialisation mode on. */
#define ST_READABLE (MD_MODE_INIT | MD_MODE_RUNNING | MD_MODE_TERMINATED | MD_MODE_ERROR)

/* Log categories: md_settings.h, from the table modelDescription.xml <LogCategories> is
   written from. */
static const char *const LOG_NAMES[MD_FMI2_NLOG] = MD_FMI2_LOG_NAMES;

static fmi2Status status_of(md_result result) {
    switch (result) {
    case MD_RESULT_OK: return fmi2OK;
    case MD_RESULT_WARNING: return fmi2Warning;
    case MD_RESULT_DISCARD: return fmi2Discard;
    case MD_RESULT_ERROR: return fmi2Error;
    case MD_RESULT_FATAL: return fmi2Fatal;
    }
    return fmi2Fatal;
}

/* The logger is variadic and treats its message as a format: pass the text as an argument. */
static void log_message(const md_instance *m, md_result status, const char *category,
                        const char *text) {
    const Instance *c = (const Instance *)m;
    c->cb.logger(c->cb.componentEnvironment, m->name, status_of(status), category, "%s", text);
}

static const md_layer FMI2 = {
    .enter_initialization = "fmi2EnterInitializationMode",
    .exit_initialization = "fmi2ExitInitializationMode",
    .do_step = "fmi2DoStep",
    .stop_time_source = "fmi2SetupExperiment",
    .recovery = "fmi2Reset or fmi2SetFMUstate",
    .fmu_state = "FMUstate",
    .real_type = "Real",
    .parameter = "parameter",
    .settings_tunable = 1, /* declared tunable in modelDescription.xml */
    .has_time = 0,
    .state_magic = 0x32494D46u, /* "FMI2" */
    .categories = LOG_NAMES,
    .ncategories = MD_FMI2_NLOG,
    .category_of = {[MD_CATEGORY_EVENTS] = MD_FMI2_LOG_EVENTS,
                    [MD_CATEGORY_WARNING] = MD_FMI2_LOG_STATUS_ERROR,
                    [MD_CATEGORY_ERROR] = MD_FMI2_LOG_STATUS_ERROR,
                    [MD_CATEGORY_ALL] = MD_FMI2_LOG_ALL},
    .errors_always_logged = 0,
    .quiet_log_mask = 1u << MD_FMI2_LOG_STATUS_ERROR, /* errors are reported unless switched off */
    .log = log_message,
};

/* Gatekeeper at the top of every entry point. */
#define GUARD(m, function, allowed) MD_GUARD(m, function, allowed, status_of)

/* ---------------------------------------------------------------------------------------
 * Inquire platform and version, logging (sec. 2.1.4, 2.1.5)
 * ------------------------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn,
                               size_t nCategories, const fmi2String categories[]) {
    md_instance *m = component;
    GUARD(m, "fmi2SetDebugLogging", MD_MODE_ANY);
    return status_of(md_set_debug_logging(m, "fmi2SetDebugLogging", loggingOn, nCategories,
                                          categories));
}

/* ---------------------------------------------------------------------------------------
 * Creation and destruction (sec. 2.1.5)
 * ------------------------------------------------------------------------------------- */

static void instantiate_error(const fmi2CallbackFunctions *functions, fmi2String name,
                              const char *text) {
    if (functions != NULL && functions->logger != NULL) {
        functions->logger(functions->componentEnvironment, name != NULL ? name : "", fmi2Error,
                          "logStatusError", "%s", text);
    }
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    Instance *c;
    char text[MD_MESSAGE_SIZE];

    (void)fmuResourceLocation; /* the FMU has no resources */
    (void)visible;
    if (functions == NULL || functions->allocateMemory == NULL
        || functions->freeMemory == NULL) {
        instantiate_error(functions, instanceName,
                          "fmi2Instantiate: allocateMemory and freeMemory callbacks are required");
        return NULL;
    }
    if (instanceName == NULL) {
        instantiate_error(functions, instanceName, "fmi2Instantiate: instanceName is NULL");
        return NULL;
    }
    if ((fmuType == fmi2CoSimulation && !md_offers(MD_INTERFACE_CS))
        || (fmuType == fmi2ModelExchange && !md_offers(MD_INTERFACE_ME))
        || (fmuType != fmi2CoSimulation && fmuType != fmi2ModelExchange)) {
        snprintf(text, sizeof text, "fmi2Instantiate: fmuType %d is not offered by this FMU "
                 "(it offers %s)", (int)fmuType,
                 md_offers(MD_INTERFACE_ME)
                     ? (md_offers(MD_INTERFACE_CS) ? "Co-Simulation and Model Exchange"
                                                   : "Model Exchange only")
                     : "Co-Simulation only");
        instantiate_error(functions, instanceName, text);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MD_INFO.guid) != 0) {
        snprintf(text, sizeof text, "fmi2Instantiate: GUID %s does not match this binary's %s "
                 "(modelDescription.xml and binary out of step?)",
                 fmuGUID != NULL ? fmuGUID : "(null)", MD_INFO.guid);
        instantiate_error(functions, instanceName, text);
        return NULL;
    }

    c = (Instance *)md_instance_new(&FMI2, sizeof *c, functions->allocateMemory,
                                    functions->freeMemory, instanceName);
    if (c == NULL) {
        instantiate_error(functions, instanceName, "fmi2Instantiate: out of memory");
        return NULL;
    }
    c->cb = *functions;
    c->last_step_status = fmi2OK;
    c->base.interface = fmuType == fmi2ModelExchange ? MD_INTERFACE_ME : MD_INTERFACE_CS;
    md_instance_start_logging(&c->base, functions->logger != NULL, loggingOn);
    return c;
}

void fmi2FreeInstance(fmi2Component component) { md_instance_free(component); }

/* ---------------------------------------------------------------------------------------
 * Initialisation, termination, reset (sec. 2.1.6)
 * ------------------------------------------------------------------------------------- */

fmi2Status fmi2SetupExperiment(fmi2Component component, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    md_instance *m = component;
    GUARD(m, "fmi2SetupExperiment", MD_MODE_INSTANTIATED);
    return status_of(md_setup_experiment(m, "fmi2SetupExperiment", toleranceDefined, tolerance,
                                         startTime, stopTimeDefined, stopTime));
}

fmi2Status fmi2EnterInitializationMode(fmi2Component component) {
    md_instance *m = component;
    GUARD(m, "fmi2EnterInitializationMode", MD_MODE_INSTANTIATED);
    return status_of(md_enter_initialization(m, "fmi2EnterInitializationMode"));
}

fmi2Status fmi2ExitInitializationMode(fmi2Component component) {
    md_instance *m = component;
    Instance *c = component;
    md_result result;
    GUARD(m, "fmi2ExitInitializationMode", MD_MODE_INIT);
    result = md_exit_initialization(m, "fmi2ExitInitializationMode");
    if (result == MD_RESULT_OK) { c->last_step_status = fmi2OK; }
    return status_of(result);
}

fmi2Status fmi2Terminate(fmi2Component component) {
    md_instance *m = component;
    /* from error too: a master that tidies up after a failed step should not get a second
       error for it */
    GUARD(m, "fmi2Terminate", MD_MODE_RUNNING | MD_MODE_ERROR);
    m->mode = MD_MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component component) {
    md_instance *m = component;
    Instance *c = component;
    GUARD(m, "fmi2Reset", MD_MODE_ANY);
    md_reset(m);
    c->last_step_status = fmi2OK;
    return fmi2OK;
}

/* ---------------------------------------------------------------------------------------
 * Getting and setting variable values (sec. 2.1.7; which variable may be set when: the
 * causality/variability table of sec. 2.2.7, in md_set_values)
 * ------------------------------------------------------------------------------------- */

static double boolean_at(const void *values, size_t i) {
    return ((const fmi2Boolean *)values)[i] ? 1.0 : 0.0;
}

static void boolean_put(void *values, size_t i, double value) {
    ((fmi2Boolean *)values)[i] = value != 0.0 ? fmi2True : fmi2False;
}

fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    md_instance *m = component;
    GUARD(m, "fmi2GetReal", ST_READABLE);
    return status_of(md_get_values(m, "fmi2GetReal", vr, nvr, value, nvr, md_real_put, 0));
}

fmi2Status fmi2GetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    md_instance *m = component;
    GUARD(m, "fmi2GetBoolean", ST_READABLE);
    return status_of(md_get_values(m, "fmi2GetBoolean", vr, nvr, value, nvr, boolean_put, 1));
}

fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    md_instance *m = component;
    GUARD(m, "fmi2SetReal", MD_MODE_SETTABLE);
    return status_of(md_set_values(m, "fmi2SetReal", vr, nvr, value, nvr, md_real_at, 0));
}

fmi2Status fmi2SetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    md_instance *m = component;
    GUARD(m, "fmi2SetBoolean", MD_MODE_SETTABLE);
    return status_of(md_set_values(m, "fmi2SetBoolean", vr, nvr, value, nvr, boolean_at, 1));
}

/* No Integer or String variables. */
static fmi2Status no_such_variables(md_instance *m, const char *function, const char *type,
                                    const fmi2ValueReference vr[], size_t nvr) {
    if (nvr == 0) { return fmi2OK; }
    return status_of(md_report(m, MD_RESULT_ERROR, "%s: no %s variable with value reference %u "
                               "(this FMU has Real and Boolean variables only)", function, type,
                               vr != NULL ? vr[0] : 0u));
}

/* The Integer variables are the integrator statistics (solver.steps, ...). */
fmi2Status fmi2GetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    md_instance *m = component;
    int64_t counts[MD_NSTATISTICS];
    md_result result = MD_RESULT_OK;
    GUARD(m, "fmi2GetInteger", ST_READABLE);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return status_of(md_report(m, MD_RESULT_ERROR, "fmi2GetInteger: NULL array"));
    }
    for (size_t i = 0; i < nvr && result == MD_RESULT_OK; ++i) {
        result = md_get_statistics(m, "fmi2GetInteger", &vr[i], 1, counts, 1);
        /* saturate: fmi2Integer is an int */
        if (result == MD_RESULT_OK) { value[i] = counts[0] > 2147483647 ? 2147483647 : (fmi2Integer)counts[0]; }
    }
    return status_of(result);
}

fmi2Status fmi2GetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    md_instance *m = component;
    (void)value;
    GUARD(m, "fmi2GetString", ST_READABLE);
    return no_such_variables(m, "fmi2GetString", "String", vr, nvr);
}

fmi2Status fmi2SetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    md_instance *m = component;
    (void)value;
    GUARD(m, "fmi2SetInteger", MD_MODE_SETTABLE);
    if (nvr == 0) { return fmi2OK; }
    return status_of(md_report(m, MD_RESULT_ERROR, "fmi2SetInteger: value reference %u is not "
                               "settable (the Integer variables are the solver's statistics)",
                               vr != NULL ? vr[0] : 0u));
}

fmi2Status fmi2SetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    md_instance *m = component;
    (void)value;
    GUARD(m, "fmi2SetString", MD_MODE_SETTABLE);
    return no_such_variables(m, "fmi2SetString", "String", vr, nvr);
}

/* ---------------------------------------------------------------------------------------
 * FMU state (sec. 2.1.8). The in-memory copy and the serialised form are the same bytes.
 * ------------------------------------------------------------------------------------- */

fmi2Status fmi2GetFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    md_instance *m = component;
    GUARD(m, "fmi2GetFMUstate", MD_MODE_ANY);
    return status_of(md_get_state(m, "fmi2GetFMUstate", FMUstate));
}

fmi2Status fmi2SetFMUstate(fmi2Component component, fmi2FMUstate FMUstate) {
    md_instance *m = component;
    Instance *c = component;
    md_result result;
    GUARD(m, "fmi2SetFMUstate", MD_MODE_ANY);
    result = md_set_state(m, "fmi2SetFMUstate", FMUstate);
    if (result == MD_RESULT_OK) {
        c->last_step_status = m->mode == MD_MODE_ERROR ? fmi2Error : fmi2OK;
    }
    return status_of(result);
}

fmi2Status fmi2FreeFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    md_instance *m = component;
    GUARD(m, "fmi2FreeFMUstate", MD_MODE_ANY);
    return status_of(md_free_state(m, "fmi2FreeFMUstate", FMUstate));
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component component, fmi2FMUstate FMUstate,
                                      size_t *size) {
    md_instance *m = component;
    GUARD(m, "fmi2SerializedFMUstateSize", MD_MODE_ANY);
    return status_of(md_serialized_state_size(m, "fmi2SerializedFMUstateSize", FMUstate, size));
}

fmi2Status fmi2SerializeFMUstate(fmi2Component component, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    md_instance *m = component;
    GUARD(m, "fmi2SerializeFMUstate", MD_MODE_ANY);
    return status_of(md_serialize_state(m, "fmi2SerializeFMUstate", FMUstate, serializedState,
                                        size));
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component component, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    md_instance *m = component;
    GUARD(m, "fmi2DeSerializeFMUstate", MD_MODE_ANY);
    return status_of(md_deserialize_state(m, "fmi2DeSerializeFMUstate", serializedState, size,
                                          FMUstate));
}

/* ---------------------------------------------------------------------------------------
 * Not provided (capability flags false in modelDescription.xml)
 * ------------------------------------------------------------------------------------- */

fmi2Status fmi2GetDirectionalDerivative(fmi2Component component,
                                        const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown;
    (void)dvUnknown;
    return status_of(md_unsupported(component, "fmi2GetDirectionalDerivative", "not provided "
                                    "by this FMU (providesDirectionalDerivative=\"false\")"));
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component component, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return status_of(md_unsupported(component, "fmi2SetRealInputDerivatives", "not provided by "
                                    "this FMU (canInterpolateInputs=\"false\"; inputs are held "
                                    "constant over a step)"));
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component component, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return status_of(md_unsupported(component, "fmi2GetRealOutputDerivatives", "not provided "
                                    "by this FMU (maxOutputDerivativeOrder=\"0\")"));
}

/* ---------------------------------------------------------------------------------------
 * Stepping (sec. 4.2.2) and status (sec. 4.2.3)
 * ------------------------------------------------------------------------------------- */

fmi2Status fmi2DoStep(fmi2Component component, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    md_instance *m = component;
    Instance *c = component;
    md_result result;
    (void)noSetFMUStatePriorToCurrentPoint;
    GUARD(m, "fmi2DoStep", MD_MODE_STEP | MD_MODE_EVENT | MD_MODE_CONTINUOUS);
    if (m->interface != MD_INTERFACE_CS) {
        return status_of(md_report(m, MD_RESULT_ERROR, "fmi2DoStep: a Model Exchange instance "
                                   "does not step (instantiate as fmi2CoSimulation)"));
    }
    result = md_do_step(m, "fmi2DoStep", currentCommunicationPoint, communicationStepSize);
    if (result == MD_RESULT_OK) {
        c->last_step_status = fmi2OK;
    } else if (m->mode == MD_MODE_ERROR) { /* the step failed (not its arguments) */
        c->last_step_status = fmi2Error;
    }
    return status_of(result);
}

fmi2Status fmi2CancelStep(fmi2Component component) {
    return status_of(md_unsupported(component, "fmi2CancelStep", "no step in progress (this "
                                    "FMU steps synchronously)"));
}

/* The common part of the fmi2Get*Status calls: available after the first step; `answered`
 * is the one status kind the call answers (-1: none; then value is not needed). fmi2OK: the
 * caller writes *value. */
static fmi2Status status_query(md_instance *m, const char *function, fmi2StatusKind kind,
                               int answered, const void *value, const char *note) {
    GUARD(m, function, MD_MODE_STEP | MD_MODE_TERMINATED | MD_MODE_ERROR);
    if (answered >= 0 && value == NULL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "%s: value is NULL", function));
    }
    if ((int)kind == answered) { return fmi2OK; }
    return status_of(md_report(m, MD_RESULT_DISCARD, "%s: status kind %d is not available%s",
                               function, (int)kind, note));
}

fmi2Status fmi2GetStatus(fmi2Component component, const fmi2StatusKind kind, fmi2Status *value) {
    const Instance *c = component;
    fmi2Status status = status_query(component, "fmi2GetStatus", kind, fmi2DoStepStatus, value,
                                     "");
    if (status == fmi2OK) { *value = c->last_step_status; }
    return status;
}

fmi2Status fmi2GetRealStatus(fmi2Component component, const fmi2StatusKind kind,
                             fmi2Real *value) {
    md_instance *m = component;
    fmi2Status status = status_query(m, "fmi2GetRealStatus", kind, fmi2LastSuccessfulTime,
                                     value, "");
    /* the last good point, also after a failed step */
    if (status == fmi2OK) { *value = m->solver->t; }
    return status;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component component, const fmi2StatusKind kind,
                                fmi2Integer *value) {
    (void)value;
    return status_query(component, "fmi2GetIntegerStatus", kind, -1, NULL, "");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component component, const fmi2StatusKind kind,
                                fmi2Boolean *value) {
    fmi2Status status = status_query(component, "fmi2GetBooleanStatus", kind, fmi2Terminated,
                                     value, "");
    /* the slave never asks to end the simulation */
    if (status == fmi2OK) { *value = fmi2False; }
    return status;
}

fmi2Status fmi2GetStringStatus(fmi2Component component, const fmi2StatusKind kind,
                               fmi2String *value) {
    (void)value;
    return status_query(component, "fmi2GetStringStatus", kind, -1, NULL,
                        " (no asynchronous steps)");
}

/* ---------------------------------------------------------------------------------------
 * Model Exchange (sec. 3.2)
 * ------------------------------------------------------------------------------------- */

/* At the top of every Model Exchange function: the instance must be one. */
#define GUARD_ME(m, function, allowed) MD_GUARD_ME(m, function, allowed, status_of)

fmi2Status fmi2EnterEventMode(fmi2Component component) {
    md_instance *m = component;
    GUARD_ME(m, "fmi2EnterEventMode", MD_MODE_EVENT | MD_MODE_CONTINUOUS);
    m->mode = MD_MODE_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component component, fmi2EventInfo *eventInfo) {
    md_instance *m = component;
    int changed = 0;
    md_result result;
    GUARD_ME(m, "fmi2NewDiscreteStates", MD_MODE_EVENT);
    if (eventInfo == NULL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "fmi2NewDiscreteStates: eventInfo is "
                                   "NULL"));
    }
    result = md_me_update_discrete_states(m, "fmi2NewDiscreteStates", &changed);
    eventInfo->newDiscreteStatesNeeded = fmi2False; /* event iteration is done inside */
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = changed ? fmi2True : fmi2False;
    eventInfo->nextEventTimeDefined = fmi2False; /* no time events */
    eventInfo->nextEventTime = 0.0;
    return status_of(result);
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component component) {
    md_instance *m = component;
    GUARD_ME(m, "fmi2EnterContinuousTimeMode", MD_MODE_EVENT);
    m->mode = MD_MODE_CONTINUOUS;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component component,
                                       fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation) {
    md_instance *m = component;
    (void)noSetFMUStatePriorToCurrentPoint;
    GUARD_ME(m, "fmi2CompletedIntegratorStep", MD_MODE_CONTINUOUS);
    if (enterEventMode == NULL || terminateSimulation == NULL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "fmi2CompletedIntegratorStep: an "
                                   "output argument is NULL"));
    }
    md_me_completed_step(m);
    *enterEventMode = fmi2False; /* no step events: every event has an indicator */
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component component, fmi2Real time) {
    md_instance *m = component;
    GUARD_ME(m, "fmi2SetTime", MD_MODE_EVENT | MD_MODE_CONTINUOUS);
    return status_of(md_me_set_time(m, "fmi2SetTime", time));
}

fmi2Status fmi2SetContinuousStates(fmi2Component component, const fmi2Real x[], size_t nx) {
    md_instance *m = component;
    GUARD_ME(m, "fmi2SetContinuousStates", MD_MODE_EVENT | MD_MODE_CONTINUOUS);
    return status_of(md_me_set_states(m, "fmi2SetContinuousStates", x, nx));
}

fmi2Status fmi2GetDerivatives(fmi2Component component, fmi2Real derivatives[], size_t nx) {
    md_instance *m = component;
    GUARD_ME(m, "fmi2GetDerivatives", MD_MODE_EVALUABLE);
    return status_of(md_me_get_derivatives(m, "fmi2GetDerivatives", derivatives, nx));
}

fmi2Status fmi2GetEventIndicators(fmi2Component component, fmi2Real eventIndicators[],
                                  size_t ni) {
    md_instance *m = component;
    GUARD_ME(m, "fmi2GetEventIndicators", MD_MODE_EVALUABLE);
    return status_of(md_me_get_indicators(m, "fmi2GetEventIndicators", eventIndicators, ni));
}

fmi2Status fmi2GetContinuousStates(fmi2Component component, fmi2Real x[], size_t nx) {
    md_instance *m = component;
    GUARD_ME(m, "fmi2GetContinuousStates", MD_MODE_EVALUABLE);
    return status_of(md_me_get_states(m, "fmi2GetContinuousStates", x, nx));
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component component, fmi2Real x_nominal[],
                                             size_t nx) {
    md_instance *m = component;
    GUARD_ME(m, "fmi2GetNominalsOfContinuousStates", MD_MODE_ANY);
    return status_of(md_me_get_nominals(m, "fmi2GetNominalsOfContinuousStates", x_nominal, nx));
}
