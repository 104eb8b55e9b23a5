/* toggle-cosim benchmark: the controller FMU's cost per sample from C, no Python in the loop.
 *
 *     controller_driver BINARY GUID N REPETITIONS
 *
 * dlopens the FMI 2.0 binary of ToggleVSC, instantiates it, and per sample sets the inputs
 * x_B and v_B (a stroke from 0.2329 m towards the target), reads the five outputs and calls
 * fmi2DoStep(t_k, T_s), for N samples; prints the best time per sample in nanoseconds over
 * REPETITIONS runs (a fresh instance each) and the last command, on one line. */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env; (void)category;
    if (status > fmi2Warning) { fprintf(stderr, "%s: %s\n", name, message); }
}

#define LOAD(type, name) type name = (type)dlsym(library, #name); if (name == NULL) { return 2; }

int main(int argc, char **argv) {
    if (argc != 5) { fprintf(stderr, "usage: controller_driver BINARY GUID N REPETITIONS\n"); return 2; }
    void *library = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (library == NULL) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    LOAD(fmi2InstantiateTYPE *, fmi2Instantiate)
    LOAD(fmi2SetupExperimentTYPE *, fmi2SetupExperiment)
    LOAD(fmi2EnterInitializationModeTYPE *, fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationModeTYPE *, fmi2ExitInitializationMode)
    LOAD(fmi2SetRealTYPE *, fmi2SetReal)
    LOAD(fmi2GetRealTYPE *, fmi2GetReal)
    LOAD(fmi2DoStepTYPE *, fmi2DoStep)
    LOAD(fmi2FreeInstanceTYPE *, fmi2FreeInstance)
    long n = atol(argv[3]), repetitions = atol(argv[4]);
    const fmi2ValueReference in_vr[2] = {1, 2}, out_vr[5] = {5, 6, 7, 8, 9};
    const double T_s = 0.0005;
    double best = 1e300, out[5] = {0};
    fmi2CallbackFunctions callbacks = {logger, NULL, NULL, NULL, NULL};
    for (long r = 0; r < repetitions; r++) {
        fmi2Component c = fmi2Instantiate("bench", fmi2CoSimulation, argv[2], "", &callbacks, fmi2False, fmi2False);
        if (c == NULL) { return 1; }
        if (fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) > fmi2Warning ||
            fmi2EnterInitializationMode(c) > fmi2Warning || fmi2ExitInitializationMode(c) > fmi2Warning) {
            return 1;
        }
        struct timespec start, end;
        clock_gettime(CLOCK_MONOTONIC, &start);
        for (long k = 0; k < n; k++) {
            double s = (double)k / (double)n, in[2];
            in[0] = 0.2329 + 0.0875 * s;
            in[1] = 0.0875 / (n * T_s);
            if (fmi2SetReal(c, in_vr, 2, in) > fmi2Warning || fmi2GetReal(c, out_vr, 5, out) > fmi2Warning ||
                fmi2DoStep(c, (double)k * T_s, T_s, fmi2True) > fmi2Warning) {
                return 1;
            }
        }
        clock_gettime(CLOCK_MONOTONIC, &end);
        double seconds = (double)(end.tv_sec - start.tv_sec) + 1e-9 * (double)(end.tv_nsec - start.tv_nsec);
        if (seconds < best) { best = seconds; }
        fmi2FreeInstance(c);
    }
    printf("%.3f %.17g\n", 1e9 * best / (double)n, out[0]);
    return 0;
}
