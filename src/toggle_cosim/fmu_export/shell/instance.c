/* The generic FMU shell, shared by the FMI 2.0 and FMI 3.0 layers. See instance.h for the
 * contract. Compiled as a unit of its own beside solver.c and one FMI layer. */
#include "instance.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

/* The FMU state's tag (md_solver_save): the mode in the low byte, and two flags. */
#define TAG_MODE_MASK 0xff
#define TAG_DIRTY 0x100
#define TAG_RELTOL_SET 0x200

#define CATEGORY_BIT(index) (1u << (index))

/* ---------------------------------------------------------------------------------------
 * Logging and status reporting
 * ------------------------------------------------------------------------------------- */

static const char *mode_name(md_mode mode) {
    switch (mode) {
    case MD_MODE_INSTANTIATED: return "instantiated";
    case MD_MODE_INIT: return "initialisation mode";
    case MD_MODE_STEP: return "step mode";
    case MD_MODE_TERMINATED: return "terminated";
    case MD_MODE_ERROR: return "error";
    case MD_MODE_FATAL: return "fatal";
    case MD_MODE_EVENT: return "event mode";
    case MD_MODE_CONTINUOUS: return "continuous-time mode";
    default: return "?";
    }
}

int md_log_enabled(const md_instance *m, md_result status, md_category category) {
    const md_layer *layer = m->layer;
    if (!m->has_logger) { return 0; }
    if (status >= MD_RESULT_ERROR && layer->errors_always_logged) { return 1; }
    return (m->log_mask & (CATEGORY_BIT(layer->category_of[category])
                           | CATEGORY_BIT(layer->category_of[MD_CATEGORY_ALL]))) != 0;
}

static void emit(const md_instance *m, md_result status, md_category category, const char *text) {
    if (md_log_enabled(m, status, category)) {
        m->layer->log(m, status, m->layer->categories[m->layer->category_of[category]], text);
    }
}

void md_log(const md_instance *m, md_category category, const char *format, ...) {
    char text[MD_MESSAGE_SIZE];
    va_list args;
    if (!md_log_enabled(m, MD_RESULT_OK, category)) { return; }
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    emit(m, MD_RESULT_OK, category, text);
}

md_result md_report(md_instance *m, md_result status, const char *format, ...) {
    va_list args;
    va_start(args, format);
    vsnprintf(m->message, sizeof m->message, format, args);
    va_end(args);
    emit(m, status, status >= MD_RESULT_ERROR ? MD_CATEGORY_ERROR : MD_CATEGORY_WARNING,
         m->message);
    return status;
}

md_result md_set_debug_logging(md_instance *m, const char *function, int logging_on,
                               size_t ncategories, const char *const categories[]) {
    const md_layer *layer = m->layer;
    md_result status = MD_RESULT_OK;
    if (ncategories == 0) {
        m->log_mask = logging_on ? CATEGORY_BIT(layer->ncategories) - 1u : 0u;
        return MD_RESULT_OK;
    }
    if (categories == NULL) {
        return md_report(m, MD_RESULT_ERROR, "%s: categories is NULL", function);
    }
    for (size_t i = 0; i < ncategories; ++i) {
        int found = -1;
        for (int k = 0; k < layer->ncategories; ++k) {
            if (categories[i] != NULL && strcmp(categories[i], layer->categories[k]) == 0) {
                found = k;
            }
        }
        if (found < 0) {
            char known[MD_MESSAGE_SIZE] = "";
            for (int k = 0; k < layer->ncategories; ++k) {
                size_t used = strlen(known);
                snprintf(known + used, sizeof known - used, "%s%s", k > 0 ? ", " : "",
                         layer->categories[k]);
            }
            status = md_report(m, MD_RESULT_WARNING, "%s: unknown log category \"%s\" ignored "
                               "(known: %s)", function,
                               categories[i] != NULL ? categories[i] : "(null)", known);
        } else if (logging_on) {
            m->log_mask |= CATEGORY_BIT(found);
        } else {
            m->log_mask &= ~CATEGORY_BIT(found);
        }
    }
    return status;
}

/* ---------------------------------------------------------------------------------------
 * Creation and destruction
 * ------------------------------------------------------------------------------------- */

/* Solver host services: the instance's memory functions and logger. */

static void *host_allocate(void *env, size_t nobj, size_t size) {
    return ((md_instance *)env)->allocate(nobj, size);
}

static void host_release(void *env, void *ptr) { ((md_instance *)env)->release(ptr); }

static md_category host_category(md_log_category category) {
    return category == MD_LOG_EVENTS ? MD_CATEGORY_EVENTS : MD_CATEGORY_ALL;
}

static int host_log_enabled(void *env, md_log_category category) {
    return md_log_enabled((md_instance *)env, MD_RESULT_OK, host_category(category));
}

static void host_log(void *env, md_log_category category, const char *message) {
    emit((md_instance *)env, MD_RESULT_OK, host_category(category), message);
}

/* The experiment and the flags, as instantiation leaves them (and reset). */
static void clear(md_instance *m) {
    m->mode = MD_MODE_INSTANTIATED;
    m->start_time = 0.0;
    m->stop_time = 0.0;
    m->stop_defined = 0;
    m->rel_tol_set = 0;
    m->params_dirty = 0;
    m->obs_stale = 0;
    m->message[0] = '\0';
}

md_instance *md_instance_new(const md_layer *layer, size_t size, md_allocate allocate,
                             md_release release, const char *name) {
    md_instance *m;
    md_host host;
    size_t length = strlen(name);
    if (size < sizeof *m) { return NULL; }
    m = allocate(1, size);
    if (m == NULL) { return NULL; }
    memset(m, 0, size);
    m->layer = layer;
    m->allocate = allocate;
    m->release = release;
    m->name = allocate(length + 1, 1);
    if (m->name != NULL) { memcpy(m->name, name, length + 1); }
    host.allocate = host_allocate;
    host.release = host_release;
    host.log = host_log;
    host.log_enabled = host_log_enabled;
    host.env = m;
    m->solver = m->name != NULL ? md_solver_new(&MD_INFO, &host) : NULL;
    if (m->solver == NULL) {
        if (m->name != NULL) { release(m->name); }
        release(m);
        return NULL;
    }
    m->states = NULL;
    m->interface = MD_INTERFACE_CS;
    m->has_logger = 0;
    m->log_mask = 0u;
    clear(m);
    return m;
}

void md_instance_start_logging(md_instance *m, int has_logger, int logging_on) {
    m->has_logger = has_logger;
    /* debug output if asked for; else what the layer reports by default */
    m->log_mask = logging_on ? CATEGORY_BIT(m->layer->ncategories) - 1u
                             : m->layer->quiet_log_mask;
    md_log(m, MD_CATEGORY_ALL, "instantiated %s: %d states, %d event indicators, %d variables",
           MD_INFO.model_name, MD_INFO.ny, MD_INFO.nz, MD_INFO.nvars);
}

/* An FMU state: the solver's flat state buffer, tagged with the mode. */
typedef struct md_fmu_state {
    uint32_t magic;                    /* the layer's state_magic; 0 once freed */
    md_instance *owner;                /* the instance whose list holds it */
    struct md_fmu_state *prev, *next;
    size_t size;
    unsigned char data[];              /* md_solver_save() format */
} md_fmu_state;

void md_instance_free(md_instance *m) {
    md_release release;
    if (m == NULL) { return; }
    release = m->release;
    while (m->states != NULL) {
        md_fmu_state *st = m->states;
        m->states = st->next;
        st->magic = 0;
        release(st);
    }
    md_solver_free(m->solver);
    release(m->name);
    release(m);
}

/* ---------------------------------------------------------------------------------------
 * The state machine
 * ------------------------------------------------------------------------------------- */

md_result md_guard(md_instance *m, const char *function, unsigned allowed) {
    if (m == NULL) { return MD_RESULT_ERROR; }
    if (m->mode == MD_MODE_FATAL) { return MD_RESULT_FATAL; }
    if ((m->mode & allowed) == 0) {
        if (m->mode == MD_MODE_ERROR) {
            return md_report(m, MD_RESULT_ERROR, "%s: not allowed after an error (%s); call %s",
                             function, md_solver_message(m->solver), m->layer->recovery);
        }
        return md_report(m, MD_RESULT_ERROR, "%s: not allowed in %s", function,
                         mode_name(m->mode));
    }
    return MD_RESULT_OK;
}

md_result md_guard_me(md_instance *m, const char *function, unsigned allowed) {
    if (m != NULL && m->mode != MD_MODE_FATAL && m->interface != MD_INTERFACE_ME) {
        return md_report(m, MD_RESULT_ERROR, "%s: a Model Exchange function, but the instance is a "
                         "Co-Simulation one", function);
    }
    return md_guard(m, function, allowed);
}

md_result md_unsupported(md_instance *m, const char *function, const char *why) {
    md_result status = md_guard(m, function, MD_MODE_ANY);
    if (status != MD_RESULT_OK) { return status; }
    return md_report(m, MD_RESULT_ERROR, "%s: %s", function, why);
}

md_result md_setup_experiment(md_instance *m, const char *function, int tolerance_defined,
                              double tolerance, double start_time, int stop_time_defined,
                              double stop_time) {
    md_result status = MD_RESULT_OK;
    if (!isfinite(start_time)) {
        return md_report(m, MD_RESULT_ERROR, "%s: startTime %g is not finite", function,
                         start_time);
    }
    if (stop_time_defined && !(stop_time >= start_time && isfinite(stop_time))) {
        return md_report(m, MD_RESULT_ERROR, "%s: stopTime %g before startTime %g", function,
                         stop_time, start_time);
    }
    /* for Co-Simulation the tolerance is "usually a relative tolerance" (FMI 2.0 sec. 4.2.1,
       FMI 3.0 fmi3EnterInitializationMode) */
    if (tolerance_defined && !m->rel_tol_set) {
        if (md_solver_set_setting(m->solver, MD_SETTING_RELTOL, tolerance) != MD_OK) {
            status = md_report(m, MD_RESULT_WARNING, "%s: tolerance ignored: %s", function,
                               md_solver_message(m->solver));
        }
    }
    m->start_time = start_time;
    m->solver->t = start_time;
    m->stop_defined = stop_time_defined != 0;
    m->stop_time = stop_time;
    return status;
}

md_result md_enter_initialization(md_instance *m, const char *function) {
    if (md_solver_start(m->solver, m->start_time) != MD_OK) {
        m->mode = MD_MODE_ERROR;
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(m->solver));
    }
    m->params_dirty = 0;
    m->mode = MD_MODE_INIT;
    return MD_RESULT_OK;
}

md_result md_exit_initialization(md_instance *m, const char *function) {
    md_solver *s = m->solver;
    /* parameters set in initialisation mode: start values that depend on them follow */
    if (m->params_dirty && md_solver_start(s, m->start_time) != MD_OK) {
        m->mode = MD_MODE_ERROR;
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(s));
    }
    m->params_dirty = 0;
    if (md_solver_initialize(s) != MD_OK) {
        m->mode = MD_MODE_ERROR;
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(s));
    }
    /* Model Exchange: into event mode, where the importer settles the discrete states */
    m->mode = m->interface == MD_INTERFACE_ME ? MD_MODE_EVENT : MD_MODE_STEP;
    m->obs_stale = 0;
    md_log(m, MD_CATEGORY_ALL, "initialised at t=%.17g s (relTol=%g, absTol=%g, maxStep=%g)",
           s->t, s->settings.rel_tol, s->settings.abs_tol, s->settings.max_step);
    return MD_RESULT_OK;
}

void md_reset(md_instance *m) {
    md_solver_reset(m->solver);
    clear(m);
}

md_result md_do_step(md_instance *m, const char *function, double current_time,
                     double step_size) {
    md_solver *s = m->solver;
    double t_end;
    if (!isfinite(current_time) || fabs(current_time - s->t) > 1e-9 * fmax(1.0, fabs(s->t))) {
        return md_report(m, MD_RESULT_ERROR, "%s: currentCommunicationPoint %.17g s is not "
                         "the FMU's time %.17g s", function, current_time, s->t);
    }
    if (!(step_size >= 0.0) || !isfinite(step_size)) {
        return md_report(m, MD_RESULT_ERROR, "%s: communicationStepSize %g must be >= 0",
                         function, step_size);
    }
    t_end = current_time + step_size;
    if (m->stop_defined && t_end > m->stop_time + 1e-9 * fmax(1.0, fabs(m->stop_time))) {
        return md_report(m, MD_RESULT_ERROR, "%s: t=%.17g s is past the stopTime %.17g s given "
                         "to %s", function, t_end, m->stop_time, m->layer->stop_time_source);
    }
    s->t = current_time; /* follow the importer's clock exactly */
    if (md_solver_advance(s, t_end) != MD_OK) {
        m->mode = MD_MODE_ERROR;
        /* outputs at the last good point, if they can be had */
        (void)md_solver_observe(s);
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(s));
    }
    return MD_RESULT_OK;
}

/* ---------------------------------------------------------------------------------------
 * Variable values
 * ------------------------------------------------------------------------------------- */

double md_real_at(const void *values, size_t i) { return ((const double *)values)[i]; }

void md_real_put(void *values, size_t i, double value) { ((double *)values)[i] = value; }

static md_vr time_vr(void) { return MD_VR_TIME; }

/* Every variable is a scalar: one value per value reference. */
static md_result check_arrays(md_instance *m, const char *function, const md_vr vr[], size_t nvr,
                              const void *values, size_t nvalues) {
    if (nvalues != nvr) {
        return md_report(m, MD_RESULT_ERROR, "%s: nValues = %lu but nValueReferences = %lu "
                         "(all variables of this FMU are scalars)", function,
                         (unsigned long)nvalues, (unsigned long)nvr);
    }
    if (nvr > 0 && (vr == NULL || values == NULL)) {
        return md_report(m, MD_RESULT_ERROR, "%s: NULL array", function);
    }
    return MD_RESULT_OK;
}

/* Before reading: the values must follow the parameters set so far. */
static md_result refresh_for_get(md_instance *m, const md_vr vr[], size_t nvr) {
    if (m->obs_stale && m->mode != MD_MODE_INSTANTIATED) {
        if (md_solver_observe(m->solver) != MD_OK) {
            return md_report(m, MD_RESULT_ERROR, "%s", md_solver_message(m->solver));
        }
        m->obs_stale = 0;
    }
    if (m->mode == MD_MODE_INIT && m->params_dirty) {
        if (md_solver_start(m->solver, m->start_time) != MD_OK) {
            return md_report(m, MD_RESULT_ERROR, "%s", md_solver_message(m->solver));
        }
        m->params_dirty = 0;
    } else if (m->mode == MD_MODE_INSTANTIATED) {
        /* start values of calculated parameters and constants follow the parameters set so
           far; md_parameters only writes their slots (md_solver_start runs it again) */
        for (size_t i = 0; i < nvr; ++i) {
            if (vr[i] < (md_vr)MD_INFO.nvars && MD_INFO.kind[vr[i]] == MD_CALCULATED) {
                md_parameters(m->solver->p);
                break;
            }
        }
    }
    return MD_RESULT_OK;
}

/* The value of variable r as a double (a solver setting or time only if !boolean). */
static md_result get_value(md_instance *m, const char *function, md_vr r, int boolean,
                           double *value) {
    const md_info *info = &MD_INFO;
    const md_layer *layer = m->layer;
    const md_vr nvars = (md_vr)info->nvars;
    if (r < nvars) {
        if (m->mode == MD_MODE_INSTANTIATED) {
            /* start values: only what lives in p has one before initialisation */
            if (info->par_slot[r] < 0) {
                return md_report(m, MD_RESULT_ERROR, "%s: %s has no value before %s (it is "
                                 "calculated there)", function, info->names[r],
                                 layer->enter_initialization);
            }
            *value = m->solver->p[info->par_slot[r]];
        } else if (info->obs_slot[r] >= 0) {
            *value = m->solver->obs[info->obs_slot[r]];
        } else if (info->par_slot[r] >= 0) {
            *value = m->solver->p[info->par_slot[r]];
        } else {
            return md_report(m, MD_RESULT_ERROR, "%s: variable %s has no value slot", function,
                             info->names[r]);
        }
        return MD_RESULT_OK;
    }
    if (r < nvars + MD_SHELL_NREAL) {
        if (boolean) {
            return md_report(m, MD_RESULT_ERROR, "%s: %s is a %s variable", function,
                             MD_SHELL_SETTINGS[r - nvars].name, layer->real_type);
        }
        *value = md_solver_get_setting(m->solver, (int)(r - nvars));
        return MD_RESULT_OK;
    }
    if (layer->has_time && r == time_vr()) {
        if (boolean) {
            return md_report(m, MD_RESULT_ERROR, "%s: time is a %s variable", function,
                             layer->real_type);
        }
        *value = m->solver->t;
        return MD_RESULT_OK;
    }
    if (!boolean && r >= MD_VR_DERIVATIVES && r < MD_VR_END) {
        /* der(x) or an event indicator, evaluated at the present point; from
           initialisation on (a start value of the states is needed) */
        md_solver *s = m->solver;
        double *scratch = s->ydense; /* no step in progress: free */
        const int derivatives = r < MD_VR_INDICATORS;
        md_status status;
        if (m->mode == MD_MODE_INSTANTIATED) {
            return md_report(m, MD_RESULT_ERROR, "%s: value reference %u has no value before %s",
                             function, r, layer->enter_initialization);
        }
        if (derivatives) {
            status = md_solver_derivatives(s, scratch);
        } else {
            status = md_solver_indicators(s, s->zm);
            scratch = s->zm;
        }
        if (status != MD_OK) {
            return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(s));
        }
        *value = scratch[r - (derivatives ? MD_VR_DERIVATIVES : MD_VR_INDICATORS)];
        return MD_RESULT_OK;
    }
    return md_report(m, MD_RESULT_ERROR, "%s: unknown value reference %u", function, r);
}

md_result md_get_values(md_instance *m, const char *function, const md_vr vr[], size_t nvr,
                        void *values, size_t nvalues, md_value_put put, int boolean) {
    if (check_arrays(m, function, vr, nvr, values, nvalues) != MD_RESULT_OK
        || refresh_for_get(m, vr, nvr) != MD_RESULT_OK) {
        return MD_RESULT_ERROR;
    }
    for (size_t i = 0; i < nvr; ++i) {
        double value = 0.0;
        if (get_value(m, function, vr[i], boolean, &value) != MD_RESULT_OK) {
            return MD_RESULT_ERROR;
        }
        put(values, i, value);
    }
    return MD_RESULT_OK;
}

/* Is variable r settable now with this value? (Error with the reason if not.) */
static md_result check_settable(md_instance *m, const char *function, md_vr r, double value,
                                int boolean) {
    const md_info *info = &MD_INFO;
    const md_layer *layer = m->layer;
    const md_vr nvars = (md_vr)info->nvars;
    const int before_run = (m->mode & (MD_MODE_INSTANTIATED | MD_MODE_INIT)) != 0;
    const char *name;
    if (r < nvars) {
        name = info->names[r];
        if (info->kind[r] == MD_PARAMETER) {
            if (!before_run) {
                return md_report(m, MD_RESULT_ERROR, "%s: variable %s is a %s: it can only be "
                                 "set before %s", function, name, layer->parameter,
                                 layer->exit_initialization);
            }
        } else if (info->kind[r] != MD_INPUT) {
            return md_report(m, MD_RESULT_ERROR, "%s: variable %s is not settable", function,
                             name);
        }
        if (info->par_slot[r] < 0) {
            return md_report(m, MD_RESULT_ERROR, "%s: variable %s has no parameter slot",
                             function, name);
        }
    } else if (r < nvars + MD_SHELL_NREAL) {
        name = MD_SHELL_SETTINGS[r - nvars].name;
        if (boolean) {
            return md_report(m, MD_RESULT_ERROR, "%s: %s is a %s variable", function, name,
                             layer->real_type);
        }
        if (!before_run && !layer->settings_tunable) {
            return md_report(m, MD_RESULT_ERROR, "%s: %s is a parameter: it can only be set "
                             "before %s", function, name, layer->exit_initialization);
        }
    } else if (layer->has_time && r == time_vr()) {
        return md_report(m, MD_RESULT_ERROR, "%s: time is the independent variable: only %s "
                         "advances it", function, layer->do_step);
    } else if (r >= MD_VR_STATISTICS && r < MD_VR_END) {
        return md_report(m, MD_RESULT_ERROR, "%s: value reference %u is computed by the FMU "
                         "(a derivative, an event indicator or a statistic): not settable",
                         function, r);
    } else {
        return md_report(m, MD_RESULT_ERROR, "%s: unknown value reference %u", function, r);
    }
    if (!isfinite(value)) {
        return md_report(m, MD_RESULT_ERROR, "%s: refusing the non-finite value %g for %s",
                         function, value, name);
    }
    return MD_RESULT_OK;
}

md_result md_set_values(md_instance *m, const char *function, const md_vr vr[], size_t nvr,
                        const void *values, size_t nvalues, md_value_at at, int boolean) {
    const md_info *info = &MD_INFO;
    const md_vr nvars = (md_vr)info->nvars;
    md_solver *s = m->solver;
    int inputs = 0, parameters = 0;
    md_settings saved;
    if (check_arrays(m, function, vr, nvr, values, nvalues) != MD_RESULT_OK) {
        return MD_RESULT_ERROR;
    }
    for (size_t i = 0; i < nvr; ++i) {
        if (check_settable(m, function, vr[i], at(values, i), boolean) != MD_RESULT_OK) {
            return MD_RESULT_ERROR;
        }
    }
    /* solver settings: range-checked by the solver; undo all of them if one is refused */
    saved = s->settings;
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] >= nvars
            && md_solver_set_setting(s, (int)(vr[i] - nvars), at(values, i)) != MD_OK) {
            s->settings = saved;
            return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(s));
        }
    }
    for (size_t i = 0; i < nvr; ++i) {
        md_vr r = vr[i];
        if (r >= nvars) {
            if (r - nvars == MD_SETTING_RELTOL) { m->rel_tol_set = 1; }
            continue;
        }
        /* an input changed mid-run restarts the integrator at the next step */
        md_solver_set_parameter(s, info->par_slot[r], at(values, i), m->mode == MD_MODE_STEP);
        if (info->kind[r] == MD_INPUT) { inputs = 1; } else { parameters = 1; }
    }
    if (parameters && m->mode == MD_MODE_INIT) { m->params_dirty = 1; }
    if (inputs && (m->mode & (MD_MODE_EVENT | MD_MODE_CONTINUOUS))) {
        m->obs_stale = 1; /* outputs follow when they are read */
        return MD_RESULT_OK;
    }
    if (inputs && (m->mode & (MD_MODE_INIT | MD_MODE_STEP)) && !m->params_dirty
        && md_solver_observe(s) != MD_OK) {
        return md_report(m, MD_RESULT_WARNING, "%s: outputs not updated: %s", function,
                         md_solver_message(s));
    }
    return MD_RESULT_OK;
}

/* ---------------------------------------------------------------------------------------
 * FMU states
 * ------------------------------------------------------------------------------------- */

static int is_state(const md_instance *m, const md_fmu_state *st) {
    return st != NULL && st->magic == m->layer->state_magic;
}

static int tag_valid(int tag) {
    int mode = tag & TAG_MODE_MASK;
    return mode == MD_MODE_INSTANTIATED || mode == MD_MODE_INIT || mode == MD_MODE_STEP
           || mode == MD_MODE_TERMINATED || mode == MD_MODE_ERROR || mode == MD_MODE_EVENT
           || mode == MD_MODE_CONTINUOUS;
}

/* The state *state points to, to be overwritten, or a new one (linked into m->states). */
static md_fmu_state *state_object(md_instance *m, void **state, size_t size) {
    md_fmu_state *st = *state;
    if (is_state(m, st) && st->owner == m && st->size == size) { return st; }
    st = m->allocate(1, sizeof(md_fmu_state) + size);
    if (st == NULL) { return NULL; }
    st->magic = m->layer->state_magic;
    st->size = size;
    st->owner = m;
    st->prev = NULL;
    st->next = m->states;
    if (m->states != NULL) { m->states->prev = st; }
    m->states = st;
    /* A foreign pointer in *state is not ours to free: just replace it. */
    *state = st;
    return st;
}

md_result md_get_state(md_instance *m, const char *function, void **state) {
    size_t size = md_solver_state_size(&MD_INFO);
    md_fmu_state *st;
    int tag;
    if (state == NULL) {
        return md_report(m, MD_RESULT_ERROR, "%s: %s is NULL", function, m->layer->fmu_state);
    }
    if (m->obs_stale && md_solver_observe(m->solver) == MD_OK) { m->obs_stale = 0; }
    st = state_object(m, state, size);
    if (st == NULL) { return md_report(m, MD_RESULT_ERROR, "%s: out of memory", function); }
    tag = (int)m->mode | (m->params_dirty ? TAG_DIRTY : 0)
          | (m->rel_tol_set ? TAG_RELTOL_SET : 0);
    if (md_solver_save(m->solver, tag, st->data, size) != MD_OK) {
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(m->solver));
    }
    return MD_RESULT_OK;
}

md_result md_set_state(md_instance *m, const char *function, const void *state) {
    const md_fmu_state *st = state;
    int tag = 0;
    if (!is_state(m, st)) {
        return md_report(m, MD_RESULT_ERROR, "%s: not an FMU state of this FMU", function);
    }
    if (md_solver_check(m->solver, st->data, st->size, &tag) != MD_OK) {
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(m->solver));
    }
    if (!tag_valid(tag)) {
        return md_report(m, MD_RESULT_ERROR, "%s: the state is corrupted (mode)", function);
    }
    (void)md_solver_restore(m->solver, st->data, st->size, NULL);
    m->mode = (md_mode)(tag & TAG_MODE_MASK);
    m->params_dirty = (tag & TAG_DIRTY) != 0;
    m->rel_tol_set = (tag & TAG_RELTOL_SET) != 0;
    m->obs_stale = 0;
    return MD_RESULT_OK;
}

md_result md_free_state(md_instance *m, const char *function, void **state) {
    md_fmu_state *st;
    if (state == NULL || *state == NULL) { return MD_RESULT_OK; }
    st = *state;
    if (!is_state(m, st)) {
        return md_report(m, MD_RESULT_ERROR, "%s: not an FMU state of this FMU", function);
    }
    if (st->prev != NULL) {
        st->prev->next = st->next;
    } else {
        st->owner->states = st->next;
    }
    if (st->next != NULL) { st->next->prev = st->prev; }
    st->magic = 0;
    m->release(st);
    *state = NULL;
    return MD_RESULT_OK;
}

md_result md_serialized_state_size(md_instance *m, const char *function, const void *state,
                                   size_t *size) {
    const md_fmu_state *st = state;
    if (!is_state(m, st) || size == NULL) {
        return md_report(m, MD_RESULT_ERROR, "%s: not an FMU state of this FMU", function);
    }
    *size = st->size;
    return MD_RESULT_OK;
}

md_result md_serialize_state(md_instance *m, const char *function, const void *state,
                             void *buffer, size_t size) {
    const md_fmu_state *st = state;
    if (!is_state(m, st) || buffer == NULL) {
        return md_report(m, MD_RESULT_ERROR, "%s: not an FMU state of this FMU", function);
    }
    if (size != st->size) {
        return md_report(m, MD_RESULT_ERROR, "%s: buffer of %lu bytes, %lu needed", function,
                         (unsigned long)size, (unsigned long)st->size);
    }
    memcpy(buffer, st->data, size);
    return MD_RESULT_OK;
}

md_result md_deserialize_state(md_instance *m, const char *function, const void *buffer,
                               size_t size, void **state) {
    md_fmu_state *st;
    int tag = 0;
    if (state == NULL) {
        return md_report(m, MD_RESULT_ERROR, "%s: %s is NULL", function, m->layer->fmu_state);
    }
    if (buffer == NULL) {
        return md_report(m, MD_RESULT_ERROR, "%s: serializedState is NULL", function);
    }
    if (md_solver_check(m->solver, buffer, size, &tag) != MD_OK) {
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(m->solver));
    }
    if (!tag_valid(tag)) {
        return md_report(m, MD_RESULT_ERROR, "%s: the state is corrupted (mode)", function);
    }
    st = state_object(m, state, size);
    if (st == NULL) { return md_report(m, MD_RESULT_ERROR, "%s: out of memory", function); }
    memcpy(st->data, buffer, size);
    return MD_RESULT_OK;
}

/* ---------------------------------------------------------------------------------------
 * Integrator statistics
 * ------------------------------------------------------------------------------------- */

md_result md_get_statistics(md_instance *m, const char *function, const md_vr vr[], size_t nvr,
                            int64_t values[], size_t nvalues) {
    const md_counters *count = &m->solver->count;
    if (check_arrays(m, function, vr, nvr, values, nvalues) != MD_RESULT_OK) {
        return MD_RESULT_ERROR;
    }
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] < MD_VR_STATISTICS || vr[i] >= MD_VR_STATISTICS + MD_NSTATISTICS) {
            return md_report(m, MD_RESULT_ERROR, "%s: no integer variable with value reference "
                             "%u (the integer variables are solver.steps, "
                             "solver.rejectedSteps and solver.events, %u to %u)", function,
                             vr[i], MD_VR_STATISTICS, MD_VR_STATISTICS + MD_NSTATISTICS - 1u);
        }
    }
    for (size_t i = 0; i < nvr; ++i) {
        switch ((int)(vr[i] - MD_VR_STATISTICS)) {
        case MD_STATISTIC_STEPS: values[i] = (int64_t)count->steps; break;
        case MD_STATISTIC_REJECTED: values[i] = (int64_t)count->rejected; break;
        default: values[i] = (int64_t)count->events; break;
        }
    }
    return MD_RESULT_OK;
}

/* ---------------------------------------------------------------------------------------
 * Model Exchange
 * ------------------------------------------------------------------------------------- */

int md_offers(int interface) {
    int offered = MD_INFO.interfaces != 0 ? MD_INFO.interfaces : MD_INTERFACE_CS;
    return (offered & interface) != 0;
}

static md_result check_vector(md_instance *m, const char *function, const void *x, size_t n,
                              int expected, const char *what) {
    if (n != (size_t)expected) {
        return md_report(m, MD_RESULT_ERROR, "%s: %lu %s given, this model has %d", function,
                         (unsigned long)n, what, expected);
    }
    if (n > 0 && x == NULL) { return md_report(m, MD_RESULT_ERROR, "%s: NULL array", function); }
    return MD_RESULT_OK;
}

md_result md_me_set_time(md_instance *m, const char *function, double time) {
    if (!isfinite(time)) {
        return md_report(m, MD_RESULT_ERROR, "%s: time %g is not finite", function, time);
    }
    md_solver_set_point(m->solver, time, NULL);
    m->obs_stale = 1;
    return MD_RESULT_OK;
}

md_result md_me_set_states(md_instance *m, const char *function, const double x[], size_t nx) {
    if (check_vector(m, function, x, nx, MD_INFO.ny, "states") != MD_RESULT_OK) {
        return MD_RESULT_ERROR;
    }
    for (size_t i = 0; i < nx; ++i) {
        if (!isfinite(x[i])) {
            return md_report(m, MD_RESULT_ERROR, "%s: state %lu is not finite (%g)", function,
                             (unsigned long)i, x[i]);
        }
    }
    md_solver_set_point(m->solver, m->solver->t, x);
    m->obs_stale = 1;
    return MD_RESULT_OK;
}

md_result md_me_get_states(md_instance *m, const char *function, double x[], size_t nx) {
    if (check_vector(m, function, x, nx, MD_INFO.ny, "states") != MD_RESULT_OK) {
        return MD_RESULT_ERROR;
    }
    if (nx > 0) { memcpy(x, m->solver->y, sizeof(double) * nx); }
    return MD_RESULT_OK;
}

md_result md_me_get_derivatives(md_instance *m, const char *function, double dx[], size_t nx) {
    if (check_vector(m, function, dx, nx, MD_INFO.ny, "derivatives") != MD_RESULT_OK) {
        return MD_RESULT_ERROR;
    }
    if (nx > 0 && md_solver_derivatives(m->solver, dx) != MD_OK) {
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(m->solver));
    }
    return MD_RESULT_OK;
}

md_result md_me_get_indicators(md_instance *m, const char *function, double z[], size_t nz) {
    if (check_vector(m, function, z, nz, MD_INFO.nz, "event indicators") != MD_RESULT_OK) {
        return MD_RESULT_ERROR;
    }
    if (nz > 0 && md_solver_indicators(m->solver, z) != MD_OK) {
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(m->solver));
    }
    return MD_RESULT_OK;
}

md_result md_me_get_nominals(md_instance *m, const char *function, double x[], size_t nx) {
    if (check_vector(m, function, x, nx, MD_INFO.ny, "nominals") != MD_RESULT_OK) {
        return MD_RESULT_ERROR;
    }
    for (size_t i = 0; i < nx; ++i) { x[i] = MD_INFO.nominal != NULL ? MD_INFO.nominal[i] : 1.0; }
    return MD_RESULT_OK;
}

md_result md_me_update_discrete_states(md_instance *m, const char *function,
                                       int *states_changed) {
    *states_changed = 0;
    if (md_solver_handle_events(m->solver, states_changed) != MD_OK) {
        m->mode = MD_MODE_ERROR;
        return md_report(m, MD_RESULT_ERROR, "%s: %s", function, md_solver_message(m->solver));
    }
    m->obs_stale = 0;
    return MD_RESULT_OK;
}

void md_me_completed_step(md_instance *m) { m->solver->count.steps++; }
