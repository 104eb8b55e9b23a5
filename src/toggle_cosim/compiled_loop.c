/* toggle-cosim: the co-simulation loop in C (see fmu_io.py). Compile with -ffp-contract=off
   and no -ffast-math: every expression is evaluated in the order Python evaluates it. */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>

typedef int (*get2_t)(void *, const unsigned int *, size_t, double *);
typedef int (*set2_t)(void *, const unsigned int *, size_t, const double *);
typedef int (*step2_t)(void *, double, double, int);
typedef int (*get3_t)(void *, const unsigned int *, size_t, double *, size_t);
typedef int (*set3_t)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*step3_t)(void *, double, double, bool, bool *, bool *, bool *, double *);

/* Keep in step with class _Kernel in fmu_io.py: pointers, then longs, then doubles. */
typedef struct {
    void *get, *set, *step, *component;
    const unsigned int *out_vr, *in_vr;
    double *data;
    long fmi3, n_out, ncols, i_x, i_v, col_u, n, objective;
    long k, fault, status;  /* next sample; the failed FMI function (1 get, 2 set, 3 step), its status */
    double T_s, F_E;
    double target, C, Q, P, delta, beta, K_f, t0, T_h;
    double r1, r3, r4, r5, f, h, phi, m3, m5, mB, mC, J2, g;
} kernel_t;

enum { DONE = 0, HAND_BACK = 1, FMI_FAILED = 2 };

/* mechanism._theta1_omega1_from_slider, for f == 0 (then math.hypot(x_B, f) == |x_B| exactly;
   the master uses this kernel only then). Returns 0, or 1 where Python would raise or go
   non-finite. */
static int theta1_omega1(const kernel_t *s, double x_B, double v_B, double *t1, double *w1) {
    double rho = fabs(x_B), den, arg, s1, c1, s2, q, c2, dxB;
    den = 2.0 * s->r1 * rho;
    if (den == 0.0) { return 1; }
    arg = (x_B * x_B + s->r1 * s->r1 + s->f * s->f - s->r3 * s->r3) / den;
    if (!(arg >= -1.0 && arg <= 1.0)) { return 1; }
    *t1 = asin(arg) - atan2(x_B, s->f);
    s1 = sin(*t1);
    c1 = cos(*t1);
    s2 = (s->f - s->r1 * s1) / s->r3;
    q = 1.0 - s2 * s2;
    if (!(q >= 0.0)) { return 1; }
    c2 = sqrt(q);
    den = s->r3 * c2;
    if (den == 0.0) { return 1; }
    dxB = -s->r1 * s1 + s->r3 * s2 * s->r1 * c1 / den;
    if (dxB == 0.0) { return 1; }
    *w1 = v_B / dxB;
    return 0;
}

/* mechanism._nominal_reduced: out = (acc0, dacc, dxB, bB). */
static int nominal_reduced(const kernel_t *s, double t1, double w1, double out[4]) {
    const double r1 = s->r1, r3 = s->r3, r4 = s->r4, r5 = s->r5;
    double s1, c1, sp, cp, s2, c2, s5, c5, q, rho2, rho5, w2, w5, w1s, w2s, w5s, g1, g2, sv2, sv5;
    double a3, a5, m3, m5, mB, mC, c12, s12, cp5, sp5, M11, M12, M15, M22, M55;
    double d11_1, d12_1, d12_2, d15_1, d15_5, N1, N2, N5, g, V1, V2, V5;
    double m_eff, RMs, RQ0, dxB, dxC, den2, den5;
    s1 = sin(t1);
    c1 = cos(t1);
    sp = sin(t1 + s->phi);
    cp = cos(t1 + s->phi);
    s2 = (s->f - r1 * s1) / r3;
    q = 1.0 - s2 * s2;
    if (!(q >= 0.0)) { return 1; }
    c2 = sqrt(q);
    s5 = (s->h - r4 * sp) / r5;
    q = 1.0 - s5 * s5;
    if (!(q >= 0.0)) { return 1; }
    c5 = sqrt(q);
    den2 = r3 * c2;
    den5 = r5 * c5;
    if (den2 == 0.0 || den5 == 0.0) { return 1; }
    rho2 = -r1 * c1 / den2;
    rho5 = -r4 * cp / den5;
    w2 = rho2 * w1;
    w5 = rho5 * w1;
    w1s = w1 * w1;
    w2s = w2 * w2;
    w5s = w5 * w5;
    g1 = r1 * s1 * w1s + r3 * s2 * w2s;
    g2 = -r4 * sp * w1s - r5 * s5 * w5s;
    sv2 = g1 / den2;
    sv5 = -g2 / den5;

    a3 = 0.5 * r3;
    a5 = 0.5 * r5;
    m3 = s->m3; m5 = s->m5; mB = s->mB; mC = s->mC;
    c12 = c1 * c2 + s1 * s2;
    s12 = s1 * c2 - c1 * s2;
    cp5 = cp * c5 + sp * s5;
    sp5 = sp * c5 - cp * s5;
    M11 = s->J2 + m3 * r1 * r1 + m5 * r4 * r4 + mB * r1 * r1 * s1 * s1 + mC * r4 * r4 * sp * sp;
    M12 = m3 * r1 * a3 * c12 + mB * r1 * r3 * s1 * s2;
    M15 = m5 * r4 * a5 * cp5 + mC * r4 * r5 * sp * s5;
    M22 = m3 * r3 * r3 / 12.0 + m3 * a3 * a3 + mB * r3 * r3 * s2 * s2;
    M55 = m5 * r5 * r5 / 12.0 + m5 * a5 * a5 + mC * r5 * r5 * s5 * s5;
    d11_1 = 2.0 * (mB * r1 * r1 * s1 * c1 + mC * r4 * r4 * sp * cp);
    d12_1 = -m3 * r1 * a3 * s12 + mB * r1 * r3 * c1 * s2;
    d12_2 = m3 * r1 * a3 * s12 + mB * r1 * r3 * s1 * c2;
    d15_1 = -m5 * r4 * a5 * sp5 + mC * r4 * r5 * cp * s5;
    d15_5 = m5 * r4 * a5 * sp5 + mC * r4 * r5 * sp * c5;
    N1 = 0.5 * d11_1 * w1s + d12_2 * w2s + d15_5 * w5s;
    N2 = d12_1 * w1s + mB * r3 * r3 * s2 * c2 * w2s;
    N5 = d15_1 * w1s + mC * r5 * r5 * s5 * c5 * w5s;
    g = s->g;
    V1 = g * (m3 * r1 * c1 + m5 * r4 * cp);
    V2 = g * m3 * a3 * c2;
    V5 = g * m5 * a5 * c5;

    m_eff = M11 + 2.0 * (M12 * rho2 + M15 * rho5) + M22 * rho2 * rho2 + M55 * rho5 * rho5;
    RMs = sv2 * (M12 + M22 * rho2) + sv5 * (M15 + M55 * rho5);
    RQ0 = -(N1 + V1) - rho2 * (N2 + V2) - rho5 * (N5 + V5);
    dxB = -r1 * s1 - r3 * s2 * rho2;
    dxC = -r4 * sp - r5 * s5 * rho5;
    if (m_eff == 0.0) { return 1; }
    out[0] = (RQ0 - RMs) / m_eff;
    out[1] = -dxC / m_eff;
    out[2] = dxB;
    out[3] = -r1 * c1 * w1s - r3 * (s2 * sv2 + c2 * w2s);
    return 0;
}

/* controller.VSCController.step: out = (u, S, phase, e), phase 0 reaching, 1 sliding.
   Returns 0, or 1 where the Python must evaluate this sample itself. */
int kernel_control(const kernel_t *s, double t, double x_B, double v_B, double out[4]) {
    double t1, w1, red[4], e, edot, f, G, S, u, sg, den;
    int reaching;
    if (theta1_omega1(s, x_B, v_B, &t1, &w1) || nominal_reduced(s, t1, w1, red)) { return 1; }
    if (s->objective == 0) {               /* x_B: mechanism.nominal_fG */
        f = red[2] * red[0] + red[3];
        G = s->K_f * red[2] * red[1];
        e = s->target - x_B;
        edot = -v_B;
    } else {                               /* theta1: mechanism.nominal_fG_theta1 */
        f = red[0];
        G = s->K_f * red[1];
        e = s->target - t1;
        edot = -w1;
    }
    S = s->C * e + edot;
    reaching = t - s->t0 < s->T_h;
    if (G == 0.0) { return 1; }
    if (reaching) {
        sg = S > 0.0 ? 1.0 : (S < 0.0 ? -1.0 : 0.0);
        u = (s->C * edot + s->P * S + s->Q * sg - f) / G;
    } else {
        den = fabs(S) + s->delta;
        if (den == 0.0) { return 1; }
        u = (s->C * edot + s->beta * S / den - f) / G;
    }
    if (!(isfinite(u) && isfinite(S) && isfinite(e) && isfinite(f) && isfinite(G))) { return 1; }
    out[0] = u;
    out[1] = S;
    out[2] = reaching ? 0.0 : 1.0;
    out[3] = e;
    return 0;
}

/* Samples s->k .. k_end - 1: read outputs into the trace row, control, record, then (except
   after the last sample n) set the inputs and doStep. Stops early with HAND_BACK at a sample
   the Python must take (nothing of it sent to the FMU) or FMI_FAILED. s->k is the next
   sample on return (the failed one for FMI_FAILED). */
int kernel_run(kernel_t *s, long k_end) {
    double in[2], c[4], t, x_B, v_B, *row;
    long k;
    int status;
    bool event, terminate, early;
    double last;
    for (k = s->k; k < k_end; k++) {
        t = (double)k * s->T_s;
        row = s->data + k * s->ncols;
        status = s->fmi3 ? ((get3_t)s->get)(s->component, s->out_vr, (size_t)s->n_out, row + 1, (size_t)s->n_out)
                         : ((get2_t)s->get)(s->component, s->out_vr, (size_t)s->n_out, row + 1);
        if (status > 1) { s->k = k; s->fault = 1; s->status = status; return FMI_FAILED; }
        x_B = row[s->i_x];
        v_B = row[s->i_v];
        if (!(isfinite(x_B) && isfinite(v_B)) || kernel_control(s, t, x_B, v_B, c)) {
            s->k = k;
            return HAND_BACK;
        }
        row[0] = t;
        row[s->col_u] = c[0];
        row[s->col_u + 1] = s->F_E;
        row[s->col_u + 2] = c[1];
        row[s->col_u + 3] = c[2];
        row[s->col_u + 4] = c[3];
        if (k == s->n) { s->k = k + 1; return DONE; }
        in[0] = c[0];
        in[1] = s->F_E;
        status = s->fmi3 ? ((set3_t)s->set)(s->component, s->in_vr, 2, in, 2)
                         : ((set2_t)s->set)(s->component, s->in_vr, 2, in);
        if (status > 1) { s->k = k; s->fault = 2; s->status = status; return FMI_FAILED; }
        status = s->fmi3 ? ((step3_t)s->step)(s->component, t, s->T_s, true, &event, &terminate, &early, &last)
                         : ((step2_t)s->step)(s->component, t, s->T_s, 1);
        if (status > 1) { s->k = k; s->fault = 3; s->status = status; return FMI_FAILED; }
    }
    s->k = k_end;
    return DONE;
}
