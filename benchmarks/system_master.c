/* toggle-cosim benchmark: a plain C master of the plant FMU and COPIES instances of a controller
 * FMU (FMI 2.0), written without the project's code: no Python, no tables, no plan.
 *
 *     system_master PLANT_BINARY PLANT_GUID CTRL_BINARY CTRL_GUID COPIES N T_S T_END REPETITIONS < SPEC
 *
 * SPEC (whitespace-separated numbers, benchmarks/system_bench.py writes it):
 *     plant:      n_real (vr value)*  n_int (vr value)*  n_bool (vr value)*
 *                 n_out vr*                                    the outputs read every sample
 *                 vr_iq_ref vr_F_E F_E                         its inputs; F_E constant
 *     controller: n_real (vr value)*  n_int (vr value)*  n_bool (vr value)*
 *                 n_in (vr plant_output_index)*                each input and the plant output it reads
 *                 n_cout vr*                                   the outputs read, the command first
 *
 * Instance 0 of the controller drives the plant (its command to iq_ref); the others read the
 * plant's outputs and their outputs are only recorded. Per sample k: get the plant's outputs,
 * per controller instance set its inputs and get its outputs, record the row, then (k < N) set
 * the plant's iq_ref and F_E, doStep the plant and every controller from t_k = k T_s.
 * Initialisation: instantiate, setupExperiment(0, T_END), the parameters, enter, (the plant: its
 * inputs 0 and F_E), exit. Prints the best time per sample in nanoseconds over REPETITIONS runs
 * (fresh instances each), the plant's first output at sample N, instance 0's command at N, and
 * the sum of the plant's first output over the samples 0 .. N in order, on one line. */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "fmi2Functions.h"

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2SetBooleanTYPE *set_boolean;
    fmi2GetRealTYPE *get_real;
    fmi2DoStepTYPE *do_step;
    fmi2TerminateTYPE *terminate;
    fmi2FreeInstanceTYPE *free_instance;
} api_t;

typedef struct {
    long n;
    fmi2ValueReference *vr;
    double *value;
} values_t;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env; (void)category;
    if (status > fmi2Warning) { fprintf(stderr, "%s: %s\n", name, message); }
}

static int load(const char *path, api_t *api) {
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) { fprintf(stderr, "%s\n", dlerror()); return 1; }
#define LOAD(field, name) api->field = (void *)dlsym(library, #name); if (api->field == NULL) { return 1; }
    LOAD(instantiate, fmi2Instantiate)
    LOAD(setup, fmi2SetupExperiment)
    LOAD(enter, fmi2EnterInitializationMode)
    LOAD(exit_, fmi2ExitInitializationMode)
    LOAD(set_real, fmi2SetReal)
    LOAD(set_integer, fmi2SetInteger)
    LOAD(set_boolean, fmi2SetBoolean)
    LOAD(get_real, fmi2GetReal)
    LOAD(do_step, fmi2DoStep)
    LOAD(terminate, fmi2Terminate)
    LOAD(free_instance, fmi2FreeInstance)
#undef LOAD
    return 0;
}

static int read_values(values_t *v) {
    if (scanf("%ld", &v->n) != 1 || v->n < 0) { return 1; }
    v->vr = malloc(sizeof(fmi2ValueReference) * (size_t)(v->n + 1));
    v->value = malloc(sizeof(double) * (size_t)(v->n + 1));
    for (long i = 0; i < v->n; i++) {
        if (scanf("%u %lf", &v->vr[i], &v->value[i]) != 2) { return 1; }
    }
    return 0;
}

static int read_vrs(long *n, fmi2ValueReference **vr, long **index, int with_index) {
    if (scanf("%ld", n) != 1 || *n < 0) { return 1; }
    *vr = malloc(sizeof(fmi2ValueReference) * (size_t)(*n + 1));
    if (with_index) { *index = malloc(sizeof(long) * (size_t)(*n + 1)); }
    for (long i = 0; i < *n; i++) {
        if (scanf("%u", &(*vr)[i]) != 1) { return 1; }
        if (with_index && scanf("%ld", &(*index)[i]) != 1) { return 1; }
    }
    return 0;
}

/* Set the parameters: reals, then (as integers or booleans) the others. */
static int set_values(const api_t *a, fmi2Component c, const values_t *real, const values_t *integer,
                      const values_t *boolean) {
    for (long i = 0; i < real->n; i++) {
        if (a->set_real(c, &real->vr[i], 1, &real->value[i]) > fmi2Warning) { return 1; }
    }
    for (long i = 0; i < integer->n; i++) {
        fmi2Integer value = (fmi2Integer)integer->value[i];
        if (a->set_integer(c, &integer->vr[i], 1, &value) > fmi2Warning) { return 1; }
    }
    for (long i = 0; i < boolean->n; i++) {
        fmi2Boolean value = boolean->value[i] != 0.0 ? fmi2True : fmi2False;
        if (a->set_boolean(c, &boolean->vr[i], 1, &value) > fmi2Warning) { return 1; }
    }
    return 0;
}

#define MAX_COPIES 16

int main(int argc, char **argv) {
    if (argc != 10) {
        fprintf(stderr, "usage: system_master PLANT_BINARY PLANT_GUID CTRL_BINARY CTRL_GUID COPIES N T_S T_END REPS < SPEC\n");
        return 2;
    }
    api_t plant, ctrl;
    if (load(argv[1], &plant) || load(argv[3], &ctrl)) { return 2; }
    long copies = atol(argv[5]), n = atol(argv[6]), repetitions = atol(argv[9]);
    double T_s = atof(argv[7]), t_end = atof(argv[8]);
    if (copies < 1 || copies > MAX_COPIES || n < 1) { return 2; }
    values_t p_real, p_int, p_bool, c_real, c_int, c_bool;
    long n_out, n_in, n_cout, *feeds = NULL;
    fmi2ValueReference *out_vr, *in_vr, *cout_vr, plant_in_vr[2];
    double F_E;
    if (read_values(&p_real) || read_values(&p_int) || read_values(&p_bool) || read_vrs(&n_out, &out_vr, NULL, 0) ||
        scanf("%u %u %lf", &plant_in_vr[0], &plant_in_vr[1], &F_E) != 3 || read_values(&c_real) ||
        read_values(&c_int) || read_values(&c_bool) || read_vrs(&n_in, &in_vr, &feeds, 1) ||
        read_vrs(&n_cout, &cout_vr, NULL, 0) || n_out < 1 || n_cout < 1) {
        fprintf(stderr, "system_master: the spec on stdin cannot be read\n");
        return 2;
    }
    long width = n_out + copies * n_cout;
    double *trace = malloc(sizeof(double) * (size_t)((n + 1) * width));
    for (long i = 0; i < (n + 1) * width; i++) { trace[i] = 0.0; } /* touched before timing, as the loop's trace is */
    double *in = malloc(sizeof(double) * (size_t)(n_in + 1));
    double best = 1e300, sum = 0.0;
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    for (long r = 0; r < repetitions; r++) {
        fmi2Component p = plant.instantiate("plant", fmi2CoSimulation, argv[2], "", &callbacks, fmi2False, fmi2False);
        fmi2Component c[MAX_COPIES];
        double start_inputs[2] = {0.0, F_E};
        if (p == NULL || plant.setup(p, fmi2False, 0.0, 0.0, fmi2True, t_end) > fmi2Warning ||
            set_values(&plant, p, &p_real, &p_int, &p_bool) || plant.enter(p) > fmi2Warning ||
            plant.set_real(p, plant_in_vr, 2, start_inputs) > fmi2Warning || plant.exit_(p) > fmi2Warning) {
            fprintf(stderr, "system_master: the plant cannot be initialised\n");
            return 1;
        }
        for (long i = 0; i < copies; i++) {
            c[i] = ctrl.instantiate("controller", fmi2CoSimulation, argv[4], "", &callbacks, fmi2False, fmi2False);
            if (c[i] == NULL || ctrl.setup(c[i], fmi2False, 0.0, 0.0, fmi2True, t_end) > fmi2Warning ||
                set_values(&ctrl, c[i], &c_real, &c_int, &c_bool) || ctrl.enter(c[i]) > fmi2Warning ||
                ctrl.exit_(c[i]) > fmi2Warning) {
                fprintf(stderr, "system_master: the controller cannot be initialised\n");
                return 1;
            }
        }
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (long k = 0; k <= n; k++) {
            double t = (double)k * T_s, *row = trace + k * width, *y = row;
            if (plant.get_real(p, out_vr, (size_t)n_out, y) > fmi2Warning) { return 1; }
            for (long i = 0; i < copies; i++) {
                for (long j = 0; j < n_in; j++) { in[j] = y[feeds[j]]; }
                if (ctrl.set_real(c[i], in_vr, (size_t)n_in, in) > fmi2Warning ||
                    ctrl.get_real(c[i], cout_vr, (size_t)n_cout, row + n_out + i * n_cout) > fmi2Warning) {
                    return 1;
                }
            }
            if (k == n) { break; }
            double u[2] = {row[n_out], F_E};
            if (plant.set_real(p, plant_in_vr, 2, u) > fmi2Warning || plant.do_step(p, t, T_s, fmi2False) > fmi2Warning) {
                return 1;
            }
            for (long i = 0; i < copies; i++) {
                if (ctrl.do_step(c[i], t, T_s, fmi2False) > fmi2Warning) { return 1; }
            }
        }
        clock_gettime(CLOCK_MONOTONIC, &t1);
        double seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
        if (seconds < best) { best = seconds; }
        for (long i = 0; i < copies; i++) {
            ctrl.terminate(c[i]);
            ctrl.free_instance(c[i]);
        }
        plant.terminate(p);
        plant.free_instance(p);
    }
    for (long k = 0; k <= n; k++) { sum += trace[k * width]; }
    printf("%.3f %.17g %.17g %.17g\n", 1e9 * best / (double)n, trace[n * width], trace[n * width + n_out], sum);
    return 0;
}
