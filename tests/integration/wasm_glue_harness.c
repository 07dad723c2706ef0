/* The FMI-LS-WASM glue (src/fmi/wasm/fmi3_wasm.c) built natively and driven as a
 * component host drives it: arguments written through cabi_realloc (the glue frees them),
 * results read from the return areas, every function of the world called, on the plant
 * model. Run under AddressSanitizer + UBSan and under valgrind memcheck by
 * tests/integration/test_wasm.py: the glue's memory handling (arguments, result lists
 * kept until the next call, FMU states, strings) checked where wasm's sandbox would hide
 * a slip inside the component's own memory.
 *
 * Prints "steps N, messages M, fatal 0" and exits 0 when every result was as expected.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *ptr;
    size_t len;
} Str;
typedef void Glue;

void *cabi_realloc(void *ptr, size_t old, size_t align, size_t size);
uint8_t *w_get_version(void);
uint8_t *w_instantiate(const char *, size_t, const char *, size_t, const char *, size_t, int32_t,
                       int32_t, int32_t, int32_t, const uint32_t *, size_t);
void w_free(Glue *);
int32_t w_set_debug_logging(Glue *, int32_t, const Str *, size_t);
int32_t w_enter_init(Glue *, int32_t, double, double, int32_t, double);
int32_t w_ExitInitializationMode(Glue *);
int32_t w_EnterEventMode(Glue *);
int32_t w_Terminate(Glue *);
int32_t w_Reset(Glue *);
int32_t w_EnterConfigurationMode(Glue *);
int32_t w_EvaluateDiscreteStates(Glue *);
uint8_t *w_update_discrete_states(Glue *);
uint8_t *w_get_Float64(Glue *, const uint32_t *, size_t);
int32_t w_set_Float64(Glue *, const uint32_t *, size_t, const double *, size_t);
uint8_t *w_get_Int32(Glue *, const uint32_t *, size_t);
uint8_t *w_get_Boolean(Glue *, const uint32_t *, size_t);
int32_t w_set_Boolean(Glue *, const uint32_t *, size_t, const uint8_t *, size_t);
uint8_t *w_get_UInt64(Glue *, const uint32_t *, size_t);
uint8_t *w_get_string(Glue *, const uint32_t *, size_t);
int32_t w_set_string(Glue *, const uint32_t *, size_t, const Str *, size_t);
uint8_t *w_get_binary(Glue *, const uint32_t *, size_t);
int32_t w_set_binary(Glue *, const uint32_t *, size_t, const Str *, size_t);
uint8_t *w_get_clock(Glue *, const uint32_t *, size_t);
int32_t w_set_clock(Glue *, const uint32_t *, size_t, const uint8_t *, size_t);
uint8_t *w_get_number_of_dependencies(Glue *, uint32_t);
uint8_t *w_get_variable_dependencies(Glue *, uint32_t);
uint8_t *w_get_fmu_state(Glue *);
int32_t w_set_fmu_state(Glue *, const uint8_t *, size_t);
uint8_t *w_GetDirectionalDerivative(Glue *, const uint32_t *, size_t, const uint32_t *, size_t,
                                    const double *, size_t);
int32_t w_set_input_derivatives(Glue *, const uint32_t *, size_t, const double *, size_t);
uint8_t *w_get_output_derivatives(Glue *, const uint32_t *, size_t);
uint8_t *w_get_interval_decimal(Glue *, const uint32_t *, size_t);
uint8_t *w_get_interval_fraction(Glue *, const uint32_t *, size_t);
uint8_t *w_get_shift_fraction(Glue *, const uint32_t *, size_t);
int32_t w_SetIntervalFraction(Glue *, const uint32_t *, size_t, const uint64_t *, size_t);
int32_t w_SetShiftDecimal(Glue *, const uint32_t *, size_t, const double *, size_t);
uint8_t *w_do_step(Glue *, double, double, int32_t);

/* ------------------------------------------------------------------ the host's side */
static int messages, fatal, failures;
static intptr_t reps[8];

void host_log(const char *name, size_t nl, int32_t status, const char *cat, size_t cl,
              const char *msg, size_t ml) {
    (void)name, (void)nl, (void)cat, (void)cl;
    messages++;
    if (status == 4) fatal++;
    if (getenv("GLUE_SHOW")) fprintf(stderr, "[%d] %.*s\n", (int)status, (int)ml, msg);
}

int32_t resource_new(intptr_t rep) {
    static int n;
    reps[n] = rep;
    return ++n;
}

#define EXPECT(cond)                                                                      \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            fprintf(stderr, "line %d: %s\n", __LINE__, #cond);                            \
            failures++;                                                                   \
        }                                                                                 \
    } while (0)

/* an argument: a copy in the guest's memory (the glue frees it) */
static void *arg(const void *data, size_t size, size_t align) {
    void *p = cabi_realloc(NULL, 0, align, size);
    if (size) memcpy(p, data, size);
    return p;
}
static const uint32_t *vrs(const uint32_t *v, size_t n) { return arg(v, 4 * n, 4); }
static Str *strs(const char *const *s, size_t n) {
    Str *out = cabi_realloc(NULL, 0, 4, n * sizeof *out);
    size_t i;
    for (i = 0; i < n; ++i) {
        out[i].len = strlen(s[i]);
        out[i].ptr = arg(s[i], out[i].len, 1);
    }
    return out;
}

/* a result<list<T>, status>: the list (NULL and *status on an error) */
static const void *list(const uint8_t *r, size_t *n, int *status) {
    uintptr_t p;
    uint32_t len;
    if (r[0]) {
        *status = r[sizeof(void *)];
        *n = 0;
        return NULL;
    }
    memcpy(&p, r + sizeof(void *), sizeof p);
    memcpy(&len, r + 2 * sizeof(void *), 4);
    *n = len;
    *status = 0;
    return (const void *)p;
}

static Glue *instantiate(const char *name, int event_mode) {
    size_t nl = strlen(name);
    const uint8_t *r = w_instantiate(arg(name, nl, 1), nl, arg("tok", 3, 1), 3, arg("", 0, 1), 0,
                                     0, 0, event_mode, 0, vrs(NULL, 0), 0);
    int32_t h;
    if (!r[0]) return NULL;
    memcpy(&h, r + 4, 4);
    return (Glue *)reps[h - 1];
}

static int step(Glue *g, double t) {
    const uint8_t *r = w_do_step(g, t, 0.02, 1);
    return r[0] ? r[8] : r[17] ? 2 : 0;
}

int main(void) {
    static const uint32_t outs[] = {3, 4, 5, 6, 7, 8}, cmd[] = {0}; /* Float64s, delta_cmd */
    const char *cats[] = {"logAll", "logFmiCalls"};
    const char *odd[] = {"nope"};
    const char *texts[] = {"x", "%s%n", ""};
    const uint8_t *r;
    const double *v;
    const Str *s;
    size_t n, k, state_size;
    int st, steps = 0;
    uint8_t *state;
    double in = 0.01, last = 0.0;
    uint64_t fractions[4] = {1, 2, 3, 4};
    uint32_t pairs[2] = {0, 1};
    Glue *g, *bad;

    r = w_get_version();
    {
        uintptr_t p;
        uint32_t len;
        memcpy(&p, r, sizeof p);
        memcpy(&len, r + sizeof(void *), 4);
        EXPECT(len == 3 && !memcmp((const char *)p, "3.0", 3));
    }
    bad = instantiate("odd", 1); /* event mode: refused, one message */
    EXPECT(bad == NULL && messages == 1);
    g = instantiate("plant", 0);
    EXPECT(g != NULL);
    EXPECT(w_set_debug_logging(g, 1, strs(odd, 1), 1) == 3);
    EXPECT(w_Reset(g) == 0);
    EXPECT(w_set_debug_logging(g, 1, strs(cats, 2), 2) == 0);
    EXPECT(w_enter_init(g, 0, 0.0, 0.0, 1, 10.0) == 0);
    EXPECT(w_ExitInitializationMode(g) == 0);
    for (k = 0; k < 200; ++k) {
        EXPECT(w_set_Float64(g, vrs(cmd, 1), 1, arg(&in, 8, 8), 1) <= 1);
        st = step(g, 0.02 * (double)k);
        EXPECT(st == 0);
        steps += st == 0;
        v = list(w_get_Float64(g, vrs(outs, 6), 6), &n, &st);
        EXPECT(st == 0 && n == 6 && isfinite(v[0]));
        if (v) last = v[1];
    }
    r = w_get_fmu_state(g);
    state = (uint8_t *)list(r, &state_size, &st);
    EXPECT(st == 0 && state_size > 100);
    state = arg(state, state_size, 1); /* the host's copy, handed back */
    st = step(g, 4.0);
    EXPECT(st == 0);
    EXPECT(w_set_fmu_state(g, state, state_size) == 0);
    v = list(w_get_Float64(g, vrs(outs, 6), 6), &n, &st);
    EXPECT(st == 0 && v[1] == last); /* back where the state was taken */
    /* what the plant has none of, or refuses: statuses and messages, nothing leaked */
    list(w_get_Int32(g, vrs(outs, 2), 2), &n, &st);
    EXPECT(st == 3);
    EXPECT(w_Reset(g) == 0);
    EXPECT(w_enter_init(g, 1, 1e-6, 0.0, 0, 0.0) == 0 && w_ExitInitializationMode(g) == 0);
    s = list(w_get_string(g, vrs(outs, 1), 1), &n, &st);
    EXPECT(st == 3 && s == NULL);
    EXPECT(w_Reset(g) == 0 && w_set_string(g, vrs(outs, 3), 3, strs(texts, 3), 3) == 3);
    EXPECT(w_Reset(g) == 0 && w_set_binary(g, vrs(outs, 3), 3, strs(texts, 3), 3) == 3);
    EXPECT(w_Reset(g) == 0);
    list(w_get_binary(g, vrs(outs, 2), 2), &n, &st);
    EXPECT(st == 3 && w_Reset(g) == 0);
    list(w_get_Boolean(g, vrs(outs, 2), 2), &n, &st);
    EXPECT(st == 3 && w_Reset(g) == 0);
    EXPECT(w_set_Boolean(g, vrs(outs, 1), 1, arg("\1\0", 2, 1), 2) == 3 && w_Reset(g) == 0);
    list(w_get_UInt64(g, vrs(outs, 1), 1), &n, &st);
    EXPECT(st == 3 && w_Reset(g) == 0);
    list(w_get_clock(g, vrs(outs, 1), 1), &n, &st);
    EXPECT(st == 3 && w_Reset(g) == 0);
    EXPECT(w_set_clock(g, vrs(outs, 2), 2, arg("\1", 1, 1), 1) == 3 && w_Reset(g) == 0);
    EXPECT(w_get_number_of_dependencies(g, 3)[0] == 1 && w_Reset(g) == 0);
    EXPECT(w_get_variable_dependencies(g, 3)[0] == 1 && w_Reset(g) == 0);
    EXPECT(w_GetDirectionalDerivative(g, vrs(outs, 2), 2, vrs(outs, 1), 1,
                                      arg(&in, 8, 8), 1)[0] == 1 && w_Reset(g) == 0);
    EXPECT(w_set_input_derivatives(g, vrs(pairs, 2), 1, arg(&in, 8, 8), 1) == 3);
    EXPECT(w_Reset(g) == 0 && w_get_output_derivatives(g, vrs(pairs, 2), 1)[0] == 1);
    EXPECT(w_Reset(g) == 0 && w_get_interval_decimal(g, vrs(outs, 2), 2)[0] == 1);
    EXPECT(w_Reset(g) == 0 && w_get_interval_fraction(g, vrs(outs, 2), 2)[0] == 1);
    EXPECT(w_Reset(g) == 0 && w_get_shift_fraction(g, vrs(outs, 2), 2)[0] == 1);
    EXPECT(w_Reset(g) == 0 && w_SetIntervalFraction(g, vrs(outs, 2), 2,
                                                    arg(fractions, 32, 8), 2) == 3);
    EXPECT(w_Reset(g) == 0 && w_SetShiftDecimal(g, vrs(outs, 2), 2, arg(&in, 8, 8), 1) == 3);
    EXPECT(w_Reset(g) == 0 && w_update_discrete_states(g)[0] == 1);
    EXPECT(w_Reset(g) == 0 && w_EnterEventMode(g) == 3);
    EXPECT(w_Reset(g) == 0 && w_EnterConfigurationMode(g) == 3);
    EXPECT(w_Reset(g) == 0 && w_EvaluateDiscreteStates(g) == 3);
    EXPECT(w_set_fmu_state(g, arg("garbage!", 8, 1), 8) == 3);
    EXPECT(w_Reset(g) == 0 && w_Terminate(g) == 3); /* not stepping yet */
    w_free(g);
    printf("steps %d, messages %d, fatal %d\n", steps, messages, fatal);
    return failures != 0 || fatal != 0;
}
