/* glider-cosim's FMI-LS-WASM glue: the co-simulation-fmu world of fmi:fmi3@3.0.0 (the
 * WIT next to this file, wit/) in the component model's canonical ABI, over the FMI 3.0
 * front end (fmi3_layer.c) of the same FMI layer and native back end as every native FMU.
 *
 * Each export lifts its arguments (strings and lists the host wrote into this memory
 * through cabi_realloc), makes the fmi3 call and lowers the result: a status, or a
 * result<..., status> in a return area. One instance of the resource co-simulation-instance
 * is a Glue (its rep); dropping it is fmi3FreeInstance. Log messages go to the imported
 * callbacks.log-message with the instance's name. The draft's mapping, kept here:
 * - a result<T, status> is ok(T) when the call returned OK or Warning (the warning's text
 *   reaches the logger), err(status) otherwise; do-step's Discard (the model stopped the
 *   simulation: terminateSimulation) is err(discard);
 * - get-fmu-state is fmi3GetFMUState + fmi3SerializeFMUState (the state freed), set-fmu-state
 *   fmi3DeserializeFMUState + fmi3SetFMUState;
 * - set-input-derivatives has no FMI 3.0 call: refused like any call this FMU lacks.
 * Memory: arguments are freed after the call; a result's list is kept until the next call
 * that returns one (no post-return functions needed). No WASI call is made: the component
 * imports the standard's callbacks and nothing else.
 *
 * C99 (with the wasm import/export attributes of clang). Written from the FMI-LS-WASM draft
 * (modelica/fmi-ls-wasm @ c1aac17) and the component model's canonical ABI.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "fmi_layer.h"

#define IFACE "fmi:fmi3/co-simulation@3.0.0#"
#define METHOD(n) __attribute__((export_name(IFACE "[method]co-simulation-instance." n)))
#define IMPORT(module, name) __attribute__((import_module(module), import_name(name)))

typedef struct {
    fmi3Instance fmi;
    char *name;
} Glue;

typedef struct {
    const char *ptr;
    size_t len;
} Str; /* a string or list<u8> in the canonical ABI: pointer, length */

IMPORT("fmi:fmi3/callbacks@3.0.0", "log-message")
extern void host_log(const char *name, size_t name_len, int32_t status, const char *category,
                     size_t category_len, const char *message, size_t message_len);
IMPORT("[export]fmi:fmi3/co-simulation@3.0.0", "[resource-new]co-simulation-instance")
extern int32_t resource_new(intptr_t rep);

/* A pointer in a return area, and the length after it: the canonical ABI's (wasm32) i32
 * at 4 and 8 in a result's payload; in a native build of this file (the memory checks of
 * tests/integration/wasm_glue_harness.c) pointer-sized, at 8 and 16. */
#define PTR_AT sizeof(void *)
#define LEN_AT (2 * sizeof(void *))

/* ------------------------------------------------------------------ memory */
static uint64_t g_ret[4]; /* the return area of a result (aligned 8, 32 bytes) */
static void *g_out;       /* the list of the last result, freed at the next one */

__attribute__((export_name("cabi_realloc"))) void *cabi_realloc(void *ptr, size_t old,
                                                                  size_t align, size_t size) {
    void *p;
    (void)old;
    if (size == 0) return (void *)align; /* a non-null, aligned, empty block */
    if (!(p = realloc(ptr, size))) abort();
    return p;
}

static void *out_alloc(size_t size) {
    free(g_out);
    if (!(g_out = calloc(size ? size : 1, 1))) abort();
    return g_out;
}

static void *tmp_alloc(size_t size) {
    void *p = calloc(size ? size : 1, 1);
    if (!p) abort();
    return p;
}

/* an argument the host allocated (nothing when it is empty: then it is no block) */
static void drop(const void *p, size_t n) {
    if (n) free((void *)p);
}

static void drop_strs(const Str *s, size_t n) {
    size_t i;
    for (i = 0; i < n; ++i) drop(s[i].ptr, s[i].len);
    drop(s, n);
}

static char *cstr(const char *p, size_t n) {
    char *s = tmp_alloc(n + 1);
    memcpy(s, p, n);
    s[n] = '\0';
    drop(p, n);
    return s;
}

/* result<list<T>, status> */
static uint8_t *ret_list(int st, void *list, size_t n) {
    uint8_t *r = (uint8_t *)g_ret;
    uintptr_t p = (uintptr_t)list;
    uint32_t len = (uint32_t)n;
    memset(g_ret, 0, sizeof g_ret);
    if (st <= fmi3Warning) {
        memcpy(r + PTR_AT, &p, sizeof p);
        memcpy(r + LEN_AT, &len, 4);
    } else {
        r[0] = 1;
        r[PTR_AT] = (uint8_t)st;
    }
    return r;
}

/* result<T, status> with T of alignment 8: the payload at 8 (the status too) */
static uint8_t *ret_err8(int st) {
    uint8_t *r = (uint8_t *)g_ret;
    memset(g_ret, 0, sizeof g_ret);
    r[0] = 1;
    r[8] = (uint8_t)st;
    return r;
}

/* ------------------------------------------------------------------ logging */
static void on_log(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                   fmi3String message) {
    const char *name = env ? (const char *)env : "?";
    if (!category) category = "";
    if (!message) message = "";
    host_log(name, strlen(name), (int32_t)status, category, strlen(category), message,
             strlen(message));
}

/* ------------------------------------------------------------------ common */
__attribute__((export_name("fmi:fmi3/common@3.0.0#get-version"))) uint8_t *w_get_version(void) {
    const char *v = fmi3GetVersion();
    uintptr_t p = (uintptr_t)v;
    uint32_t n = (uint32_t)strlen(v);
    memcpy((uint8_t *)g_ret, &p, sizeof p);
    memcpy((uint8_t *)g_ret + PTR_AT, &n, 4);
    return (uint8_t *)g_ret;
}

/* ------------------------------------------------------------------ the instance */
__attribute__((export_name(IFACE "[static]co-simulation-instance.instantiate-co-simulation")))
uint8_t *w_instantiate(const char *name, size_t name_len, const char *token, size_t token_len,
                       const char *resources, size_t resources_len, int32_t visible,
                       int32_t logging_on, int32_t event_mode_used, int32_t early_return_allowed,
                       const uint32_t *required, size_t nrequired) {
    uint8_t *r = (uint8_t *)g_ret;
    Glue *g = tmp_alloc(sizeof *g);
    char *tok = cstr(token, token_len), *res = cstr(resources, resources_len);
    int32_t handle;
    g->name = cstr(name, name_len);
    g->fmi = fmi3InstantiateCoSimulation(g->name, tok, res, visible != 0, logging_on != 0,
                                         event_mode_used != 0, early_return_allowed != 0,
                                         required, nrequired, g->name, on_log, NULL);
    free(tok);
    free(res);
    drop(required, nrequired * 4);
    memset(g_ret, 0, sizeof g_ret);
    if (!g->fmi) {
        free(g->name);
        free(g);
        return r;
    }
    handle = resource_new((intptr_t)g);
    r[0] = 1;
    memcpy(r + 4, &handle, 4);
    return r;
}

__attribute__((export_name(IFACE "[dtor]co-simulation-instance"))) void w_free(Glue *g) {
    fmi3FreeInstance(g->fmi);
    free(g->name);
    free(g);
}

METHOD("set-debug-logging")
int32_t w_set_debug_logging(Glue *g, int32_t on, const Str *cats, size_t n) {
    const char **names = tmp_alloc(n * sizeof *names);
    size_t i;
    int st;
    for (i = 0; i < n; ++i) names[i] = cstr(cats[i].ptr, cats[i].len);
    drop(cats, n);
    st = fmi3SetDebugLogging(g->fmi, on != 0, n, names);
    for (i = 0; i < n; ++i) free((void *)names[i]);
    free(names);
    return st;
}

METHOD("enter-initialization-mode")
int32_t w_enter_init(Glue *g, int32_t has_tolerance, double tolerance, double start,
                     int32_t has_stop, double stop) {
    return fmi3EnterInitializationMode(g->fmi, has_tolerance != 0, tolerance, start,
                                       has_stop != 0, stop);
}

#define NO_ARGS(wit, fn)                                                                  \
    METHOD(wit) int32_t w_##fn(Glue *g) { return fmi3##fn(g->fmi); }
NO_ARGS("exit-initialization-mode", ExitInitializationMode)
NO_ARGS("enter-event-mode", EnterEventMode)
NO_ARGS("terminate", Terminate)
NO_ARGS("reset", Reset)
NO_ARGS("enter-configuration-mode", EnterConfigurationMode)
NO_ARGS("exit-configuration-mode", ExitConfigurationMode)
NO_ARGS("evaluate-discrete-states", EvaluateDiscreteStates)
NO_ARGS("enter-step-mode", EnterStepMode)
#undef NO_ARGS

METHOD("update-discrete-states") uint8_t *w_update_discrete_states(Glue *g) {
    fmi3Boolean b[5] = {0, 0, 0, 0, 0};
    fmi3Float64 next = 0.0;
    uint8_t *r = (uint8_t *)g_ret;
    int st = fmi3UpdateDiscreteStates(g->fmi, &b[0], &b[1], &b[2], &b[3], &b[4], &next);
    int i;
    if (st > fmi3Warning) return ret_err8(st);
    memset(g_ret, 0, sizeof g_ret);
    for (i = 0; i < 5; ++i) r[8 + i] = b[i] ? 1 : 0;
    memcpy(r + 16, &next, 8);
    return r;
}

/* ------------------------------------------------------------------ values
 * The types whose C array is the canonical ABI's list: the same bytes (fmi3Boolean and
 * fmi3Clock are C's bool, one byte, as WIT's bool). */
#define VALUES(wit, Type)                                                                 \
    METHOD("get-" wit)                                                                    \
    uint8_t *w_get_##Type(Glue *g, const uint32_t *vr, size_t n) {                        \
        fmi3##Type *v = out_alloc(n * sizeof *v);                                         \
        int st = fmi3Get##Type(g->fmi, vr, n, v, n);                                      \
        drop(vr, n);                                                                      \
        return ret_list(st, v, n);                                                        \
    }                                                                                     \
    METHOD("set-" wit)                                                                    \
    int32_t w_set_##Type(Glue *g, const uint32_t *vr, size_t n, const fmi3##Type *v,      \
                         size_t nv) {                                                     \
        int st = fmi3Set##Type(g->fmi, vr, n, v, nv);                                     \
        drop(vr, n);                                                                      \
        drop(v, nv);                                                                      \
        return st;                                                                        \
    }
VALUES("float32", Float32)
VALUES("float64", Float64)
VALUES("int8", Int8)
VALUES("int16", Int16)
VALUES("int32", Int32)
VALUES("int64", Int64)
VALUES("uint8", UInt8)
VALUES("uint16", UInt16)
VALUES("uint32", UInt32)
VALUES("uint64", UInt64)
VALUES("boolean", Boolean)
#undef VALUES

METHOD("get-string") uint8_t *w_get_string(Glue *g, const uint32_t *vr, size_t n) {
    fmi3String *v = tmp_alloc(n * sizeof *v);
    Str *out = out_alloc(n * sizeof *out);
    size_t i;
    int st = fmi3GetString(g->fmi, vr, n, v, n);
    drop(vr, n);
    for (i = 0; st <= fmi3Warning && i < n; ++i) {
        out[i].ptr = v[i] ? v[i] : "";
        out[i].len = strlen(out[i].ptr);
    }
    free(v);
    return ret_list(st, out, n);
}

METHOD("set-string")
int32_t w_set_string(Glue *g, const uint32_t *vr, size_t n, const Str *v, size_t nv) {
    fmi3String *s = tmp_alloc(nv * sizeof *s);
    size_t i;
    int st;
    for (i = 0; i < nv; ++i) s[i] = cstr(v[i].ptr, v[i].len);
    drop(v, nv);
    st = fmi3SetString(g->fmi, vr, n, s, nv);
    drop(vr, n);
    for (i = 0; i < nv; ++i) free((void *)s[i]);
    free(s);
    return st;
}

METHOD("get-binary") uint8_t *w_get_binary(Glue *g, const uint32_t *vr, size_t n) {
    size_t *sizes = tmp_alloc(n * sizeof *sizes), i;
    fmi3Binary *v = tmp_alloc(n * sizeof *v);
    Str *out = out_alloc(n * sizeof *out);
    int st = fmi3GetBinary(g->fmi, vr, n, sizes, v, n);
    drop(vr, n);
    for (i = 0; st <= fmi3Warning && i < n; ++i) {
        out[i].ptr = (const char *)v[i];
        out[i].len = sizes[i];
    }
    free(sizes);
    free(v);
    return ret_list(st, out, n);
}

METHOD("set-binary")
int32_t w_set_binary(Glue *g, const uint32_t *vr, size_t n, const Str *v, size_t nv) {
    size_t *sizes = tmp_alloc(nv * sizeof *sizes), i;
    fmi3Binary *b = tmp_alloc(nv * sizeof *b);
    int st;
    for (i = 0; i < nv; ++i) {
        b[i] = (fmi3Binary)v[i].ptr;
        sizes[i] = v[i].len;
    }
    st = fmi3SetBinary(g->fmi, vr, n, sizes, b, nv);
    drop(vr, n);
    drop_strs(v, nv);
    free(sizes);
    free(b);
    return st;
}

/* at least n elements of size each from a list of nv (FMI's clock functions take one
 * length: the references') */
static void *padded(const void *v, size_t nv, size_t n, size_t size) {
    void *p = tmp_alloc(n * size);
    memcpy(p, v, (nv < n ? nv : n) * size);
    drop(v, nv);
    return p;
}

METHOD("get-clock") uint8_t *w_get_clock(Glue *g, const uint32_t *vr, size_t n) {
    fmi3Clock *v = out_alloc(n * sizeof *v);
    int st = fmi3GetClock(g->fmi, vr, n, v);
    drop(vr, n);
    return ret_list(st, v, n);
}

METHOD("set-clock")
int32_t w_set_clock(Glue *g, const uint32_t *vr, size_t n, const fmi3Clock *v, size_t nv) {
    fmi3Clock *c = padded(v, nv, n, sizeof *c);
    int st = fmi3SetClock(g->fmi, vr, n, c);
    drop(vr, n);
    free(c);
    return st;
}

/* ------------------------------------------------------------------ dependencies */
METHOD("get-number-of-variable-dependencies")
uint8_t *w_get_number_of_dependencies(Glue *g, uint32_t vr) {
    size_t n = 0;
    uint64_t n64;
    int st = fmi3GetNumberOfVariableDependencies(g->fmi, vr, &n);
    if (st > fmi3Warning) return ret_err8(st);
    memset(g_ret, 0, sizeof g_ret);
    n64 = n;
    memcpy((uint8_t *)g_ret + 8, &n64, 8);
    return (uint8_t *)g_ret;
}

METHOD("get-variable-dependencies")
uint8_t *w_get_variable_dependencies(Glue *g, uint32_t dependent) {
    size_t n = 0, i, *ed, *ei;
    fmi3ValueReference *ind;
    fmi3DependencyKind *kind;
    uint8_t *out;
    int st = fmi3GetNumberOfVariableDependencies(g->fmi, dependent, &n);
    if (st > fmi3Warning) return ret_list(st, NULL, 0);
    ed = tmp_alloc(n * sizeof *ed);
    ei = tmp_alloc(n * sizeof *ei);
    ind = tmp_alloc(n * sizeof *ind);
    kind = tmp_alloc(n * sizeof *kind);
    st = fmi3GetVariableDependencies(g->fmi, dependent, ed, ind, ei, kind, n);
    out = out_alloc(n * 20); /* record: 4 x u32, an enum (u8): 20 bytes, align 4 */
    for (i = 0; st <= fmi3Warning && i < n; ++i) {
        uint32_t row[4];
        row[0] = dependent;
        row[1] = (uint32_t)ed[i];
        row[2] = ind[i];
        row[3] = (uint32_t)ei[i];
        memcpy(out + 20 * i, row, 16);
        out[20 * i + 16] = (uint8_t)kind[i];
    }
    free(ed);
    free(ei);
    free(ind);
    free(kind);
    return ret_list(st, out, n);
}

/* ------------------------------------------------------------------ FMU state */
METHOD("get-fmu-state") uint8_t *w_get_fmu_state(Glue *g) {
    fmi3FMUState s = NULL;
    size_t size = 0;
    void *bytes = NULL;
    int st = fmi3GetFMUState(g->fmi, &s);
    if (st <= fmi3Warning) st = fmi3SerializedFMUStateSize(g->fmi, s, &size);
    if (st <= fmi3Warning) st = fmi3SerializeFMUState(g->fmi, s, bytes = out_alloc(size), size);
    if (s) fmi3FreeFMUState(g->fmi, &s);
    return ret_list(st, bytes, size);
}

METHOD("set-fmu-state") int32_t w_set_fmu_state(Glue *g, const fmi3Byte *data, size_t n) {
    fmi3FMUState s = NULL;
    int st = fmi3DeserializeFMUState(g->fmi, data, n, &s);
    drop(data, n);
    if (st <= fmi3Warning) st = fmi3SetFMUState(g->fmi, s);
    if (s) fmi3FreeFMUState(g->fmi, &s);
    return st;
}

/* ------------------------------------------------------------------ derivatives */
#define DERIVATIVE(wit, fn, nout)                                                         \
    METHOD(wit)                                                                           \
    uint8_t *w_##fn(Glue *g, const uint32_t *u, size_t nu, const uint32_t *k, size_t nk,  \
                    const double *seed, size_t ns) {                                      \
        double *out = out_alloc((nout) * sizeof *out);                                    \
        int st = fmi3##fn(g->fmi, u, nu, k, nk, seed, ns, out, nout);                     \
        drop(u, nu);                                                                      \
        drop(k, nk);                                                                      \
        drop(seed, ns);                                                                   \
        return ret_list(st, out, nout);                                                   \
    }
DERIVATIVE("get-directional-derivative", GetDirectionalDerivative, nu)
DERIVATIVE("get-adjoint-derivative", GetAdjointDerivative, nk)
#undef DERIVATIVE

/* (value reference, order) pairs -> two arrays */
static void split_pairs(const uint32_t *pairs, size_t n, uint32_t **vr, fmi3Int32 **orders) {
    size_t i;
    *vr = tmp_alloc(n * sizeof **vr);
    *orders = tmp_alloc(n * sizeof **orders);
    for (i = 0; i < n; ++i) {
        (*vr)[i] = pairs[2 * i];
        (*orders)[i] = (fmi3Int32)pairs[2 * i + 1];
    }
    drop(pairs, n * 8);
}

METHOD("set-input-derivatives")
int32_t w_set_input_derivatives(Glue *g, const uint32_t *pairs, size_t n, const double *v,
                                size_t nv) {
    drop(pairs, n);
    drop(v, nv);
    return glider_op_unsupported(g->fmi, C_FMI3_ONLY); /* no such call in FMI 3.0 */
}

METHOD("get-output-derivatives")
uint8_t *w_get_output_derivatives(Glue *g, const uint32_t *pairs, size_t n) {
    uint32_t *vr;
    fmi3Int32 *orders;
    double *out = out_alloc(n * sizeof *out);
    int st;
    split_pairs(pairs, n, &vr, &orders);
    st = fmi3GetOutputDerivatives(g->fmi, vr, n, orders, out, n);
    free(vr);
    free(orders);
    return ret_list(st, out, n);
}

/* ------------------------------------------------------------------ clocks */
METHOD("get-interval-decimal") uint8_t *w_get_interval_decimal(Glue *g, const uint32_t *vr,
                                                                size_t n) {
    double *iv = tmp_alloc(n * sizeof *iv);
    fmi3IntervalQualifier *q = tmp_alloc(n * sizeof *q);
    uint8_t *out = out_alloc(n * 16); /* tuple<f64, enum>: 16 bytes */
    size_t i;
    int st = fmi3GetIntervalDecimal(g->fmi, vr, n, iv, q);
    drop(vr, n);
    for (i = 0; st <= fmi3Warning && i < n; ++i) {
        memcpy(out + 16 * i, &iv[i], 8);
        out[16 * i + 8] = (uint8_t)q[i];
    }
    free(iv);
    free(q);
    return ret_list(st, out, n);
}

METHOD("get-interval-fraction") uint8_t *w_get_interval_fraction(Glue *g, const uint32_t *vr,
                                                                  size_t n) {
    fmi3UInt64 *c = tmp_alloc(n * 8), *r = tmp_alloc(n * 8);
    fmi3IntervalQualifier *q = tmp_alloc(n * sizeof *q);
    uint8_t *out = out_alloc(n * 24); /* tuple<record{u64, u64}, enum>: 24 bytes */
    size_t i;
    int st = fmi3GetIntervalFraction(g->fmi, vr, n, c, r, q);
    drop(vr, n);
    for (i = 0; st <= fmi3Warning && i < n; ++i) {
        memcpy(out + 24 * i, &c[i], 8);
        memcpy(out + 24 * i + 8, &r[i], 8);
        out[24 * i + 16] = (uint8_t)q[i];
    }
    free(c);
    free(r);
    free(q);
    return ret_list(st, out, n);
}

METHOD("get-shift-decimal") uint8_t *w_get_shift_decimal(Glue *g, const uint32_t *vr, size_t n) {
    double *out = out_alloc(n * sizeof *out);
    int st = fmi3GetShiftDecimal(g->fmi, vr, n, out);
    drop(vr, n);
    return ret_list(st, out, n);
}

METHOD("get-shift-fraction") uint8_t *w_get_shift_fraction(Glue *g, const uint32_t *vr,
                                                            size_t n) {
    fmi3UInt64 *c = tmp_alloc(n * 8), *r = tmp_alloc(n * 8);
    uint8_t *out = out_alloc(n * 16);
    size_t i;
    int st = fmi3GetShiftFraction(g->fmi, vr, n, c, r);
    drop(vr, n);
    for (i = 0; st <= fmi3Warning && i < n; ++i) {
        memcpy(out + 16 * i, &c[i], 8);
        memcpy(out + 16 * i + 8, &r[i], 8);
    }
    free(c);
    free(r);
    return ret_list(st, out, n);
}

#define SET_DECIMAL(wit, fn)                                                              \
    METHOD(wit)                                                                           \
    int32_t w_##fn(Glue *g, const uint32_t *vr, size_t n, const double *v, size_t nv) {   \
        double *d = padded(v, nv, n, sizeof *d);                                          \
        int st = fmi3##fn(g->fmi, vr, n, d);                                              \
        drop(vr, n);                                                                      \
        free(d);                                                                          \
        return st;                                                                        \
    }
SET_DECIMAL("set-interval-decimal", SetIntervalDecimal)
SET_DECIMAL("set-shift-decimal", SetShiftDecimal)
#undef SET_DECIMAL

#define SET_FRACTION(wit, fn)                                                             \
    METHOD(wit)                                                                           \
    int32_t w_##fn(Glue *g, const uint32_t *vr, size_t n, const fmi3UInt64 *v, size_t nv) { \
        fmi3UInt64 *p = padded(v, nv, n, 16), *c = tmp_alloc(n * 8), *r = tmp_alloc(n * 8); \
        size_t i;                                                                         \
        int st;                                                                           \
        for (i = 0; i < n; ++i) {                                                         \
            c[i] = p[2 * i];                                                              \
            r[i] = p[2 * i + 1];                                                          \
        }                                                                                 \
        st = fmi3##fn(g->fmi, vr, n, c, r);                                               \
        drop(vr, n);                                                                      \
        free(p);                                                                          \
        free(c);                                                                          \
        free(r);                                                                          \
        return st;                                                                        \
    }
SET_FRACTION("set-interval-fraction", SetIntervalFraction)
SET_FRACTION("set-shift-fraction", SetShiftFraction)
#undef SET_FRACTION

/* ------------------------------------------------------------------ stepping */
METHOD("do-step")
uint8_t *w_do_step(Glue *g, double t, double h, int32_t no_set_prior) {
    fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
    fmi3Float64 last = t;
    uint8_t *r = (uint8_t *)g_ret;
    int st = fmi3DoStep(g->fmi, t, h, no_set_prior != 0, &event, &terminate, &early, &last);
    if (st > fmi3Warning) return ret_err8(st);
    memset(g_ret, 0, sizeof g_ret);
    memcpy(r + 8, &last, 8);
    r[16] = event ? 1 : 0;
    r[17] = terminate ? 1 : 0;
    r[18] = early ? 1 : 0;
    return r;
}
