/* FMI 3.0 Co-Simulation entry points for a generated model (md_model.h): a thin layer over
 * the generic shell (instance.c) and the solver core (solver.c) -- the same ones fmi2.c
 * wraps, so an FMI 3.0 build and an FMI 2.0 build of one model compute the same numbers.
 *
 * References in quotes are section titles of the FMI 3.0 standard.
 *
 * Interface types: Co-Simulation and Model Exchange, as modelDescription.xml offers them
 * (MD_INFO.interfaces); Scheduled Execution is refused (its instantiation returns NULL). Model
 * Exchange ("Model Exchange" chapter): Instantiated -> Initialization Mode -> Event Mode <->
 * Continuous-Time Mode -> Terminated; fmi3UpdateDiscreteStates handles every event at the
 * present point with event iteration, so one call settles it (discreteStatesNeedUpdate is
 * always false); there are no time events. Event indicators and der(x) are Float64
 * variables (MD_VR_INDICATORS, MD_VR_DERIVATIVES), as FMI 3.0 lists them in ModelStructure.
 * Co-Simulation without Event Mode (hasEventMode="false"), early return, intermediate update,
 * clocks, derivatives or configuration mode: a request for any of them is refused with
 * fmi3Error and a log message; the instance is not damaged by that.
 *
 * Value references: 0 .. nvars-1 are the model's variables (MD_INFO tables), Float64 or
 * Boolean (a Boolean lives as 0.0 / 1.0 in the same arrays, so both fmi3Get/SetFloat64 and
 * fmi3Get/SetBoolean reach it, as in fmi2.c); nvars + MD_SETTING_* are the solver settings
 * of MD_SHELL_SETTINGS, tunable Float64 parameters; VR_TIME = nvars + MD_SHELL_NREAL is the
 * independent variable `time` (read-only). All variables are scalars: nValues must equal
 * nValueReferences. There are no other types.
 *
 * State machine ("State Machine and Semantics", "State Machine for Co-Simulation"), what a
 * Co-Simulation FMU without Event Mode needs:
 * instantiated -> initialisationMode -> stepMode -> terminated, plus error and fatal.
 *   instantiated: fmi3Set for parameters, inputs and settings; fmi3Get returns start values
 *                 (parameters, inputs, settings, calculated parameters and constants
 *                 evaluated from them, and time); a computed variable has none yet.
 *   initialisationMode: fmi3Set for parameters, inputs and settings; fmi3Get for everything.
 *   stepMode:     fmi3Set for inputs and the (tunable) settings; fmi3Get; fmi3DoStep.
 *   terminated:   fmi3Get.
 * A doStep that fails leaves the instance in `error`: variables can still be read
 * (diagnostics), fmi3Terminate is accepted, fmi3SetFMUState or fmi3Reset bring it back.
 * Misuse that does not damage the instance returns fmi3Error and leaves the state unchanged.
 * fmi3Fatal is sticky (reserved, as in fmi2.c).
 *
 * Logging ("Status Returned by Functions and Logging Mechanism"): error and fatal statuses
 * are always reported through logMessage (if it is not NULL); warnings under
 * logStatusWarning and debug output under logEvents / logAll only when enabled by loggingOn
 * or fmi3SetDebugLogging. '#' in messages is escaped as "##" (the standard uses #vr# to
 * reference variables).
 *
 * Memory: FMI 3.0 has no memory callbacks; the shell uses calloc and free.
 *
 * What is FMI 3.0's own, and so lives here rather than in instance.c (the logic both
 * standards share):
 *   - every function of fmi3Functions.h, the unsupported ones included; no memory callbacks
 *     (calloc and free); the logMessage callback with '#' escaped;
 *   - log categories logEvents, logStatusWarning, logStatusError, logAll; errors are always
 *     logged; with loggingOn false, nothing else is;
 *   - fmi3EnterInitializationMode takes the experiment (start, stop time and tolerance);
 *     variables can be read from instantiation on (start values); the solver settings are
 *     tunable (settable in Step Mode too); the independent variable `time` (VR_TIME);
 *   - the nValues arguments, the types this FMU has none of, and fmi3DoStep's output flags
 *     (eventHandlingNeeded, terminateSimulation, earlyReturn: always false) and
 *     lastSuccessfulTime.
 */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "instance.h"
#include "instance.h" /* the generic shell (instance.c), compiled as a unit of its own */

/* ---------------------------------------------------------------------------------------
 * Instance and layer description
 * ------------------------------------------------------------------------------------- */

typedef struct {
    md_instance base;               /* first: an fmi3Instance is also an md_instance * */
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback logger;  /* may be NULL: then nothing is logged */
} Instance;

/* Variables can be read from instantiation on (start values). */
#define ST_READABLE MD_MODE_ANY

/* The independent variable's value reference: after the model's variables and the settings.
   model_description.py (fmi3_model_description) writes the same number. */
#define VR_TIME ((fmi3ValueReference)MD_INFO.nvars + (fmi3ValueReference)MD_SHELL_NREAL)

/* Log categories: md_settings.h, from the table modelDescription.xml <LogCategories> is
   written from. */
static const char *const LOG_NAMES[MD_FMI3_NLOG] = MD_FMI3_LOG_NAMES;

static fmi3Status status_of(md_result result) {
    switch (result) {
    case MD_RESULT_OK: return fmi3OK;
    case MD_RESULT_WARNING: return fmi3Warning;
    case MD_RESULT_DISCARD: return fmi3Discard;
    case MD_RESULT_ERROR: return fmi3Error;
    case MD_RESULT_FATAL: return fmi3Fatal;
    }
    return fmi3Fatal;
}

/* Copy text with '#' doubled ('#' is the escape character of logMessage). */
static void escape_hashes(const char *text, char *out, size_t size) {
    size_t n = 0;
    for (; *text != '\0' && n + 2 < size; ++text) {
        if (*text == '#') { out[n++] = '#'; }
        out[n++] = *text;
    }
    out[n] = '\0';
}

static void log_message(const md_instance *m, md_result status, const char *category,
                        const char *text) {
    const Instance *c = (const Instance *)m;
    char escaped[2 * MD_MESSAGE_SIZE];
    escape_hashes(text, escaped, sizeof escaped);
    c->logger(c->env, status_of(status), category, escaped);
}

static const md_layer FMI3 = {
    .enter_initialization = "fmi3EnterInitializationMode",
    .exit_initialization = "fmi3ExitInitializationMode",
    .do_step = "fmi3DoStep",
    .stop_time_source = "fmi3EnterInitializationMode",
    .recovery = "fmi3Reset or fmi3SetFMUState",
    .fmu_state = "FMUState",
    .real_type = "Float64",
    .parameter = "fixed parameter",
    .settings_tunable = 1,
    .has_time = 1,
    .state_magic = 0x33494D46u, /* "FMI3" */
    .categories = LOG_NAMES,
    .ncategories = MD_FMI3_NLOG,
    .category_of = {[MD_CATEGORY_EVENTS] = MD_FMI3_LOG_EVENTS,
                    [MD_CATEGORY_WARNING] = MD_FMI3_LOG_STATUS_WARNING,
                    [MD_CATEGORY_ERROR] = MD_FMI3_LOG_STATUS_ERROR,
                    [MD_CATEGORY_ALL] = MD_FMI3_LOG_ALL},
    .errors_always_logged = 1,
    .quiet_log_mask = 0u, /* loggingOn enables every category; errors are reported regardless */
    .log = log_message,
};

/* Gatekeeper at the top of every entry point. */
#define GUARD(m, function, allowed) MD_GUARD(m, function, allowed, status_of)

/* A function this FMU does not provide (its capability flag is false, or it belongs to an
 * interface type other than Co-Simulation): fmi3Error with the reason, state unchanged. */
static fmi3Status unsupported(fmi3Instance instance, const char *function, const char *why) {
    return status_of(md_unsupported(instance, function, why));
}

/* ---------------------------------------------------------------------------------------
 * Version and logging
 * ------------------------------------------------------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                               size_t nCategories, const fmi3String categories[]) {
    md_instance *m = instance;
    GUARD(m, "fmi3SetDebugLogging", MD_MODE_ANY);
    return status_of(md_set_debug_logging(m, "fmi3SetDebugLogging", loggingOn, nCategories,
                                          categories));
}

/* ---------------------------------------------------------------------------------------
 * Creation and destruction ("Super State: FMU State Settable")
 * ------------------------------------------------------------------------------------- */

static void instantiate_error(fmi3LogMessageCallback logger, fmi3InstanceEnvironment env,
                              const char *text) {
    char escaped[2 * MD_MESSAGE_SIZE];
    if (logger != NULL) {
        escape_hashes(text, escaped, sizeof escaped);
        logger(env, fmi3Error, "logStatusError", escaped);
    }
}

static int blank(const char *text) {
    for (; *text != '\0'; ++text) {
        if (*text != ' ' && *text != '\t' && *text != '\n' && *text != '\r') { return 0; }
    }
    return 1;
}

/* The checks both instantiation functions make; NULL and a logged reason if one fails. */
static Instance *instantiate(const char *function, int interface, fmi3String instanceName,
                             fmi3String instantiationToken, fmi3Boolean loggingOn,
                             fmi3InstanceEnvironment instanceEnvironment,
                             fmi3LogMessageCallback logMessage) {
    Instance *c;
    char text[MD_MESSAGE_SIZE];
    if (!md_offers(interface)) {
        snprintf(text, sizeof text, "%s: this FMU does not offer %s (modelDescription.xml has "
                 "no <%s>)", function, interface == MD_INTERFACE_ME ? "Model Exchange"
                 : "Co-Simulation", interface == MD_INTERFACE_ME ? "ModelExchange"
                 : "CoSimulation");
        instantiate_error(logMessage, instanceEnvironment, text);
        return NULL;
    }
    if (instanceName == NULL || blank(instanceName)) {
        snprintf(text, sizeof text, "%s: instanceName must be a non-empty string", function);
        instantiate_error(logMessage, instanceEnvironment, text);
        return NULL;
    }
    if (instantiationToken == NULL || strcmp(instantiationToken, MD_INFO.guid) != 0) {
        snprintf(text, sizeof text, "%s: instantiationToken %s does "
                 "not match this binary's %s (modelDescription.xml and binary out of step?)",
                 function, instantiationToken != NULL ? instantiationToken : "(null)",
                 MD_INFO.guid);
        instantiate_error(logMessage, instanceEnvironment, text);
        return NULL;
    }
    /* FMI 3.0 has no memory callbacks */
    c = (Instance *)md_instance_new(&FMI3, sizeof *c, calloc, free, instanceName);
    if (c == NULL) {
        snprintf(text, sizeof text, "%s: out of memory", function);
        instantiate_error(logMessage, instanceEnvironment, text);
        return NULL;
    }
    c->env = instanceEnvironment;
    c->logger = logMessage;
    c->base.interface = interface;
    md_instance_start_logging(&c->base, logMessage != NULL, loggingOn);
    return c;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)resourcePath; /* the FMU has no resources */
    (void)visible;
    return instantiate("fmi3InstantiateModelExchange", MD_INTERFACE_ME, instanceName,
                       instantiationToken, loggingOn, instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName,
                                               fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible,
                                               fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn; (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    instantiate_error(logMessage, instanceEnvironment, "fmi3InstantiateScheduledExecution: "
                      "this FMU supports Co-Simulation only (modelDescription.xml has no "
                      "<ScheduledExecution>)");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName,
                                         fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible,
                                         fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)resourcePath;       /* the FMU has no resources */
    (void)visible;
    (void)earlyReturnAllowed; /* allowed, never used: fmi3DoStep always completes its step */
    (void)requiredIntermediateVariables;
    (void)intermediateUpdate; /* providesIntermediateUpdate="false": never called */
    if (eventModeUsed) {
        /* eventModeUsed may only be true if hasEventMode = true (fmi3InstantiateCoSimulation) */
        instantiate_error(logMessage, instanceEnvironment, "fmi3InstantiateCoSimulation: "
                          "eventModeUsed = true, but this FMU has no Event Mode "
                          "(hasEventMode=\"false\")");
        return NULL;
    }
    if (nRequiredIntermediateVariables > 0) {
        instantiate_error(logMessage, instanceEnvironment, "fmi3InstantiateCoSimulation: "
                          "requiredIntermediateVariables given, but no variable of this FMU "
                          "has intermediateUpdate=\"true\" (providesIntermediateUpdate=\"false\")");
        return NULL;
    }
    return instantiate("fmi3InstantiateCoSimulation", MD_INTERFACE_CS, instanceName,
                       instantiationToken, loggingOn, instanceEnvironment, logMessage);
}

void fmi3FreeInstance(fmi3Instance instance) { md_instance_free(instance); }

/* ---------------------------------------------------------------------------------------
 * Initialisation, termination, reset
 * ------------------------------------------------------------------------------------- */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    md_instance *m = instance;
    md_result experiment, started;
    GUARD(m, "fmi3EnterInitializationMode", MD_MODE_INSTANTIATED);
    experiment = md_setup_experiment(m, "fmi3EnterInitializationMode", toleranceDefined,
                                     tolerance, startTime, stopTimeDefined, stopTime);
    if (experiment >= MD_RESULT_ERROR) { return status_of(experiment); }
    started = md_enter_initialization(m, "fmi3EnterInitializationMode");
    /* a Warning about the tolerance stands if the start succeeds */
    return status_of(started != MD_RESULT_OK ? started : experiment);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    md_instance *m = instance;
    GUARD(m, "fmi3ExitInitializationMode", MD_MODE_INIT);
    /* Co-Simulation (eventModeUsed is false): straight to Step Mode; Model Exchange: Event
       Mode */
    return status_of(md_exit_initialization(m, "fmi3ExitInitializationMode"));
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    md_instance *m = instance;
    /* from error too: a master that tidies up after a failed step should not get a second
       error for it */
    GUARD(m, "fmi3Terminate", MD_MODE_RUNNING | MD_MODE_ERROR);
    m->mode = MD_MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    md_instance *m = instance;
    GUARD(m, "fmi3Reset", MD_MODE_ANY);
    md_reset(m);
    return fmi3OK;
}

/* ---------------------------------------------------------------------------------------
 * Getting and setting variable values. Which variable may be set when (md_set_values):
 * parameters (fixed) before fmi3ExitInitializationMode; inputs and the tunable solver
 * settings also in Step Mode ("State: Step Mode"); never calculated parameters, constants,
 * computed variables or time.
 * ------------------------------------------------------------------------------------- */

static double boolean_at(const void *values, size_t i) {
    return ((const fmi3Boolean *)values)[i] ? 1.0 : 0.0;
}

static void boolean_put(void *values, size_t i, double value) {
    ((fmi3Boolean *)values)[i] = value != 0.0;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    md_instance *m = instance;
    GUARD(m, "fmi3GetFloat64", ST_READABLE);
    return status_of(md_get_values(m, "fmi3GetFloat64", valueReferences, nValueReferences,
                                   values, nValues, md_real_put, 0));
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    md_instance *m = instance;
    GUARD(m, "fmi3GetBoolean", ST_READABLE);
    return status_of(md_get_values(m, "fmi3GetBoolean", valueReferences, nValueReferences,
                                   values, nValues, boolean_put, 1));
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[],
                          size_t nValues) {
    md_instance *m = instance;
    GUARD(m, "fmi3SetFloat64", MD_MODE_SETTABLE);
    return status_of(md_set_values(m, "fmi3SetFloat64", valueReferences, nValueReferences,
                                   values, nValues, md_real_at, 0));
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Boolean values[],
                          size_t nValues) {
    md_instance *m = instance;
    GUARD(m, "fmi3SetBoolean", MD_MODE_SETTABLE);
    return status_of(md_set_values(m, "fmi3SetBoolean", valueReferences, nValueReferences,
                                   values, nValues, boolean_at, 1));
}

/* The other variable types: this FMU has none. An empty request is fine; anything else names
 * the first value reference and what it is. */
static fmi3Status no_such_type(fmi3Instance instance, const char *function, const char *type,
                               unsigned allowed, const fmi3ValueReference vr[], size_t nvr) {
    md_instance *m = instance;
    const fmi3ValueReference nvars = (fmi3ValueReference)MD_INFO.nvars;
    fmi3ValueReference r;
    GUARD(m, function, allowed);
    if (nvr == 0) { return fmi3OK; }
    if (vr == NULL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "%s: NULL array", function));
    }
    r = vr[0];
    if (r < nvars) {
        return status_of(md_report(m, MD_RESULT_ERROR, "%s: %s is not a %s variable (this FMU "
                                   "has Float64 and Boolean variables only)", function,
                                   MD_INFO.names[r], type));
    }
    if (r < nvars + MD_SHELL_NREAL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "%s: %s is a Float64 variable", function,
                                   MD_SHELL_SETTINGS[r - nvars].name));
    }
    if (r == VR_TIME) {
        return status_of(md_report(m, MD_RESULT_ERROR, "%s: time is a Float64 variable",
                                   function));
    }
    return status_of(md_report(m, MD_RESULT_ERROR, "%s: unknown value reference %u", function,
                               r));
}

#define NO_GET(Type, CType)                                                                  \
    fmi3Status fmi3Get##Type(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, CType values[], size_t nValues) {      \
        (void)values; (void)nValues;                                                          \
        return no_such_type(instance, "fmi3Get" #Type, #Type, ST_READABLE, valueReferences,   \
                            nValueReferences);                                                \
    }

#define NO_SET(Type, CType)                                                                  \
    fmi3Status fmi3Set##Type(fmi3Instance instance, const fmi3ValueReference valueReferences[], \
                             size_t nValueReferences, const CType values[], size_t nValues) { \
        (void)values; (void)nValues;                                                          \
        return no_such_type(instance, "fmi3Set" #Type, #Type, MD_MODE_SETTABLE,               \
                            valueReferences, nValueReferences);                               \
    }

NO_GET(Float32, fmi3Float32)
NO_GET(Int8, fmi3Int8)
NO_GET(UInt8, fmi3UInt8)
NO_GET(Int16, fmi3Int16)
NO_GET(UInt16, fmi3UInt16)
NO_GET(Int32, fmi3Int32)
NO_GET(UInt32, fmi3UInt32)
NO_GET(UInt64, fmi3UInt64)
NO_GET(String, fmi3String)

/* The Int64 variables are the integrator statistics (solver.steps, ...). */
fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int64 values[], size_t nValues) {
    md_instance *m = instance;
    GUARD(m, "fmi3GetInt64", ST_READABLE);
    return status_of(md_get_statistics(m, "fmi3GetInt64", valueReferences, nValueReferences,
                                       values, nValues));
}

NO_SET(Float32, fmi3Float32)
NO_SET(Int8, fmi3Int8)
NO_SET(UInt8, fmi3UInt8)
NO_SET(Int16, fmi3Int16)
NO_SET(UInt16, fmi3UInt16)
NO_SET(Int32, fmi3Int32)
NO_SET(UInt32, fmi3UInt32)
NO_SET(Int64, fmi3Int64)
NO_SET(UInt64, fmi3UInt64)
NO_SET(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[],
                         size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return no_such_type(instance, "fmi3GetBinary", "Binary", ST_READABLE, valueReferences,
                        nValueReferences);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return no_such_type(instance, "fmi3SetBinary", "Binary", MD_MODE_SETTABLE, valueReferences,
                        nValueReferences);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[]) {
    (void)values;
    return no_such_type(instance, "fmi3GetClock", "Clock", MD_MODE_ANY, valueReferences,
                        nValueReferences);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[]) {
    (void)values;
    return no_such_type(instance, "fmi3SetClock", "Clock", MD_MODE_ANY, valueReferences,
                        nValueReferences);
}

/* ---------------------------------------------------------------------------------------
 * FMU state ("Getting and Setting the Complete FMU State"). The in-memory copy and the
 * serialised form are the same bytes.
 * ------------------------------------------------------------------------------------- */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    md_instance *m = instance;
    GUARD(m, "fmi3GetFMUState", MD_MODE_ANY);
    return status_of(md_get_state(m, "fmi3GetFMUState", FMUState));
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    md_instance *m = instance;
    GUARD(m, "fmi3SetFMUState", MD_MODE_ANY);
    return status_of(md_set_state(m, "fmi3SetFMUState", FMUState));
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    md_instance *m = instance;
    GUARD(m, "fmi3FreeFMUState", MD_MODE_ANY);
    return status_of(md_free_state(m, "fmi3FreeFMUState", FMUState));
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) {
    md_instance *m = instance;
    GUARD(m, "fmi3SerializedFMUStateSize", MD_MODE_ANY);
    return status_of(md_serialized_state_size(m, "fmi3SerializedFMUStateSize", FMUState, size));
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    md_instance *m = instance;
    GUARD(m, "fmi3SerializeFMUState", MD_MODE_ANY);
    return status_of(md_serialize_state(m, "fmi3SerializeFMUState", FMUState, serializedState,
                                        size));
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    md_instance *m = instance;
    GUARD(m, "fmi3DeserializeFMUState", MD_MODE_ANY);
    return status_of(md_deserialize_state(m, "fmi3DeserializeFMUState", serializedState, size,
                                          FMUState));
}

/* ---------------------------------------------------------------------------------------
 * Stepping ("State: Step Mode", fmi3DoStep)
 * ------------------------------------------------------------------------------------- */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    md_instance *m = instance;
    md_result result;
    (void)noSetFMUStatePriorToCurrentPoint;
    GUARD(m, "fmi3DoStep", MD_MODE_STEP);
    if (eventHandlingNeeded == NULL || terminateSimulation == NULL || earlyReturn == NULL
        || lastSuccessfulTime == NULL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "fmi3DoStep: an output argument is "
                                   "NULL"));
    }
    /* no Event Mode, no early return, never asks to stop: all three are always false */
    *eventHandlingNeeded = 0;
    *terminateSimulation = 0;
    *earlyReturn = 0;
    result = md_do_step(m, "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    /* where it got to: the end of the step, or the last good point if the step failed */
    *lastSuccessfulTime = m->solver->t;
    return status_of(result);
}

/* ---------------------------------------------------------------------------------------
 * Not provided: capability flags false in modelDescription.xml, or another interface type
 * ------------------------------------------------------------------------------------- */

#define NO_EVENT_MODE "this FMU has no Event Mode (hasEventMode=\"false\")"
#define NO_CLOCKS "this FMU has no clocks"

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    md_instance *m = instance;
    if (m != NULL && m->interface == MD_INTERFACE_ME) {
        GUARD(m, "fmi3EnterEventMode", MD_MODE_EVENT | MD_MODE_CONTINUOUS);
        m->mode = MD_MODE_EVENT;
        return fmi3OK;
    }
    return unsupported(instance, "fmi3EnterEventMode", NO_EVENT_MODE);
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterStepMode", NO_EVENT_MODE
                       "; fmi3ExitInitializationMode enters Step Mode directly");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    return unsupported(instance, "fmi3EvaluateDiscreteStates",
                       "not provided (providesEvaluateDiscreteStates=\"false\")");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    md_instance *m = instance;
    int changed = 0;
    md_result result;
    if (m == NULL || m->interface != MD_INTERFACE_ME) {
        return unsupported(instance, "fmi3UpdateDiscreteStates", NO_EVENT_MODE);
    }
    GUARD(m, "fmi3UpdateDiscreteStates", MD_MODE_EVENT);
    if (discreteStatesNeedUpdate == NULL || terminateSimulation == NULL
        || nominalsOfContinuousStatesChanged == NULL || valuesOfContinuousStatesChanged == NULL
        || nextEventTimeDefined == NULL || nextEventTime == NULL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "fmi3UpdateDiscreteStates: an output "
                                   "argument is NULL"));
    }
    result = md_me_update_discrete_states(m, "fmi3UpdateDiscreteStates", &changed);
    *discreteStatesNeedUpdate = 0; /* event iteration is done inside */
    *terminateSimulation = 0;
    *nominalsOfContinuousStatesChanged = 0;
    *valuesOfContinuousStatesChanged = changed ? 1 : 0;
    *nextEventTimeDefined = 0; /* no time events */
    *nextEventTime = 0.0;
    return status_of(result);
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance,
                                    const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[],
                                    fmi3Float64 values[], size_t nValues) {
    (void)valueReferences; (void)nValueReferences; (void)orders; (void)values; (void)nValues;
    return unsupported(instance, "fmi3GetOutputDerivatives",
                       "not provided (maxOutputDerivativeOrder=\"0\")");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance,
                                        const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns,
                                        const fmi3Float64 seed[], size_t nSeed,
                                        fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed;
    (void)sensitivity; (void)nSensitivity;
    return unsupported(instance, "fmi3GetDirectionalDerivative",
                       "not provided (providesDirectionalDerivatives=\"false\")");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                    size_t nUnknowns, const fmi3ValueReference knowns[],
                                    size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                    fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed;
    (void)sensitivity; (void)nSensitivity;
    return unsupported(instance, "fmi3GetAdjointDerivative",
                       "not provided (providesAdjointDerivatives=\"false\")");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                               fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference; (void)nDependencies;
    return unsupported(instance, "fmi3GetNumberOfVariableDependencies",
                       "not provided (providesPerElementDependencies=\"false\")");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents;
    (void)elementIndicesOfIndependents; (void)dependencyKinds; (void)nDependencies;
    return unsupported(instance, "fmi3GetVariableDependencies",
                       "not provided (providesPerElementDependencies=\"false\")");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterConfigurationMode",
                       "this FMU has no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3ExitConfigurationMode",
                       "this FMU has no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance,
                                  const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences; (void)nValueReferences; (void)intervals; (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance,
                                   const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[],
                                   fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) {
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return unsupported(instance, "fmi3GetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance,
                                const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[],
                                fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3GetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance,
                                  const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[]) {
    (void)valueReferences; (void)nValueReferences; (void)intervals;
    return unsupported(instance, "fmi3SetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance,
                                   const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3SetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) {
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return unsupported(instance, "fmi3SetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance,
                                const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) {
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3SetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    return unsupported(instance, "fmi3ActivateModelPartition",
                       "Scheduled Execution is not supported by this FMU (Co-Simulation only)");
}

/* ---------------------------------------------------------------------------------------
 * Model Exchange ("Model Exchange" chapter)
 * ------------------------------------------------------------------------------------- */

/* At the top of every Model Exchange function: the instance must be one. */
#define GUARD_ME(m, function, allowed) MD_GUARD_ME(m, function, allowed, status_of)

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    md_instance *m = instance;
    GUARD_ME(m, "fmi3EnterContinuousTimeMode", MD_MODE_EVENT);
    m->mode = MD_MODE_CONTINUOUS;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) {
    md_instance *m = instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    GUARD_ME(m, "fmi3CompletedIntegratorStep", MD_MODE_CONTINUOUS);
    if (enterEventMode == NULL || terminateSimulation == NULL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "fmi3CompletedIntegratorStep: an "
                                   "output argument is NULL"));
    }
    md_me_completed_step(m);
    *enterEventMode = 0; /* no step events: every event has an indicator */
    *terminateSimulation = 0;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    md_instance *m = instance;
    GUARD_ME(m, "fmi3SetTime", MD_MODE_EVENT | MD_MODE_CONTINUOUS);
    return status_of(md_me_set_time(m, "fmi3SetTime", time));
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    md_instance *m = instance;
    GUARD_ME(m, "fmi3SetContinuousStates", MD_MODE_EVENT | MD_MODE_CONTINUOUS);
    return status_of(md_me_set_states(m, "fmi3SetContinuousStates", continuousStates,
                                      nContinuousStates));
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    md_instance *m = instance;
    GUARD_ME(m, "fmi3GetContinuousStateDerivatives", MD_MODE_EVALUABLE);
    return status_of(md_me_get_derivatives(m, "fmi3GetContinuousStateDerivatives", derivatives,
                                           nContinuousStates));
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) {
    md_instance *m = instance;
    GUARD_ME(m, "fmi3GetEventIndicators", MD_MODE_EVALUABLE);
    return status_of(md_me_get_indicators(m, "fmi3GetEventIndicators", eventIndicators,
                                          nEventIndicators));
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    md_instance *m = instance;
    GUARD_ME(m, "fmi3GetContinuousStates", MD_MODE_EVALUABLE);
    return status_of(md_me_get_states(m, "fmi3GetContinuousStates", continuousStates,
                                      nContinuousStates));
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    md_instance *m = instance;
    GUARD_ME(m, "fmi3GetNominalsOfContinuousStates", MD_MODE_ANY);
    return status_of(md_me_get_nominals(m, "fmi3GetNominalsOfContinuousStates", nominals,
                                        nContinuousStates));
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    md_instance *m = instance;
    GUARD(m, "fmi3GetNumberOfEventIndicators", MD_MODE_ANY);
    if (nEventIndicators == NULL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "fmi3GetNumberOfEventIndicators: "
                                   "nEventIndicators is NULL"));
    }
    *nEventIndicators = (size_t)MD_INFO.nz;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    md_instance *m = instance;
    GUARD(m, "fmi3GetNumberOfContinuousStates", MD_MODE_ANY);
    if (nContinuousStates == NULL) {
        return status_of(md_report(m, MD_RESULT_ERROR, "fmi3GetNumberOfContinuousStates: "
                                   "nContinuousStates is NULL"));
    }
    *nContinuousStates = (size_t)MD_INFO.ny;
    return fmi3OK;
}
