/* toggle-cosim: a system's stepping plan run in C (cosim/system_loop.py builds the tables from a
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
   each is read by its own getter after the getReal and stored as a double (get_typed). */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef int (*get2_t)(void *, const unsigned int *, size_t, double *);
typedef int (*set2_t)(void *, const unsigned int *, size_t, const double *);
typedef int (*step2_t)(void *, double, double, int);
typedef int (*get3_t)(void *, const unsigned int *, size_t, double *, size_t);
typedef int (*set3_t)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*step3_t)(void *, double, double, bool, bool *, bool *, bool *, double *);

/* One component of the table. Its ctypes mirror is built in cosim/system_loop.py from the same
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
} system_t;

enum { DONE = 0, FMI_FAILED = 2 };
enum { CALL_GET = 1, CALL_SET = 2, CALL_STEP = 3, CALL_TYPED = 4 };

/* Only OK (0) and Warning (1) let the loop go on: Discard, Error, Fatal, Pending and any value
   the standard does not define fail the run. */
#define FAILED(status) ((status) != 0 && (status) != 1)

static int get_outputs(const component_t *c, double *values) {
    size_t n = (size_t)c->n_out;
    return c->fmi3 ? ((get3_t)c->get)(c->component, c->out_vr, n, values, n)
                   : ((get2_t)c->get)(c->component, c->out_vr, n, values);
}

/* One value of another type than Real, by its getter, as a double (the kind codes of
   cosim/fmi_pointers.py's KINDS: 0 an FMI 2.0 Integer, Enumeration or Boolean, all ints; then FMI
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

/* Samples s->k .. k_end - 1 (module comment). Returns DONE with s->k = k_end, or FMI_FAILED with
   s->k the sample of the failed call (its row not recorded when the call came before recording)
   and s->failed, s->fault, s->status naming it; nothing after a failed call is made. */
int system_run(system_t *s, long k_end) {
    long k, i, c;
    int status;
    for (k = s->k; k < k_end; k++) {
        const double *row = s->signals + k * s->n_signals;
        double t = (double)k * s->T_s, *out = s->trace + k * (1 + s->n_record);
        for (c = 0; c < s->n_components; c++) {
            component_t *p = &s->components[c];
            *s->calling = p->id;
            if (p->n_early) {
                compute(s, p, p->early_slot, p->n_early, row);
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
            if (p->n_late) {
                *s->calling = p->id;
                for (i = 0; i < p->n_late; i++) { p->scratch[i] = s->buffer[p->late_slot[i]]; }
                status = set_inputs(p, p->late_vr, p->n_late, p->scratch);
                if (FAILED(status)) { return fail(s, k, c, CALL_SET, status); }
            }
        }
        for (c = 0; c < s->n_components; c++) {
            *s->calling = s->components[c].id;
            status = do_step(&s->components[c], t, s->T_s, s->no_prior != 0);
            if (FAILED(status)) { return fail(s, k, c, CALL_STEP, status); }
        }
    }
    s->k = k_end;
    return DONE;
}
