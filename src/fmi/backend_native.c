/* glider-cosim's native back end: runs a component's C model behind the FMI layer.
 *
 * The model (GLIDER_NATIVE_MODEL, native_model.h) brings its variable table and three
 * functions; this file does what the Python slave base (glider_fmi/slave_base.py) does
 * for the Python flavor, with the same messages: start values, the parameters' range
 * checks at fmi2ExitInitializationMode, setting parameters after initialisation (tunable
 * ones only, range-checked), refusing to set outputs, the step's time and input checks,
 * and the FMU state, which is a copy of the instance's data (no pointers in it), so it
 * serializes as its bytes.
 *
 * No heap in the step path, no global state: many instances live in one process and each
 * may be called from any thread (one thread at a time per instance, as FMI requires).
 * C99, libc and libm only.
 */
#include "glider_fp.h" /* first: no fused multiply-add (see there) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi_layer.h"
#include "native_model.h"

#define M GLIDER_NATIVE_MODEL
#define FAIL glider_fail

/* The instance's data: the FMI-level flags, then the model's data. */
typedef struct {
    size_t size; /* of the whole block: a serialized state must match it */
    int initialized;
    int discarded;
    double time; /* the model's time: start time, then the end of each successful step */
    double model[1]; /* the model's data (double-aligned), M.data_size bytes */
} NativeInstance;

#define HEADER_SIZE offsetof(NativeInstance, model)
#define BLOCK_SIZE (HEADER_SIZE + M.data_size)
#define NI(inst) ((NativeInstance *)(inst)->backend)

static const char *const CATEGORIES[] = {"logStatusWarning", "logStatusDiscard",
                                         "logStatusError",   "logStatusFatal",
                                         "logAll",           "logFmiCalls"};

static const char *nat_model_identifier(void) { return M.identifier; }

static int nat_start(const char *resources, char *err, size_t errsize) {
    (void)resources, (void)err, (void)errsize;
    return 1;
}

static int nat_alive(void) { return 1; }

static void *value_at(NativeInstance *ni, const NativeVar *v) {
    return (char *)ni->model + v->offset;
}

static void set_start_values(NativeInstance *ni) {
    size_t i;
    memset(ni, 0, BLOCK_SIZE);
    ni->size = BLOCK_SIZE;
    for (i = 0; i < M.nvars; ++i) {
        const NativeVar *v = &M.vars[i];
        if (v->type == T_REAL) *(double *)value_at(ni, v) = v->start;
        else *(int *)value_at(ni, v) = (int)v->start;
    }
}

static Status nat_create(Ctx *x) {
    Instance *inst = x->inst;
    glider_set_categories(inst, CATEGORIES, (int)(sizeof CATEGORIES / sizeof *CATEGORIES));
    if (!(inst->backend = malloc(BLOCK_SIZE))) return FAIL(x, "out of memory");
    set_start_values(NI(inst));
    inst->nvars = M.nvars;
    inst->var_type = M.var_types;
    inst->var_names = M.var_names;
    if (M.jacobian) {
        inst->jac_row = M.jac_row;
        inst->jac_col = M.jac_col;
        inst->jac_nrows = M.jac_nrows;
        inst->jac_ncols = M.jac_ncols;
    }
    return ST_OK;
}

static Status nat_reset(Ctx *x) {
    set_start_values(NI(x->inst));
    return ST_OK;
}

static void nat_destroy(Instance *inst, int alive) {
    (void)alive;
    free(inst->backend);
    inst->backend = NULL;
}

static Status nat_setup(Ctx *x, int tolerance_defined, double tolerance, double start,
                        int stop_defined, double stop) {
    (void)tolerance_defined, (void)tolerance, (void)stop_defined, (void)stop;
    NI(x->inst)->time = start;
    return ST_OK;
}

/* ------------------------------------------------------------------ value checks */
static int in_range(const NativeVar *v, double value) {
    if (!isfinite(value)) return 0;
    if (v->low > -HUGE_VAL && (v->low_open ? value <= v->low : value < v->low)) return 0;
    if (v->high < HUGE_VAL && (v->high_open ? value >= v->high : value > v->high)) return 0;
    return 1;
}

/* repr() of a variable's value, as the Python slave prints it */
static void value_repr(const NativeVar *v, double value, char *buf, size_t size) {
    if (v->type == T_REAL) py_float_repr(value, buf, size);
    else if (v->type == T_BOOLEAN) snprintf(buf, size, "%s", value != 0.0 ? "True" : "False");
    else snprintf(buf, size, "%d", (int)value);
}

static double number(NativeInstance *ni, const NativeVar *v) {
    return v->type == T_REAL ? *(double *)value_at(ni, v) : (double)*(int *)value_at(ni, v);
}

static Status refuse_value(Ctx *x, const NativeVar *v, double value) {
    char text[64];
    value_repr(v, value, text, sizeof text);
    return FAIL(x, "%s = %s is invalid: expected %s", v->name, text, v->expected);
}

/* The initial state and outputs from the parameters, start values and inputs set so far
 * (range checks first): at fmi2ExitInitializationMode, and in Initialization Mode before
 * an output is read (FMI's <InitialUnknowns>: the same values as after Exit, bit for bit;
 * the models' initialize() depends on nothing else). */
static Status initial_values(Ctx *x) {
    NativeInstance *ni = NI(x->inst);
    char msg[1024] = "";
    size_t i;
    for (i = 0; i < M.nvars; ++i) {
        const NativeVar *v = &M.vars[i];
        if (!v->has_range || v->causality == NV_OUTPUT) continue;
        if (!in_range(v, number(ni, v))) return refuse_value(x, v, number(ni, v));
    }
    if (M.initialize(ni->model, msg, sizeof msg) != NATIVE_OK) return FAIL(x, "%s", msg);
    return ST_OK;
}

static Status exit_initialization(Ctx *x) {
    Status st = initial_values(x);
    if (st == ST_OK) NI(x->inst)->initialized = 1;
    return st;
}

static Status nat_transition(Ctx *x, int call) {
    return call == C_EXIT_INIT ? exit_initialization(x) : ST_OK;
}

/* ------------------------------------------------------------------ value access */
/* The values of Real variables vr (checked), the computed outputs brought up to date
 * first when one of them is read (as after initialisation when initialized). */
static void get_reals(NativeInstance *ni, const ValueRef vr[], size_t nvr, double *out,
                      int initialized) {
    size_t i;
    for (i = 0; M.update && i < nvr; ++i) {
        if (M.vars[vr[i]].computed) {
            M.update(ni->model, ni->time, initialized);
            break;
        }
    }
    for (i = 0; i < nvr; ++i) out[i] = *(const double *)value_at(ni, &M.vars[vr[i]]);
}

static Status nat_get(Ctx *x, char type, const ValueRef vr[], size_t nvr, void *out) {
    NativeInstance *ni = NI(x->inst);
    size_t i;
    if (type == T_STRING) return FAIL(x, "the model has no String variables");
    if (type == T_REAL) {
        int init_mode = x->inst->state == S_INIT;
        for (i = 0; init_mode && i < nvr; ++i) {
            if (M.vars[vr[i]].causality == NV_OUTPUT || M.vars[vr[i]].causality == NV_LOCAL) {
                /* an initial unknown (an output, a state derivative) */
                Status st = initial_values(x);
                if (st != ST_OK) return st;
                break;
            }
        }
        get_reals(ni, vr, nvr, out, ni->initialized || init_mode);
        return ST_OK;
    }
    for (i = 0; i < nvr; ++i) { /* Integer and Boolean variables are ints */
        const int *p = value_at(ni, &M.vars[vr[i]]);
        ((int *)out)[i] = type == T_INTEGER ? *p : *p ? 1 : 0;
    }
    return ST_OK;
}

static Status nat_set(Ctx *x, char type, const ValueRef vr[], size_t nvr, const void *values) {
    NativeInstance *ni = NI(x->inst);
    size_t i;
    if (type == T_STRING) return FAIL(x, "the model has no String variables");
    for (i = 0; i < nvr; ++i) {
        const NativeVar *v = &M.vars[vr[i]];
        double value = type == T_REAL      ? ((const double *)values)[i]
                       : type == T_INTEGER ? (double)((const int *)values)[i]
                                           : (double)(((const int *)values)[i] != 0);
        if (v->causality == NV_OUTPUT || v->causality == NV_LOCAL)
            return FAIL(x, "%s is %s: it cannot be set", v->name,
                        v->causality == NV_OUTPUT ? "an output" : "a calculated variable");
        if (ni->initialized && v->causality == NV_PARAMETER) {
            if (!v->tunable)
                return FAIL(x, "%s is a fixed parameter: it cannot be set after initialisation "
                               "(only tunable parameters can)", v->name);
            if (v->has_range && !in_range(v, value)) return refuse_value(x, v, value);
        }
        if (type == T_REAL) *(double *)value_at(ni, v) = value;
        else if (type == T_INTEGER) *(int *)value_at(ni, v) = ((const int *)values)[i];
        else *(int *)value_at(ni, v) = value != 0.0;
    }
    return ST_OK;
}

/* The exchange's calls without the layer's framing (Backend.quick_real): a get of Real
 * variables once initialised, or a set of Real inputs (what nat_set stores without a
 * check); anything else (another reference, an output or parameter set, a get before
 * Exit) is left to nat_get/nat_set. */
static int nat_quick_real(Instance *inst, const ValueRef vr[], size_t nvr, const double *in,
                          double *out) {
    NativeInstance *ni = NI(inst);
    size_t i;
    if (out && !ni->initialized) return 0; /* Initialization Mode computes (nat_get) */
    for (i = 0; i < nvr; ++i) {
        if (vr[i] >= M.nvars || M.var_types[vr[i]] != T_REAL) return 0;
        if (!out && M.vars[vr[i]].causality != NV_INPUT) return 0;
    }
    if (out) get_reals(ni, vr, nvr, out, 1);
    else
        for (i = 0; i < nvr; ++i) *(double *)value_at(ni, &M.vars[vr[i]]) = in[i];
    return 1;
}

/* ------------------------------------------------------------------ stepping */
static Status nat_step(Ctx *x, double t, double h, int *go_on) {
    NativeInstance *ni = NI(x->inst);
    char msg[1024], warning[1024], a[64], b[64]; /* no "" initializers: 2 kB to zero */
    size_t i;
    int r;
    msg[0] = warning[0] = '\0';
    if (fabs(t - ni->time) > 1e-9 * (fabs(ni->time) > 1.0 ? fabs(ni->time) : 1.0)) {
        py_float_repr(t, a, sizeof a);
        py_float_repr(ni->time, b, sizeof b);
        return FAIL(x, "doStep at t = %s s is invalid: expected the current time %s s", a, b);
    }
    for (i = 0; i < M.nreal_inputs; ++i) {
        const NativeVar *v = &M.vars[M.real_inputs[i]];
        if (!isfinite(*(const double *)value_at(ni, v))) {
            py_float_repr(number(ni, v), a, sizeof a);
            return FAIL(x, "input %s = %s at t = %g s is invalid: expected a finite value",
                        v->name, a, ni->time);
        }
    }
    r = M.step(ni->model, t, ni->time, h, msg, sizeof msg, warning, sizeof warning);
    if (warning[0])
        glider_add_msg(x, ST_WARNING, x->inst->cat_warning, "%s: %s", x->inst->name, warning);
    if (r == NATIVE_REFUSED) return FAIL(x, "%s", msg);
    if (r == NATIVE_DISCARD) {
        glider_add_msg(x, ST_DISCARD, x->inst->cat_discard, "%s: %s", x->inst->name, msg);
        ni->discarded = 1;
        *go_on = 0;
        return ST_OK;
    }
    ni->time = t + h;
    *go_on = 1;
    return ST_OK;
}

/* ------------------------------------------------------------------ derivatives */
static Status nat_jacobian(Ctx *x, double *J) {
    NativeInstance *ni = NI(x->inst);
    M.jacobian(ni->model, ni->initialized, J);
    return ST_OK;
}

/* ------------------------------------------------------------------ FMU state */
static Status nat_state_get(Ctx *x, FmuState *s) {
    if (!s->value && !(s->value = malloc(BLOCK_SIZE))) return FAIL(x, "out of memory");
    memcpy(s->value, x->inst->backend, BLOCK_SIZE);
    return ST_OK;
}

static Status nat_state_set(Ctx *x, const FmuState *s) {
    memcpy(x->inst->backend, s->value, BLOCK_SIZE);
    return ST_OK;
}

static void nat_state_release(FmuState *s, int alive) {
    (void)alive;
    free(s->value);
    s->value = NULL;
}

static Status nat_state_bytes(Ctx *x, FmuState *s, const char **data, size_t *n) {
    (void)x;
    *data = (const char *)s->value;
    *n = BLOCK_SIZE;
    return ST_OK;
}

static Status nat_state_from_bytes(Ctx *x, FmuState *s, const char *data, size_t n) {
    NativeInstance *ni;
    size_t recorded;
    if (n != BLOCK_SIZE)
        return FAIL(x, "the state has %lu bytes: expected %lu for %s", (unsigned long)n,
                    (unsigned long)BLOCK_SIZE, M.identifier);
    memcpy(&recorded, data, sizeof recorded);
    if (recorded != BLOCK_SIZE) return FAIL(x, "the state is not one of %s", M.identifier);
    if (!(ni = malloc(BLOCK_SIZE))) return FAIL(x, "out of memory");
    memcpy(ni, data, BLOCK_SIZE);
    if ((ni->initialized != 0 && ni->initialized != 1) ||
        (ni->discarded != 0 && ni->discarded != 1) || !isfinite(ni->time) ||
        (M.valid && !M.valid(ni->model))) {
        free(ni);
        return FAIL(x, "the state is not a valid state of %s", M.identifier);
    }
    s->value = ni;
    return ST_OK;
}

const Backend GLIDER_BACKEND = {
    nat_model_identifier, nat_start,        NULL,                NULL,           nat_create,
    nat_reset,            nat_destroy,      nat_alive,           nat_setup,      nat_transition,
    nat_get,              nat_set,          nat_step,            nat_state_get,  nat_state_set,
    nat_state_release,    nat_state_bytes,  nat_state_from_bytes, nat_quick_real,
    nat_jacobian,
};
