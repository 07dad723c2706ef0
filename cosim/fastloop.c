/* The master's per-step FMI calls in C (glider_cosim.fastloop): one call from Python per
 * communication point for the exchange and one for the steps, instead of one per FMI
 * call. Real values only. Returns the index of the first call whose status is worse
 * than fmi2Warning (its status in *status), or -1.
 */
#include <stddef.h>

typedef int (*values_fn)(void *c, const unsigned *vr, size_t n, double *values);
typedef int (*step_fn)(void *c, double t, double h, int no_set_prior);

typedef struct {
    void *fn;             /* fmi2GetReal or fmi2SetReal */
    void *comp;
    const unsigned *vr;
    size_t n;
    double *values;
    const double *const *sources; /* for a write: where each value comes from; else NULL */
} Op;

int glider_exchange(const Op *ops, int nops, int *status) {
    for (int i = 0; i < nops; ++i) {
        const Op *o = &ops[i];
        if (o->sources)
            for (size_t k = 0; k < o->n; ++k) o->values[k] = *o->sources[k];
        int st = ((values_fn)o->fn)(o->comp, o->vr, o->n, o->values);
        if (st > 1) {
            *status = st;
            return i;
        }
    }
    return -1;
}

int glider_step(void *const *fns, void *const *comps, int n, double t, double h, int *status) {
    for (int i = 0; i < n; ++i) {
        int st = ((step_fn)fns[i])(comps[i], t, h, 1);
        if (st > 1) {
            *status = st;
            return i;
        }
    }
    return -1;
}
