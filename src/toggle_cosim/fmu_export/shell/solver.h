/* The model-independent core of the FMU shell: one simulation instance of a generated model
 * (see md_model.h) and everything that advances it -- an adaptive Dormand-Prince 5(4)
 * integrator with dense output, state-event location and event iteration, and copy /
 * serialisation of the whole instance state.
 *
 * Nothing here knows about FMI: instance.c (the generic FMU shell under fmi2.c and fmi3.c)
 * wraps it. Nothing here knows which model it runs either: everything model-specific comes
 * through MD_INFO and the generated functions. There is no global mutable state; instances
 * are independent.
 *
 * Errors: functions that can fail return MD_FAIL and leave a one-line explanation in
 * md_solver_message(). The simulation state is then left at the last good point.
 */
#ifndef MD_SOLVER_H
#define MD_SOLVER_H

#include <stddef.h>
#include "md_model.h"
#include "md_settings.h" /* the settings table, written by shell_settings.py */

/* ---------------------------------------------------------------------------------------
 * Solver settings
 *
 * MD_SHELL_NREAL of them are exposed by the FMU as Real parameters with value references
 * MD_INFO.nvars + MD_SETTING_* (after the model's own variables): names, defaults, units
 * and order come from md_settings.h, which shell_settings.py writes from the table the
 * modelDescription.xml is written from. Valid ranges: relTol (0, 0.1], absTol > 0,
 * maxStep >= 0 (0: unbounded). The limits below are compile-time defaults (-D...).
 * ------------------------------------------------------------------------------------- */

typedef struct {
    const char *name;
    double start;
    const char *unit;
    const char *description;
} md_setting;

/* [MD_SHELL_NREAL] names, defaults, units and descriptions, in value-reference order. */
extern const md_setting MD_SHELL_SETTINGS[MD_SHELL_NREAL];

#ifndef MD_MAX_EVENTS_PER_STEP
#define MD_MAX_EVENTS_PER_STEP 10000L  /* Zeno / chattering guard, events per doStep */
#endif
#ifndef MD_MAX_STEPS
#define MD_MAX_STEPS 1000000L          /* internal steps (accepted + rejected) per doStep */
#endif
#ifndef MD_MAX_EVENT_ITERATIONS
#define MD_MAX_EVENT_ITERATIONS 20     /* event-iteration rounds at one instant */
#endif

#define MD_MESSAGE_SIZE 512

/* ---------------------------------------------------------------------------------------
 * Host services: memory and logging, supplied by the FMI layer.
 * ------------------------------------------------------------------------------------- */

/* The solver does not log its failures: it returns MD_FAIL and the FMI layer reports
   md_solver_message() with the status it returns (FMI category logStatusError). */
typedef enum {
    MD_LOG_EVENTS = 0,  /* one line per event: time, indicator, kind */
    MD_LOG_ALL = 1      /* chatty diagnostics: step statistics per communication step */
} md_log_category;

typedef struct {
    void *(*allocate)(void *env, size_t nobj, size_t size); /* zero-filled, like calloc */
    void (*release)(void *env, void *ptr);
    /* May be NULL. The message is complete text (not a format string). */
    void (*log)(void *env, md_log_category category, const char *message);
    /* Asked before a message is formatted, so a disabled category costs nothing. May be NULL
       (then everything is formatted and handed to log). */
    int (*log_enabled)(void *env, md_log_category category);
    void *env;
} md_host;

typedef enum { MD_OK = 0, MD_FAIL = 1 } md_status;

/* ---------------------------------------------------------------------------------------
 * The instance. Fields are public for the FMI layers; only the solver writes them, except
 * p (parameters and inputs), which the FMI layer writes through md_solver_set_parameter.
 * ------------------------------------------------------------------------------------- */

typedef struct {
    double rel_tol;
    double abs_tol;
    double max_step;          /* 0 = unbounded */
    long max_events_per_step; /* MD_MAX_EVENTS_PER_STEP */
    long max_steps;           /* MD_MAX_STEPS */
} md_settings;

typedef struct {
    unsigned long steps;      /* accepted internal steps (Model Exchange: the importer's
                                 completed integrator steps) */
    unsigned long rejected;   /* rejected internal steps (error test or non-finite) */
    unsigned long rhs_calls;
    unsigned long events;     /* transition() calls: state and time events handled */
} md_counters;

typedef struct md_solver {
    const md_info *info;
    md_host host;

    /* ---- simulation state: all of it is copied by md_solver_save / md_solver_restore ---- */
    md_settings settings;
    double t;
    double *y;      /* [ny] */
    double *p;      /* [np] */
    double *w;      /* [nw] */
    double *obs;    /* [nobs] observe() output at (t, y), refreshed after every change */
    double *z;      /* [nz] indicators at (t, y) */
    unsigned char *cond; /* [nz] z_k > 0 as last acted upon (latched condition) */
    double h_next;  /* proposed next internal step (0: none yet, use the heuristic) */
    int fsal_valid; /* k1 holds rhs(t, y) */
    double *k1;     /* [ny] first-same-as-last derivative */
    md_counters count;

    /* ---- scratch, not part of the state ---- */
    double *k;      /* [7*ny] stages; k1 above is stage 0's storage */
    double *ynew, *ytmp, *yerr, *ydense, *rcont; /* [ny] each, rcont [5*ny] */
    double *zl, *zr, *zm; /* [nz] root-finder brackets */
    double *obs_tmp;      /* [nobs] */
    double *w_tmp;        /* [nw] w kept aside while derivatives are read (md_solver_rhs_at) */
    int *fired;           /* [nz] */
    char message[MD_MESSAGE_SIZE];
} md_solver;

/* Create an instance: p at the model's declared values (md_defaults), settings at their
 * defaults, t = 0, y and w zero. NULL if memory is short. */
md_solver *md_solver_new(const md_info *info, const md_host *host);
void md_solver_free(md_solver *s);

/* Back to the state md_solver_new left (FMI reset). */
void md_solver_reset(md_solver *s);

/* Settings by index MD_SETTING_*; MD_FAIL (with message) for an invalid value. */
md_status md_solver_set_setting(md_solver *s, int index, double value);
double md_solver_get_setting(const md_solver *s, int index);

/* Write p[slot] = value. If restart is nonzero and the value differs from the present one
 * (an input changed during the run), the integrator is restarted at the next advance. The
 * caller refreshes obs (md_solver_observe) once it has set everything it is setting. */
void md_solver_set_parameter(md_solver *s, int slot, double value, int restart);

/* Initialisation, in two halves:
 *   md_solver_start:      t = t0, md_parameters(p), md_start(p, y, w) (y and w zeroed
 *                         first), observe. Call again whenever a parameter changes before
 *                         initialize, so that start values that depend on parameters follow.
 *   md_solver_initialize: indicators at (t, y); set the latch slots and the conditions from
 *                         them, without firing any `when` branch; observe. */
md_status md_solver_start(md_solver *s, double t0);
md_status md_solver_initialize(md_solver *s);

/* Refresh obs at (t, y). MD_FAIL if an observed value is not finite (obs then keeps its
 * previous contents). */
md_status md_solver_observe(md_solver *s);

/* Integrate from s->t to t_end (>= s->t), handling state events on the way, landing exactly
 * on t_end, and refresh obs. On MD_FAIL, s->t is the last good point. */
md_status md_solver_advance(md_solver *s, double t_end);

const char *md_solver_message(const md_solver *s);

/* ---------------------------------------------------------------------------------------
 * Model Exchange: the importer integrates; the core evaluates the model at the point it
 * sets and handles the events it reports. The same event logic as md_solver_advance.
 * ------------------------------------------------------------------------------------- */

/* Move to (t, y) as the importer sets them (y may be NULL: time only). The derivative
 * cache is invalid afterwards; obs is not refreshed (call md_solver_observe). */
void md_solver_set_point(md_solver *s, double t, const double *y);
/* The state derivatives at (s->t, s->y) into dy[ny]. w is left exactly as it was, so reading
 * derivatives between Co-Simulation steps cannot change the integration. MD_FAIL if any is
 * not finite. */
md_status md_solver_derivatives(md_solver *s, double *dy);
/* The event indicators at (s->t, s->y) into z[nz]. */
md_status md_solver_indicators(md_solver *s, double *z);
/* Event mode: act on every condition that changed since the last event (or initialisation)
 * at the present point, with event iteration (as at a located event in md_solver_advance),
 * then refresh obs. *state_changed: transition() moved the continuous state. */
md_status md_solver_handle_events(md_solver *s, int *state_changed);

/* ---------------------------------------------------------------------------------------
 * State copy and serialisation.
 *
 * A state is a flat byte buffer of fixed size for a given model: a header (magic number,
 * format version, hash of MD_INFO.guid, the array sizes, a payload checksum) and the
 * payload (settings, t, step size, FSAL derivative, y, p, w, obs, z, conditions, counters,
 * and an int `tag` the caller can use for its own mode). The same buffer serves as the
 * in-memory copy (get/set FMU state) and as the serialised form, so both are bit-exact.
 * A buffer for another model, of the wrong size, or with a damaged payload is refused.
 * ------------------------------------------------------------------------------------- */

size_t md_solver_state_size(const md_info *info);
/* Write the whole state into buf (size must be md_solver_state_size). */
md_status md_solver_save(md_solver *s, int tag, void *buf, size_t size);
/* Check a buffer without touching the state; on success *tag (if not NULL) is its tag. */
md_status md_solver_check(md_solver *s, const void *buf, size_t size, int *tag);
/* Check, then restore the state from buf. Nothing changes on MD_FAIL. */
md_status md_solver_restore(md_solver *s, const void *buf, size_t size, int *tag);

#endif
