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

/* Up to n whole macro steps from step k (time t0 + k*h): every instance steps, then the
 * planned exchange runs, then the recorded values (read through `record`) go into one row
 * of `rows` (time first, nrec values after it). Returns the number of rows written; when
 * a call fails, *where says which (0 a doStep, 1 the exchange after it), *index and
 * *status which call and what it returned, and the rows before it are all there. */
long glider_run(const Op *ops, int nops, void *const *fns, void *const *comps, int nsteppers,
                double t0, long k, double h, long n, const double *const *record, int nrec,
                double *rows, int *where, int *index, int *status) {
    for (long j = 0; j < n; ++j, ++k) {
        int i = glider_step(fns, comps, nsteppers, t0 + (double)k * h, h, status);
        if (i >= 0) {
            *where = 0;
            *index = i;
            return j;
        }
        i = glider_exchange(ops, nops, status);
        if (i >= 0) {
            *where = 1;
            *index = i;
            return j;
        }
        double *row = rows + j * (long)(nrec + 1);
        row[0] = t0 + (double)(k + 1) * h;
        for (int c = 0; c < nrec; ++c) row[1 + c] = *record[c];
    }
    return n;
}

/* FMI 3.0 instances behind the FMI 2.0 signatures the loops above call (and the master's
 * Python loop): `a` is a Fmi3Adapter holding the instance and its FMU's fmi3 functions.
 * Float64 and Int32 are passed through (nValues = n); Booleans are converted between
 * fmi2Boolean (int) and fmi3Boolean (bool); a doStep that reports terminateSimulation is
 * fmi3Discard, the stop the master already handles for FMI 2.0. */
#include <stdbool.h>
#include <stdint.h>

typedef struct {
    void *instance;
    void *get_float64, *set_float64, *get_int32, *set_int32, *get_boolean, *set_boolean;
    void *do_step;
} Fmi3Adapter;

typedef int (*get_f64_fn)(void *, const unsigned *, size_t, double *, size_t);
typedef int (*set_f64_fn)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*get_i32_fn)(void *, const unsigned *, size_t, int32_t *, size_t);
typedef int (*set_i32_fn)(void *, const unsigned *, size_t, const int32_t *, size_t);
typedef int (*get_bool_fn)(void *, const unsigned *, size_t, bool *, size_t);
typedef int (*set_bool_fn)(void *, const unsigned *, size_t, const bool *, size_t);
typedef int (*do_step3_fn)(void *, double, double, bool, bool *, bool *, bool *, double *);

int glider_shim_get_float64(void *a, const unsigned *vr, size_t n, double *v) {
    const Fmi3Adapter *x = a;
    return ((get_f64_fn)x->get_float64)(x->instance, vr, n, v, n);
}

int glider_shim_set_float64(void *a, const unsigned *vr, size_t n, const double *v) {
    const Fmi3Adapter *x = a;
    return ((set_f64_fn)x->set_float64)(x->instance, vr, n, v, n);
}

int glider_shim_get_int32(void *a, const unsigned *vr, size_t n, int *v) {
    const Fmi3Adapter *x = a;
    return ((get_i32_fn)x->get_int32)(x->instance, vr, n, (int32_t *)v, n);
}

int glider_shim_set_int32(void *a, const unsigned *vr, size_t n, const int *v) {
    const Fmi3Adapter *x = a;
    return ((set_i32_fn)x->set_int32)(x->instance, vr, n, (const int32_t *)v, n);
}

#define SHIM_CHUNK 64

int glider_shim_get_boolean(void *a, const unsigned *vr, size_t n, int *v) {
    const Fmi3Adapter *x = a;
    bool b[SHIM_CHUNK];
    int worst = 0;
    for (size_t i = 0; i < n || (n == 0 && i == 0); i += SHIM_CHUNK) {
        size_t m = n - i < SHIM_CHUNK ? n - i : SHIM_CHUNK;
        int st = ((get_bool_fn)x->get_boolean)(x->instance, vr + i, m, b, m);
        if (st > worst) worst = st;
        if (st > 1) return st;
        for (size_t k = 0; k < m; ++k) v[i + k] = b[k] ? 1 : 0;
        if (n == 0) break;
    }
    return worst;
}

int glider_shim_set_boolean(void *a, const unsigned *vr, size_t n, const int *v) {
    const Fmi3Adapter *x = a;
    bool b[SHIM_CHUNK];
    int worst = 0;
    for (size_t i = 0; i < n || (n == 0 && i == 0); i += SHIM_CHUNK) {
        size_t m = n - i < SHIM_CHUNK ? n - i : SHIM_CHUNK;
        for (size_t k = 0; k < m; ++k) b[k] = v[i + k] != 0;
        int st = ((set_bool_fn)x->set_boolean)(x->instance, vr + i, m, b, m);
        if (st > worst) worst = st;
        if (st > 1) return st;
        if (n == 0) break;
    }
    return worst;
}

int glider_shim_do_step(void *a, double t, double h, int no_set_prior) {
    const Fmi3Adapter *x = a;
    bool event = false, terminate = false, early = false;
    double last = t;
    int st = ((do_step3_fn)x->do_step)(x->instance, t, h, no_set_prior != 0, &event, &terminate,
                                      &early, &last);
    if (st <= 1 && terminate) return 2; /* fmi3Discard: the FMU ends the run */
    return st;
}
