/* A part that refuses steps: Real x (vr 0, input), y (vr 1, output) = the integral of x over the
   steps taken (y += x h), and the parameters (vr 2, 3, 4) refuse_from, refuse_until, pass_below:
   a doStep from t in [refuse_from, refuse_until) returns fmi2Discard, logging why, unless its
   step is shorter than pass_below (a retry's substeps pass; 0: none does). Real no_prior (vr 5,
   output) is the last doStep's noSetFMUStatePriorToCurrentPoint (1 or 0). It saves and restores
   its state (fmi2GetFMUstate / fmi2SetFMUstate: a copy of its struct); built with -DREFUSE_STATE,
   its fmi2GetFMUstate returns fmi2Error; built with -DINTERRUPT_AT=t, the doStep from t sends
   the process SIGINT (an interrupt that lands while the C runs). */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stddef.h>
#define API __attribute__((visibility("default")))
typedef void (*logger_t)(void *, const char *, int, const char *, const char *, ...);
typedef struct { logger_t logger; void *alloc, *free, *finished; void *environment; } callbacks_t;
typedef struct { double x, y, refuse_from, refuse_until, pass_below, no_prior; } values_t;
typedef struct { values_t v; logger_t logger; void *environment; char name[64]; } part_t;
API const char *fmi2GetTypesPlatform(void) { return "default"; }
API const char *fmi2GetVersion(void) { return "2.0"; }
API int fmi2SetDebugLogging(void *c, int on, size_t n, const char *const cats[]) { (void)c; (void)on; (void)n; (void)cats; return 0; }
API void *fmi2Instantiate(const char *name, int type, const char *guid, const char *uri, const callbacks_t *functions, int visible, int logging) {
    part_t *p = calloc(1, sizeof(part_t));
    (void)type; (void)guid; (void)uri; (void)visible; (void)logging;
    if (!p) return NULL;
    p->v.refuse_from = 1e300;
    p->v.refuse_until = 1e300;
    p->logger = functions ? functions->logger : NULL;
    p->environment = functions ? functions->environment : NULL;
    strncpy(p->name, name ? name : "", sizeof(p->name) - 1);
    return p;
}
API void fmi2FreeInstance(void *c) { free(c); }
API int fmi2SetupExperiment(void *c, int tol_defined, double tol, double start, int stop_defined, double stop) {
    (void)c; (void)tol_defined; (void)tol; (void)start; (void)stop_defined; (void)stop; return 0;
}
API int fmi2EnterInitializationMode(void *c) { (void)c; return 0; }
API int fmi2ExitInitializationMode(void *c) { (void)c; return 0; }
API int fmi2Terminate(void *c) { (void)c; return 0; }
API int fmi2Reset(void *c) { part_t *p = c; p->v.x = p->v.y = 0.0; return 0; }
static double *slot(part_t *p, unsigned int vr) {
    switch (vr) {
    case 0: return &p->v.x;
    case 1: return &p->v.y;
    case 2: return &p->v.refuse_from;
    case 3: return &p->v.refuse_until;
    case 4: return &p->v.pass_below;
    case 5: return &p->v.no_prior;
    default: return NULL;
    }
}
API int fmi2GetReal(void *c, const unsigned int vr[], size_t n, double value[]) {
    for (size_t i = 0; i < n; i++) { double *s = slot(c, vr[i]); if (!s) return 3; value[i] = *s; }
    return 0;
}
API int fmi2SetReal(void *c, const unsigned int vr[], size_t n, const double value[]) {
    for (size_t i = 0; i < n; i++) { double *s = slot(c, vr[i]); if (!s || vr[i] == 1 || vr[i] == 5) return 3; *s = value[i]; }
    return 0;
}
API int fmi2DoStep(void *c, double t, double h, int no_prior) {
    part_t *p = c;
    p->v.no_prior = no_prior ? 1.0 : 0.0;
    if (t >= p->v.refuse_from && t < p->v.refuse_until && !(h < p->v.pass_below)) {
        char said[128];
        snprintf(said, sizeof(said), "refused the step of %g s at t = %g s", h, t);
        if (p->logger) p->logger(p->environment, p->name, 2, "logStatusDiscard", said);
        return 2; /* fmi2Discard */
    }
    p->v.y += p->v.x * h;
#ifdef INTERRUPT_AT
    if (t >= INTERRUPT_AT && t < INTERRUPT_AT + 0.5 * h) { raise(SIGINT); }
#endif
    return 0;
}
API int fmi2GetFMUstate(void *c, void **state) {
#ifdef REFUSE_STATE
    (void)c; (void)state; return 3; /* fmi2Error: it declares the capability, yet refuses */
#endif
    if (!*state) { *state = malloc(sizeof(values_t)); if (!*state) return 3; }
    memcpy(*state, &((part_t *)c)->v, sizeof(values_t));
    return 0;
}
API int fmi2SetFMUstate(void *c, void *state) {
    if (!state) return 3;
    memcpy(&((part_t *)c)->v, state, sizeof(values_t));
    return 0;
}
API int fmi2FreeFMUstate(void *c, void **state) { (void)c; free(*state); *state = NULL; return 0; }
API int fmi2CancelStep(void *c) { (void)c; return 3; }
/* the rest of the FMI 2.0 Co-Simulation API, which this part does not offer */
#define UNSUPPORTED(name) API int name() { return 3; }
UNSUPPORTED(fmi2GetInteger)
UNSUPPORTED(fmi2GetBoolean)
UNSUPPORTED(fmi2GetString)
UNSUPPORTED(fmi2SetInteger)
UNSUPPORTED(fmi2SetBoolean)
UNSUPPORTED(fmi2SetString)
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
