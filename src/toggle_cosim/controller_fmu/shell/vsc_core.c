/* toggle-cosim: the instance core of a sampled controller FMU (see vsc_core.h). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vsc_core.h"

static const char VSC_STATE_TAG[8] = {'T', 'g', 'V', 'S', 'C', 's', 't', '1'};

int vsc_log(const vsc_core *c, int status, const char *format, ...) {
    char message[1024];
    const char *category = "logEvents";
    unsigned bit = VSC_LOG_EVENTS;
    va_list args;
    if (status == VSC_WARNING) { category = "logStatusWarning"; bit = VSC_LOG_WARNING; }
    if (status >= VSC_DISCARD) { category = "logStatusError"; bit = VSC_LOG_ERROR; }
    /* errors are always reported; anything else only when logging is on for its category */
    if (status < VSC_DISCARD && !(c->logging_on && (c->categories & (bit | VSC_LOG_ALL)))) {
        return status;
    }
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    if (c->emit != NULL) { c->emit(c, status, category, message); }
    return status;
}

int vsc_set_categories(vsc_core *c, int on, size_t n, const char *const categories[]) {
    static const char *const names[] = {"logEvents", "logStatusWarning", "logStatusError", "logAll"};
    size_t i, j;
    unsigned mask = 0;
    c->logging_on = on;
    if (n == 0) { c->categories = VSC_LOG_EVENTS | VSC_LOG_WARNING | VSC_LOG_ERROR | VSC_LOG_ALL; return VSC_OK; }
    for (i = 0; i < n; i++) {
        for (j = 0; j < 4; j++) {
            if (categories[i] != NULL && strcmp(categories[i], names[j]) == 0) { mask |= 1u << j; break; }
        }
        if (j == 4) {
            return vsc_log(c, VSC_ERROR, "SetDebugLogging: unknown log category %s (the categories are "
                           "logEvents, logStatusWarning, logStatusError, logAll)",
                           categories[i] ? categories[i] : "(null)");
        }
    }
    c->categories = on ? (c->categories | mask) : (c->categories & ~mask);
    return VSC_OK;
}

void vsc_defaults(vsc_data *d) {
    size_t i;
    memset(d, 0, sizeof *d);
    for (i = 0; i < VSC_NIN; i++) { d->inputs[i] = vsc_in_start[i]; }
    for (i = 0; i < VSC_NPAR; i++) { *(double *)((char *)&d->law + vsc_par_offset[i]) = vsc_par_start[i]; }
    d->stale = 1;
    d->mode = VSC_INSTANTIATED;
}

vsc_core *vsc_new(const char *name, vsc_emit emit, const void *env, int logging_on) {
    vsc_core *c = calloc(1, sizeof *c);
    if (c == NULL) { return NULL; }
    c->name = malloc(strlen(name) + 1);
    if (c->name == NULL) { free(c); return NULL; }
    strcpy(c->name, name);
    c->emit = emit;
    c->env = env;
    c->logging_on = logging_on;
    /* logging on at instantiation: the status categories; a line per sample (logEvents, logAll)
       only when asked for by fmi2SetDebugLogging / fmi3SetDebugLogging */
    c->categories = VSC_LOG_WARNING | VSC_LOG_ERROR;
    vsc_defaults(&c->d);
    return c;
}

void vsc_free(vsc_core *c) {
    if (c == NULL) { return; }
    free(c->name);
    free(c);
}

static const char *const MODE_NAMES[] = {"Instantiated", "Initialization Mode", "Step Mode", "Terminated"};

int vsc_check_mode(const vsc_core *c, const char *function, unsigned allowed) {
    if (allowed & VSC_MODE_BIT(c->d.mode)) { return VSC_OK; }
    return vsc_log(c, VSC_ERROR, "%s: not allowed in %s", function, MODE_NAMES[c->d.mode]);
}

double vsc_time(const vsc_core *c) { return c->d.start_time + (double)c->d.k * VSC_SAMPLE_TIME(&c->d.law); }

int vsc_set_start(vsc_core *c, double start_time) {
    if (!isfinite(start_time)) {
        return vsc_log(c, VSC_ERROR, "the start time must be finite, got %.17g", start_time);
    }
    c->d.start_time = start_time;
    c->d.stale = 1;
    return VSC_OK;
}

int vsc_enter_initialization(vsc_core *c, const char *function) {
    int status = vsc_check_mode(c, function, VSC_MODE_BIT(VSC_INSTANTIATED));
    if (status != VSC_OK) { return status; }
    c->d.mode = VSC_INITIALIZATION;
    return VSC_OK;
}

int vsc_exit_initialization(vsc_core *c, const char *function) {
    size_t i;
    int status = vsc_check_mode(c, function, VSC_MODE_BIT(VSC_INITIALIZATION));
    if (status != VSC_OK) { return status; }
    for (i = 0; i < VSC_NPAR; i++) {
        double v = *(const double *)((const char *)&c->d.law + vsc_par_offset[i]);
        if (vsc_par_code[i] && v != floor(v)) {
            return vsc_log(c, VSC_ERROR, "%s: the parameter %s is a code (%s), got %.17g", function,
                           vsc_par_names[i], vsc_par_descriptions[i], v);
        }
    }
    if (!(VSC_SAMPLE_TIME(&c->d.law) > 0.0)) {
        return vsc_log(c, VSC_ERROR, "%s: the sample time T_s must be positive, got %.17g", function,
                       VSC_SAMPLE_TIME(&c->d.law));
    }
    c->d.mode = VSC_STEPPING;
    return VSC_OK;
}

/* The law at the present sample from the present inputs: the outputs, and at k = 0 the start. */
static int evaluate(vsc_core *c, const char *function) {
    vsc_data *d = &c->d;
    double t = vsc_time(c), out[VSC_NOUT];
    size_t iq = VSC_READS(&d->law, 0), iqd = VSC_READS(&d->law, 1), i;
    double q = d->inputs[iq], qd = d->inputs[iqd];
    int failed;
    if (d->k == 0) {
        double S0, T_h, z0;
        failed = vsc_law_start(q, qd, d->inputs + VSC_REF_IN, &d->law, &S0, &T_h, &z0) || !isfinite(S0) || !isfinite(T_h) || !isfinite(z0);
        if (!failed) {
            VSC_SET_START(&d->law, t, T_h);
            d->z = z0;
        }
    } else {
        failed = 0;
    }
    failed = failed || vsc_law_step(t, q, qd, d->z, d->inputs + VSC_REF_IN, &d->law, out);
    for (i = 0; i < VSC_NOUT && !failed; i++) { failed = !isfinite(out[i]); }
    if (failed) {
        return vsc_log(c, VSC_ERROR, "%s: the law cannot be evaluated at t = %.17g s (sample %lld) from "
                       "%s = %.17g %s, %s = %.17g %s: out of the nominal mechanism's reach, a division "
                       "by zero or a result that is not finite", function, t, d->k, vsc_in_names[iq], q,
                       vsc_in_units[iq], vsc_in_names[iqd], qd, vsc_in_units[iqd]);
    }
    memcpy(d->outputs, out, sizeof out);
    d->stale = 0;
    return VSC_OK;
}

static int unknown_reference(const vsc_core *c, const char *function, unsigned r) {
    return vsc_log(c, VSC_ERROR, "%s: no Float64 (Real) variable has the value reference %u", function, r);
}

int vsc_get(vsc_core *c, const char *function, const unsigned vr[], size_t n, double values[]) {
    size_t i;
    int status = VSC_OK;
    if (n > 0 && (vr == NULL || values == NULL)) { return vsc_log(c, VSC_ERROR, "%s: NULL array", function); }
    for (i = 0; i < n; i++) {
        unsigned r = vr[i];
        if (r >= VSC_VR_IN && r < VSC_VR_IN + VSC_NIN) {
            values[i] = c->d.inputs[r - VSC_VR_IN];
        } else if (r >= VSC_VR_OUT && r < VSC_VR_OUT + VSC_NOUT) {
            if (c->d.stale) {
                status = evaluate(c, function);
                if (status != VSC_OK) { return status; }
            }
            values[i] = c->d.outputs[r - VSC_VR_OUT];
        } else if (r >= VSC_VR_PAR && r < VSC_VR_PAR + VSC_NPAR) {
            values[i] = *(const double *)((const char *)&c->d.law + vsc_par_offset[r - VSC_VR_PAR]);
        } else if (r == VSC_VR_TIME && c->has_time) {
            values[i] = vsc_time(c);
        } else {
            return unknown_reference(c, function, r);
        }
    }
    return VSC_OK;
}

int vsc_set(vsc_core *c, const char *function, const unsigned vr[], size_t n, const double values[]) {
    size_t i;
    if (n > 0 && (vr == NULL || values == NULL)) { return vsc_log(c, VSC_ERROR, "%s: NULL array", function); }
    /* check everything first: a refused call changes nothing */
    for (i = 0; i < n; i++) {
        unsigned r = vr[i];
        double v = values[i];
        if (r >= VSC_VR_IN && r < VSC_VR_IN + VSC_NIN) {
            if (c->d.mode == VSC_TERMINATED) {
                return vsc_log(c, VSC_ERROR, "%s: inputs cannot be set after Terminate", function);
            }
        } else if (r >= VSC_VR_PAR && r < VSC_VR_PAR + VSC_NPAR) {
            size_t j = r - VSC_VR_PAR;
            if (c->d.mode != VSC_INSTANTIATED && c->d.mode != VSC_INITIALIZATION) {
                return vsc_log(c, VSC_ERROR, "%s: the parameter %s is fixed: it can be set only before "
                               "ExitInitializationMode", function, vsc_par_names[j]);
            }
            if (!isfinite(v) || v < vsc_par_min[j] || v > vsc_par_max[j]) {
                return vsc_log(c, VSC_ERROR, "%s: %s = %.17g is out of its range [%.17g, %.17g]", function,
                               vsc_par_names[j], v, vsc_par_min[j], vsc_par_max[j]);
            }
        } else if (r >= VSC_VR_OUT && r < VSC_VR_OUT + VSC_NOUT) {
            return vsc_log(c, VSC_ERROR, "%s: %s is an output and cannot be set", function,
                           vsc_out_names[r - VSC_VR_OUT]);
        } else if (r == VSC_VR_TIME && c->has_time) {
            return vsc_log(c, VSC_ERROR, "%s: time is the independent variable and cannot be set", function);
        } else {
            return unknown_reference(c, function, r);
        }
    }
    for (i = 0; i < n; i++) {
        unsigned r = vr[i];
        if (r < VSC_VR_IN + VSC_NIN) {
            c->d.inputs[r - VSC_VR_IN] = values[i];
        } else {
            *(double *)((char *)&c->d.law + vsc_par_offset[r - VSC_VR_PAR]) = values[i];
        }
    }
    if (n > 0) { c->d.stale = 1; }
    return VSC_OK;
}

int vsc_do_step(vsc_core *c, const char *function, double t, double h) {
    double T_s = VSC_SAMPLE_TIME(&c->d.law), t_k = vsc_time(c);
    int status = vsc_check_mode(c, function, VSC_MODE_BIT(VSC_STEPPING));
    if (status != VSC_OK) { return status; }
    if (!(fabs(h - T_s) <= 1e-9 * T_s)) {
        return vsc_log(c, VSC_ERROR, "%s: the communication step size h = %.17g s is not the sample time "
                       "T_s = %.17g s; this controller samples every T_s and steps by T_s only",
                       function, h, T_s);
    }
    if (!(fabs(t - t_k) <= 1e-6 * T_s)) {
        return vsc_log(c, VSC_ERROR, "%s: the communication point t = %.17g s is not the FMU's time "
                       "t_k = %.17g s (sample %lld, t_k = startTime + k T_s)", function, t, t_k, c->d.k);
    }
    if (c->d.stale) {
        status = evaluate(c, function);
        if (status != VSC_OK) { return status; }
    }
    c->d.z = c->d.outputs[VSC_NOUT - 1];  /* commit z_{k+1} */
    c->d.k += 1;
    vsc_log(c, VSC_OK, "%s: sample %lld taken at t = %.17g s, u = %.17g", function, c->d.k - 1, t_k,
            c->d.outputs[0]);
    return VSC_OK;
}

int vsc_terminate(vsc_core *c, const char *function) {
    int status = vsc_check_mode(c, function, VSC_MODE_BIT(VSC_STEPPING) | VSC_MODE_BIT(VSC_INITIALIZATION));
    if (status != VSC_OK) { return status; }
    c->d.mode = VSC_TERMINATED;
    return VSC_OK;
}

void vsc_reset(vsc_core *c) { vsc_defaults(&c->d); }

int vsc_get_state(vsc_core *c, const char *function, void **state) {
    if (state == NULL) { return vsc_log(c, VSC_ERROR, "%s: NULL state pointer", function); }
    if (*state == NULL) {
        *state = malloc(sizeof(vsc_data));
        if (*state == NULL) { return vsc_log(c, VSC_ERROR, "%s: out of memory", function); }
    }
    memcpy(*state, &c->d, sizeof(vsc_data));
    return VSC_OK;
}

int vsc_set_state(vsc_core *c, const char *function, const void *state) {
    if (state == NULL) { return vsc_log(c, VSC_ERROR, "%s: NULL state", function); }
    memcpy(&c->d, state, sizeof(vsc_data));
    return VSC_OK;
}

void vsc_free_state(void *state) { free(state); }

size_t vsc_serialized_size(void) { return sizeof VSC_STATE_TAG + sizeof(vsc_data); }

int vsc_serialize(vsc_core *c, const char *function, const void *state, unsigned char out[], size_t size) {
    if (state == NULL || out == NULL) { return vsc_log(c, VSC_ERROR, "%s: NULL state or buffer", function); }
    if (size < vsc_serialized_size()) {
        return vsc_log(c, VSC_ERROR, "%s: the buffer holds %zu bytes, a state needs %zu", function, size,
                       vsc_serialized_size());
    }
    memcpy(out, VSC_STATE_TAG, sizeof VSC_STATE_TAG);
    memcpy(out + sizeof VSC_STATE_TAG, state, sizeof(vsc_data));
    return VSC_OK;
}

int vsc_deserialize(vsc_core *c, const char *function, const unsigned char in[], size_t size, void **state) {
    vsc_data d;
    if (in == NULL || state == NULL) { return vsc_log(c, VSC_ERROR, "%s: NULL state or buffer", function); }
    if (size != vsc_serialized_size() || memcmp(in, VSC_STATE_TAG, sizeof VSC_STATE_TAG) != 0) {
        return vsc_log(c, VSC_ERROR, "%s: not a state of this FMU (%zu bytes; a state has %zu and starts "
                       "with its tag)", function, size, vsc_serialized_size());
    }
    memcpy(&d, in + sizeof VSC_STATE_TAG, sizeof d);
    if (d.mode < VSC_INSTANTIATED || d.mode > VSC_TERMINATED || d.k < 0) {
        return vsc_log(c, VSC_ERROR, "%s: the serialized state is damaged", function);
    }
    if (*state == NULL) {
        *state = malloc(sizeof(vsc_data));
        if (*state == NULL) { return vsc_log(c, VSC_ERROR, "%s: out of memory", function); }
    }
    memcpy(*state, &d, sizeof d);
    return VSC_OK;
}
