/* The generic FMU shell: what an FMI 2.0 and an FMI 3.0 Co-Simulation FMU of a generated model
 * (md_model.h) have in common, written once, on top of the solver core (solver.h).
 *
 * An md_instance is one FMU instance: the solver, the FMI mode (state machine), the
 * experiment (start / stop time), the logging switches and the FMU states handed out. The
 * functions below hold the logic of the FMI calls -- argument and mode checks, get and set of
 * variable values with the causality / variability rules, the solver settings, the input
 * restart, initialisation, doStep, reset, FMU state copy and serialisation -- in plain C
 * types, and return an md_result that the FMI layer maps to its fmi2Status / fmi3Status.
 *
 * The FMI layers (fmi2.c, fmi3.c) are thin: they define the exported functions, translate
 * types and statuses, and implement only what the two standards do differently (see each
 * file's header). A layer describes itself to this file with an md_layer: the names its
 * messages use, the rules that differ, and its log categories and logger.
 *
 * Messages name the FMI function the user called: every function that can fail takes it as
 * `function` ("fmi2SetReal", "fmi3SetFloat64", ...).
 *
 * Build: an FMU binary is solver.c + instance.c + fmi2.c (or fmi3.c) + model.c, each its own
 * translation unit; instance.c needs no FMI header. With -fvisibility=hidden only the fmi2* or
 * fmi3* entry points are exported.
 */
#ifndef MD_INSTANCE_H
#define MD_INSTANCE_H

#include <stddef.h>
#include <stdint.h>

#include "md_model.h"
#include "solver.h"

/* ---------------------------------------------------------------------------------------
 * Statuses, modes, value references
 * ------------------------------------------------------------------------------------- */

/* The status of an FMI call, in the order (and with the meaning) of fmi2Status / fmi3Status. */
typedef enum {
    MD_RESULT_OK = 0,
    MD_RESULT_WARNING = 1,
    MD_RESULT_DISCARD = 2,
    MD_RESULT_ERROR = 3,
    MD_RESULT_FATAL = 4
} md_result;

/* The FMI state machine, collapsed to what a synchronous Co-Simulation FMU without Event
 * Mode needs: instantiated -> initialisationMode -> stepMode -> terminated, plus error (a
 * doStep failed: variables can still be read; reset or set an FMU state to go on) and fatal
 * (sticky; reserved: nothing in this shell damages an instance beyond repair today). The
 * values are stored in FMU states (md_save_state): do not renumber. */
typedef enum {
    MD_MODE_INSTANTIATED = 1 << 0,
    MD_MODE_INIT = 1 << 1,
    MD_MODE_STEP = 1 << 2,
    MD_MODE_TERMINATED = 1 << 3,
    MD_MODE_ERROR = 1 << 4,
    MD_MODE_FATAL = 1 << 5,
    MD_MODE_EVENT = 1 << 6,     /* Model Exchange: event mode */
    MD_MODE_CONTINUOUS = 1 << 7 /* Model Exchange: continuous-time mode */
} md_mode;

/* Sets of modes, for md_guard. */
#define MD_MODE_ANY                                                                         \
    (MD_MODE_INSTANTIATED | MD_MODE_INIT | MD_MODE_STEP | MD_MODE_TERMINATED | MD_MODE_ERROR \
     | MD_MODE_EVENT | MD_MODE_CONTINUOUS)
#define MD_MODE_RUNNING (MD_MODE_STEP | MD_MODE_EVENT | MD_MODE_CONTINUOUS)
#define MD_MODE_SETTABLE (MD_MODE_INSTANTIATED | MD_MODE_INIT | MD_MODE_RUNNING)
/* Model Exchange: where the model can be evaluated (states, derivatives, indicators). */
#define MD_MODE_EVALUABLE \
    (MD_MODE_INIT | MD_MODE_EVENT | MD_MODE_CONTINUOUS | MD_MODE_TERMINATED | MD_MODE_ERROR)

/* A value reference: 0 .. nvars-1 the model's variables (MD_INFO tables), nvars +
 * MD_SETTING_* the solver settings (Real / Float64 parameters), and, if the layer has one,
 * nvars + MD_SHELL_NREAL the independent variable `time` (read-only). Same type as
 * fmi2ValueReference (unsigned int) and fmi3ValueReference (uint32_t) on every platform FMI
 * binaries are built for. */
typedef uint32_t md_vr;

/* The value references after the model's variables and the solver settings, in this order
 * (model_description.py writes the same numbers):
 *   MD_VR_TIME        the independent variable (FMI 3.0 only; unused in FMI 2.0)
 *   MD_VR_STATISTICS  MD_NSTATISTICS integer counters of the integrator (md_statistic)
 *   MD_VR_DERIVATIVES der(x) of each continuous state, ny Real / Float64 (read-only)
 *   MD_VR_INDICATORS  the event indicators, nz Float64 (FMI 3.0 lists them; read-only) */
/* MD_STATISTIC_STEPS ("solver.steps": accepted integrator steps), MD_STATISTIC_REJECTED
 * ("solver.rejectedSteps"), MD_STATISTIC_EVENTS ("solver.events": transition calls) and
 * MD_NSTATISTICS come from md_settings.h. */
#define MD_VR_TIME ((md_vr)MD_INFO.nvars + (md_vr)MD_SHELL_NREAL)
#define MD_VR_STATISTICS (MD_VR_TIME + 1u)
#define MD_VR_DERIVATIVES (MD_VR_STATISTICS + (md_vr)MD_NSTATISTICS)
#define MD_VR_INDICATORS (MD_VR_DERIVATIVES + (md_vr)MD_INFO.ny)
#define MD_VR_END (MD_VR_INDICATORS + (md_vr)MD_INFO.nz)

/* ---------------------------------------------------------------------------------------
 * What the FMI layer tells the generic shell about itself
 * ------------------------------------------------------------------------------------- */

typedef struct md_instance md_instance;

/* What a message or a log line is about; each layer maps these to its own log categories. */
typedef enum {
    MD_CATEGORY_EVENTS = 0,  /* the solver's event lines */
    MD_CATEGORY_WARNING = 1, /* non-OK statuses below Error (Warning, Discard) */
    MD_CATEGORY_ERROR = 2,   /* Error and Fatal statuses */
    MD_CATEGORY_ALL = 3,     /* debug output (and: enabling it enables every category) */
    MD_NCATEGORIES = 4
} md_category;

typedef struct {
    /* Names the generic messages use. */
    const char *enter_initialization; /* "fmi2EnterInitializationMode" */
    const char *exit_initialization;  /* "fmi2ExitInitializationMode" */
    const char *do_step;              /* "fmi2DoStep" */
    const char *stop_time_source;     /* the one that takes stopTime: "fmi2SetupExperiment" */
    const char *recovery;             /* out of error mode: "fmi2Reset or fmi2SetFMUstate" */
    const char *fmu_state;            /* the FMU state argument: "FMUstate" / "FMUState" */
    const char *real_type;            /* "Real" / "Float64" */
    const char *parameter;            /* "parameter" / "fixed parameter" (set before the run) */

    /* Rules that differ between the standards. */
    int settings_tunable;   /* the solver settings can also be set in step mode */
    int has_time;           /* value reference nvars + MD_SHELL_NREAL is `time` */
    uint32_t state_magic;   /* marks this layer's FMU state objects */

    /* Logging: the layer's categories (as modelDescription.xml lists them, in its order), which
       of them each md_category goes to, and the callback that hands a line to the importer
       (called only when the line is enabled; category is one of `categories`). */
    const char *const *categories;
    int ncategories;
    int category_of[MD_NCATEGORIES];
    int errors_always_logged; /* Error and Fatal are logged whatever the switches say */
    unsigned quiet_log_mask;  /* categories enabled when loggingOn is false (bit k: category k) */
    void (*log)(const md_instance *instance, md_result status, const char *category,
                const char *text);
} md_layer;

/* Memory: fmi2CallbackAllocateMemory / fmi2CallbackFreeMemory, or calloc / free. */
typedef void *(*md_allocate)(size_t nobj, size_t size);
typedef void (*md_release)(void *ptr);

struct md_fmu_state;

/* The instance. A layer that needs fields of its own puts an md_instance first in its own
 * struct and gives md_instance_new that struct's size. The fields are public to the layers. */
struct md_instance {
    const md_layer *layer;
    md_allocate allocate;
    md_release release;
    char *name;                   /* instanceName */
    md_solver *solver;
    md_mode mode;
    int has_logger;               /* the importer gave a logger */
    unsigned log_mask;            /* enabled categories of the layer, bit k: category k */
    double start_time;
    double stop_time;
    int stop_defined;
    int rel_tol_set;   /* solver.relTol set explicitly: it wins over the tolerance argument */
    int params_dirty;  /* a parameter changed in initialisation mode since md_solver_start */
    int interface;     /* MD_INTERFACE_CS or MD_INTERFACE_ME: what it was instantiated as */
    int obs_stale;     /* Model Exchange: time, states or inputs set since obs was computed */
    struct md_fmu_state *states;  /* FMU states not yet freed: md_instance_free frees them */
    char message[MD_MESSAGE_SIZE];/* the explanation of the last non-OK status */
};

/* ---------------------------------------------------------------------------------------
 * Creation and destruction
 * ------------------------------------------------------------------------------------- */

/* Allocate `size` (>= sizeof(md_instance)) zero-filled bytes, copy the name, create the
 * solver, mode instantiated. NULL if memory is short (nothing is left allocated). Logging is
 * off until md_instance_start_logging: the layer first fills in its own fields. */
md_instance *md_instance_new(const md_layer *layer, size_t size, md_allocate allocate,
                             md_release release, const char *name);
/* Switch logging on as instantiation asks (loggingOn: every category; otherwise the layer's
 * quiet mask) and log the instance's size under logAll. */
void md_instance_start_logging(md_instance *instance, int has_logger, int logging_on);
/* Free the instance, its solver and every FMU state it handed out. NULL is fine. */
void md_instance_free(md_instance *instance);

/* ---------------------------------------------------------------------------------------
 * Logging and status reporting
 * ------------------------------------------------------------------------------------- */

int md_log_enabled(const md_instance *instance, md_result status, md_category category);
/* A debug line (status OK); formatted only if enabled. */
void md_log(const md_instance *instance, md_category category, const char *format, ...);
/* Record a non-OK status with its explanation (in instance->message), log it under the
 * warning or error category, and return it. */
md_result md_report(md_instance *instance, md_result status, const char *format, ...);
/* fmi2SetDebugLogging / fmi3SetDebugLogging: no categories: all on or all off; otherwise
 * switch the named ones (an unknown name is a Warning, the others still switch). */
md_result md_set_debug_logging(md_instance *instance, const char *function, int logging_on,
                               size_t ncategories, const char *const categories[]);

/* ---------------------------------------------------------------------------------------
 * The state machine
 * ------------------------------------------------------------------------------------- */

/* Gatekeeper at the top of every entry point: Error (with a message naming `function`) if
 * the instance is not in one of the modes `allowed` (a set of md_mode bits), Error without a
 * message for a NULL instance, Fatal if the instance is fatal, else OK. */
md_result md_guard(md_instance *instance, const char *function, unsigned allowed);
/* For the layers, at the top of an entry point: return the verdict of `check` (md_guard or
 * md_guard_me), mapped to the layer's status type by `map` (an md_result -> fmi2Status /
 * fmi3Status function), unless the call may go on. */
#define MD_GUARD_WITH(check, instance, function, allowed, map)              \
    do {                                                                    \
        md_result guard_result = check((instance), (function), (allowed));  \
        if (guard_result != MD_RESULT_OK) { return map(guard_result); }     \
    } while (0)
#define MD_GUARD(instance, function, allowed, map) MD_GUARD_WITH(md_guard, instance, function, allowed, map)

/* md_guard for a Model Exchange entry point: Error first if the instance was created for
 * Co-Simulation. MD_GUARD_ME returns its verdict as MD_GUARD does. */
md_result md_guard_me(md_instance *instance, const char *function, unsigned allowed);
#define MD_GUARD_ME(instance, function, allowed, map) MD_GUARD_WITH(md_guard_me, instance, function, allowed, map)

/* A function this FMU does not provide: md_guard for any mode, then Error "function: why". */
md_result md_unsupported(md_instance *instance, const char *function, const char *why);

/* The experiment (fmi2SetupExperiment; the arguments of fmi3EnterInitializationMode): check
 * and keep the start and stop time; the tolerance becomes solver.relTol unless that was set
 * explicitly (Warning if the solver refuses it). Error, and nothing kept, for bad times. */
md_result md_setup_experiment(md_instance *instance, const char *function, int tolerance_defined,
                              double tolerance, double start_time, int stop_time_defined,
                              double stop_time);
/* Into initialisation mode: md_solver_start at the start time (mode error if that fails). */
md_result md_enter_initialization(md_instance *instance, const char *function);
/* Out of initialisation mode into step mode: start values follow the parameters set in
 * initialisation mode, then md_solver_initialize (mode error if either fails). */
md_result md_exit_initialization(md_instance *instance, const char *function);
/* Back to the state md_instance_new left (the FMU states handed out stay valid). */
void md_reset(md_instance *instance);
/* One communication step from current_time (the FMU's time, within 1e-9 relative) over
 * step_size >= 0, not past the stop time. A solver failure: mode error, outputs at the last
 * good point (instance->solver->t). Argument errors change nothing. */
md_result md_do_step(md_instance *instance, const char *function, double current_time,
                     double step_size);

/* ---------------------------------------------------------------------------------------
 * Variable values
 *
 * Real / Float64 and Boolean variables share the model's arrays: md_model.h has no type
 * table, a Boolean is held as 0.0 / 1.0 and read as (value != 0). modelDescription.xml says
 * which of the typed calls each variable takes; the shell serves both from the same slots.
 * The solver settings and time are Real / Float64 only (boolean != 0 refuses them). The
 * layer reads and writes its arrays through `at` / `put`; md_real_at and md_real_put serve
 * fmi2Real and fmi3Float64 (both double). All variables are scalars: nvalues must equal nvr.
 * ------------------------------------------------------------------------------------- */

typedef double (*md_value_at)(const void *values, size_t i);
typedef void (*md_value_put)(void *values, size_t i, double value);
double md_real_at(const void *values, size_t i);
void md_real_put(void *values, size_t i, double value);

/* Get: in initialisation mode, start values follow the parameters set so far; before
 * initialisation, a variable without a parameter slot has no value yet (Error). */
md_result md_get_values(md_instance *instance, const char *function, const md_vr vr[],
                        size_t nvr, void *values, size_t nvalues, md_value_put put, int boolean);
/* Set, all or nothing: everything is checked before anything is written. Parameters: before
 * exitInitializationMode; inputs: in any settable mode (an input changed in step mode
 * restarts the integrator at the next step); solver settings: range-checked by the solver,
 * before exitInitializationMode unless the layer's settings are tunable; nothing else. */
md_result md_set_values(md_instance *instance, const char *function, const md_vr vr[],
                        size_t nvr, const void *values, size_t nvalues, md_value_at at,
                        int boolean);

/* The integrator statistics (value references MD_VR_STATISTICS ..), cumulative since
 * instantiation (or reset), readable in every mode but instantiated. */
md_result md_get_statistics(md_instance *instance, const char *function, const md_vr vr[],
                            size_t nvr, int64_t values[], size_t nvalues);

/* ---------------------------------------------------------------------------------------
 * Model Exchange (instance->interface == MD_INTERFACE_ME). md_exit_initialization leaves a
 * Model Exchange instance in event mode. The layer guards the modes; these check arguments.
 * ------------------------------------------------------------------------------------- */

/* Does the modelDescription offer this interface type? (Error with the reason if not.) */
int md_offers(int interface);
md_result md_me_set_time(md_instance *instance, const char *function, double time);
md_result md_me_set_states(md_instance *instance, const char *function, const double x[],
                           size_t nx);
md_result md_me_get_states(md_instance *instance, const char *function, double x[], size_t nx);
md_result md_me_get_derivatives(md_instance *instance, const char *function, double dx[],
                                size_t nx);
md_result md_me_get_indicators(md_instance *instance, const char *function, double z[],
                               size_t nz);
md_result md_me_get_nominals(md_instance *instance, const char *function, double x[],
                             size_t nx);
/* Event mode: handle the events at the present point (event iteration included); the
 * discrete states are then settled (no further update is needed). */
md_result md_me_update_discrete_states(md_instance *instance, const char *function,
                                       int *states_changed);
/* An integrator step of the importer was completed (counted in solver.steps). */
void md_me_completed_step(md_instance *instance);

/* ---------------------------------------------------------------------------------------
 * FMU states: the solver's flat state buffer (md_solver_save) tagged with the mode and two
 * flags, in an object the instance keeps in a list so that md_instance_free can free what
 * the importer did not. The in-memory copy and the serialised form are the same bytes.
 * `state` is the layer's fmi2FMUstate / fmi3FMUState (void *).
 * ------------------------------------------------------------------------------------- */

/* Save into *state: reused if it is one of this instance's states, else a new one. */
md_result md_get_state(md_instance *instance, const char *function, void **state);
/* Restore mode, flags and the whole solver state from `state`; nothing changes on Error. */
md_result md_set_state(md_instance *instance, const char *function, const void *state);
/* Free *state and set it to NULL (NULL or *state NULL: nothing to do). */
md_result md_free_state(md_instance *instance, const char *function, void **state);
md_result md_serialized_state_size(md_instance *instance, const char *function,
                                   const void *state, size_t *size);
md_result md_serialize_state(md_instance *instance, const char *function, const void *state,
                             void *buffer, size_t size);
/* A new state (or *state reused, as md_get_state) from serialised bytes, checked first. */
md_result md_deserialize_state(md_instance *instance, const char *function, const void *buffer,
                               size_t size, void **state);

#endif
