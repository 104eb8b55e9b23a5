/* FMI 2.0 Co-Simulation entry points for a generated model (md_model.h), on top of the
 * model-independent core in solver.c. Co-Simulation only: the Model Exchange functions are
 * deliberately not defined, and fmi2Instantiate refuses fmi2ModelExchange.
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
 */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "md_model.h"
#include "solver.h"

/* ---------------------------------------------------------------------------------------
 * Instance
 * ------------------------------------------------------------------------------------- */

typedef enum {
    ST_INSTANTIATED = 1 << 0,
    ST_INIT = 1 << 1,
    ST_STEP = 1 << 2,       /* stepComplete: ready for fmi2DoStep */
    ST_TERMINATED = 1 << 3,
    ST_ERROR = 1 << 4,
    ST_FATAL = 1 << 5       /* reserved: nothing in this shell damages an instance beyond
                               repair today (all failures are caught at the last good point) */
} fmu_state;

#define ST_ANY (ST_INSTANTIATED | ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR)
#define ST_READABLE (ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR)

/* Log categories (modelDescription.xml <LogCategories> lists the same names). */
enum { LOG_EVENTS = 0, LOG_STATUS_ERROR = 1, LOG_ALL = 2, LOG_NCATEGORIES = 3 };
static const char *const LOG_NAMES[LOG_NCATEGORIES] = {"logEvents", "logStatusError", "logAll"};
#define LOG_BIT(category) (1u << (category))
#define LOG_EVERYTHING (LOG_BIT(LOG_EVENTS) | LOG_BIT(LOG_STATUS_ERROR) | LOG_BIT(LOG_ALL))

struct FmuState;

typedef struct {
    fmi2CallbackFunctions cb;  /* a copy: the environment's struct need not outlive the call */
    char *name;
    struct FmuState *states;   /* FMU states not yet freed: fmi2FreeInstance frees them */
    md_solver *solver;
    fmu_state state;
    unsigned log_mask;
    double start_time;
    double stop_time;
    int stop_defined;
    int rel_tol_set;      /* solver.relTol set explicitly: it wins over SetupExperiment's */
    int params_dirty;     /* a parameter changed since md_solver_start ran */
    fmi2Status last_step_status;
    char message[MD_MESSAGE_SIZE];
} Instance;

/* An FMU state (sec. 2.1.8): the solver's flat state buffer, tagged with the FMI mode.
 * Each instance keeps a list of the states it handed out, so that fmi2FreeInstance can
 * free what the environment did not ("frees all the allocated memory", sec. 2.1.5). */
#define FMU_STATE_MAGIC 0x32494D46u /* "FMI2" */
typedef struct FmuState {
    uint32_t magic;
    void *owner;                  /* the Instance whose list holds it */
    struct FmuState *prev, *next;
    size_t size;
    unsigned char data[]; /* md_solver_save() format */
} FmuState;

/* The solver state's tag: the FMI mode and two flags. */
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

static int log_enabled(const Instance *c, int category) {
    return c->cb.logger != NULL
           && (c->log_mask & (LOG_BIT(category) | LOG_BIT(LOG_ALL))) != 0;
}

/* The logger is variadic and treats its message as a format: pass the text as an argument. */
static void emit(const Instance *c, fmi2Status status, int category, const char *text) {
    if (log_enabled(c, category)) {
        c->cb.logger(c->cb.componentEnvironment, c->name, status, LOG_NAMES[category], "%s",
                     text);
    }
}

static void logf_(const Instance *c, int category, const char *format, ...) {
    char text[MD_MESSAGE_SIZE];
    va_list args;
    if (!log_enabled(c, category)) { return; }
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    emit(c, fmi2OK, category, text);
}

/* Record a non-OK status with its explanation (kept in c->message), log it under
 * logStatusError, and return it. */
static fmi2Status report(Instance *c, fmi2Status status, const char *format, ...) {
    va_list args;
    va_start(args, format);
    vsnprintf(c->message, sizeof c->message, format, args);
    va_end(args);
    emit(c, status, LOG_STATUS_ERROR, c->message);
    return status;
}

/* Gatekeeper at the top of every entry point. */
static fmi2Status guard(Instance *c, const char *function, unsigned allowed) {
    if (c == NULL) { return fmi2Error; }
    if (c->state == ST_FATAL) { return fmi2Fatal; }
    if ((c->state & allowed) == 0) {
        if (c->state == ST_ERROR) {
            return report(c, fmi2Error, "%s: not allowed after an error (%s); call fmi2Reset "
                          "or fmi2SetFMUstate", function, md_solver_message(c->solver));
        }
        return report(c, fmi2Error, "%s: not allowed in %s", function, state_name(c->state));
    }
    return fmi2OK;
}

#define GUARD(c, function, allowed)                                  \
    do {                                                             \
        fmi2Status guard_status = guard((c), (function), (allowed)); \
        if (guard_status != fmi2OK) { return guard_status; }         \
    } while (0)

/* Solver host services */

static void *host_allocate(void *env, size_t nobj, size_t size) {
    return ((Instance *)env)->cb.allocateMemory(nobj, size);
}

static void host_release(void *env, void *ptr) { ((Instance *)env)->cb.freeMemory(ptr); }

static int host_log_enabled(void *env, md_log_category category) {
    return log_enabled((Instance *)env, category == MD_LOG_EVENTS ? LOG_EVENTS : LOG_ALL);
}

static void host_log(void *env, md_log_category category, const char *message) {
    emit((Instance *)env, fmi2OK, category == MD_LOG_EVENTS ? LOG_EVENTS : LOG_ALL, message);
}

/* ---------------------------------------------------------------------------------------
 * Inquire platform and version, logging (sec. 2.1.4, 2.1.5)
 * ------------------------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn,
                               size_t nCategories, const fmi2String categories[]) {
    Instance *c = component;
    fmi2Status status = fmi2OK;
    GUARD(c, "fmi2SetDebugLogging", ST_ANY);
    if (nCategories == 0) {
        c->log_mask = loggingOn ? LOG_EVERYTHING : 0u;
        return fmi2OK;
    }
    if (categories == NULL) {
        return report(c, fmi2Error, "fmi2SetDebugLogging: categories is NULL");
    }
    for (size_t i = 0; i < nCategories; ++i) {
        int found = -1;
        for (int k = 0; k < LOG_NCATEGORIES; ++k) {
            if (categories[i] != NULL && strcmp(categories[i], LOG_NAMES[k]) == 0) { found = k; }
        }
        if (found < 0) {
            status = report(c, fmi2Warning, "fmi2SetDebugLogging: unknown log category \"%s\" "
                            "ignored (known: logEvents, logStatusError, logAll)",
                            categories[i] != NULL ? categories[i] : "(null)");
        } else if (loggingOn) {
            c->log_mask |= LOG_BIT(found);
        } else {
            c->log_mask &= ~LOG_BIT(found);
        }
    }
    return status;
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
    md_host host;
    size_t length;
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
    if (fmuType != fmi2CoSimulation) {
        instantiate_error(functions, instanceName,
                          "fmi2Instantiate: this FMU supports Co-Simulation only "
                          "(fmuType must be fmi2CoSimulation)");
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MD_INFO.guid) != 0) {
        snprintf(text, sizeof text, "fmi2Instantiate: GUID %s does not match this binary's %s "
                 "(modelDescription.xml and binary out of step?)",
                 fmuGUID != NULL ? fmuGUID : "(null)", MD_INFO.guid);
        instantiate_error(functions, instanceName, text);
        return NULL;
    }

    c = functions->allocateMemory(1, sizeof *c);
    if (c == NULL) {
        instantiate_error(functions, instanceName, "fmi2Instantiate: out of memory");
        return NULL;
    }
    c->cb = *functions;
    length = strlen(instanceName);
    c->name = functions->allocateMemory(length + 1, 1);
    if (c->name != NULL) { memcpy(c->name, instanceName, length + 1); }
    host.allocate = host_allocate;
    host.release = host_release;
    host.log = host_log;
    host.log_enabled = host_log_enabled;
    host.env = c;
    c->solver = c->name != NULL ? md_solver_new(&MD_INFO, &host) : NULL;
    if (c->solver == NULL) {
        instantiate_error(functions, instanceName, "fmi2Instantiate: out of memory");
        if (c->name != NULL) { functions->freeMemory(c->name); }
        functions->freeMemory(c);
        return NULL;
    }
    c->state = ST_INSTANTIATED;
    /* Errors are reported unless switched off explicitly; debug output if asked for. */
    c->log_mask = loggingOn ? LOG_EVERYTHING : LOG_BIT(LOG_STATUS_ERROR);
    c->start_time = 0.0;
    c->stop_time = 0.0;
    c->stop_defined = 0;
    c->rel_tol_set = 0;
    c->params_dirty = 0;
    c->last_step_status = fmi2OK;
    c->message[0] = '\0';
    logf_(c, LOG_ALL, "instantiated %s: %d states, %d event indicators, %d variables",
          MD_INFO.model_name, MD_INFO.ny, MD_INFO.nz, MD_INFO.nvars);
    return c;
}

void fmi2FreeInstance(fmi2Component component) {
    Instance *c = component;
    fmi2CallbackFreeMemory release;
    if (c == NULL) { return; }
    release = c->cb.freeMemory;
    while (c->states != NULL) {
        FmuState *st = c->states;
        c->states = st->next;
        st->magic = 0;
        release(st);
    }
    md_solver_free(c->solver);
    release(c->name);
    release(c);
}

/* ---------------------------------------------------------------------------------------
 * Initialisation, termination, reset (sec. 2.1.6)
 * ------------------------------------------------------------------------------------- */

fmi2Status fmi2SetupExperiment(fmi2Component component, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *c = component;
    fmi2Status status = fmi2OK;
    GUARD(c, "fmi2SetupExperiment", ST_INSTANTIATED);
    if (!isfinite(startTime)) {
        return report(c, fmi2Error, "fmi2SetupExperiment: startTime %g is not finite", startTime);
    }
    if (stopTimeDefined && !(stopTime >= startTime && isfinite(stopTime))) {
        return report(c, fmi2Error, "fmi2SetupExperiment: stopTime %g before startTime %g",
                      stopTime, startTime);
    }
    /* sec. 4.2.1 ("tolerance ... usually as relative tolerance") */
    if (toleranceDefined && !c->rel_tol_set) {
        if (md_solver_set_setting(c->solver, MD_SETTING_RELTOL, tolerance) != MD_OK) {
            status = report(c, fmi2Warning, "fmi2SetupExperiment: tolerance ignored: %s",
                            md_solver_message(c->solver));
        }
    }
    c->start_time = startTime;
    c->solver->t = startTime;
    c->stop_defined = stopTimeDefined != 0;
    c->stop_time = stopTime;
    return status;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component component) {
    Instance *c = component;
    GUARD(c, "fmi2EnterInitializationMode", ST_INSTANTIATED);
    if (md_solver_start(c->solver, c->start_time) != MD_OK) {
        c->state = ST_ERROR;
        return report(c, fmi2Error, "fmi2EnterInitializationMode: %s",
                      md_solver_message(c->solver));
    }
    c->params_dirty = 0;
    c->state = ST_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component component) {
    Instance *c = component;
    GUARD(c, "fmi2ExitInitializationMode", ST_INIT);
    /* parameters set in initialisation mode: start values that depend on them follow */
    if (c->params_dirty && md_solver_start(c->solver, c->start_time) != MD_OK) {
        c->state = ST_ERROR;
        return report(c, fmi2Error, "fmi2ExitInitializationMode: %s",
                      md_solver_message(c->solver));
    }
    c->params_dirty = 0;
    if (md_solver_initialize(c->solver) != MD_OK) {
        c->state = ST_ERROR;
        return report(c, fmi2Error, "fmi2ExitInitializationMode: %s",
                      md_solver_message(c->solver));
    }
    c->state = ST_STEP;
    c->last_step_status = fmi2OK;
    logf_(c, LOG_ALL, "initialised at t=%.17g s (relTol=%g, absTol=%g, maxStep=%g)",
          c->solver->t, c->solver->settings.rel_tol, c->solver->settings.abs_tol,
          c->solver->settings.max_step);
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component component) {
    Instance *c = component;
    /* from error too: a master that tidies up after a failed step should not get a second
       error for it */
    GUARD(c, "fmi2Terminate", ST_STEP | ST_ERROR);
    c->state = ST_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component component) {
    Instance *c = component;
    GUARD(c, "fmi2Reset", ST_ANY);
    md_solver_reset(c->solver);
    c->state = ST_INSTANTIATED;
    c->start_time = 0.0;
    c->stop_time = 0.0;
    c->stop_defined = 0;
    c->rel_tol_set = 0;
    c->params_dirty = 0;
    c->last_step_status = fmi2OK;
    c->message[0] = '\0';
    return fmi2OK;
}

/* ---------------------------------------------------------------------------------------
 * Getting and setting variable values (sec. 2.1.7)
 * ------------------------------------------------------------------------------------- */

static fmi2Status refresh_if_dirty(Instance *c) {
    if (c->state == ST_INIT && c->params_dirty) {
        if (md_solver_start(c->solver, c->start_time) != MD_OK) {
            return report(c, fmi2Error, "%s", md_solver_message(c->solver));
        }
        c->params_dirty = 0;
    }
    return fmi2OK;
}

/* Real and Boolean variables share the model's arrays. md_model.h has no type table: a
 * Boolean is held as 0.0 / 1.0 and read as (value != 0). modelDescription.xml says which of
 * fmi2Get/SetReal and fmi2Get/SetBoolean each variable takes; the shell serves both from
 * the same slots. The solver settings are Real. */

typedef double (*value_at)(const void *values, size_t i);
static double real_at(const void *values, size_t i) { return ((const fmi2Real *)values)[i]; }
static double boolean_at(const void *values, size_t i) {
    return ((const fmi2Boolean *)values)[i] ? 1.0 : 0.0;
}

/* The value of variable r as a double (a solver setting only if settings_too). */
static fmi2Status get_value(Instance *c, const char *function, fmi2ValueReference r,
                            int settings_too, double *value) {
    const md_info *info = &MD_INFO;
    const fmi2ValueReference nvars = (fmi2ValueReference)info->nvars;
    if (r < nvars) {
        if (info->obs_slot[r] >= 0) {
            *value = c->solver->obs[info->obs_slot[r]];
        } else if (info->par_slot[r] >= 0) {
            *value = c->solver->p[info->par_slot[r]];
        } else {
            return report(c, fmi2Error, "%s: variable %s has no value slot", function,
                          info->names[r]);
        }
        return fmi2OK;
    }
    if (r < nvars + MD_SHELL_NREAL) {
        if (!settings_too) {
            return report(c, fmi2Error, "%s: %s is a Real variable", function,
                          MD_SHELL_SETTINGS[r - nvars].name);
        }
        *value = md_solver_get_setting(c->solver, (int)(r - nvars));
        return fmi2OK;
    }
    return report(c, fmi2Error, "%s: unknown value reference %u", function, r);
}

/* Set variables from values[i] read through `at` (boolean: the call was fmi2SetBoolean).
 * Everything is checked before anything is written, so that a refused call changes nothing.
 * Parameters: before fmi2ExitInitializationMode; inputs: at any time (sec. 2.1.7 and the
 * causality/variability table of sec. 2.2.7). */
static fmi2Status set_values(Instance *c, const char *function, const fmi2ValueReference vr[],
                             size_t nvr, const void *values, value_at at, int boolean) {
    const md_info *info = &MD_INFO;
    const fmi2ValueReference nvars = (fmi2ValueReference)info->nvars;
    const int before_run = (c->state & (ST_INSTANTIATED | ST_INIT)) != 0;
    int inputs = 0, parameters = 0;
    md_settings saved;
    if (nvr > 0 && (vr == NULL || values == NULL)) {
        return report(c, fmi2Error, "%s: NULL array", function);
    }
    for (size_t i = 0; i < nvr; ++i) {
        fmi2ValueReference r = vr[i];
        double value = at(values, i);
        const char *name;
        if (r < nvars) {
            name = info->names[r];
            if (info->kind[r] == MD_PARAMETER) {
                if (!before_run) {
                    return report(c, fmi2Error, "%s: variable %s is a parameter: it can only be "
                                  "set before fmi2ExitInitializationMode", function, name);
                }
            } else if (info->kind[r] != MD_INPUT) {
                return report(c, fmi2Error, "%s: variable %s is not settable", function, name);
            }
            if (info->par_slot[r] < 0) {
                return report(c, fmi2Error, "%s: variable %s has no parameter slot", function,
                              name);
            }
        } else if (r < nvars + MD_SHELL_NREAL) {
            name = MD_SHELL_SETTINGS[r - nvars].name;
            if (boolean) {
                return report(c, fmi2Error, "%s: %s is a Real variable", function, name);
            }
            if (!before_run) {
                return report(c, fmi2Error, "%s: %s is a parameter: it can only be set before "
                              "fmi2ExitInitializationMode", function, name);
            }
        } else {
            return report(c, fmi2Error, "%s: unknown value reference %u", function, r);
        }
        if (!isfinite(value)) {
            return report(c, fmi2Error, "%s: refusing the non-finite value %g for %s", function,
                          value, name);
        }
    }
    /* solver settings: range-checked by the solver; undo all of them if one is refused */
    saved = c->solver->settings;
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] >= nvars
            && md_solver_set_setting(c->solver, (int)(vr[i] - nvars), at(values, i)) != MD_OK) {
            c->solver->settings = saved;
            return report(c, fmi2Error, "%s: %s", function, md_solver_message(c->solver));
        }
    }
    for (size_t i = 0; i < nvr; ++i) {
        fmi2ValueReference r = vr[i];
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
        return report(c, fmi2Warning, "%s: outputs not updated: %s", function,
                      md_solver_message(c->solver));
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    Instance *c = component;
    GUARD(c, "fmi2GetReal", ST_READABLE);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return report(c, fmi2Error, "fmi2GetReal: NULL array");
    }
    if (refresh_if_dirty(c) != fmi2OK) { return fmi2Error; }
    for (size_t i = 0; i < nvr; ++i) {
        if (get_value(c, "fmi2GetReal", vr[i], 1, &value[i]) != fmi2OK) { return fmi2Error; }
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    Instance *c = component;
    GUARD(c, "fmi2GetBoolean", ST_READABLE);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return report(c, fmi2Error, "fmi2GetBoolean: NULL array");
    }
    if (refresh_if_dirty(c) != fmi2OK) { return fmi2Error; }
    for (size_t i = 0; i < nvr; ++i) {
        double v;
        if (get_value(c, "fmi2GetBoolean", vr[i], 0, &v) != fmi2OK) { return fmi2Error; }
        value[i] = v != 0.0 ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    Instance *c = component;
    GUARD(c, "fmi2SetReal", ST_INSTANTIATED | ST_INIT | ST_STEP);
    return set_values(c, "fmi2SetReal", vr, nvr, value, real_at, 0);
}

fmi2Status fmi2SetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    Instance *c = component;
    GUARD(c, "fmi2SetBoolean", ST_INSTANTIATED | ST_INIT | ST_STEP);
    return set_values(c, "fmi2SetBoolean", vr, nvr, value, boolean_at, 1);
}

/* No Integer or String variables. */
static fmi2Status no_such_variables(Instance *c, const char *function, const char *type,
                                    const fmi2ValueReference vr[], size_t nvr) {
    if (nvr == 0) { return fmi2OK; }
    return report(c, fmi2Error, "%s: no %s variable with value reference %u (this FMU has "
                  "Real and Boolean variables only)", function, type, vr != NULL ? vr[0] : 0u);
}

fmi2Status fmi2GetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    Instance *c = component;
    (void)value;
    GUARD(c, "fmi2GetInteger", ST_READABLE);
    return no_such_variables(c, "fmi2GetInteger", "Integer", vr, nvr);
}

fmi2Status fmi2GetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    Instance *c = component;
    (void)value;
    GUARD(c, "fmi2GetString", ST_READABLE);
    return no_such_variables(c, "fmi2GetString", "String", vr, nvr);
}

fmi2Status fmi2SetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    Instance *c = component;
    (void)value;
    GUARD(c, "fmi2SetInteger", ST_INSTANTIATED | ST_INIT | ST_STEP);
    return no_such_variables(c, "fmi2SetInteger", "Integer", vr, nvr);
}

fmi2Status fmi2SetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    Instance *c = component;
    (void)value;
    GUARD(c, "fmi2SetString", ST_INSTANTIATED | ST_INIT | ST_STEP);
    return no_such_variables(c, "fmi2SetString", "String", vr, nvr);
}

/* ---------------------------------------------------------------------------------------
 * FMU state (sec. 2.1.8). The in-memory copy and the serialised form are the same bytes.
 * ------------------------------------------------------------------------------------- */

static int tag_state_valid(int tag) {
    int state = tag & TAG_STATE_MASK;
    return state == ST_INSTANTIATED || state == ST_INIT || state == ST_STEP
           || state == ST_TERMINATED || state == ST_ERROR;
}

/* The state *FMUstate points to, to be overwritten, or a new one (linked into c->states). */
static FmuState *state_object(Instance *c, fmi2FMUstate *FMUstate, size_t size) {
    FmuState *st = *FMUstate;
    if (st != NULL && st->magic == FMU_STATE_MAGIC && st->size == size) { return st; }
    st = c->cb.allocateMemory(1, sizeof(FmuState) + size);
    if (st == NULL) { return NULL; }
    st->magic = FMU_STATE_MAGIC;
    st->size = size;
    st->owner = c;
    st->prev = NULL;
    st->next = c->states;
    if (c->states != NULL) { c->states->prev = st; }
    c->states = st;
    /* A foreign pointer in *FMUstate is not ours to free: just replace it. */
    *FMUstate = st;
    return st;
}

fmi2Status fmi2GetFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    Instance *c = component;
    size_t size = md_solver_state_size(&MD_INFO);
    FmuState *st;
    int tag;
    GUARD(c, "fmi2GetFMUstate", ST_ANY);
    if (FMUstate == NULL) { return report(c, fmi2Error, "fmi2GetFMUstate: FMUstate is NULL"); }
    st = state_object(c, FMUstate, size);
    if (st == NULL) { return report(c, fmi2Error, "fmi2GetFMUstate: out of memory"); }
    tag = (int)c->state | (c->params_dirty ? TAG_DIRTY : 0) | (c->rel_tol_set ? TAG_RELTOL_SET : 0);
    if (md_solver_save(c->solver, tag, st->data, size) != MD_OK) {
        return report(c, fmi2Error, "fmi2GetFMUstate: %s", md_solver_message(c->solver));
    }
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component component, fmi2FMUstate FMUstate) {
    Instance *c = component;
    const FmuState *st = FMUstate;
    int tag = 0;
    GUARD(c, "fmi2SetFMUstate", ST_ANY);
    if (st == NULL || st->magic != FMU_STATE_MAGIC) {
        return report(c, fmi2Error, "fmi2SetFMUstate: not an FMU state of this FMU");
    }
    if (md_solver_check(c->solver, st->data, st->size, &tag) != MD_OK) {
        return report(c, fmi2Error, "fmi2SetFMUstate: %s", md_solver_message(c->solver));
    }
    if (!tag_state_valid(tag)) {
        return report(c, fmi2Error, "fmi2SetFMUstate: the state is corrupted (mode)");
    }
    (void)md_solver_restore(c->solver, st->data, st->size, NULL);
    c->state = (fmu_state)(tag & TAG_STATE_MASK);
    c->params_dirty = (tag & TAG_DIRTY) != 0;
    c->rel_tol_set = (tag & TAG_RELTOL_SET) != 0;
    c->last_step_status = c->state == ST_ERROR ? fmi2Error : fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    Instance *c = component;
    FmuState *st;
    GUARD(c, "fmi2FreeFMUstate", ST_ANY);
    if (FMUstate == NULL || *FMUstate == NULL) { return fmi2OK; }
    st = *FMUstate;
    if (st->magic != FMU_STATE_MAGIC) {
        return report(c, fmi2Error, "fmi2FreeFMUstate: not an FMU state of this FMU");
    }
    if (st->prev != NULL) {
        st->prev->next = st->next;
    } else {
        ((Instance *)st->owner)->states = st->next;
    }
    if (st->next != NULL) { st->next->prev = st->prev; }
    st->magic = 0;
    c->cb.freeMemory(st);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component component, fmi2FMUstate FMUstate,
                                      size_t *size) {
    Instance *c = component;
    const FmuState *st = FMUstate;
    GUARD(c, "fmi2SerializedFMUstateSize", ST_ANY);
    if (st == NULL || st->magic != FMU_STATE_MAGIC || size == NULL) {
        return report(c, fmi2Error, "fmi2SerializedFMUstateSize: not an FMU state of this FMU");
    }
    *size = st->size;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component component, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    Instance *c = component;
    const FmuState *st = FMUstate;
    GUARD(c, "fmi2SerializeFMUstate", ST_ANY);
    if (st == NULL || st->magic != FMU_STATE_MAGIC || serializedState == NULL) {
        return report(c, fmi2Error, "fmi2SerializeFMUstate: not an FMU state of this FMU");
    }
    if (size != st->size) {
        return report(c, fmi2Error, "fmi2SerializeFMUstate: buffer of %lu bytes, %lu needed",
                      (unsigned long)size, (unsigned long)st->size);
    }
    memcpy(serializedState, st->data, size);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component component, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    Instance *c = component;
    FmuState *st;
    int tag = 0;
    GUARD(c, "fmi2DeSerializeFMUstate", ST_ANY);
    if (FMUstate == NULL) {
        return report(c, fmi2Error, "fmi2DeSerializeFMUstate: FMUstate is NULL");
    }
    if (md_solver_check(c->solver, serializedState, size, &tag) != MD_OK) {
        return report(c, fmi2Error, "fmi2DeSerializeFMUstate: %s", md_solver_message(c->solver));
    }
    if (!tag_state_valid(tag)) {
        return report(c, fmi2Error, "fmi2DeSerializeFMUstate: the state is corrupted (mode)");
    }
    st = state_object(c, FMUstate, size);
    if (st == NULL) { return report(c, fmi2Error, "fmi2DeSerializeFMUstate: out of memory"); }
    memcpy(st->data, serializedState, size);
    return fmi2OK;
}

/* ---------------------------------------------------------------------------------------
 * Not provided (capability flags false in modelDescription.xml)
 * ------------------------------------------------------------------------------------- */

fmi2Status fmi2GetDirectionalDerivative(fmi2Component component,
                                        const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    Instance *c = component;
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown;
    (void)dvUnknown;
    GUARD(c, "fmi2GetDirectionalDerivative", ST_ANY);
    return report(c, fmi2Error, "fmi2GetDirectionalDerivative: not provided by this FMU "
                  "(providesDirectionalDerivative=\"false\")");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component component, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    Instance *c = component;
    (void)vr; (void)nvr; (void)order; (void)value;
    GUARD(c, "fmi2SetRealInputDerivatives", ST_ANY);
    return report(c, fmi2Error, "fmi2SetRealInputDerivatives: not provided by this FMU "
                  "(canInterpolateInputs=\"false\"; inputs are held constant over a step)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component component, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    Instance *c = component;
    (void)vr; (void)nvr; (void)order; (void)value;
    GUARD(c, "fmi2GetRealOutputDerivatives", ST_ANY);
    return report(c, fmi2Error, "fmi2GetRealOutputDerivatives: not provided by this FMU "
                  "(maxOutputDerivativeOrder=\"0\")");
}

/* ---------------------------------------------------------------------------------------
 * Stepping (sec. 4.2.2) and status (sec. 4.2.3)
 * ------------------------------------------------------------------------------------- */

fmi2Status fmi2DoStep(fmi2Component component, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *c = component;
    md_solver *s;
    double t_end, slack;
    (void)noSetFMUStatePriorToCurrentPoint;
    GUARD(c, "fmi2DoStep", ST_STEP);
    s = c->solver;
    slack = 1e-9 * fmax(1.0, fabs(s->t));
    if (!isfinite(currentCommunicationPoint) || fabs(currentCommunicationPoint - s->t) > slack) {
        return report(c, fmi2Error, "fmi2DoStep: currentCommunicationPoint %.17g s is not the "
                      "FMU's time %.17g s", currentCommunicationPoint, s->t);
    }
    if (!(communicationStepSize >= 0.0) || !isfinite(communicationStepSize)) {
        return report(c, fmi2Error, "fmi2DoStep: communicationStepSize %g must be >= 0",
                      communicationStepSize);
    }
    t_end = currentCommunicationPoint + communicationStepSize;
    if (c->stop_defined && t_end > c->stop_time + 1e-9 * fmax(1.0, fabs(c->stop_time))) {
        return report(c, fmi2Error, "fmi2DoStep: t=%.17g s is past the stopTime %.17g s given "
                      "to fmi2SetupExperiment", t_end, c->stop_time);
    }
    s->t = currentCommunicationPoint; /* follow the master's clock exactly */
    if (md_solver_advance(s, t_end) != MD_OK) {
        c->state = ST_ERROR;
        c->last_step_status = fmi2Error;
        /* outputs at the last good point, if they can be had */
        (void)md_solver_observe(s);
        return report(c, fmi2Error, "fmi2DoStep: %s", md_solver_message(s));
    }
    c->last_step_status = fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component component) {
    Instance *c = component;
    GUARD(c, "fmi2CancelStep", ST_ANY);
    return report(c, fmi2Error, "fmi2CancelStep: no step in progress (this FMU steps "
                  "synchronously)");
}

fmi2Status fmi2GetStatus(fmi2Component component, const fmi2StatusKind kind, fmi2Status *value) {
    Instance *c = component;
    GUARD(c, "fmi2GetStatus", ST_STEP | ST_TERMINATED | ST_ERROR);
    if (value == NULL) { return report(c, fmi2Error, "fmi2GetStatus: value is NULL"); }
    if (kind == fmi2DoStepStatus) {
        *value = c->last_step_status;
        return fmi2OK;
    }
    return report(c, fmi2Discard, "fmi2GetStatus: status kind %d is not available", (int)kind);
}

fmi2Status fmi2GetRealStatus(fmi2Component component, const fmi2StatusKind kind,
                             fmi2Real *value) {
    Instance *c = component;
    GUARD(c, "fmi2GetRealStatus", ST_STEP | ST_TERMINATED | ST_ERROR);
    if (value == NULL) { return report(c, fmi2Error, "fmi2GetRealStatus: value is NULL"); }
    if (kind == fmi2LastSuccessfulTime) {
        *value = c->solver->t; /* the last good point, also after a failed step */
        return fmi2OK;
    }
    return report(c, fmi2Discard, "fmi2GetRealStatus: status kind %d is not available",
                  (int)kind);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component component, const fmi2StatusKind kind,
                                fmi2Integer *value) {
    Instance *c = component;
    (void)value;
    GUARD(c, "fmi2GetIntegerStatus", ST_STEP | ST_TERMINATED | ST_ERROR);
    return report(c, fmi2Discard, "fmi2GetIntegerStatus: status kind %d is not available",
                  (int)kind);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component component, const fmi2StatusKind kind,
                                fmi2Boolean *value) {
    Instance *c = component;
    GUARD(c, "fmi2GetBooleanStatus", ST_STEP | ST_TERMINATED | ST_ERROR);
    if (value == NULL) { return report(c, fmi2Error, "fmi2GetBooleanStatus: value is NULL"); }
    if (kind == fmi2Terminated) {
        *value = fmi2False; /* the slave never asks to end the simulation */
        return fmi2OK;
    }
    return report(c, fmi2Discard, "fmi2GetBooleanStatus: status kind %d is not available",
                  (int)kind);
}

fmi2Status fmi2GetStringStatus(fmi2Component component, const fmi2StatusKind kind,
                               fmi2String *value) {
    Instance *c = component;
    (void)value;
    GUARD(c, "fmi2GetStringStatus", ST_STEP | ST_TERMINATED | ST_ERROR);
    return report(c, fmi2Discard, "fmi2GetStringStatus: status kind %d is not available "
                  "(no asynchronous steps)", (int)kind);
}
