/* The model-independent simulation core of the FMU shell. See solver.h for the contract.
 *
 * Integrator: Dormand-Prince 5(4) (Hairer, Norsett & Wanner, Solving ODEs I, sec. II.5 and
 * the DOPRI5 code), local extrapolation, FSAL, mixed absolute/relative RMS error norm, an
 * elementary step-size controller, and the 4th-order continuous extension ("dense output")
 * used to locate state events inside an accepted step.
 *
 * State events (Modelica semantics as cgen emits them; see md_model.h):
 *   cond_k = (z_k > 0). direction > 0 (a `when` branch): an event when cond_k turns
 *   false -> true. direction == 0 (a relation latched in w): an event whenever cond_k changes.
 *   (direction < 0, true -> false only, is accepted for completeness; cgen does not emit it.)
 * After each accepted step the indicators are evaluated at its end. If an event fired, the
 * earliest crossing is bracketed by a safeguarded Illinois (modified regula falsi) iteration
 * on the dense output, the state is moved to the right-hand end of the final bracket (where
 * the new condition already holds, so the event cannot re-fire from noise), transition() is
 * called for every event in that bracket, and then event iteration runs until no condition
 * changes at that instant. The integrator then restarts (FSAL invalid).
 */
#include "solver.h"

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

/* ---------------------------------------------------------------------------------------
 * Settings table (md_settings.h, written from shell_settings.py)
 * ------------------------------------------------------------------------------------- */

const md_setting MD_SHELL_SETTINGS[MD_SHELL_NREAL] = MD_SHELL_SETTINGS_TABLE;

/* ---------------------------------------------------------------------------------------
 * Dormand-Prince 5(4) coefficients
 * ------------------------------------------------------------------------------------- */

static const double C2 = 1.0 / 5.0, C3 = 3.0 / 10.0, C4 = 4.0 / 5.0, C5 = 8.0 / 9.0;
static const double A21 = 1.0 / 5.0;
static const double A31 = 3.0 / 40.0, A32 = 9.0 / 40.0;
static const double A41 = 44.0 / 45.0, A42 = -56.0 / 15.0, A43 = 32.0 / 9.0;
static const double A51 = 19372.0 / 6561.0, A52 = -25360.0 / 2187.0, A53 = 64448.0 / 6561.0,
                    A54 = -212.0 / 729.0;
static const double A61 = 9017.0 / 3168.0, A62 = -355.0 / 33.0, A63 = 46732.0 / 5247.0,
                    A64 = 49.0 / 176.0, A65 = -5103.0 / 18656.0;
static const double A71 = 35.0 / 384.0, A73 = 500.0 / 1113.0, A74 = 125.0 / 192.0,
                    A75 = -2187.0 / 6784.0, A76 = 11.0 / 84.0;
/* error estimate: 5th-order minus embedded 4th-order weights */
static const double E1 = 71.0 / 57600.0, E3 = -71.0 / 16695.0, E4 = 71.0 / 1920.0,
                    E5 = -17253.0 / 339200.0, E6 = 22.0 / 525.0, E7 = -1.0 / 40.0;
/* dense output (Hairer's contd5) */
static const double D1 = -12715105075.0 / 11282082432.0, D3 = 87487479700.0 / 32700410799.0,
                    D4 = -10690763975.0 / 1880347072.0, D5 = 701980252875.0 / 199316789632.0,
                    D6 = -1453857185.0 / 822651844.0, D7 = 69997945.0 / 29380423.0;

/* Step-size control */
static const double SAFETY = 0.9, FAC_MIN = 0.2, FAC_MAX = 5.0, FAC_NONFINITE = 0.25;

/* ---------------------------------------------------------------------------------------
 * Small helpers
 * ------------------------------------------------------------------------------------- */

static int all_finite(const double *v, int n) {
    for (int i = 0; i < n; ++i) {
        if (!isfinite(v[i])) { return 0; }
    }
    return 1;
}

static double min_step(double t) { return 1e-14 * fmax(1.0, fabs(t)); }

static md_status fail(md_solver *s, const char *format, ...) {
    va_list args;
    va_start(args, format);
    vsnprintf(s->message, sizeof s->message, format, args);
    va_end(args);
    return MD_FAIL;
}

static int log_on(const md_solver *s, md_log_category category) {
    if (s->host.log == NULL) { return 0; }
    return s->host.log_enabled == NULL || s->host.log_enabled(s->host.env, category);
}

static void logf_(const md_solver *s, md_log_category category, const char *format, ...) {
    char text[MD_MESSAGE_SIZE];
    va_list args;
    if (!log_on(s, category)) { return; }
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    s->host.log(s->host.env, category, text);
}

/* The name of the variable observe() writes into slot `slot`, for messages. */
static const char *observed_name(const md_info *info, int slot) {
    for (int v = 0; v < info->nvars; ++v) {
        if (info->obs_slot[v] == slot) { return info->names[v]; }
    }
    return "?";
}

static const char *event_kind(double direction) {
    if (direction > 0.0) { return "when condition became true"; }
    if (direction < 0.0) { return "condition became false"; }
    return "relation changed";
}

/* Does an indicator going from condition `before` to value `z` trigger an event? */
static int fires(double direction, int before, double z) {
    int after = z > 0.0;
    if (direction > 0.0) { return !before && after; }
    if (direction < 0.0) { return before && !after; }
    return before != after;
}

static void *allocate(md_solver *s, size_t n, size_t size) {
    return s->host.allocate(s->host.env, n > 0 ? n : 1, size);
}

/* ---------------------------------------------------------------------------------------
 * Life cycle
 * ------------------------------------------------------------------------------------- */

static void default_settings(md_settings *settings) {
    settings->rel_tol = MD_SHELL_SETTINGS[MD_SETTING_RELTOL].start;
    settings->abs_tol = MD_SHELL_SETTINGS[MD_SETTING_ABSTOL].start;
    settings->max_step = MD_SHELL_SETTINGS[MD_SETTING_MAXSTEP].start;
    settings->max_events_per_step = MD_MAX_EVENTS_PER_STEP;
    settings->max_steps = MD_MAX_STEPS;
}

md_solver *md_solver_new(const md_info *info, const md_host *host) {
    md_solver *s;
    size_t ny, np, nw, nobs, nz, total;
    double *d;

    if (info == NULL || host == NULL || host->allocate == NULL || host->release == NULL) {
        return NULL;
    }
    if (info->ny < 0 || info->np < 0 || info->nw < 0 || info->nobs < 0 || info->nz < 0) {
        return NULL;
    }
    s = host->allocate(host->env, 1, sizeof *s);
    if (s == NULL) { return NULL; }
    s->info = info;
    s->host = *host;

    ny = (size_t)info->ny; np = (size_t)info->np; nw = (size_t)info->nw;
    nobs = (size_t)info->nobs; nz = (size_t)info->nz;
    /* y p w obs z | k(7 ny) ynew ytmp yerr ydense | rcont(5 ny) | zl zr zm | obs_tmp | w_tmp */
    total = ny + np + nw + nobs + nz + 7 * ny + 4 * ny + 5 * ny + 3 * nz + nobs + nw;
    d = allocate(s, total, sizeof(double));
    s->cond = allocate(s, nz, sizeof(unsigned char));
    s->fired = allocate(s, nz, sizeof(int));
    if (d == NULL || s->cond == NULL || s->fired == NULL) {
        if (d != NULL) { host->release(host->env, d); }
        if (s->cond != NULL) { host->release(host->env, s->cond); }
        if (s->fired != NULL) { host->release(host->env, s->fired); }
        host->release(host->env, s);
        return NULL;
    }
    s->y = d; d += ny;
    s->p = d; d += np;
    s->w = d; d += nw;
    s->obs = d; d += nobs;
    s->z = d; d += nz;
    s->k = d; d += 7 * ny;
    s->k1 = s->k; /* stage 1 of the next step is the FSAL derivative */
    s->ynew = d; d += ny;
    s->ytmp = d; d += ny;
    s->yerr = d; d += ny;
    s->ydense = d; d += ny;
    s->rcont = d; d += 5 * ny;
    s->zl = d; d += nz;
    s->zr = d; d += nz;
    s->zm = d; d += nz;
    s->obs_tmp = d; d += nobs;
    s->w_tmp = d;
    md_solver_reset(s);
    return s;
}

void md_solver_free(md_solver *s) {
    md_host host;
    if (s == NULL) { return; }
    host = s->host;
    host.release(host.env, s->y); /* the start of the block of doubles */
    host.release(host.env, s->cond);
    host.release(host.env, s->fired);
    host.release(host.env, s);
}

void md_solver_reset(md_solver *s) {
    const md_info *info = s->info;
    default_settings(&s->settings);
    s->t = 0.0;
    memset(s->y, 0, sizeof(double) * (size_t)info->ny);
    memset(s->p, 0, sizeof(double) * (size_t)info->np);
    memset(s->w, 0, sizeof(double) * (size_t)info->nw);
    memset(s->obs, 0, sizeof(double) * (size_t)info->nobs);
    memset(s->z, 0, sizeof(double) * (size_t)info->nz);
    memset(s->k1, 0, sizeof(double) * (size_t)info->ny);
    memset(s->cond, 0, (size_t)info->nz);
    s->h_next = 0.0;
    s->fsal_valid = 0;
    memset(&s->count, 0, sizeof s->count);
    s->message[0] = '\0';
    md_defaults(s->p); /* independent parameters and inputs at their declared values */
}

md_status md_solver_set_setting(md_solver *s, int index, double value) {
    switch (index) {
    case MD_SETTING_RELTOL:
        if (!(value > 0.0 && value <= 0.1)) {
            return fail(s, "%s = %g is out of range: it must be in (0, 0.1]",
                        MD_SHELL_SETTINGS[index].name, value);
        }
        s->settings.rel_tol = value;
        return MD_OK;
    case MD_SETTING_ABSTOL:
        if (!(value > 0.0 && isfinite(value))) {
            return fail(s, "%s = %g is out of range: it must be > 0",
                        MD_SHELL_SETTINGS[index].name, value);
        }
        s->settings.abs_tol = value;
        return MD_OK;
    case MD_SETTING_MAXSTEP:
        if (!(value >= 0.0 && isfinite(value))) {
            return fail(s, "%s = %g is out of range: it must be >= 0 (0 = unbounded)",
                        MD_SHELL_SETTINGS[index].name, value);
        }
        s->settings.max_step = value;
        return MD_OK;
    default:
        return fail(s, "no solver setting with index %d", index);
    }
}

double md_solver_get_setting(const md_solver *s, int index) {
    switch (index) {
    case MD_SETTING_RELTOL: return s->settings.rel_tol;
    case MD_SETTING_ABSTOL: return s->settings.abs_tol;
    case MD_SETTING_MAXSTEP: return s->settings.max_step;
    default: return NAN;
    }
}

void md_solver_set_parameter(md_solver *s, int slot, double value, int restart) {
    if (restart && memcmp(&s->p[slot], &value, sizeof value) != 0) {
        s->fsal_valid = 0; /* the right-hand side changed: k1 is stale */
    }
    s->p[slot] = value;
}

const char *md_solver_message(const md_solver *s) { return s->message; }

/* ---------------------------------------------------------------------------------------
 * Model evaluations
 * ------------------------------------------------------------------------------------- */

md_status md_solver_observe(md_solver *s) {
    const md_info *info = s->info;
    observe(s->t, s->y, s->p, s->w, s->obs_tmp);
    for (int i = 0; i < info->nobs; ++i) {
        if (!isfinite(s->obs_tmp[i])) {
            return fail(s, "the value of %s is not finite (%g) at t=%.10g s",
                        observed_name(info, i), s->obs_tmp[i], s->t);
        }
    }
    memcpy(s->obs, s->obs_tmp, sizeof(double) * (size_t)info->nobs);
    return MD_OK;
}

static int derivative(md_solver *s, double t, const double *y, double *dy) {
    rhs(t, y, s->p, s->w, dy);
    s->count.rhs_calls++;
    return all_finite(dy, s->info->ny);
}

static md_status evaluate_indicators(md_solver *s, double t, const double *y, double *z) {
    const md_info *info = s->info;
    if (info->nz == 0) { return MD_OK; }
    indicators(t, y, s->p, s->w, z);
    for (int k = 0; k < info->nz; ++k) {
        if (!isfinite(z[k])) {
            return fail(s, "event indicator %d is not finite (%g) at t=%.10g s", k, z[k], t);
        }
    }
    return MD_OK;
}

/* ---------------------------------------------------------------------------------------
 * Initialisation (FMI: enter / exit initialisation mode)
 * ------------------------------------------------------------------------------------- */

md_status md_solver_start(md_solver *s, double t0) {
    const md_info *info = s->info;
    s->t = t0;
    memset(s->y, 0, sizeof(double) * (size_t)info->ny);
    memset(s->w, 0, sizeof(double) * (size_t)info->nw);
    md_parameters(s->p);
    md_start(s->p, s->y, s->w);
    s->fsal_valid = 0;
    s->h_next = 0.0;
    memset(s->cond, 0, (size_t)info->nz);
    if (!all_finite(s->y, info->ny)) {
        return fail(s, "a start value of a state is not finite (check the parameters)");
    }
    return md_solver_observe(s);
}

md_status md_solver_initialize(md_solver *s) {
    const md_info *info = s->info;
    int settled = 0;
    /* No `when` branch fires at initialisation; a relation latch holds what its relation
       says at the start. A latch can feed another relation (through w), so repeat until
       they agree. */
    for (int round = 0; round <= MD_MAX_EVENT_ITERATIONS && !settled; ++round) {
        if (evaluate_indicators(s, s->t, s->y, s->z) != MD_OK) { return MD_FAIL; }
        settled = 1;
        for (int k = 0; k < info->nz; ++k) {
            int slot = info->latch[k];
            if (slot >= 0) {
                double held = s->z[k] > 0.0 ? 1.0 : 0.0;
                if (s->w[slot] != held) { s->w[slot] = held; settled = 0; }
            }
        }
    }
    if (!settled) {
        return fail(s, "initialisation: the relation latches did not settle after %d rounds",
                    MD_MAX_EVENT_ITERATIONS);
    }
    for (int k = 0; k < info->nz; ++k) { s->cond[k] = s->z[k] > 0.0; }
    s->fsal_valid = 0;
    s->h_next = 0.0;
    return md_solver_observe(s);
}

/* ---------------------------------------------------------------------------------------
 * Dormand-Prince 5(4)
 * ------------------------------------------------------------------------------------- */

#define STAGE(i) (s->k + (size_t)(i) * (size_t)ny)

/* One trial step of size h from (s->t, s->y), with stage 1 = k1 = f(t, y) already in place.
 * Leaves y(t+h) in ynew and f(t_new, ynew) in stage 7. Returns 0 if anything came out
 * non-finite, else 1 with the scaled RMS error estimate in *err. */
static int dopri_step(md_solver *s, double h, double t_new, double *err) {
    const int ny = s->info->ny;
    const double t = s->t, *y = s->y;
    double *k1 = STAGE(0), *k2 = STAGE(1), *k3 = STAGE(2), *k4 = STAGE(3), *k5 = STAGE(4),
           *k6 = STAGE(5), *k7 = STAGE(6), *yt = s->ytmp, *yn = s->ynew;
    double sum = 0.0;
    int i;

    for (i = 0; i < ny; ++i) { yt[i] = y[i] + h * A21 * k1[i]; }
    if (!derivative(s, t + C2 * h, yt, k2)) { return 0; }
    for (i = 0; i < ny; ++i) { yt[i] = y[i] + h * (A31 * k1[i] + A32 * k2[i]); }
    if (!derivative(s, t + C3 * h, yt, k3)) { return 0; }
    for (i = 0; i < ny; ++i) { yt[i] = y[i] + h * (A41 * k1[i] + A42 * k2[i] + A43 * k3[i]); }
    if (!derivative(s, t + C4 * h, yt, k4)) { return 0; }
    for (i = 0; i < ny; ++i) {
        yt[i] = y[i] + h * (A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i]);
    }
    if (!derivative(s, t + C5 * h, yt, k5)) { return 0; }
    for (i = 0; i < ny; ++i) {
        yt[i] = y[i] + h * (A61 * k1[i] + A62 * k2[i] + A63 * k3[i] + A64 * k4[i] + A65 * k5[i]);
    }
    if (!derivative(s, t_new, yt, k6)) { return 0; }
    for (i = 0; i < ny; ++i) {
        yn[i] = y[i] + h * (A71 * k1[i] + A73 * k3[i] + A74 * k4[i] + A75 * k5[i] + A76 * k6[i]);
    }
    if (!all_finite(yn, ny)) { return 0; }
    if (!derivative(s, t_new, yn, k7)) { return 0; }
    for (i = 0; i < ny; ++i) {
        double e = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i]
                        + E7 * k7[i]);
        double scale = s->settings.abs_tol
                       + s->settings.rel_tol * fmax(fabs(y[i]), fabs(yn[i]));
        sum += (e / scale) * (e / scale);
    }
    *err = ny > 0 ? sqrt(sum / ny) : 0.0;
    return isfinite(*err);
}

/* Coefficients of the continuous extension of the step just taken (size h). */
static void dense_prepare(md_solver *s, double h) {
    const int ny = s->info->ny;
    const double *k1 = STAGE(0), *k3 = STAGE(2), *k4 = STAGE(3), *k5 = STAGE(4), *k6 = STAGE(5),
                 *k7 = STAGE(6);
    double *r = s->rcont;
    for (int i = 0; i < ny; ++i) {
        double ydiff = s->ynew[i] - s->y[i];
        double bspl = h * k1[i] - ydiff;
        r[i] = s->y[i];
        r[ny + i] = ydiff;
        r[2 * ny + i] = bspl;
        r[3 * ny + i] = ydiff - h * k7[i] - bspl;
        r[4 * ny + i] = h * (D1 * k1[i] + D3 * k3[i] + D4 * k4[i] + D5 * k5[i] + D6 * k6[i]
                             + D7 * k7[i]);
    }
}

/* y(t + theta h), 0 <= theta <= 1, 4th order. */
static void dense_eval(const md_solver *s, double theta, double *out) {
    const int ny = s->info->ny;
    const double *r = s->rcont, theta1 = 1.0 - theta;
    for (int i = 0; i < ny; ++i) {
        out[i] = r[i] + theta * (r[ny + i] + theta1 * (r[2 * ny + i]
                 + theta * (r[3 * ny + i] + theta1 * r[4 * ny + i])));
    }
}

/* The starting step (Hairer, Norsett & Wanner, sec. II.4, "Starting step size"), bounded
 * by hmax. Needs k1 = f(t, y); uses stage 2 and ytmp as scratch. */
static double initial_step(md_solver *s, double hmax) {
    const int ny = s->info->ny;
    const double *y = s->y, *f0 = STAGE(0);
    double *f1 = STAGE(1), *y1 = s->ytmp;
    double dnf = 0.0, dny = 0.0, der2 = 0.0, der12, h, h1;
    for (int i = 0; i < ny; ++i) {
        double sk = s->settings.abs_tol + s->settings.rel_tol * fabs(y[i]);
        dnf += (f0[i] / sk) * (f0[i] / sk);
        dny += (y[i] / sk) * (y[i] / sk);
    }
    h = (dnf <= 1e-10 || dny <= 1e-10) ? 1e-6 : sqrt(dny / dnf) * 0.01;
    h = fmin(h, hmax);
    for (int i = 0; i < ny; ++i) { y1[i] = y[i] + h * f0[i]; }
    if (!derivative(s, s->t + h, y1, f1)) { return h; } /* let the step control sort it out */
    for (int i = 0; i < ny; ++i) {
        double sk = s->settings.abs_tol + s->settings.rel_tol * fabs(y[i]);
        der2 += ((f1[i] - f0[i]) / sk) * ((f1[i] - f0[i]) / sk);
    }
    der2 = ny > 0 ? sqrt(der2) / h : 0.0;
    der12 = fmax(fabs(der2), sqrt(dnf));
    h1 = der12 <= 1e-15 ? fmax(1e-6, h * 1e-3) : pow(0.01 / der12, 1.0 / 5.0);
    return fmin(fmin(100.0 * h, h1), hmax);
}

/* ---------------------------------------------------------------------------------------
 * Events
 * ------------------------------------------------------------------------------------- */

/* After the events at the present instant: every guard of the model (MD_INFO.guard_slot) must
 * be positive, else the mode the events left is one the model declares inconsistent (for a
 * mechanism with friction: no consistent friction mode, a Painleve-type case). observe() is
 * evaluated into obs_tmp with w kept as it was, so the check changes nothing. */
static md_status check_guards(md_solver *s) {
    const md_info *info = s->info;
    if (info->nguards <= 0 || info->guard_slot == NULL) { return MD_OK; }
    memcpy(s->w_tmp, s->w, sizeof(double) * (size_t)info->nw);
    observe(s->t, s->y, s->p, s->w, s->obs_tmp);
    memcpy(s->w, s->w_tmp, sizeof(double) * (size_t)info->nw);
    for (int g = 0; g < info->nguards; ++g) {
        double v = s->obs_tmp[info->guard_slot[g]];
        if (!(v > 0.0)) {
            return fail(s, "%s at t=%.10g s: %s = %.6g is not positive after the events there",
                        info->guard_text != NULL ? info->guard_text[g] : "inconsistent mode",
                        s->t, observed_name(info, info->guard_slot[g]), v);
        }
    }
    return MD_OK;
}

/* Act on everything that fires at the present instant (s->t, s->y), given the indicators
 * there in s->zr and the conditions just before the instant in s->cond: call transition()
 * for every event whose condition changed (index order), then re-evaluate the indicators
 * and repeat while further conditions change (event iteration). On return s->z and
 * s->cond describe the settled instant. */
static md_status settle(md_solver *s, long *events_here) {
    const md_info *info = s->info;
    const int ny = info->ny, nz = info->nz;
    int round, n;
    for (round = 0;; ++round) {
        n = 0;
        for (int k = 0; k < nz; ++k) {
            if (fires(info->direction[k], s->cond[k], s->zr[k])) { s->fired[n++] = k; }
            s->cond[k] = s->zr[k] > 0.0; /* conditions follow their indicators either way */
        }
        if (n == 0) { break; }
        if (round >= MD_MAX_EVENT_ITERATIONS) {
            return fail(s, "event iteration did not converge at t=%.10g s: indicator %d (%s) "
                           "still changes after %d rounds", s->t, s->fired[0],
                        event_kind(info->direction[s->fired[0]]), MD_MAX_EVENT_ITERATIONS);
        }
        for (int j = 0; j < n; ++j) {
            int k = s->fired[j];
            transition(k, s->t, s->y, s->p, s->w, s->ynew);
            if (!all_finite(s->ynew, ny)) {
                return fail(s, "event %d at t=%.10g s produced a non-finite state", k, s->t);
            }
            memcpy(s->y, s->ynew, sizeof(double) * (size_t)ny);
            if (info->latch[k] >= 0) {
                /* transition() flips the latch; pin it to the condition it now stands for */
                s->w[info->latch[k]] = s->cond[k] ? 1.0 : 0.0;
            }
            s->count.events++;
            ++*events_here;
            logf_(s, MD_LOG_EVENTS, "event at t=%.17g s: indicator %d (%s), z=%.3g", s->t, k,
                  event_kind(info->direction[k]), s->zr[k]);
            if (*events_here > s->settings.max_events_per_step) {
                return fail(s, "more than %ld events in one communication step: the model is "
                               "chattering (Zeno behaviour) at t=%.17g s, indicator %d (%s)",
                            s->settings.max_events_per_step, s->t, k,
                            event_kind(info->direction[k]));
            }
        }
        s->fsal_valid = 0;
        if (evaluate_indicators(s, s->t, s->y, s->zr) != MD_OK) { return MD_FAIL; }
    }
    memcpy(s->z, s->zr, sizeof(double) * (size_t)nz);
    return round > 0 ? check_guards(s) : MD_OK;
}

/* Any event between indicator values zl (left) and z (right)? */
static int any_fires(const md_solver *s, const double *zl, const double *z) {
    for (int k = 0; k < s->info->nz; ++k) {
        if (fires(s->info->direction[k], zl[k] > 0.0, z[k])) { return 1; }
    }
    return 0;
}

/* The accepted step (s->t, s->y) -> (t_new, ynew), of size h, has an event; s->zr holds
 * the indicators at t_new. Bracket the earliest crossing to within ttol with a safeguarded
 * Illinois iteration on the dense output, then move the state to the right end of the
 * bracket: s->t, s->y, s->cond (conditions at the left end, which is event-free), s->zr
 * (indicators at the right end) are ready for settle(). */
static md_status locate(md_solver *s, double t_new, double h) {
    const md_info *info = s->info;
    const int nz = info->nz, ny = info->ny;
    const double t0 = s->t;
    const double ttol = 1e-12 * fmax(1.0, fabs(t_new)) + 1e-14;
    double tl = t0, tr = t_new, scale_l = 1.0, scale_r = 1.0;
    int side_prev = 0, moved_right = 0;

    memcpy(s->zl, s->z, sizeof(double) * (size_t)nz);
    dense_prepare(s, h);
    for (int iter = 0; iter < 200 && tr - tl > ttol; ++iter) {
        double tm = 0.5 * (tl + tr), best = -1.0;
        int lead = -1, side;
        /* the crossing nearest the left end leads (largest fraction of the interval from tr) */
        for (int k = 0; k < nz; ++k) {
            if (fires(info->direction[k], s->zl[k] > 0.0, s->zr[k])) {
                double fraction = fabs(s->zr[k] / (s->zr[k] - s->zl[k]));
                if (fraction > best) { best = fraction; lead = k; }
            }
        }
        if (lead >= 0 && iter < 100) { /* Illinois step; plain bisection as a last resort */
            double a = scale_l * s->zl[lead], b = scale_r * s->zr[lead];
            if (b != a) { tm = tr - (tr - tl) * b / (b - a); }
        }
        /* keep the trial point at least ttol/2 inside the bracket (as CVODE's rootfinder) */
        if (!(tm - tl >= 0.5 * ttol) || !(tr - tm >= 0.5 * ttol)) {
            double span = tr - tl, fraction = span / ttol > 5.0 ? 0.1 : 0.5 * ttol / span;
            tm = !(tm - tl >= 0.5 * ttol) ? tl + fraction * span : tr - fraction * span;
        }
        dense_eval(s, (tm - t0) / h, s->ydense);
        if (evaluate_indicators(s, tm, s->ydense, s->zm) != MD_OK) { return MD_FAIL; }
        if (any_fires(s, s->zl, s->zm)) {
            double *swap = s->zr; s->zr = s->zm; s->zm = swap;
            tr = tm; side = 2; moved_right = 1;
        } else {
            double *swap = s->zl; s->zl = s->zm; s->zm = swap;
            tl = tm; side = 1;
        }
        /* Illinois: halve the weight of an end that has stayed put twice running */
        if (side == side_prev) {
            if (side == 2) { scale_l *= 0.5; } else { scale_r *= 0.5; }
        } else {
            scale_l = scale_r = 1.0;
        }
        side_prev = side;
    }
    if (moved_right) {
        dense_eval(s, (tr - t0) / h, s->ydense);
        memcpy(s->y, s->ydense, sizeof(double) * (size_t)ny);
    } else {
        memcpy(s->y, s->ynew, sizeof(double) * (size_t)ny);
    }
    s->t = tr;
    for (int k = 0; k < nz; ++k) { s->cond[k] = s->zl[k] > 0.0; }
    return MD_OK;
}

/* ---------------------------------------------------------------------------------------
 * Advancing
 * ------------------------------------------------------------------------------------- */

static const char NONFINITE_HINT[] =
    "(a singular constraint Jacobian? e.g. a mechanism at its toggle position)";

md_status md_solver_advance(md_solver *s, double t_end) {
    const md_info *info = s->info;
    const int ny = info->ny, nz = info->nz;
    long events_here = 0, attempts = 0;
    const unsigned long steps0 = s->count.steps, rejected0 = s->count.rejected;
    const double t_start = s->t;

    if (!(t_end >= s->t) || !isfinite(t_end)) {
        return fail(s, "cannot integrate from t=%.17g s back to t=%.17g s", s->t, t_end);
    }
    /* Anything that changed since the last step (an input, a restored state) may have
       turned a condition: act on it here, at the communication point. */
    if (evaluate_indicators(s, s->t, s->y, s->zr) != MD_OK) { return MD_FAIL; }
    if (settle(s, &events_here) != MD_OK) { return MD_FAIL; }

    while (s->t < t_end) {
        double h, t_new = 0.0, err = 0.0, h_planned, hmin = min_step(s->t);
        int rejected_here = 0, nonfinite = 0, last = 0;

        if (!s->fsal_valid) {
            if (!derivative(s, s->t, s->y, s->k1)) {
                return fail(s, "integrator failed at t=%.10g s: non-finite derivative at the "
                               "last good point %s", s->t, NONFINITE_HINT);
            }
            s->fsal_valid = 1;
        }
        h = s->h_next > 0.0 ? s->h_next : initial_step(s, t_end - s->t);
        if (s->settings.max_step > 0.0) { h = fmin(h, s->settings.max_step); }

        for (;;) { /* attempts at one step */
            double remaining = t_end - s->t;
            if (++attempts > s->settings.max_steps) {
                return fail(s, "integrator failed at t=%.10g s: more than %ld internal steps in "
                               "one communication step (a stiff model, or tolerances too tight? "
                               "relTol=%g absTol=%g)", s->t, s->settings.max_steps,
                            s->settings.rel_tol, s->settings.abs_tol);
            }
            h_planned = h;
            last = h >= remaining - hmin; /* never past t_end, and leave no sliver behind */
            if (last) { h = remaining; t_new = t_end; } else { t_new = s->t + h; }

            nonfinite = !dopri_step(s, h, t_new, &err);
            if (!nonfinite && err <= 1.0) { break; }

            s->count.rejected++;
            rejected_here = 1;
            h = nonfinite ? h * FAC_NONFINITE : h * fmax(FAC_MIN, SAFETY * pow(err, -0.2));
            if (h < hmin) {
                if (nonfinite) {
                    return fail(s, "integrator failed at t=%.10g s: non-finite derivative just "
                                   "after this point, step size reduced to %.3g s without "
                                   "success %s", s->t, h, NONFINITE_HINT);
                }
                return fail(s, "integrator failed at t=%.10g s: step size %.3g s below the "
                               "minimum %.3g s, the error test keeps failing (a discontinuity "
                               "without an event, or a singularity?)", s->t, h, hmin);
            }
        }

        /* accepted */
        s->count.steps++;
        {
            double fac = err > 0.0 ? SAFETY * pow(err, -0.2) : FAC_MAX;
            fac = fmin(FAC_MAX, fmax(FAC_MIN, fac));
            if (rejected_here) { fac = fmin(fac, 1.0); }
            s->h_next = h * fac;
            /* a step shortened to land on t_end says nothing about the step size needed */
            if (last && h < h_planned) { s->h_next = fmax(s->h_next, h_planned); }
        }

        if (nz > 0 && evaluate_indicators(s, t_new, s->ynew, s->zr) != MD_OK) {
            return MD_FAIL; /* the state stays at the start of the step */
        }
        if (nz > 0 && any_fires(s, s->z, s->zr)) {
            if (locate(s, t_new, h) != MD_OK) { return MD_FAIL; }
            if (settle(s, &events_here) != MD_OK) { return MD_FAIL; }
            s->fsal_valid = 0;
        } else {
            s->t = t_new;
            memcpy(s->y, s->ynew, sizeof(double) * (size_t)ny);
            memcpy(s->k1, STAGE(6), sizeof(double) * (size_t)ny); /* FSAL */
            memcpy(s->z, s->zr, sizeof(double) * (size_t)nz);
            for (int k = 0; k < nz; ++k) { s->cond[k] = s->z[k] > 0.0; }
        }
    }

    if (md_solver_observe(s) != MD_OK) { return MD_FAIL; }
    logf_(s, MD_LOG_ALL, "advanced t=%.10g -> %.10g s: %lu steps, %lu rejected, %ld events, "
                         "next step %.3g s", t_start, s->t, s->count.steps - steps0,
          s->count.rejected - rejected0, events_here, s->h_next);
    return MD_OK;
}

#undef STAGE

/* ---------------------------------------------------------------------------------------
 * Model Exchange
 * ------------------------------------------------------------------------------------- */

void md_solver_set_point(md_solver *s, double t, const double *y) {
    s->t = t;
    if (y != NULL) { memcpy(s->y, y, sizeof(double) * (size_t)s->info->ny); }
    s->fsal_valid = 0;
}

md_status md_solver_derivatives(md_solver *s, double *dy) {
    const md_info *info = s->info;
    memcpy(s->w_tmp, s->w, sizeof(double) * (size_t)info->nw);
    rhs(s->t, s->y, s->p, s->w, dy);
    memcpy(s->w, s->w_tmp, sizeof(double) * (size_t)info->nw);
    if (!all_finite(dy, info->ny)) {
        return fail(s, "a state derivative is not finite at t=%.10g s %s", s->t, NONFINITE_HINT);
    }
    return MD_OK;
}

md_status md_solver_indicators(md_solver *s, double *z) {
    const md_info *info = s->info;
    md_status status;
    memcpy(s->w_tmp, s->w, sizeof(double) * (size_t)info->nw);
    status = evaluate_indicators(s, s->t, s->y, z);
    memcpy(s->w, s->w_tmp, sizeof(double) * (size_t)info->nw);
    return status;
}

md_status md_solver_handle_events(md_solver *s, int *state_changed) {
    const md_info *info = s->info;
    long events_here = 0;
    /* ytmp is scratch here (no step in progress): the state before the events */
    memcpy(s->ytmp, s->y, sizeof(double) * (size_t)info->ny);
    if (evaluate_indicators(s, s->t, s->y, s->zr) != MD_OK) { return MD_FAIL; }
    if (settle(s, &events_here) != MD_OK) { return MD_FAIL; }
    *state_changed = memcmp(s->ytmp, s->y, sizeof(double) * (size_t)info->ny) != 0;
    s->fsal_valid = 0;
    return md_solver_observe(s);
}

/* ---------------------------------------------------------------------------------------
 * State copy and serialisation
 * ------------------------------------------------------------------------------------- */

#define MD_STATE_MAGIC 0x3153444Du /* "MDS1" read as little-endian bytes */
#define MD_STATE_VERSION 1u
#define MD_STATE_NDOUBLE 5          /* rel_tol abs_tol max_step t h_next */
#define MD_STATE_NINT 8             /* see write_scalars */

typedef struct {
    uint32_t magic;
    uint32_t version;
    uint64_t guid_hash;
    int32_t ny, np, nw, nobs, nz, reserved;
    uint64_t payload_size;
    uint64_t checksum;  /* FNV-1a of the payload */
} md_state_header;

static uint64_t fnv1a(const unsigned char *data, size_t n, uint64_t h) {
    for (size_t i = 0; i < n; ++i) {
        h ^= data[i];
        h *= 1099511628211ull;
    }
    return h;
}

static const uint64_t FNV_BASIS = 14695981039346656037ull;

static uint64_t guid_hash(const md_info *info) {
    const char *g = info->guid != NULL ? info->guid : "";
    return fnv1a((const unsigned char *)g, strlen(g), FNV_BASIS);
}

static size_t payload_size(const md_info *info) {
    size_t ny = (size_t)info->ny, nz = (size_t)info->nz;
    return sizeof(double) * (MD_STATE_NDOUBLE + 2 * ny + (size_t)info->np + (size_t)info->nw
                             + (size_t)info->nobs + nz)
           + sizeof(int64_t) * MD_STATE_NINT + nz;
}

size_t md_solver_state_size(const md_info *info) {
    return sizeof(md_state_header) + payload_size(info);
}

static unsigned char *put(unsigned char *at, const void *data, size_t n) {
    if (n > 0) { memcpy(at, data, n); }
    return at + n;
}

static const unsigned char *get(const unsigned char *at, void *data, size_t n) {
    if (n > 0) { memcpy(data, at, n); }
    return at + n;
}

md_status md_solver_save(md_solver *s, int tag, void *buf, size_t size) {
    const md_info *info = s->info;
    md_state_header header;
    unsigned char *payload, *at;
    double scalars[MD_STATE_NDOUBLE];
    int64_t ints[MD_STATE_NINT];

    if (buf == NULL || size != md_solver_state_size(info)) {
        return fail(s, "state buffer of %lu bytes, %lu expected", (unsigned long)size,
                    (unsigned long)md_solver_state_size(info));
    }
    scalars[0] = s->settings.rel_tol;
    scalars[1] = s->settings.abs_tol;
    scalars[2] = s->settings.max_step;
    scalars[3] = s->t;
    scalars[4] = s->h_next;
    ints[0] = s->settings.max_events_per_step;
    ints[1] = s->settings.max_steps;
    ints[2] = (int64_t)s->count.steps;
    ints[3] = (int64_t)s->count.rejected;
    ints[4] = (int64_t)s->count.rhs_calls;
    ints[5] = (int64_t)s->count.events;
    ints[6] = s->fsal_valid;
    ints[7] = tag;

    payload = at = (unsigned char *)buf + sizeof header;
    at = put(at, scalars, sizeof scalars);
    at = put(at, ints, sizeof ints);
    at = put(at, s->k1, sizeof(double) * (size_t)info->ny);
    at = put(at, s->y, sizeof(double) * (size_t)info->ny);
    at = put(at, s->p, sizeof(double) * (size_t)info->np);
    at = put(at, s->w, sizeof(double) * (size_t)info->nw);
    at = put(at, s->obs, sizeof(double) * (size_t)info->nobs);
    at = put(at, s->z, sizeof(double) * (size_t)info->nz);
    at = put(at, s->cond, (size_t)info->nz);

    memset(&header, 0, sizeof header);
    header.magic = MD_STATE_MAGIC;
    header.version = MD_STATE_VERSION;
    header.guid_hash = guid_hash(info);
    header.ny = info->ny; header.np = info->np; header.nw = info->nw;
    header.nobs = info->nobs; header.nz = info->nz;
    header.payload_size = (uint64_t)(at - payload);
    header.checksum = fnv1a(payload, (size_t)(at - payload), FNV_BASIS);
    memcpy(buf, &header, sizeof header);
    return MD_OK;
}

/* Check buf; if `into` is not NULL, also restore it into `into`. */
static md_status load(md_solver *s, const void *buf, size_t size, int *tag, int restore) {
    const md_info *info = s->info;
    md_state_header header;
    const unsigned char *payload, *at;
    double scalars[MD_STATE_NDOUBLE];
    int64_t ints[MD_STATE_NINT];
    md_settings settings;

    if (buf == NULL) { return fail(s, "no state buffer"); }
    if (size < sizeof header) {
        return fail(s, "state buffer too short (%lu bytes) to be a state of this FMU",
                    (unsigned long)size);
    }
    memcpy(&header, buf, sizeof header);
    if (header.magic != MD_STATE_MAGIC || header.version != MD_STATE_VERSION) {
        return fail(s, "not a state of this FMU (bad magic number or format version)");
    }
    if (header.guid_hash != guid_hash(info) || header.ny != info->ny || header.np != info->np
        || header.nw != info->nw || header.nobs != info->nobs || header.nz != info->nz) {
        return fail(s, "the state belongs to another model (GUID or array sizes differ)");
    }
    if (size != md_solver_state_size(info) || header.payload_size != payload_size(info)) {
        return fail(s, "state buffer of %lu bytes, %lu expected", (unsigned long)size,
                    (unsigned long)md_solver_state_size(info));
    }
    payload = (const unsigned char *)buf + sizeof header;
    if (fnv1a(payload, (size_t)header.payload_size, FNV_BASIS) != header.checksum) {
        return fail(s, "the state is corrupted (checksum mismatch)");
    }
    at = get(payload, scalars, sizeof scalars);
    at = get(at, ints, sizeof ints);

    /* plausibility, so that a state that passes the checksum by construction but was
       produced by something else cannot put the instance in an impossible state */
    settings.rel_tol = scalars[0];
    settings.abs_tol = scalars[1];
    settings.max_step = scalars[2];
    settings.max_events_per_step = (long)ints[0];
    settings.max_steps = (long)ints[1];
    if (!(settings.rel_tol > 0.0 && settings.rel_tol <= 0.1) || !(settings.abs_tol > 0.0)
        || !isfinite(settings.abs_tol) || !(settings.max_step >= 0.0)
        || !isfinite(settings.max_step) || settings.max_events_per_step < 1
        || settings.max_steps < 1 || !isfinite(scalars[3]) || !(scalars[4] >= 0.0)
        || !isfinite(scalars[4]) || (ints[6] != 0 && ints[6] != 1) || ints[2] < 0
        || ints[3] < 0 || ints[4] < 0 || ints[5] < 0) {
        return fail(s, "the state is corrupted (implausible solver settings or time)");
    }
    {
        const unsigned char *cond = at + sizeof(double) * (2 * (size_t)info->ny
                                    + (size_t)info->np + (size_t)info->nw + (size_t)info->nobs
                                    + (size_t)info->nz);
        for (int k = 0; k < info->nz; ++k) {
            if (cond[k] > 1) { return fail(s, "the state is corrupted (event conditions)"); }
        }
    }
    if (tag != NULL) { *tag = (int)ints[7]; }
    if (!restore) { return MD_OK; }

    s->settings = settings;
    s->t = scalars[3];
    s->h_next = scalars[4];
    s->count.steps = (unsigned long)ints[2];
    s->count.rejected = (unsigned long)ints[3];
    s->count.rhs_calls = (unsigned long)ints[4];
    s->count.events = (unsigned long)ints[5];
    s->fsal_valid = (int)ints[6];
    at = get(at, s->k1, sizeof(double) * (size_t)info->ny);
    at = get(at, s->y, sizeof(double) * (size_t)info->ny);
    at = get(at, s->p, sizeof(double) * (size_t)info->np);
    at = get(at, s->w, sizeof(double) * (size_t)info->nw);
    at = get(at, s->obs, sizeof(double) * (size_t)info->nobs);
    at = get(at, s->z, sizeof(double) * (size_t)info->nz);
    (void)get(at, s->cond, (size_t)info->nz);
    return MD_OK;
}

md_status md_solver_check(md_solver *s, const void *buf, size_t size, int *tag) {
    return load(s, buf, size, tag, 0);
}

md_status md_solver_restore(md_solver *s, const void *buf, size_t size, int *tag) {
    return load(s, buf, size, tag, 1);
}
