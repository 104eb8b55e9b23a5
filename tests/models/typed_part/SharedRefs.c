/* A part whose Integer and Boolean outputs share value references with Reals (as FMI 2.0 allows):
   Real x (vr 0, input), y = x + 1000 (vr 1, output), z = -7 (vr 2, local);
   Integer count (vr 1, output): the doSteps taken; Boolean flag (vr 2, output): count is odd. */
#include <stdlib.h>
#include <stddef.h>
#define API __attribute__((visibility("default")))
typedef struct { double x; int count; } part_t;
API const char *fmi2GetTypesPlatform(void) { return "default"; }
API const char *fmi2GetVersion(void) { return "2.0"; }
API int fmi2SetDebugLogging(void *c, int on, size_t n, const char *const cats[]) { (void)c; (void)on; (void)n; (void)cats; return 0; }
API void *fmi2Instantiate(const char *name, int type, const char *guid, const char *uri, const void *functions, int visible, int logging) {
    (void)name; (void)type; (void)guid; (void)uri; (void)functions; (void)visible; (void)logging;
    return calloc(1, sizeof(part_t));
}
API void fmi2FreeInstance(void *c) { free(c); }
API int fmi2SetupExperiment(void *c, int tol_defined, double tol, double start, int stop_defined, double stop) {
    (void)c; (void)tol_defined; (void)tol; (void)start; (void)stop_defined; (void)stop; return 0;
}
API int fmi2EnterInitializationMode(void *c) { (void)c; return 0; }
API int fmi2ExitInitializationMode(void *c) { (void)c; return 0; }
API int fmi2Terminate(void *c) { (void)c; return 0; }
API int fmi2Reset(void *c) { ((part_t *)c)->count = 0; return 0; }
API int fmi2GetReal(void *c, const unsigned int vr[], size_t n, double value[]) {
    part_t *p = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == 0) value[i] = p->x; else if (vr[i] == 1) value[i] = p->x + 1000.0; else if (vr[i] == 2) value[i] = -7.0; else return 3;
    }
    return 0;
}
API int fmi2GetInteger(void *c, const unsigned int vr[], size_t n, int value[]) {
    part_t *p = c;
    for (size_t i = 0; i < n; i++) { if (vr[i] != 1) return 3; value[i] = p->count; }
    return 0;
}
API int fmi2GetBoolean(void *c, const unsigned int vr[], size_t n, int value[]) {
    part_t *p = c;
    for (size_t i = 0; i < n; i++) { if (vr[i] != 2) return 3; value[i] = p->count % 2; }
    return 0;
}
API int fmi2GetString(void *c, const unsigned int vr[], size_t n, const char *value[]) { (void)c; (void)vr; (void)n; (void)value; return 3; }
API int fmi2SetReal(void *c, const unsigned int vr[], size_t n, const double value[]) {
    part_t *p = c;
    for (size_t i = 0; i < n; i++) { if (vr[i] != 0) return 3; p->x = value[i]; }
    return 0;
}
API int fmi2SetInteger(void *c, const unsigned int vr[], size_t n, const int value[]) { (void)c; (void)vr; (void)n; (void)value; return 3; }
API int fmi2SetBoolean(void *c, const unsigned int vr[], size_t n, const int value[]) { (void)c; (void)vr; (void)n; (void)value; return 3; }
API int fmi2SetString(void *c, const unsigned int vr[], size_t n, const char *const value[]) { (void)c; (void)vr; (void)n; (void)value; return 3; }
API int fmi2DoStep(void *c, double t, double h, int no_prior) { (void)t; (void)h; (void)no_prior; ((part_t *)c)->count++; return 0; }
API int fmi2CancelStep(void *c) { (void)c; return 3; }
/* the rest of the FMI 2.0 Co-Simulation API, which this part does not offer */
#define UNSUPPORTED(name) API int name() { return 3; }
UNSUPPORTED(fmi2GetFMUstate)
UNSUPPORTED(fmi2SetFMUstate)
UNSUPPORTED(fmi2FreeFMUstate)
UNSUPPORTED(fmi2SerializedFMUstateSize)
UNSUPPORTED(fmi2SerializeFMUstate)
UNSUPPORTED(fmi2DeSerializeFMUstate)
UNSUPPORTED(fmi2GetDirectionalDerivative)
UNSUPPORTED(fmi2SetRealInputDerivatives)
UNSUPPORTED(fmi2GetRealOutputDerivatives)
UNSUPPORTED(fmi2GetStatus)
UNSUPPORTED(fmi2GetRealStatus)
UNSUPPORTED(fmi2GetIntegerStatus)
UNSUPPORTED(fmi2GetBooleanStatus)
UNSUPPORTED(fmi2GetStringStatus)
