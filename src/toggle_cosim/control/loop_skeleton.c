/* toggle-cosim: the co-simulation loop in C, a skeleton with no physics and no control law.
   cosim/compiled_loop.py puts the law in front of it: the struct law_t and the function law_step,
   both generated from their Python definition (control/laws.py, control/translate.py).
   Per sample: read the FMU's outputs into the trace row, call law_step, record, set the
   inputs, doStep. */
#include <stdbool.h>
#include <stddef.h>

typedef int (*get2_t)(void *, const unsigned int *, size_t, double *);
typedef int (*set2_t)(void *, const unsigned int *, size_t, const double *);
typedef int (*step2_t)(void *, double, double, int);
typedef int (*get3_t)(void *, const unsigned int *, size_t, double *, size_t);
typedef int (*set3_t)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*step3_t)(void *, double, double, bool, bool *, bool *, bool *, double *);

/* Its ctypes mirror is built in cosim/compiled_loop.py from the same field lists. */
typedef struct {
    void *get, *set, *step, *component;
    const unsigned int *out_vr, *in_vr;
    double *data;
    long fmi3, n_out, ncols, i_q, i_qd, col_u, n;  /* i_q, i_qd: the columns the law reads (x_B, v_B or theta1, omega1) */
    long k, fault, status;  /* next sample; the failed FMI function (1 get, 2 set, 3 step), its status */
    long no_prior;          /* doStep's noSetFMUStatePriorToCurrentPoint: 1 only if no checkpoint is restored */
    double T_s, F_E, z;     /* z: the law's state (an integrator) at sample k */
    law_t law;
} kernel_t;

enum { DONE = 0, HAND_BACK = 1, FMI_FAILED = 2 };

/* Only OK (0) and Warning (1) let the loop go on: Discard, Error, Fatal, Pending and any value
   the standard does not define (a negative one, 5, ...) fail the run. */

/* One law sample from the measured coordinate and rate (q, qd): out = (u, S, phase, e, z_next).
   Returns 0, or 1 where the Python must evaluate the sample itself (it raises there, or a
   result is not finite). */
int kernel_control(const kernel_t *s, double t, double q, double qd, double z, double out[5]) {
    int i;
    if (!(isfinite(q) && isfinite(qd))) { return 1; }
    if (law_step(t, q, qd, z, &s->law, &out[0], &out[1], &out[2], &out[3], &out[4])) { return 1; }
    for (i = 0; i < 5; i++) {
        if (!isfinite(out[i])) { return 1; }
    }
    return 0;
}

/* Samples s->k .. k_end - 1: read outputs into the trace row, control, record, then (except
   after the last sample n) set the inputs and doStep. Stops early with HAND_BACK at a sample
   the Python must take (nothing of it sent to the FMU) or FMI_FAILED. s->k is the next
   sample on return (the failed one for FMI_FAILED), s->z the law's state there. */
int kernel_run(kernel_t *s, long k_end) {
    double in[2], c[5], t, *row;
    long k;
    int status;
    bool event, terminate, early;
    double last;
    for (k = s->k; k < k_end; k++) {
        t = (double)k * s->T_s;
        row = s->data + k * s->ncols;
        status = s->fmi3 ? ((get3_t)s->get)(s->component, s->out_vr, (size_t)s->n_out, row + 1, (size_t)s->n_out)
                         : ((get2_t)s->get)(s->component, s->out_vr, (size_t)s->n_out, row + 1);
        if (status != 0 && status != 1) { s->k = k; s->fault = 1; s->status = status; return FMI_FAILED; }
        if (kernel_control(s, t, row[s->i_q], row[s->i_qd], s->z, c)) {
            s->k = k;
            return HAND_BACK;
        }
        row[0] = t;
        row[s->col_u] = c[0];
        row[s->col_u + 1] = s->F_E;
        row[s->col_u + 2] = c[1];
        row[s->col_u + 3] = c[2];
        row[s->col_u + 4] = c[3];
        s->z = c[4];
        if (k == s->n) { s->k = k + 1; return DONE; }
        in[0] = c[0];
        in[1] = s->F_E;
        status = s->fmi3 ? ((set3_t)s->set)(s->component, s->in_vr, 2, in, 2)
                         : ((set2_t)s->set)(s->component, s->in_vr, 2, in);
        if (status != 0 && status != 1) { s->k = k; s->fault = 2; s->status = status; return FMI_FAILED; }
        status = s->fmi3 ? ((step3_t)s->step)(s->component, t, s->T_s, s->no_prior != 0, &event, &terminate, &early, &last)
                         : ((step2_t)s->step)(s->component, t, s->T_s, s->no_prior != 0);
        if (status != 0 && status != 1) { s->k = k; s->fault = 3; s->status = status; return FMI_FAILED; }
    }
    s->k = k_end;
    return DONE;
}
