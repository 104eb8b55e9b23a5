/* toggle-cosim benchmark: one FMU's own calls in a system, replayed alone from C.
 *
 * benchmarks/system_bench.py compiles this into a shared library and calls `replay` once per FMU
 * of a system, on a fresh instance initialised as the system's: per sample k it sets the FMU's
 * early inputs (row k of `early`), gets its outputs into row k of `outputs`, sets its late inputs
 * (row k of `late`) and, for k < n, calls doStep(k T_s, T_s): exactly the calls the system loop
 * makes on that FMU, with the values the system run recorded, and nothing else. Summed over the
 * FMUs, the times are the system's FMU work from C. FMI 2.0 only. Returns the number of samples
 * done (n + 1, or fewer where a call failed). */
#include <stddef.h>

typedef int (*get2_t)(void *, const unsigned int *, size_t, double *);
typedef int (*set2_t)(void *, const unsigned int *, size_t, const double *);
typedef int (*step2_t)(void *, double, double, int);

long replay(void *get, void *set, void *step, void *c, const unsigned int *out_vr, long n_out, double *outputs,
            const unsigned int *early_vr, long n_early, const double *early, const unsigned int *late_vr,
            long n_late, const double *late, long n, double T_s) {
    get2_t get_ = (get2_t)get;
    set2_t set_ = (set2_t)set;
    step2_t step_ = (step2_t)step;
    for (long k = 0; k <= n; k++) {
        if (n_early && set_(c, early_vr, (size_t)n_early, early + k * n_early) > 1) { return k; }
        if (n_out && get_(c, out_vr, (size_t)n_out, outputs + k * n_out) > 1) { return k; }
        if (k == n) { break; }
        if (n_late && set_(c, late_vr, (size_t)n_late, late + k * n_late) > 1) { return k; }
        if (step_(c, (double)k * T_s, T_s, 0) > 1) { return k; }
    }
    return n + 1;
}
