/* FMI 3.0 Co-Simulation entry points for a generated model (md_model.h), on top of the
 * model-independent core in solver.c -- the same core fmi2.c wraps, so an FMI 3.0 build and
 * an FMI 2.0 build of one model compute the same numbers.
 *
 References in quotes are section titles of the FMI 3.0 standard.
 *
 * Interface types: Co-Simulation only. The standard asks every function of fmi3Functions.h to
 * be present in the binary ("FMU Distribution"), so the Model Exchange and Scheduled Execution
 * functions exist: the instantiation functions return NULL and the rest return fmi3Error.
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
 * State machine ("State Machine and Semantics", "State Machine for Co-Simulation"), what a Co-Simulation FMU without Event Mode needs:
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
 * Logging ("Status Returned by Functions and Logging Mechanism"): error and fatal statuses are always reported through logMessage (if
 * it is not NULL); warnings under logStatusWarning and debug output under logEvents / logAll
 * only when enabled by loggingOn or fmi3SetDebugLogging. '#' in messages is escaped as "##"
 * (the standard uses #vr# to reference variables).
 *
 * Memory: FMI 3.0 has no memory callbacks; the shell uses calloc and free.
 */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "md_model.h"
#include "solver.h"

/* ---------------------------------------------------------------------------------------
 * Instance
 * ------------------------------------------------------------------------------------- */

typedef enum {
    ST_INSTANTIATED = 1 << 0,
    ST_INIT = 1 << 1,
    ST_STEP = 1 << 2,       /* Step Mode: ready for fmi3DoStep */
    ST_TERMINATED = 1 << 3,
    ST_ERROR = 1 << 4,
    ST_FATAL = 1 << 5       /* reserved: nothing in this shell damages an instance beyond
                               repair today (all failures are caught at the last good point) */
} fmu_state;

#define ST_ANY (ST_INSTANTIATED | ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR)
#define ST_READABLE (ST_INSTANTIATED | ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR)
#define ST_SETTABLE (ST_INSTANTIATED | ST_INIT | ST_STEP)

/* The independent variable's value reference: after the model's variables and the settings.
   model_description.py (fmi3_model_description) writes the same number. */
#define VR_TIME ((fmi3ValueReference)MD_INFO.nvars + (fmi3ValueReference)MD_SHELL_NREAL)

/* Log categories (modelDescription.xml <LogCategories> lists the same names). */
enum {
    LOG_EVENTS = 0,
    LOG_STATUS_WARNING = 1,
    LOG_STATUS_ERROR = 2,
    LOG_ALL = 3,
    LOG_NCATEGORIES = 4
};
static const char *const LOG_NAMES[LOG_NCATEGORIES] = {
    "logEvents", "logStatusWarning", "logStatusError", "logAll"};
#define LOG_BIT(category) (1u << (category))
#define LOG_EVERYTHING (LOG_BIT(LOG_NCATEGORIES) - 1u)

struct FmuState;

typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback logger; /* may be NULL: then nothing is logged */
    char *name;
    struct FmuState *states;   /* FMU states not yet freed: fmi3FreeInstance frees them */
    md_solver *solver;
    fmu_state state;
    unsigned log_mask;
    double start_time;
    double stop_time;
    int stop_defined;
    int rel_tol_set;      /* solver.relTol set explicitly: it wins over the tolerance argument */
    int params_dirty;     /* a parameter changed in initialisation mode since md_solver_start */
    char message[MD_MESSAGE_SIZE];
} Instance;

/* An FMU state ("Getting and Setting the Complete FMU State"): the solver's flat state buffer, tagged with the FMI mode.
 * Each instance keeps a list of the states it handed out, so that fmi3FreeInstance can free
 * what the importer did not (fmi3FreeInstance "frees all the allocated memory"). */
#define FMU_STATE_MAGIC 0x33494D46u /* "FMI3" */
typedef struct FmuState {
    uint32_t magic;
    void *owner;                  /* the Instance whose list holds it */
    struct FmuState *prev, *next;
    size_t size;
    unsigned char data[]; /* md_solver_save() format */
} FmuState;

/* The solver state's tag: the FMI mode and two flags (the same bits as fmi2.c). */
#define TAG_STATE_MASK 0xff
#define TAG_DIRTY 0x100
#define TAG_RELTOL_SET 0x200

/* ---------------------------------------------------------------------------------------
 * Logging and status reporting
 * ------------------------------------------------------------------------------------- */

static const char *state_name(fmu_state state) {
    switch (state) {
    case ST_INSTANTIATED: return "instantiated";
    case ST_INIT: return "initialisation mode";
    case ST_STEP: return "step mode";
    case ST_TERMINATED: return "terminated";
    case ST_ERROR: return "error";
    case ST_FATAL: return "fatal";
    default: return "?";
    }
}

/* Would a message of this status and category be passed to the logger? Errors always are. */
static int log_enabled(const Instance *c, fmi3Status status, int category) {
    if (c->logger == NULL) { return 0; }
    if (status >= fmi3Error) { return 1; }
    return (c->log_mask & (LOG_BIT(category) | LOG_BIT(LOG_ALL))) != 0;
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

static void emit(const Instance *c, fmi3Status status, int category, const char *text) {
    char escaped[2 * MD_MESSAGE_SIZE];
    if (!log_enabled(c, status, category)) { return; }
    escape_hashes(text, escaped, sizeof escaped);
    c->logger(c->env, status, LOG_NAMES[category], escaped);
}

static void logf_(const Instance *c, int category, const char *format, ...) {
    char text[MD_MESSAGE_SIZE];
    va_list args;
    if (!log_enabled(c, fmi3OK, category)) { return; }
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    emit(c, fmi3OK, category, text);
}

/* Record a non-OK status with its explanation (kept in c->message), log it under
 * logStatusWarning or logStatusError, and return it. */
static fmi3Status report(Instance *c, fmi3Status status, const char *format, ...) {
    va_list args;
    va_start(args, format);
    vsnprintf(c->message, sizeof c->message, format, args);
    va_end(args);
    emit(c, status, status >= fmi3Error ? LOG_STATUS_ERROR : LOG_STATUS_WARNING, c->message);
    return status;
}

/* Gatekeeper at the top of every entry point. */
static fmi3Status guard(Instance *c, const char *function, unsigned allowed) {
    if (c == NULL) { return fmi3Error; }
    if (c->state == ST_FATAL) { return fmi3Fatal; }
    if ((c->state & allowed) == 0) {
        if (c->state == ST_ERROR) {
            return report(c, fmi3Error, "%s: not allowed after an error (%s); call fmi3Reset "
                          "or fmi3SetFMUState", function, md_solver_message(c->solver));
        }
        return report(c, fmi3Error, "%s: not allowed in %s", function, state_name(c->state));
    }
    return fmi3OK;
}

#define GUARD(c, function, allowed)                                  \
    do {                                                             \
        fmi3Status guard_status = guard((c), (function), (allowed)); \
        if (guard_status != fmi3OK) { return guard_status; }         \
    } while (0)

/* A function this FMU does not provide (its capability flag is false, or it belongs to an
 * interface type other than Co-Simulation): fmi3Error with the reason, state unchanged. */
static fmi3Status unsupported(fmi3Instance instance, const char *function, const char *why) {
    Instance *c = instance;
    GUARD(c, function, ST_ANY);
    return report(c, fmi3Error, "%s: %s", function, why);
}

/* Solver host services */

static void *host_allocate(void *env, size_t nobj, size_t size) {
    (void)env;
    return calloc(nobj, size);
}

static void host_release(void *env, void *ptr) {
    (void)env;
    free(ptr);
}

static int host_log_enabled(void *env, md_log_category category) {
    return log_enabled((Instance *)env, fmi3OK,
                       category == MD_LOG_EVENTS ? LOG_EVENTS : LOG_ALL);
}

static void host_log(void *env, md_log_category category, const char *message) {
    emit((Instance *)env, fmi3OK, category == MD_LOG_EVENTS ? LOG_EVENTS : LOG_ALL, message);
}

/* ---------------------------------------------------------------------------------------
 * Version and logging
 * ------------------------------------------------------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                               size_t nCategories, const fmi3String categories[]) {
    Instance *c = instance;
    fmi3Status status = fmi3OK;
    GUARD(c, "fmi3SetDebugLogging", ST_ANY);
    if (nCategories == 0) {
        c->log_mask = loggingOn ? LOG_EVERYTHING : 0u;
        return fmi3OK;
    }
    if (categories == NULL) {
        return report(c, fmi3Error, "fmi3SetDebugLogging: categories is NULL");
    }
    for (size_t i = 0; i < nCategories; ++i) {
        int found = -1;
        for (int k = 0; k < LOG_NCATEGORIES; ++k) {
            if (categories[i] != NULL && strcmp(categories[i], LOG_NAMES[k]) == 0) { found = k; }
        }
        if (found < 0) {
            status = report(c, fmi3Warning, "fmi3SetDebugLogging: unknown log category \"%s\" "
                            "ignored (known: logEvents, logStatusWarning, logStatusError, "
                            "logAll)", categories[i] != NULL ? categories[i] : "(null)");
        } else if (loggingOn) {
            c->log_mask |= LOG_BIT(found);
        } else {
            c->log_mask &= ~LOG_BIT(found);
        }
    }
    return status;
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

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn;
    instantiate_error(logMessage, instanceEnvironment, "fmi3InstantiateModelExchange: this FMU "
                      "supports Co-Simulation only (modelDescription.xml has no <ModelExchange>)");
    return NULL;
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
    Instance *c;
    md_host host;
    size_t length;
    char text[MD_MESSAGE_SIZE];

    (void)resourcePath;       /* the FMU has no resources */
    (void)visible;
    (void)earlyReturnAllowed; /* allowed, never used: fmi3DoStep always completes its step */
    (void)requiredIntermediateVariables;
    (void)intermediateUpdate; /* providesIntermediateUpdate="false": never called */
    if (instanceName == NULL || blank(instanceName)) {
        instantiate_error(logMessage, instanceEnvironment,
                          "fmi3InstantiateCoSimulation: instanceName must be a non-empty string");
        return NULL;
    }
    if (instantiationToken == NULL || strcmp(instantiationToken, MD_INFO.guid) != 0) {
        snprintf(text, sizeof text, "fmi3InstantiateCoSimulation: instantiationToken %s does "
                 "not match this binary's %s (modelDescription.xml and binary out of step?)",
                 instantiationToken != NULL ? instantiationToken : "(null)", MD_INFO.guid);
        instantiate_error(logMessage, instanceEnvironment, text);
        return NULL;
    }
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

    c = calloc(1, sizeof *c);
    if (c == NULL) {
        instantiate_error(logMessage, instanceEnvironment,
                          "fmi3InstantiateCoSimulation: out of memory");
        return NULL;
    }
    c->env = instanceEnvironment;
    c->logger = logMessage;
    length = strlen(instanceName);
    c->name = malloc(length + 1);
    if (c->name != NULL) { memcpy(c->name, instanceName, length + 1); }
    host.allocate = host_allocate;
    host.release = host_release;
    host.log = host_log;
    host.log_enabled = host_log_enabled;
    host.env = c;
    c->solver = c->name != NULL ? md_solver_new(&MD_INFO, &host) : NULL;
    if (c->solver == NULL) {
        instantiate_error(logMessage, instanceEnvironment,
                          "fmi3InstantiateCoSimulation: out of memory");
        free(c->name);
        free(c);
        return NULL;
    }
    c->state = ST_INSTANTIATED;
    /* loggingOn enables every category; errors are reported regardless. */
    c->log_mask = loggingOn ? LOG_EVERYTHING : 0u;
    c->start_time = 0.0;
    c->stop_time = 0.0;
    c->stop_defined = 0;
    c->rel_tol_set = 0;
    c->params_dirty = 0;
    c->message[0] = '\0';
    logf_(c, LOG_ALL, "instantiated %s: %d states, %d event indicators, %d variables",
          MD_INFO.model_name, MD_INFO.ny, MD_INFO.nz, MD_INFO.nvars);
    return c;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Instance *c = instance;
    if (c == NULL) { return; }
    while (c->states != NULL) {
        FmuState *st = c->states;
        c->states = st->next;
        st->magic = 0;
        free(st);
    }
    md_solver_free(c->solver);
    free(c->name);
    free(c);
}

/* ---------------------------------------------------------------------------------------
 * Initialisation, termination, reset
 * ------------------------------------------------------------------------------------- */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Instance *c = instance;
    fmi3Status status = fmi3OK;
    GUARD(c, "fmi3EnterInitializationMode", ST_INSTANTIATED);
    if (!isfinite(startTime)) {
        return report(c, fmi3Error, "fmi3EnterInitializationMode: startTime %g is not finite",
                      startTime);
    }
    if (stopTimeDefined && !(stopTime >= startTime && isfinite(stopTime))) {
        return report(c, fmi3Error, "fmi3EnterInitializationMode: stopTime %g before "
                      "startTime %g", stopTime, startTime);
    }
    /* fmi3EnterInitializationMode: for Co-Simulation, "usually as relative tolerance" */
    if (toleranceDefined && !c->rel_tol_set) {
        if (md_solver_set_setting(c->solver, MD_SETTING_RELTOL, tolerance) != MD_OK) {
            status = report(c, fmi3Warning, "fmi3EnterInitializationMode: tolerance ignored: %s",
                            md_solver_message(c->solver));
        }
    }
    c->start_time = startTime;
    c->stop_defined = stopTimeDefined != 0;
    c->stop_time = stopTime;
    if (md_solver_start(c->solver, startTime) != MD_OK) {
        c->state = ST_ERROR;
        return report(c, fmi3Error, "fmi3EnterInitializationMode: %s",
                      md_solver_message(c->solver));
    }
    c->params_dirty = 0;
    c->state = ST_INIT;
    return status;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *c = instance;
    GUARD(c, "fmi3ExitInitializationMode", ST_INIT);
    /* parameters set in initialisation mode: start values that depend on them follow */
    if (c->params_dirty && md_solver_start(c->solver, c->start_time) != MD_OK) {
        c->state = ST_ERROR;
        return report(c, fmi3Error, "fmi3ExitInitializationMode: %s",
                      md_solver_message(c->solver));
    }
    c->params_dirty = 0;
    if (md_solver_initialize(c->solver) != MD_OK) {
        c->state = ST_ERROR;
        return report(c, fmi3Error, "fmi3ExitInitializationMode: %s",
                      md_solver_message(c->solver));
    }
    c->state = ST_STEP; /* eventModeUsed is false: straight to Step Mode */
    logf_(c, LOG_ALL, "initialised at t=%.17g s (relTol=%g, absTol=%g, maxStep=%g)",
          c->solver->t, c->solver->settings.rel_tol, c->solver->settings.abs_tol,
          c->solver->settings.max_step);
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    Instance *c = instance;
    /* from error too: a master that tidies up after a failed step should not get a second
       error for it */
    GUARD(c, "fmi3Terminate", ST_STEP | ST_ERROR);
    c->state = ST_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    Instance *c = instance;
    GUARD(c, "fmi3Reset", ST_ANY);
    md_solver_reset(c->solver);
    c->state = ST_INSTANTIATED;
    c->start_time = 0.0;
    c->stop_time = 0.0;
    c->stop_defined = 0;
    c->rel_tol_set = 0;
    c->params_dirty = 0;
    c->message[0] = '\0';
    return fmi3OK;
}

/* ---------------------------------------------------------------------------------------
 * Getting and setting variable values
 * ------------------------------------------------------------------------------------- */

/* Every variable is a scalar: one value per value reference. */
static fmi3Status check_arrays(Instance *c, const char *function, const void *vr, size_t nvr,
                               const void *values, size_t nValues) {
    if (nValues != nvr) {
        return report(c, fmi3Error, "%s: nValues = %lu but nValueReferences = %lu (all "
                      "variables of this FMU are scalars)", function, (unsigned long)nValues,
                      (unsigned long)nvr);
    }
    if (nvr > 0 && (vr == NULL || values == NULL)) {
        return report(c, fmi3Error, "%s: NULL array", function);
    }
    return fmi3OK;
}

static fmi3Status refresh_for_get(Instance *c, const fmi3ValueReference vr[], size_t nvr) {
    if (c->state == ST_INIT && c->params_dirty) {
        if (md_solver_start(c->solver, c->start_time) != MD_OK) {
            return report(c, fmi3Error, "%s", md_solver_message(c->solver));
        }
        c->params_dirty = 0;
    } else if (c->state == ST_INSTANTIATED) {
        /* start values of calculated parameters and constants follow the parameters set so
           far; md_parameters only writes their slots (md_solver_start runs it again) */
        for (size_t i = 0; i < nvr; ++i) {
            if (vr[i] < (fmi3ValueReference)MD_INFO.nvars
                && MD_INFO.kind[vr[i]] == MD_CALCULATED) {
                md_parameters(c->solver->p);
                break;
            }
        }
    }
    return fmi3OK;
}

/* The value of variable r as a double (a solver setting or time only if float64). */
static fmi3Status get_value(Instance *c, const char *function, fmi3ValueReference r,
                            int float64, double *value) {
    const md_info *info = &MD_INFO;
    const fmi3ValueReference nvars = (fmi3ValueReference)info->nvars;
    if (r < nvars) {
        if (c->state == ST_INSTANTIATED) {
            /* start values: only what lives in p has one before initialisation */
            if (info->par_slot[r] < 0) {
                return report(c, fmi3Error, "%s: %s has no value before "
                              "fmi3EnterInitializationMode (it is calculated there)", function,
                              info->names[r]);
            }
            *value = c->solver->p[info->par_slot[r]];
        } else if (info->obs_slot[r] >= 0) {
            *value = c->solver->obs[info->obs_slot[r]];
        } else if (info->par_slot[r] >= 0) {
            *value = c->solver->p[info->par_slot[r]];
        } else {
            return report(c, fmi3Error, "%s: variable %s has no value slot", function,
                          info->names[r]);
        }
        return fmi3OK;
    }
    if (r < nvars + MD_SHELL_NREAL) {
        if (!float64) {
            return report(c, fmi3Error, "%s: %s is a Float64 variable", function,
                          MD_SHELL_SETTINGS[r - nvars].name);
        }
        *value = md_solver_get_setting(c->solver, (int)(r - nvars));
        return fmi3OK;
    }
    if (r == VR_TIME) {
        if (!float64) {
            return report(c, fmi3Error, "%s: time is a Float64 variable", function);
        }
        *value = c->solver->t;
        return fmi3OK;
    }
    return report(c, fmi3Error, "%s: unknown value reference %u", function, r);
}

typedef double (*value_at)(const void *values, size_t i);
static double float64_at(const void *values, size_t i) {
    return ((const fmi3Float64 *)values)[i];
}
static double boolean_at(const void *values, size_t i) {
    return ((const fmi3Boolean *)values)[i] ? 1.0 : 0.0;
}

/* Set variables from values[i] read through `at` (boolean: the call was fmi3SetBoolean).
 * Everything is checked before anything is written, so that a refused call changes nothing.
 * Parameters (fixed): before fmi3ExitInitializationMode; inputs and the tunable solver
 * settings: also in Step Mode ("State: Step Mode"); never calculated parameters, constants,
 * computed variables or time. */
static fmi3Status set_values(Instance *c, const char *function, const fmi3ValueReference vr[],
                             size_t nvr, const void *values, size_t nValues, value_at at,
                             int boolean) {
    const md_info *info = &MD_INFO;
    const fmi3ValueReference nvars = (fmi3ValueReference)info->nvars;
    const int before_run = (c->state & (ST_INSTANTIATED | ST_INIT)) != 0;
    int inputs = 0, parameters = 0;
    md_settings saved;
    if (check_arrays(c, function, vr, nvr, values, nValues) != fmi3OK) { return fmi3Error; }
    for (size_t i = 0; i < nvr; ++i) {
        fmi3ValueReference r = vr[i];
        double value = at(values, i);
        const char *name;
        if (r < nvars) {
            name = info->names[r];
            if (info->kind[r] == MD_PARAMETER) {
                if (!before_run) {
                    return report(c, fmi3Error, "%s: variable %s is a fixed parameter: it can "
                                  "only be set before fmi3ExitInitializationMode", function,
                                  name);
                }
            } else if (info->kind[r] != MD_INPUT) {
                return report(c, fmi3Error, "%s: variable %s is not settable", function, name);
            }
            if (info->par_slot[r] < 0) {
                return report(c, fmi3Error, "%s: variable %s has no parameter slot", function,
                              name);
            }
        } else if (r < nvars + MD_SHELL_NREAL) {
            name = MD_SHELL_SETTINGS[r - nvars].name;
            if (boolean) {
                return report(c, fmi3Error, "%s: %s is a Float64 variable", function, name);
            }
        } else if (r == VR_TIME) {
            return report(c, fmi3Error, "%s: time is the independent variable: only fmi3DoStep "
                          "advances it", function);
        } else {
            return report(c, fmi3Error, "%s: unknown value reference %u", function, r);
        }
        if (!isfinite(value)) {
            return report(c, fmi3Error, "%s: refusing the non-finite value %g for %s", function,
                          value, name);
        }
    }
    /* solver settings: range-checked by the solver; undo all of them if one is refused */
    saved = c->solver->settings;
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] >= nvars
            && md_solver_set_setting(c->solver, (int)(vr[i] - nvars), at(values, i)) != MD_OK) {
            c->solver->settings = saved;
            return report(c, fmi3Error, "%s: %s", function, md_solver_message(c->solver));
        }
    }
    for (size_t i = 0; i < nvr; ++i) {
        fmi3ValueReference r = vr[i];
        if (r >= nvars) {
            if (r - nvars == MD_SETTING_RELTOL) { c->rel_tol_set = 1; }
            continue;
        }
        /* an input changed mid-run restarts the integrator at the next step */
        md_solver_set_parameter(c->solver, info->par_slot[r], at(values, i),
                                c->state == ST_STEP);
        if (info->kind[r] == MD_INPUT) { inputs = 1; } else { parameters = 1; }
    }
    if (parameters && c->state == ST_INIT) { c->params_dirty = 1; }
    if (inputs && (c->state & (ST_INIT | ST_STEP)) && !c->params_dirty
        && md_solver_observe(c->solver) != MD_OK) {
        return report(c, fmi3Warning, "%s: outputs not updated: %s", function,
                      md_solver_message(c->solver));
    }
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    Instance *c = instance;
    GUARD(c, "fmi3GetFloat64", ST_READABLE);
    if (check_arrays(c, "fmi3GetFloat64", valueReferences, nValueReferences, values,
                     nValues) != fmi3OK
        || refresh_for_get(c, valueReferences, nValueReferences) != fmi3OK) {
        return fmi3Error;
    }
    for (size_t i = 0; i < nValueReferences; ++i) {
        if (get_value(c, "fmi3GetFloat64", valueReferences[i], 1, &values[i]) != fmi3OK) {
            return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    Instance *c = instance;
    GUARD(c, "fmi3GetBoolean", ST_READABLE);
    if (check_arrays(c, "fmi3GetBoolean", valueReferences, nValueReferences, values,
                     nValues) != fmi3OK
        || refresh_for_get(c, valueReferences, nValueReferences) != fmi3OK) {
        return fmi3Error;
    }
    for (size_t i = 0; i < nValueReferences; ++i) {
        double v;
        if (get_value(c, "fmi3GetBoolean", valueReferences[i], 0, &v) != fmi3OK) {
            return fmi3Error;
        }
        values[i] = v != 0.0;
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[],
                          size_t nValues) {
    Instance *c = instance;
    GUARD(c, "fmi3SetFloat64", ST_SETTABLE);
    return set_values(c, "fmi3SetFloat64", valueReferences, nValueReferences, values, nValues,
                      float64_at, 0);
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Boolean values[],
                          size_t nValues) {
    Instance *c = instance;
    GUARD(c, "fmi3SetBoolean", ST_SETTABLE);
    return set_values(c, "fmi3SetBoolean", valueReferences, nValueReferences, values, nValues,
                      boolean_at, 1);
}

/* The other variable types: this FMU has none. An empty request is fine; anything else names
 * the first value reference and what it is. */
static fmi3Status no_such_type(fmi3Instance instance, const char *function, const char *type,
                               unsigned allowed, const fmi3ValueReference vr[], size_t nvr) {
    Instance *c = instance;
    const fmi3ValueReference nvars = (fmi3ValueReference)MD_INFO.nvars;
    fmi3ValueReference r;
    GUARD(c, function, allowed);
    if (nvr == 0) { return fmi3OK; }
    if (vr == NULL) { return report(c, fmi3Error, "%s: NULL array", function); }
    r = vr[0];
    if (r < nvars) {
        return report(c, fmi3Error, "%s: %s is not a %s variable (this FMU has Float64 and "
                      "Boolean variables only)", function, MD_INFO.names[r], type);
    }
    if (r < nvars + MD_SHELL_NREAL) {
        return report(c, fmi3Error, "%s: %s is a Float64 variable", function,
                      MD_SHELL_SETTINGS[r - nvars].name);
    }
    if (r == VR_TIME) {
        return report(c, fmi3Error, "%s: time is a Float64 variable", function);
    }
    return report(c, fmi3Error, "%s: unknown value reference %u", function, r);
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
        return no_such_type(instance, "fmi3Set" #Type, #Type, ST_SETTABLE, valueReferences,   \
                            nValueReferences);                                                \
    }

NO_GET(Float32, fmi3Float32)
NO_GET(Int8, fmi3Int8)
NO_GET(UInt8, fmi3UInt8)
NO_GET(Int16, fmi3Int16)
NO_GET(UInt16, fmi3UInt16)
NO_GET(Int32, fmi3Int32)
NO_GET(UInt32, fmi3UInt32)
NO_GET(Int64, fmi3Int64)
NO_GET(UInt64, fmi3UInt64)
NO_GET(String, fmi3String)

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
    return no_such_type(instance, "fmi3SetBinary", "Binary", ST_SETTABLE, valueReferences,
                        nValueReferences);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[]) {
    (void)values;
    return no_such_type(instance, "fmi3GetClock", "Clock", ST_ANY, valueReferences,
                        nValueReferences);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[]) {
    (void)values;
    return no_such_type(instance, "fmi3SetClock", "Clock", ST_ANY, valueReferences,
                        nValueReferences);
}

/* ---------------------------------------------------------------------------------------
 * FMU state. The in-memory copy and the serialised form are the same bytes.
 * ------------------------------------------------------------------------------------- */

static int tag_state_valid(int tag) {
    int state = tag & TAG_STATE_MASK;
    return state == ST_INSTANTIATED || state == ST_INIT || state == ST_STEP
           || state == ST_TERMINATED || state == ST_ERROR;
}

/* The state *FMUState points to, to be overwritten, or a new one (linked into c->states). */
static FmuState *state_object(Instance *c, fmi3FMUState *FMUState, size_t size) {
    FmuState *st = *FMUState;
    if (st != NULL && st->magic == FMU_STATE_MAGIC && st->owner == c && st->size == size) {
        return st;
    }
    st = calloc(1, sizeof(FmuState) + size);
    if (st == NULL) { return NULL; }
    st->magic = FMU_STATE_MAGIC;
    st->size = size;
    st->owner = c;
    st->prev = NULL;
    st->next = c->states;
    if (c->states != NULL) { c->states->prev = st; }
    c->states = st;
    /* A foreign pointer in *FMUState is not ours to free: just replace it. */
    *FMUState = st;
    return st;
}

static int is_state(const FmuState *st) { return st != NULL && st->magic == FMU_STATE_MAGIC; }

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    Instance *c = instance;
    size_t size = md_solver_state_size(&MD_INFO);
    FmuState *st;
    int tag;
    GUARD(c, "fmi3GetFMUState", ST_ANY);
    if (FMUState == NULL) { return report(c, fmi3Error, "fmi3GetFMUState: FMUState is NULL"); }
    st = state_object(c, FMUState, size);
    if (st == NULL) { return report(c, fmi3Error, "fmi3GetFMUState: out of memory"); }
    tag = (int)c->state | (c->params_dirty ? TAG_DIRTY : 0) | (c->rel_tol_set ? TAG_RELTOL_SET : 0);
    if (md_solver_save(c->solver, tag, st->data, size) != MD_OK) {
        return report(c, fmi3Error, "fmi3GetFMUState: %s", md_solver_message(c->solver));
    }
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    Instance *c = instance;
    const FmuState *st = FMUState;
    int tag = 0;
    GUARD(c, "fmi3SetFMUState", ST_ANY);
    if (!is_state(st)) {
        return report(c, fmi3Error, "fmi3SetFMUState: not an FMU state of this FMU");
    }
    if (md_solver_check(c->solver, st->data, st->size, &tag) != MD_OK) {
        return report(c, fmi3Error, "fmi3SetFMUState: %s", md_solver_message(c->solver));
    }
    if (!tag_state_valid(tag)) {
        return report(c, fmi3Error, "fmi3SetFMUState: the state is corrupted (mode)");
    }
    (void)md_solver_restore(c->solver, st->data, st->size, NULL);
    c->state = (fmu_state)(tag & TAG_STATE_MASK);
    c->params_dirty = (tag & TAG_DIRTY) != 0;
    c->rel_tol_set = (tag & TAG_RELTOL_SET) != 0;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    Instance *c = instance;
    FmuState *st;
    GUARD(c, "fmi3FreeFMUState", ST_ANY);
    if (FMUState == NULL || *FMUState == NULL) { return fmi3OK; }
    st = *FMUState;
    if (!is_state(st)) {
        return report(c, fmi3Error, "fmi3FreeFMUState: not an FMU state of this FMU");
    }
    if (st->prev != NULL) {
        st->prev->next = st->next;
    } else {
        ((Instance *)st->owner)->states = st->next;
    }
    if (st->next != NULL) { st->next->prev = st->prev; }
    st->magic = 0;
    free(st);
    *FMUState = NULL;
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) {
    Instance *c = instance;
    const FmuState *st = FMUState;
    GUARD(c, "fmi3SerializedFMUStateSize", ST_ANY);
    if (!is_state(st) || size == NULL) {
        return report(c, fmi3Error, "fmi3SerializedFMUStateSize: not an FMU state of this FMU");
    }
    *size = st->size;
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    Instance *c = instance;
    const FmuState *st = FMUState;
    GUARD(c, "fmi3SerializeFMUState", ST_ANY);
    if (!is_state(st) || serializedState == NULL) {
        return report(c, fmi3Error, "fmi3SerializeFMUState: not an FMU state of this FMU");
    }
    if (size != st->size) {
        return report(c, fmi3Error, "fmi3SerializeFMUState: buffer of %lu bytes, %lu needed",
                      (unsigned long)size, (unsigned long)st->size);
    }
    memcpy(serializedState, st->data, size);
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    Instance *c = instance;
    FmuState *st;
    int tag = 0;
    GUARD(c, "fmi3DeserializeFMUState", ST_ANY);
    if (FMUState == NULL) {
        return report(c, fmi3Error, "fmi3DeserializeFMUState: FMUState is NULL");
    }
    if (serializedState == NULL
        || md_solver_check(c->solver, serializedState, size, &tag) != MD_OK) {
        return report(c, fmi3Error, "fmi3DeserializeFMUState: %s",
                      serializedState == NULL ? "serializedState is NULL"
                                              : md_solver_message(c->solver));
    }
    if (!tag_state_valid(tag)) {
        return report(c, fmi3Error, "fmi3DeserializeFMUState: the state is corrupted (mode)");
    }
    st = state_object(c, FMUState, size);
    if (st == NULL) { return report(c, fmi3Error, "fmi3DeserializeFMUState: out of memory"); }
    memcpy(st->data, serializedState, size);
    return fmi3OK;
}

/* ---------------------------------------------------------------------------------------
 * Stepping ("State: Step Mode", fmi3DoStep)
 * ------------------------------------------------------------------------------------- */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    Instance *c = instance;
    md_solver *s;
    double t_end, slack;
    (void)noSetFMUStatePriorToCurrentPoint;
    GUARD(c, "fmi3DoStep", ST_STEP);
    if (eventHandlingNeeded == NULL || terminateSimulation == NULL || earlyReturn == NULL
        || lastSuccessfulTime == NULL) {
        return report(c, fmi3Error, "fmi3DoStep: an output argument is NULL");
    }
    s = c->solver;
    /* no Event Mode, no early return, never asks to stop: all three are always false */
    *eventHandlingNeeded = 0;
    *terminateSimulation = 0;
    *earlyReturn = 0;
    *lastSuccessfulTime = s->t;
    slack = 1e-9 * fmax(1.0, fabs(s->t));
    if (!isfinite(currentCommunicationPoint) || fabs(currentCommunicationPoint - s->t) > slack) {
        return report(c, fmi3Error, "fmi3DoStep: currentCommunicationPoint %.17g s is not the "
                      "FMU's time %.17g s", currentCommunicationPoint, s->t);
    }
    if (!(communicationStepSize >= 0.0) || !isfinite(communicationStepSize)) {
        return report(c, fmi3Error, "fmi3DoStep: communicationStepSize %g must be >= 0",
                      communicationStepSize);
    }
    t_end = currentCommunicationPoint + communicationStepSize;
    if (c->stop_defined && t_end > c->stop_time + 1e-9 * fmax(1.0, fabs(c->stop_time))) {
        return report(c, fmi3Error, "fmi3DoStep: t=%.17g s is past the stopTime %.17g s given "
                      "to fmi3EnterInitializationMode", t_end, c->stop_time);
    }
    s->t = currentCommunicationPoint; /* follow the importer's clock exactly */
    if (md_solver_advance(s, t_end) != MD_OK) {
        c->state = ST_ERROR;
        /* outputs at the last good point, if they can be had */
        (void)md_solver_observe(s);
        *lastSuccessfulTime = s->t;
        return report(c, fmi3Error, "fmi3DoStep: %s", md_solver_message(s));
    }
    *lastSuccessfulTime = s->t;
    return fmi3OK;
}

/* ---------------------------------------------------------------------------------------
 * Not provided: capability flags false in modelDescription.xml, or another interface type
 * ------------------------------------------------------------------------------------- */

#define NOT_ME "Model Exchange is not supported by this FMU (Co-Simulation only)"
#define NO_EVENT_MODE "this FMU has no Event Mode (hasEventMode=\"false\")"
#define NO_CLOCKS "this FMU has no clocks"

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
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
    (void)discreteStatesNeedUpdate; (void)terminateSimulation;
    (void)nominalsOfContinuousStatesChanged; (void)valuesOfContinuousStatesChanged;
    (void)nextEventTimeDefined; (void)nextEventTime;
    return unsupported(instance, "fmi3UpdateDiscreteStates", NO_EVENT_MODE);
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

/* Model Exchange */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterContinuousTimeMode", NOT_ME);
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint; (void)enterEventMode; (void)terminateSimulation;
    return unsupported(instance, "fmi3CompletedIntegratorStep", NOT_ME);
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    return unsupported(instance, "fmi3SetTime", NOT_ME);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    return unsupported(instance, "fmi3SetContinuousStates", NOT_ME);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives; (void)nContinuousStates;
    return unsupported(instance, "fmi3GetContinuousStateDerivatives", NOT_ME);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) {
    (void)eventIndicators; (void)nEventIndicators;
    return unsupported(instance, "fmi3GetEventIndicators", NOT_ME);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    return unsupported(instance, "fmi3GetContinuousStates", NOT_ME);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals; (void)nContinuousStates;
    return unsupported(instance, "fmi3GetNominalsOfContinuousStates", NOT_ME);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    (void)nEventIndicators;
    return unsupported(instance, "fmi3GetNumberOfEventIndicators", NOT_ME);
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    (void)nContinuousStates;
    return unsupported(instance, "fmi3GetNumberOfContinuousStates", NOT_ME);
}
