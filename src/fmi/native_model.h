/* What a component's C model gives the native back end (backend_native.c).
 *
 * A component (src/plant/plant_fmu.c, ...) defines GLIDER_NATIVE_MODEL: its variable
 * table (generated from the Python slave's table into <Model>_vars.h, so names, value
 * references, types, start values and valid ranges are written once), the size of its
 * data (the generated variables struct first, then the model's own state) and three
 * functions, the C counterparts of the Python slave's initialize(), step() and computed
 * outputs. The back end does everything else: start values, value checks, the time and
 * input checks of a step, FMU state (a copy of the data) and its serialization.
 *
 * C99, no heap, no globals: everything lives in the instance's data.
 */
#ifndef GLIDER_NATIVE_MODEL_H
#define GLIDER_NATIVE_MODEL_H

#include <stddef.h>

enum { NV_INPUT = 'i', NV_OUTPUT = 'o', NV_PARAMETER = 'p', NV_LOCAL = 'l' };

typedef struct {
    const char *name;
    char type;      /* 'R' Real (double), 'I' Integer (int), 'B' Boolean (int) */
    char causality; /* NV_INPUT, NV_OUTPUT, NV_PARAMETER, NV_LOCAL (a state derivative) */
    char tunable;   /* a parameter that may change after initialisation */
    char computed;  /* computed when read (direct feedthrough, a state derivative) */
    size_t offset;  /* of its value in the data */
    double start;
    /* valid range (checked at fmi2ExitInitializationMode, and when a tunable parameter
     * is set): has_range 0 means none */
    int has_range;
    double low, high; /* -HUGE_VAL / HUGE_VAL: unbounded */
    int low_open, high_open;
    const char *expected; /* the range in words, as the Python slave says it */
} NativeVar;

/* Results of a model's step */
enum { NATIVE_OK = 0, NATIVE_DISCARD = 1, NATIVE_REFUSED = 2 };

typedef struct {
    const char *identifier;
    const NativeVar *vars;
    size_t nvars;
    const char *var_types;         /* type per value reference */
    const char *const *var_names;  /* name per value reference */
    size_t data_size;
    /* after the parameters passed their range checks: 0, or NATIVE_REFUSED with a message */
    int (*initialize)(void *data, char *msg, size_t size);
    /* one step from the host's t (s) by h (s), inputs checked finite; time is the model's
     * own (the start time, then the end of each step; equal to t within 1e-9): NATIVE_OK,
     * NATIVE_DISCARD (a clean stop, message) or NATIVE_REFUSED (message); *warning gets
     * a message to pass on as fmi2Warning (left empty: none) */
    int (*step)(void *data, double t, double time, double h, char *msg, size_t size,
                char *warning, size_t wsize);
    /* computed outputs for the current inputs (before they are read), or NULL */
    void (*update)(void *data, double time, int initialized);
    /* 1 if data (e.g. from a deserialized state) is one the model can run from */
    int (*valid)(const void *data);
    /* value references of the Real inputs, checked finite before each step (generated:
     * <MODEL>_REAL_INPUTS, <MODEL>_NREAL_INPUTS) */
    const unsigned *real_inputs;
    size_t nreal_inputs;
    /* directional derivatives (generated from the slave's JACOBIAN_ROWS and
     * JACOBIAN_COLUMNS: <MODEL>_JAC_ROW, _JAC_COL, _JAC_NROWS, _JAC_NCOLS; NULL: none):
     * the row and column of each value reference (-1: none, Instance.jac_row) and the
     * Jacobian at the current point, nrows x ncols row-major */
    const int *jac_row, *jac_col;
    size_t jac_nrows, jac_ncols;
    void (*jacobian)(void *data, int initialized, double *J);
} NativeModel;

/* internal to the binary, as GLIDER_BACKEND (fmi_layer.h): reached without the GOT */
#if (defined(__GNUC__) || defined(__clang__)) && !defined(_WIN32)
__attribute__((visibility("hidden")))
#endif
extern const NativeModel GLIDER_NATIVE_MODEL;

/* Python's repr() of a float (shortest round trip: 0.1, 100.0, 1e-05, inf, nan), for
 * messages equal to the Python flavor's; defined with the models (plant_model.c). */
void py_float_repr(double value, char *buf, size_t size);

#endif
