/* toggle-cosim: the co-simulation loop in C, a skeleton with no physics and no control law.
   cosim/compiled_loop.py puts the law in front of it: the struct law_t and the function law_step,
   both generated from their Python definition (control/laws.py, control/translate.py).
   Per sample k: read the plant FMU's outputs into the trace row, control, record, set the
   plant's inputs (the command, then the load row k: F_E and the plant's other inputs, sampled
   from their signals before the run), doStep. The controller is one of three kinds: the generated law (CTRL_LAW),
   a controller FMU called through its function pointers (CTRL_FMU) in the order
   cosim/fmu_controller.py's FmuController.step calls it: the previous sample's doStep (deferred
   to this sample), set its inputs from the row, get iq_ref and its diagnostics; or a discrete
   LTI system (CTRL_LTI), u = C x + D v, x <- A x + B v on its inputs v: the error e = r - y of one
   plant output y (one input) or (r - y0, y - y0) (two; y0 the output at the first sample), r the
   reference row's q* or the constant target,
   summed in the order of control/lti.py's lti_step (lti_sums, control/lti_sums.c). plant_exchange is the plant's part of one sample
   for the Python loop (cosim/stepper.py's PythonStepper). */
#include <stdbool.h>
#include <stddef.h>

typedef int (*get2_t)(void *, const unsigned int *, size_t, double *);
typedef int (*set2_t)(void *, const unsigned int *, size_t, const double *);
typedef int (*step2_t)(void *, double, double, int);
typedef int (*get3_t)(void *, const unsigned int *, size_t, double *, size_t);
typedef int (*set3_t)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*step3_t)(void *, double, double, bool, bool *, bool *, bool *, double *);

/* One FMU's hot functions and instance (the plant, or a controller FMU). */
typedef struct {
    void *get, *set, *step, *component;
    const unsigned int *out_vr, *in_vr;
    long fmi3;
} fmu_t;

/* Its ctypes mirror is built in cosim/compiled_loop.py from the same field lists. */
typedef struct {
    fmu_t plant, ctrl;      /* ctrl: the controller FMU (CTRL_FMU only) */
    double *data;
    const double *load;     /* per sample 0 .. n, n_load values: F_E, then the plant's other inputs */
    const double *ref;      /* per sample 0 .. n, the law's reference (r, rd, rdd): q*, its rate, its acceleration;
                               NULL: CTRL_LAW reads (law.target, 0, 0) */
    double *plant_in;       /* the plant's inputs as sent: the command, then the load row (1 + n_load) */
    const long *ctrl_cols;  /* CTRL_FMU: the row's columns of the controller's inputs; -1 - i: ref's value i */
    double *ctrl_in, *ctrl_out; /* CTRL_FMU: its input values, its outputs (iq_ref, diagnostics) */
    const double *lti_a, *lti_b, *lti_c, *lti_d; /* CTRL_LTI: A (n x n), B (n x m), row by row; C (n); D (m) */
    double *lti_x, *lti_xn; /* CTRL_LTI: the state at sample k, the next state (scratch) */
    long long *rows;        /* the samples recorded, set after each whole row (NULL: not counted here);
                               a supervising process reads it, never the row's values */
    long n_out, ncols, i_q, i_qd, col_u, n;  /* i_q, i_qd: the columns the law reads (x_B, v_B or theta1, omega1) */
    long n_load, col_x;     /* load values per sample; the trace column of the first input after F_E */
    long k, fault, status;  /* next sample; the failed FMI function (1 get, 2 set, 3 step; + 3 for the controller FMU), its status */
    long no_prior;          /* doStep's noSetFMUStatePriorToCurrentPoint: 1 only if no checkpoint is restored */
    long kind;              /* CTRL_LAW or CTRL_FMU */
    long ctrl_n_in, ctrl_n_out, ctrl_due; /* CTRL_FMU: counts; 1 when the doStep from ctrl_t is due */
    long lti_n, lti_m, lti_col; /* CTRL_LTI: the numbers of states and inputs (1: e; 2: r, y); the row's column of y */
    double T_s, z;          /* z: the law's state (an integrator) at sample k */
    double ctrl_t;          /* CTRL_FMU: the time of the sample its last outputs were read at */
    double lti_target;      /* CTRL_LTI: the reference r without ref (with ref: ref's q* of the sample) */
    double lti_origin;      /* CTRL_LTI: y0, the output at the first sample (two inputs: r - y0, y - y0) */
    law_t law;
} kernel_t;

enum { DONE = 0, HAND_BACK = 1, FMI_FAILED = 2, CONTROLLER_FAILED = 3, COMMAND_REJECTED = 4 };
enum { CTRL_LAW = 0, CTRL_FMU = 1, CTRL_LTI = 2 };

/* Only OK (0) and Warning (1) let the loop go on: Discard, Error, Fatal, Pending and any value
   the standard does not define (a negative one, 5, ...) fail the run. */
#define FAILED(status) ((status) != 0 && (status) != 1)

static int fmu_get(const fmu_t *f, size_t n, double *values) {
    return f->fmi3 ? ((get3_t)f->get)(f->component, f->out_vr, n, values, n)
                   : ((get2_t)f->get)(f->component, f->out_vr, n, values);
}

static int fmu_set(const fmu_t *f, size_t n, const double *values) {
    return f->fmi3 ? ((set3_t)f->set)(f->component, f->in_vr, n, values, n)
                   : ((set2_t)f->set)(f->component, f->in_vr, n, values);
}

static int fmu_step(const fmu_t *f, double t, double h, bool no_prior) {
    bool event, terminate, early;
    double last;
    return f->fmi3 ? ((step3_t)f->step)(f->component, t, h, no_prior, &event, &terminate, &early, &last)
                   : ((step2_t)f->step)(f->component, t, h, no_prior ? 1 : 0);
}

/* One law sample from the measured coordinate and rate (q, qd) and the reference (r, rd, rdd):
   out = (u, S, phase, e, z_next). Returns 0, or 1 where the Python must evaluate the sample
   itself (it raises there, or a result is not finite). */
int kernel_control(const kernel_t *s, double t, double q, double qd, double z, double r, double rd, double rdd,
                   double out[5]) {
    int i;
    if (!(isfinite(q) && isfinite(qd))) { return 1; }
    if (law_step(t, q, qd, z, r, rd, rdd, &s->law, &out[0], &out[1], &out[2], &out[3], &out[4])) { return 1; }
    for (i = 0; i < 5; i++) {
        if (!isfinite(out[i])) { return 1; }
    }
    return 0;
}

/* The controller FMU's sample at t from the row: its deferred doStep, its inputs set, its
   outputs read into s->ctrl_out. Returns DONE, HAND_BACK (non-finite plant outputs: nothing
   sent to the controller), CONTROLLER_FAILED (s->fault, s->status say which call) or
   COMMAND_REJECTED (a command that is not finite). */
static int fmu_control(kernel_t *s, double t, const double *row, long k) {
    long j;
    int status;
    if (!(isfinite(row[s->i_q]) && isfinite(row[s->i_qd]))) { return HAND_BACK; }
    if (s->ctrl_due) {
        status = fmu_step(&s->ctrl, s->ctrl_t, s->T_s, false);
        if (FAILED(status)) { s->fault = 6; s->status = status; return CONTROLLER_FAILED; }
        s->ctrl_due = 0;
    }
    for (j = 0; j < s->ctrl_n_in; j++) {
        s->ctrl_in[j] = s->ctrl_cols[j] >= 0 ? row[s->ctrl_cols[j]] : s->ref[3 * k - 1 - s->ctrl_cols[j]];
    }
    if (s->ctrl_n_in) {
        status = fmu_set(&s->ctrl, (size_t)s->ctrl_n_in, s->ctrl_in);
        if (FAILED(status)) { s->fault = 5; s->status = status; return CONTROLLER_FAILED; }
    }
    status = fmu_get(&s->ctrl, (size_t)s->ctrl_n_out, s->ctrl_out);
    if (FAILED(status)) { s->fault = 4; s->status = status; return CONTROLLER_FAILED; }
    s->ctrl_t = t;
    s->ctrl_due = 1;
    if (!isfinite(s->ctrl_out[0])) { return COMMAND_REJECTED; }
    return DONE;
}

/* The LTI system's sample k from the row: out = (u, e), the next state in s->lti_xn. Its inputs
   are (e) or (r - y0, y - y0), y = row[lti_col], r the reference's q* at k (s->ref) or the
   constant target, e = r - y, y0 = s->lti_origin. Returns DONE, or HAND_BACK (nothing committed) where the plant outputs i_q, i_qd, e,
   u or the next state is not finite: the Python adapter then evaluates the sample itself, from
   the same state. */
static int lti_control(kernel_t *s, const double *row, long k, double out[2]) {
    double r, y, e, v[2];
    if (!(isfinite(row[s->i_q]) && isfinite(row[s->i_qd]))) { return HAND_BACK; }
    r = s->ref ? s->ref[3 * k] : s->lti_target;
    y = row[s->lti_col];
    e = r - y;
    if (!isfinite(e)) { return HAND_BACK; }
    v[0] = s->lti_m == 1 ? e : r - s->lti_origin;
    v[1] = y - s->lti_origin;
    if (lti_sums(s->lti_n, s->lti_m, s->lti_a, s->lti_b, s->lti_c, s->lti_d, s->lti_x, v, &out[0], s->lti_xn)) {
        return HAND_BACK;
    }
    out[1] = e;
    return DONE;
}

/* Samples s->k .. k_end - 1: read outputs into the trace row, control, record, then (except
   after the last sample n) set the inputs and doStep. Stops early with HAND_BACK at a sample
   the Python must take (nothing of it sent to the plant FMU), FMI_FAILED (the plant FMU),
   CONTROLLER_FAILED or COMMAND_REJECTED (the controller FMU; the sample not recorded). s->k
   is the next sample on return (the failed one for the failures), s->z the law's state there. */
int kernel_run(kernel_t *s, long k_end) {
    double c[5], t, *row, *in = s->plant_in;
    const double *load, *ref;
    long k, j;
    int status;
    for (k = s->k; k < k_end; k++) {
        t = (double)k * s->T_s;
        row = s->data + k * s->ncols;
        load = s->load + k * s->n_load;
        status = fmu_get(&s->plant, (size_t)s->n_out, row + 1);
        if (FAILED(status)) { s->k = k; s->fault = 1; s->status = status; return FMI_FAILED; }
        if (s->kind == CTRL_FMU) {
            status = fmu_control(s, t, row, k);
            if (status != DONE) { s->k = k; return status; }
            row[0] = t;
            row[s->col_u] = s->ctrl_out[0];
            row[s->col_u + 1] = load[0];
            for (j = 1; j < s->ctrl_n_out; j++) { row[s->col_u + 1 + j] = s->ctrl_out[j]; }
            in[0] = s->ctrl_out[0];
        } else if (s->kind == CTRL_LTI) {
            status = lti_control(s, row, k, c);
            if (status != DONE) { s->k = k; return status; }
            row[0] = t;
            row[s->col_u] = c[0];
            row[s->col_u + 1] = load[0];
            row[s->col_u + 2] = c[1];
            for (j = 0; j < s->lti_n; j++) { s->lti_x[j] = s->lti_xn[j]; }
            in[0] = c[0];
        } else {
            ref = s->ref ? s->ref + 3 * k : NULL;
            if (kernel_control(s, t, row[s->i_q], row[s->i_qd], s->z, ref ? ref[0] : s->law.target, ref ? ref[1] : 0.0,
                               ref ? ref[2] : 0.0, c)) {
                s->k = k;
                return HAND_BACK;
            }
            row[0] = t;
            row[s->col_u] = c[0];
            row[s->col_u + 1] = load[0];
            row[s->col_u + 2] = c[1];
            row[s->col_u + 3] = c[2];
            row[s->col_u + 4] = c[3];
            s->z = c[4];
            in[0] = c[0];
        }
        for (j = 1; j < s->n_load; j++) { row[s->col_x + j - 1] = load[j]; }
        if (s->rows) { *s->rows = k + 1; }
        if (k == s->n) { s->k = k + 1; return DONE; }
        for (j = 0; j < s->n_load; j++) { in[1 + j] = load[j]; }
        status = fmu_set(&s->plant, (size_t)(1 + s->n_load), in);
        if (FAILED(status)) { s->k = k; s->fault = 2; s->status = status; return FMI_FAILED; }
        status = fmu_step(&s->plant, t, s->T_s, s->no_prior != 0);
        if (FAILED(status)) { s->k = k; s->fault = 3; s->status = status; return FMI_FAILED; }
    }
    s->k = k_end;
    return DONE;
}

/* The plant's part of one sample k of the Python loop in one call (cosim/stepper.py's
   PythonStepper): set the inputs (the command u, then the load row k), doStep from t_k over T_s
   with s->no_prior, then, if `read_next`, get the outputs of sample k + 1 into the trace row
   k + 1. Returns 0, or the failed call (2 set, 3 step, 1 get) with its status in s->status, as
   kernel_run's s->fault does; nothing after a failed call is made. */
int plant_exchange(kernel_t *s, long k, double u, int read_next) {
    const double *load = s->load + k * s->n_load;
    double *in = s->plant_in;
    long j;
    int status;
    in[0] = u;
    for (j = 0; j < s->n_load; j++) { in[1 + j] = load[j]; }
    status = fmu_set(&s->plant, (size_t)(1 + s->n_load), in);
    if (FAILED(status)) { s->status = status; return 2; }
    status = fmu_step(&s->plant, (double)k * s->T_s, s->T_s, s->no_prior != 0);
    if (FAILED(status)) { s->status = status; return 3; }
    if (read_next) {
        status = fmu_get(&s->plant, (size_t)s->n_out, s->data + (k + 1) * s->ncols + 1);
        if (FAILED(status)) { s->status = status; return 1; }
    }
    return 0;
}
