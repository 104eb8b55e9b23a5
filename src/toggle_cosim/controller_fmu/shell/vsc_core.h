/* toggle-cosim: the instance core of a sampled controller FMU, shared by the FMI 2.0 layer
 * (vsc_fmi2.c) and the FMI 3.0 layer (vsc_fmi3.c). No control law here: the law, its parameter
 * struct law_t and the tables of variables come from the generated vsc_model.h / vsc_law.c.
 *
 * Sampling (sample and hold, latched; docs/controller-fmu.md):
 *   t_k = startTime + k * T_s, from the sample count k (never accumulated);
 *   the outputs are the law at (t_k, the current inputs, z_k); setting an input or a parameter
 *   marks them stale and the next read re-evaluates them;
 *   at k = 0 every evaluation also starts the law (S0, T_h of eq. (21), z0) from the inputs;
 *   doStep(t_k, T_s) evaluates the sample if stale, commits z_{k+1} and advances k; the
 *   outputs then hold the sample just taken until an input is set.
 * Statuses are the numbers both standards share: 0 OK, 1 Warning, 2 Discard, 3 Error, 4 Fatal.
 */
#ifndef VSC_CORE_H
#define VSC_CORE_H

#include <stddef.h>

#include "vsc_model.h"

enum { VSC_OK = 0, VSC_WARNING = 1, VSC_DISCARD = 2, VSC_ERROR = 3, VSC_FATAL = 4 };
enum { VSC_INSTANTIATED = 0, VSC_INITIALIZATION = 1, VSC_STEPPING = 2, VSC_TERMINATED = 3 };
/* log categories (bits of vsc_core.categories) */
enum { VSC_LOG_EVENTS = 1, VSC_LOG_WARNING = 2, VSC_LOG_ERROR = 4, VSC_LOG_ALL = 8 };

/* Everything an FMU state holds: the whole state of the instance but its name and callbacks. */
typedef struct {
    double inputs[VSC_NIN];
    law_t law;                /* the parameters, with t0 and T_h of the first sample */
    double outputs[VSC_NOUT]; /* iq_ref, S, phase, e, z at the next sample */
    double start_time;
    double z;                 /* the law's state z_k at the present sample */
    long long k;              /* the present sample */
    int stale;                /* the outputs must be re-evaluated before they are read */
    int mode;
} vsc_data;

struct vsc_core;
typedef void (*vsc_emit)(const struct vsc_core *c, int status, const char *category,
                         const char *message);

typedef struct vsc_core {
    vsc_data d;
    char *name;
    vsc_emit emit;      /* the layer's logger (the standard's callback) */
    const void *env;    /* what the layer's logger needs */
    int logging_on;
    unsigned categories;
    int has_time;       /* FMI 3.0: the independent variable time has VSC_VR_TIME */
} vsc_core;

vsc_core *vsc_new(const char *name, vsc_emit emit, const void *env, int logging_on);
void vsc_free(vsc_core *c);
void vsc_defaults(vsc_data *d);
int vsc_log(const vsc_core *c, int status, const char *format, ...);
int vsc_set_categories(vsc_core *c, int on, size_t n, const char *const categories[]);
int vsc_check_mode(const vsc_core *c, const char *function, unsigned allowed);
int vsc_set_start(vsc_core *c, double start_time);
int vsc_enter_initialization(vsc_core *c, const char *function);
int vsc_exit_initialization(vsc_core *c, const char *function);
int vsc_get(vsc_core *c, const char *function, const unsigned vr[], size_t n, double values[]);
int vsc_set(vsc_core *c, const char *function, const unsigned vr[], size_t n, const double values[]);
int vsc_do_step(vsc_core *c, const char *function, double t, double h);
int vsc_terminate(vsc_core *c, const char *function);
void vsc_reset(vsc_core *c);
double vsc_time(const vsc_core *c);
/* FMU states: a copy of vsc_data; serialized as a tag and the bytes of vsc_data */
int vsc_get_state(vsc_core *c, const char *function, void **state);
int vsc_set_state(vsc_core *c, const char *function, const void *state);
void vsc_free_state(void *state);
size_t vsc_serialized_size(void);
int vsc_serialize(vsc_core *c, const char *function, const void *state, unsigned char out[], size_t size);
int vsc_deserialize(vsc_core *c, const char *function, const unsigned char in[], size_t size, void **state);

#define VSC_MODE_BIT(m) (1u << (m))
#define VSC_ANY_MODE 0xFu

#endif
