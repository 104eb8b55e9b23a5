/* toggle-cosim: a system's stepping plan run in C (cosim/execution/system_loop.py builds the tables from a
   system.plan.Plan and calls system_run). No physics, no law: FMUs called through their function
   pointers, values moved between their slots in one flat buffer.

   One sample k (system/plan.py's docstring; under Jacobi no input is early):
       for each component c in order:  compute and set c's early inputs (one setReal);  get c's
                                       outputs (one getReal)
       compute the late inputs;  record row k;  if k < n: set each component's late inputs
       (one setReal each), then doStep every component from t_k = k T_s over T_s.
   An input's value is its feed: a copy of an output slot (factor 1, offset 0), factor * slot +
   offset (compiled with -ffp-contract=off: Python's bits), or column j of the signal table's row k.
   A component's outputs of other types (a recorded Integer, Boolean, ...) follow its Real ones:
   each is read by its own getter after the getReal and stored as a double (get_typed).

   A component is an FMU (its function pointers) or a native controller (native_t, NULL for an
   FMU): the built-in law (NATIVE_LAW: law_step, generated from control/laws.py in front of this
   skeleton by cosim/execution/system_loop.py) or a discrete LTI system (NATIVE_LTI: lti_sums, the sums of
   control/lti.py's lti_step). A native controller samples as cosim/execution/slaves.py's ControllerSlave
   does: a set stores its inputs and marks it dirty; its outputs are computed from the inputs as
   set, at the time of the first get or doStep after the set, and held; a doStep commits the state
   that computation gave. Where the Python might raise or a value is not finite, the loop stops
   with HAND_BACK at that sample before any doStep of it, and the saved copy (`saved`: what the
   controller held at the sample's start) lets the Python execution take the sample from its start.

   A component run in Python (a user's Python controller: cosim/execution/system_python.py's callback) is
   called back once a sample, at its early turn, its early inputs computed into its scratch as for
   an FMU: the callback sets its early inputs and gets its outputs into their buffer slots. Its
   late inputs and its doStep of sample k are its own calls too, in the same order, made by the
   same callback at sample k + 1 before the rest (CALL_AFTER_STEP: `pending`; the late values stay
   in their buffer slots until then), or by the Python once the loop returns. So the component
   sees the calls and values the Python execution makes, one callback a sample. The callback sets
   *s->answered to 1 when the call is done; anything else (the Python raised, or an interrupt
   landed in the callback) stops the loop with RAISED at that sample, and the Python raises what
   it caught.

   The finiteness guard (cosim/execution/guard.py): a component with guarded slots has its
   computed inputs checked before they are set (early and late) and its outputs after they are
   read; the first guarded value that is not finite stops the loop with NOT_FINITE at that
   sample, before the call that would pass it on, as the Python execution checks it. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef int (*get2_t)(void *, const unsigned int *, size_t, double *);
typedef int (*set2_t)(void *, const unsigned int *, size_t, const double *);
typedef int (*step2_t)(void *, double, double, int);
typedef int (*get3_t)(void *, const unsigned int *, size_t, double *, size_t);
typedef int (*set3_t)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*step3_t)(void *, double, double, bool, bool *, bool *, bool *, double *);
typedef void (*python_t)(long, long, long); /* (component, CALL_EARLY [| CALL_AFTER_STEP], k) */

/* A native controller's kinds, and its memory: mem = dirty, held[n_held] (the command, then the
   diagnostics), row[n_in] (its fed inputs as set, in plan order), next[n_state] (the state its
   last computation gave); saved: mem at the start of the sample. */
enum { NATIVE_LAW = 1, NATIVE_LTI = 2 };

typedef struct {
    long kind;                  /* NATIVE_LAW or NATIVE_LTI */
    long n_in, n_held, n_state; /* its fed inputs, its outputs, its state's size (the law: 1, z; LTI: n, x) */
    long i_q, i_qd;             /* the inputs it reads: the law's q and qd; the LTI system's y (i_q) */
    long m;                     /* NATIVE_LTI: its inputs (1: e = r - y; 2: r - y0, y - y0) */
    const long *early_pos, *late_pos; /* the positions among its inputs of its early and late inputs */
    double *mem, *saved;
    double *state;              /* n_state: the committed state */
    const double *ref;          /* (n + 1) x 3: (q*, q̇*, q̈*) per sample; NULL: the constant target */
    const double *a, *b, *c, *d; /* NATIVE_LTI: A (n x n), B (n x m) row by row, C (n), D (m) */
    double target, origin;      /* NATIVE_LTI: the constant r; y0, its output at the first sample */
    law_t law;                  /* NATIVE_LAW: its parameters, with its start's t0 and T_h */
} native_t;

/* One component of the table. Its ctypes mirror is built in cosim/execution/system_loop.py from the same
   field lists. */
typedef struct {
    void *get, *set, *step, *component;
    const unsigned int *out_vr;                 /* n_out: its outputs, in plan order */
    const unsigned int *early_vr, *late_vr;     /* n_early, n_late: its fed inputs set early / late */
    const long *early_slot, *late_slot;         /* their buffer slots */
    double *scratch;                            /* max(n_early, n_late) values, gathered for one setReal */
    void *const *typed_get;                     /* n_typed: the getter of each output of another type */
    const unsigned int *typed_vr;               /* its value reference */
    const long *typed_kind, *typed_slot;        /* its kind (get_typed) and buffer slot */
    long fmi3, n_out, out0, n_early, n_late;    /* n_out Real outputs; out0: the buffer slot of the first */
    long id;                                    /* what *calling holds while it is called */
    long n_typed;
    native_t *native;                           /* NULL: an FMU */
    void *python;                               /* a python_t: the component runs in Python (NULL: not) */
    long pending;                               /* its late inputs and doStep of the last sample are still to make */
    long guard;                                 /* 1: some of its slots are guarded (system_t's guarded) */
} component_t;

typedef struct {
    component_t *components;
    double *buffer;             /* size values: per component its outputs, then its fed inputs */
    const long *source;         /* per slot: the feeding slot, or -1 - j for signal column j */
    const double *factor, *offset;
    const double *signals;      /* (n + 1) x n_signals, row by row */
    double *trace;              /* (n + 1) x (1 + n_record), row by row */
    const long *record;         /* the recorded slots */
    long long *rows;            /* the samples recorded, set after each whole row (NULL: not counted here);
                                   a supervising process reads it, never the row's values */
    long n_components, n_signals, n_record, n;
    long k, failed, fault, status; /* next sample; on a failure the component, the call (1 get, 2 set, 3 step,
                                      4 + i its typed read i), its status */
    long no_prior;              /* doStep's noSetFMUStatePriorToCurrentPoint, for every component */
    double T_s;
    long long *calling;         /* the id of the component being called, written before each call: a
                                   supervising process reads it when a call ends the process */
    long long *answered;        /* set to 0 before a callback of a component run in Python, to 1 by it when done */
    const long *guarded;        /* per slot, 1: its value must be finite (cosim/execution/guard.py) */
} system_t;

enum { DONE = 0, HAND_BACK = 1, FMI_FAILED = 2, RAISED = 3, NOT_FINITE = 4 };
enum { CALL_GET = 1, CALL_SET = 2, CALL_STEP = 3, CALL_TYPED = 4 };
enum { CALL_EARLY = 1, CALL_AFTER_STEP = 2 }; /* a component run in Python: its callback's call */

/* Only OK (0) and Warning (1) let the loop go on: Discard, Error, Fatal, Pending and any value
   the standard does not define fail the run. */
#define FAILED(status) ((status) != 0 && (status) != 1)

static int get_outputs(const component_t *c, double *values) {
    size_t n = (size_t)c->n_out;
    return c->fmi3 ? ((get3_t)c->get)(c->component, c->out_vr, n, values, n)
                   : ((get2_t)c->get)(c->component, c->out_vr, n, values);
}

/* One value of another type than Real, by its getter, as a double (the kind codes of
   cosim/execution/fmi_pointers.py's KINDS: 0 an FMI 2.0 Integer, Enumeration or Boolean, all ints; then FMI
   3.0's Int8, UInt8, Int16, UInt16, Int32, UInt32, Int64 (and Enumeration), UInt64, Boolean, Float32). */
#define GET3(type) { type v = 0; status = ((int (*)(void *, const unsigned int *, size_t, type *, size_t))f)( \
                         c->component, vr, 1, &v, 1); *value = (double)v; return status; }
static int get_typed(const component_t *c, long i, double *value) {
    void *f = c->typed_get[i];
    const unsigned int *vr = c->typed_vr + i;
    int status;
    switch (c->typed_kind[i]) {
    case 0: { int v = 0; status = ((int (*)(void *, const unsigned int *, size_t, int *))f)(c->component, vr, 1, &v);
              *value = (double)v; return status; }
    case 1: GET3(int8_t)
    case 2: GET3(uint8_t)
    case 3: GET3(int16_t)
    case 4: GET3(uint16_t)
    case 5: GET3(int32_t)
    case 6: GET3(uint32_t)
    case 7: GET3(int64_t)
    case 8: GET3(uint64_t)
    case 9: GET3(bool)
    case 10: GET3(float)
    default: return 3; /* fmi2Error: a kind this loop does not know */
    }
}

static int set_inputs(const component_t *c, const unsigned int *vr, long count, const double *values) {
    size_t n = (size_t)count;
    return c->fmi3 ? ((set3_t)c->set)(c->component, vr, n, values, n)
                   : ((set2_t)c->set)(c->component, vr, n, values);
}

static int do_step(const component_t *c, double t, double h, bool no_prior) {
    bool event, terminate, early;
    double last;
    return c->fmi3 ? ((step3_t)c->step)(c->component, t, h, no_prior, &event, &terminate, &early, &last)
                   : ((step2_t)c->step)(c->component, t, h, no_prior ? 1 : 0);
}

/* The value the feed of `slot` gives at sample k (row: the signal table's row k). */
static double feed(const system_t *s, long slot, const double *row) {
    long from = s->source[slot];
    double f, o;
    if (from < 0) { return row[-1 - from]; }
    f = s->factor[slot];
    o = s->offset[slot];
    if (f == 1.0 && o == 0.0) { return s->buffer[from]; }
    return f * s->buffer[from] + o;
}

/* Compute the inputs at `slots` into the buffer and gather them into the component's scratch. */
static void compute(system_t *s, const component_t *c, const long *slots, long count, const double *row) {
    long i;
    for (i = 0; i < count; i++) {
        double value = feed(s, slots[i], row);
        s->buffer[slots[i]] = value;
        c->scratch[i] = value;
    }
}

static int fail(system_t *s, long k, long component, long call, int status) {
    s->k = k;
    s->failed = component;
    s->fault = call;
    s->status = status;
    return FMI_FAILED;
}

#define MEM_SIZE(p) (1 + (p)->n_held + (p)->n_in + (p)->n_state)

/* The native controller's outputs and next state at sample k (time t) from its inputs as set:
   control/controller.py's VSCController.step (law_step) or control/lti.py's
   DiscreteSystemController.step (lti_sums). Returns DONE (held, next written; no longer dirty) or
   HAND_BACK (the Python must take the sample: it raises, might raise, or a value is not finite). */
static int native_compute(native_t *p, long k, double t) {
    double *held = p->mem + 1, *row = held + p->n_held, *next = row + p->n_in;
    long i;
    if (p->kind == NATIVE_LAW) {
        const double *ref = p->ref ? p->ref + 3 * k : NULL;
        double q = row[p->i_q], qd = row[p->i_qd];
        if (!(isfinite(q) && isfinite(qd))) { return HAND_BACK; }
        if (law_step(t, q, qd, p->state[0], ref ? ref[0] : p->law.target, ref ? ref[1] : 0.0, ref ? ref[2] : 0.0,
                     &p->law, &held[0], &held[1], &held[2], &held[3], &next[0])) {
            return HAND_BACK;
        }
    } else {
        double r = p->ref ? p->ref[3 * k] : p->target, y = row[p->i_q], e = r - y, v[2];
        if (!isfinite(e)) { return HAND_BACK; }
        v[0] = p->m == 1 ? e : r - p->origin;
        v[1] = y - p->origin;
        if (lti_sums(p->n_state, p->m, p->a, p->b, p->c, p->d, p->state, v, &held[0], next)) { return HAND_BACK; }
        held[1] = e;
    }
    for (i = 0; i < p->n_held; i++) {
        if (!isfinite(held[i])) { return HAND_BACK; }
    }
    for (i = 0; i < p->n_state; i++) {
        if (!isfinite(next[i])) { return HAND_BACK; }
    }
    p->mem[0] = 0.0;
    return DONE;
}

/* A native controller's set: the values stored at their positions among its inputs; dirty. */
static void native_set(native_t *p, const long *pos, long count, const double *values) {
    double *row = p->mem + 1 + p->n_held;
    long i;
    for (i = 0; i < count; i++) { row[pos[i]] = values[i]; }
    p->mem[0] = 1.0;
}

/* Call back the component c run in Python at its early turn of sample k (first its late inputs and
   doStep of sample k - 1 when pending): DONE, or RAISED (s->k, s->failed set) when the callback
   did not say it was done. */
static int call_python(system_t *s, component_t *p, long c, long k) {
    long call = CALL_EARLY | (p->pending ? CALL_AFTER_STEP : 0);
    p->pending = 0;
    *s->answered = 0;
    ((python_t)p->python)(c, call, k);
    if (*s->answered == 1) { return DONE; }
    s->k = k;
    s->failed = c;
    return RAISED;
}

/* The finiteness guard (cosim/execution/guard.py): the first of `count` slots from `first` (or,
   `slots` not NULL, of slots[0 .. count - 1]) that is guarded and holds a value that is not
   finite, or -1. */
static long unguarded(const system_t *s, const long *slots, long first, long count) {
    long i;
    for (i = 0; i < count; i++) {
        long slot = slots ? slots[i] : first + i;
        if (s->guarded[slot] && !isfinite(s->buffer[slot])) { return slot; }
    }
    return -1;
}

/* The guard refused the value of `slot`, set on or read from component c at sample k: NOT_FINITE,
   s->k, s->failed and s->fault (the slot) naming it. */
static int refuse(system_t *s, long k, long c, long slot) {
    s->k = k;
    s->failed = c;
    s->fault = slot;
    return NOT_FINITE;
}

static int hand_back(system_t *s, long k, long component) {
    s->k = k;
    s->failed = component;
    return HAND_BACK;
}

/* Samples s->k .. k_end - 1 (module comment). Returns DONE with s->k = k_end, FMI_FAILED with
   s->k the sample of the failed call (its row not recorded when the call came before recording)
   and s->failed, s->fault, s->status naming it (nothing after a failed call is made), or HAND_BACK
   with s->k the sample a native controller s->failed hands to the Python (no doStep of it made;
   each native controller's `saved` is what it held at that sample's start), or RAISED with s->k the
   sample at which a component run in Python s->failed raised (call_python), or NOT_FINITE with s->k
   the sample at which the guard refused the value of the slot s->fault of component s->failed,
   before it was set or, an output, passed on (refuse). */
int system_run(system_t *s, long k_end) {
    long k, i, c, bad;
    int status;
    for (k = s->k; k < k_end; k++) {
        const double *row = s->signals + k * s->n_signals;
        double t = (double)k * s->T_s, *out = s->trace + k * (1 + s->n_record);
        for (c = 0; c < s->n_components; c++) {
            native_t *native = s->components[c].native;
            if (native) {
                for (i = 0; i < MEM_SIZE(native); i++) { native->saved[i] = native->mem[i]; }
            }
        }
        for (c = 0; c < s->n_components; c++) {
            component_t *p = &s->components[c];
            *s->calling = p->id;
            if (p->n_early) {
                compute(s, p, p->early_slot, p->n_early, row);
                if (p->guard && (bad = unguarded(s, p->early_slot, 0, p->n_early)) >= 0) { return refuse(s, k, c, bad); }
            }
            if (p->native) {
                if (p->n_early) {
                    native_set(p->native, p->native->early_pos, p->n_early, p->scratch);
                }
                if (p->native->mem[0] != 0.0 && native_compute(p->native, k, t) != DONE) { return hand_back(s, k, c); }
                for (i = 0; i < p->n_out; i++) { s->buffer[p->out0 + i] = p->native->mem[1 + i]; }
                continue;
            }
            if (p->python) {
                if (call_python(s, p, c, k) != DONE) { return RAISED; }
                if (p->guard && (bad = unguarded(s, NULL, p->out0, p->n_out)) >= 0) { return refuse(s, k, c, bad); }
                continue;
            }
            if (p->n_early) {
                status = set_inputs(p, p->early_vr, p->n_early, p->scratch);
                if (FAILED(status)) { return fail(s, k, c, CALL_SET, status); }
            }
            if (p->n_out) {
                status = get_outputs(p, s->buffer + p->out0);
                if (FAILED(status)) { return fail(s, k, c, CALL_GET, status); }
            }
            for (i = 0; i < p->n_typed; i++) {
                status = get_typed(p, i, s->buffer + p->typed_slot[i]);
                if (FAILED(status)) { return fail(s, k, c, CALL_TYPED + i, status); }
            }
            if (p->guard && (bad = unguarded(s, NULL, p->out0, p->n_out)) >= 0) { return refuse(s, k, c, bad); }
        }
        for (c = 0; c < s->n_components; c++) {
            component_t *p = &s->components[c];
            for (i = 0; i < p->n_late; i++) { s->buffer[p->late_slot[i]] = feed(s, p->late_slot[i], row); }
        }
        out[0] = t;
        for (i = 0; i < s->n_record; i++) { out[1 + i] = s->buffer[s->record[i]]; }
        if (s->rows) { *s->rows = k + 1; }
        if (k == s->n) { s->k = k + 1; return DONE; }
        for (c = 0; c < s->n_components; c++) {
            component_t *p = &s->components[c];
            if (p->guard && (bad = unguarded(s, p->late_slot, 0, p->n_late)) >= 0) { return refuse(s, k, c, bad); }
            if (p->n_late && !p->python) { /* a component run in Python: set with its doStep (pending) */
                *s->calling = p->id;
                for (i = 0; i < p->n_late; i++) { p->scratch[i] = s->buffer[p->late_slot[i]]; }
                if (p->native) {
                    native_set(p->native, p->native->late_pos, p->n_late, p->scratch);
                    continue;
                }
                status = set_inputs(p, p->late_vr, p->n_late, p->scratch);
                if (FAILED(status)) { return fail(s, k, c, CALL_SET, status); }
            }
        }
        /* a native controller set since its last computation computes now, before any doStep of
           the sample, so a sample it hands back has stepped nothing */
        for (c = 0; c < s->n_components; c++) {
            native_t *native = s->components[c].native;
            if (native && native->mem[0] != 0.0) {
                *s->calling = s->components[c].id;
                if (native_compute(native, k, t) != DONE) { return hand_back(s, k, c); }
            }
        }
        for (c = 0; c < s->n_components; c++) {
            native_t *native = s->components[c].native;
            *s->calling = s->components[c].id;
            if (native) {
                for (i = 0; i < native->n_state; i++) { native->state[i] = native->mem[1 + native->n_held + native->n_in + i]; }
                continue;
            }
            if (s->components[c].python) {
                s->components[c].pending = 1; /* its late inputs and doStep, at its next call */
                continue;
            }
            status = do_step(&s->components[c], t, s->T_s, s->no_prior != 0);
            if (FAILED(status)) { return fail(s, k, c, CALL_STEP, status); }
        }
    }
    s->k = k_end;
    return DONE;
}
