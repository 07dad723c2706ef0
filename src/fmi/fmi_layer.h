/* glider-cosim's FMI layer: what the one FMI 2.0 front end (fmi2_layer.c) and its back
 * ends share.
 *
 * The layer owns everything FMI says about an instance: the registry of live instances,
 * the state machine (CALL_TABLE: which call is allowed in which state), statuses, the
 * messages of a call and when they reach the host's logger, value-reference checks, the
 * FMU-state handles and their serialized framing. A back end knows only how to run one
 * model: the Python back end (backend_python.c) hosts a pythonfmu slave in an embedded
 * interpreter, the native back end (backend_native.c) calls a component's C model. The
 * layer reaches a back end only through the table of functions `GliderBackend` that the
 * back end defines (one per binary), the way the Reference-FMUs' shared code reaches a
 * model through model.h.
 *
 * C99; no Python and no FMI header here: the layer speaks its own names for what FMI 2.0
 * and 3.0 share (below), so that an FMI 3.0 FMU's sources build with only the FMI 3.0
 * headers and an FMI 2.0 FMU's with only the FMI 2.0 ones; each front end includes its
 * version's header. Written from the FMI 2.0.4 and 3.0 standards and fmpy's FMI headers.
 */
#ifndef GLIDER_FMI_LAYER_H
#define GLIDER_FMI_LAYER_H

#include <stddef.h>
#include <stdint.h>

/* ------------------------------------------------------------------ FMI's vocabulary
 * Statuses have the same numbers in FMI 2.0 and 3.0 (fmi2OK .. fmi2Fatal, fmi3OK ..
 * fmi3Fatal); the front ends cast them to their version's type. Value references are
 * fmi2ValueReference (unsigned int) and fmi3ValueReference (uint32_t, the same type on
 * every platform the FMUs are built for). Values: Real/Float64 double, Integer/Int32 int,
 * Boolean int (0 or 1; FMI 3's bool is converted by its front end), String const char *. */
/* ST_GONE is the layer's own, never returned to a host: a back end's enter says with it
 * that it cannot be called any more (the host's Python finalized); begin() and end()
 * turn it into what the call does then (fmi_layer.c, after_exit). */
typedef enum {
    ST_GONE = -1,
    ST_OK = 0,
    ST_WARNING = 1,
    ST_DISCARD = 2,
    ST_ERROR = 3,
    ST_FATAL = 4
} Status;
typedef unsigned int ValueRef;

/* ------------------------------------------------------------------ the state machine */
enum {
    S_INSTANTIATED = 1 << 0,
    S_INIT = 1 << 1,
    S_STEP_COMPLETE = 1 << 2,
    S_STEP_FAILED = 1 << 3, /* doStep returned fmi2Discard */
    S_TERMINATED = 1 << 4,
    S_ERROR = 1 << 5,
    S_FATAL = 1 << 6
};
#define S_LIVE (S_INSTANTIATED | S_INIT | S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR)
#define S_STEPPING (S_STEP_COMPLETE | S_STEP_FAILED)
#define S_GETTABLE (S_INSTANTIATED | S_INIT | S_STEPPING | S_TERMINATED | S_ERROR)
#define S_SETTABLE (S_INSTANTIATED | S_INIT | S_STEP_COMPLETE)

/* Allowed states per call, after the FMI 2.0 and 3.0 co-simulation state tables (getters
 * are also accepted right after instantiation: they return the start values), with the
 * call's name in each version ("-": the version has no such call). FMI 3's
 * fmi3EnterInitializationMode takes the experiment (FMI 2's fmi2SetupExperiment). */
#define CALL_TABLE(X)                                                                     \
    X(C_INSTANTIATE, "fmi2Instantiate", "fmi3InstantiateCoSimulation", 0)                  \
    X(C_SET_DEBUG_LOGGING, "fmi2SetDebugLogging", "fmi3SetDebugLogging", S_LIVE)           \
    X(C_SETUP_EXPERIMENT, "fmi2SetupExperiment", "-", S_INSTANTIATED)                      \
    X(C_ENTER_INIT, "fmi2EnterInitializationMode", "fmi3EnterInitializationMode",          \
      S_INSTANTIATED)                                                                      \
    X(C_EXIT_INIT, "fmi2ExitInitializationMode", "fmi3ExitInitializationMode", S_INIT)     \
    X(C_TERMINATE, "fmi2Terminate", "fmi3Terminate", S_STEPPING)                           \
    X(C_RESET, "fmi2Reset", "fmi3Reset", S_LIVE)                                           \
    X(C_FREE, "fmi2FreeInstance", "fmi3FreeInstance", S_LIVE | S_FATAL)                    \
    X(C_GET_REAL, "fmi2GetReal", "fmi3GetFloat64", S_GETTABLE)                             \
    X(C_GET_INTEGER, "fmi2GetInteger", "fmi3GetInt32", S_GETTABLE)                         \
    X(C_GET_BOOLEAN, "fmi2GetBoolean", "fmi3GetBoolean", S_GETTABLE)                       \
    X(C_GET_STRING, "fmi2GetString", "fmi3GetString", S_GETTABLE)                          \
    X(C_GET_OTHER, "-", "fmi3Get<type>", S_GETTABLE)                                       \
    X(C_SET_REAL, "fmi2SetReal", "fmi3SetFloat64", S_SETTABLE)                             \
    X(C_SET_INTEGER, "fmi2SetInteger", "fmi3SetInt32", S_SETTABLE)                         \
    X(C_SET_BOOLEAN, "fmi2SetBoolean", "fmi3SetBoolean", S_SETTABLE)                       \
    X(C_SET_STRING, "fmi2SetString", "fmi3SetString", S_SETTABLE)                          \
    X(C_SET_OTHER, "-", "fmi3Set<type>", S_SETTABLE)                                       \
    X(C_GET_FMU_STATE, "fmi2GetFMUstate", "fmi3GetFMUState", S_LIVE)                       \
    X(C_SET_FMU_STATE, "fmi2SetFMUstate", "fmi3SetFMUState", S_LIVE)                       \
    X(C_FREE_FMU_STATE, "fmi2FreeFMUstate", "fmi3FreeFMUState", S_LIVE)                    \
    X(C_STATE_SIZE, "fmi2SerializedFMUstateSize", "fmi3SerializedFMUStateSize", S_LIVE)    \
    X(C_SERIALIZE, "fmi2SerializeFMUstate", "fmi3SerializeFMUState", S_LIVE)               \
    X(C_DESERIALIZE, "fmi2DeSerializeFMUstate", "fmi3DeserializeFMUState", S_LIVE)         \
    X(C_DIRECTIONAL, "fmi2GetDirectionalDerivative", "fmi3GetDirectionalDerivative",      \
      S_STEPPING | S_TERMINATED)                                                           \
    X(C_SET_INPUT_DERIVATIVES, "fmi2SetRealInputDerivatives", "-", 0)                      \
    X(C_GET_OUTPUT_DERIVATIVES, "fmi2GetRealOutputDerivatives", "fmi3GetOutputDerivatives", \
      0)                                                                                   \
    X(C_DO_STEP, "fmi2DoStep", "fmi3DoStep", S_STEP_COMPLETE)                              \
    X(C_CANCEL_STEP, "fmi2CancelStep", "-", 0)                                             \
    X(C_GET_STATUS, "fmi2GetStatus", "-", S_STEPPING | S_TERMINATED | S_ERROR)             \
    X(C_GET_REAL_STATUS, "fmi2GetRealStatus", "-", S_STEPPING | S_TERMINATED | S_ERROR)    \
    X(C_GET_INTEGER_STATUS, "fmi2GetIntegerStatus", "-", S_STEPPING | S_TERMINATED | S_ERROR) \
    X(C_GET_BOOLEAN_STATUS, "fmi2GetBooleanStatus", "-", S_STEPPING | S_TERMINATED | S_ERROR) \
    X(C_GET_STRING_STATUS, "fmi2GetStringStatus", "-", S_STEPPING | S_TERMINATED | S_ERROR)   \
    X(C_FMI3_ONLY, "-", "this function", 0) /* FMI 3 functions we do not provide */
#define CALL_ID(id, name2, name3, allowed) id,
enum { CALL_TABLE(CALL_ID) C_COUNT };
#undef CALL_ID

typedef struct {
    const char *name[2]; /* in FMI 2, in FMI 3 */
    unsigned allowed;
} CallSpec;
extern const CallSpec GLIDER_CALLS[C_COUNT];

/* ------------------------------------------------------------------ instances */
#define MAX_CATEGORIES 64
#define MODEL_ID_SIZE 256

typedef enum { T_REAL = 'R', T_INTEGER = 'I', T_BOOLEAN = 'B', T_STRING = 'S' } VarType;

typedef struct FmuState {
    uint32_t magic;
    struct FmuState *next;
    void *value;      /* the back end's saved state */
    void *bytes;      /* the back end's serialization, cached between Size and Serialize */
    unsigned machine; /* the FMI state it was taken in */
    double time;      /* last successful time */
    int terminated;   /* the model had asked to stop */
} FmuState;

/* The host's logger: FMI 2's (printf-style, with the instance name) or FMI 3's, each
 * called with the layer's status (FMI's number). */
typedef void (*Fmi2Logger)(void *env, const char *instance, int status, const char *category,
                           const char *message, ...);
typedef void (*Fmi3Logger)(void *env, int status, const char *category, const char *message);
typedef struct {
    int fmi3; /* 0: FMI 2.0, 1: FMI 3.0 */
    Fmi2Logger log2;
    Fmi3Logger log3;
    void *env;
} HostLogger;

typedef struct Instance {
    uint32_t magic;
    struct Instance *next; /* registry of live instances */
    char *name, *resources;
    HostLogger logger;
    int logging_on;
    uint64_t cat_on, cat_off; /* debug categories on, categories switched off */
    int ncat, cat_calls, cat_all, cat_error, cat_discard, cat_warning;
    char *cat_names[MAX_CATEGORIES];
    unsigned state;
    double time;    /* time of the last successful step end (or start time) */
    int terminated; /* the model stopped the simulation (fmi2Discard) */
    int visible;
    /* the variables, filled by the back end at instantiation: type and name per value
     * reference (0 .. nvars-1), owned by the back end */
    size_t nvars;
    const char *var_type;
    const char *const *var_names;
    /* FMI 3.0 declares the independent variable, time (Float64, value reference nvars,
     * after the model's: cosim/fmus/fmi3_description.py writes it there); a get of it
     * returns the instance's current time, a set is refused. FMI 2.0 declares none. */
    int has_time;
    /* directional derivatives (NULL jac_row: none; filled by the back end at
     * instantiation): per value reference, its row of the back end's Jacobian (an
     * unknown: a state derivative or an output) and its column (a known: a state or an
     * input), -1 for none; a state that is an output has a column and no row (its row is
     * the column's unit vector) */
    const int *jac_row, *jac_col;
    size_t jac_nrows, jac_ncols;
    FmuState *states;
    void *backend; /* the back end's per-instance data */
} Instance;

/* ------------------------------------------------------------------ a call */
typedef struct {
    Status status;
    int category; /* index into the instance's categories, -1: none */
    char *text;
} Msg;

typedef struct {
    Instance *inst;
    int call;
    int token;      /* the back end's (e.g. the GIL state taken for this call) */
    int have_token; /* the back end entered this call */
    Msg *msgs;
    size_t nmsgs, cap;
} Ctx;

/* The call's name in the instance's FMI version. */
const char *glider_call_name(const Ctx *x);
/* A variable type's name in the instance's FMI version (Real or Float64, Integer or Int32, ...). */
const char *glider_type_name(const Ctx *x, char t);

/* A message of this call: kept, and passed to the host's logger when the call ends if
 * the logging rules let it through (errors always). */
void glider_add_msg(Ctx *x, Status status, int category, const char *fmt, ...);
/* An error of this call: message "<call>: <what>"; returns fmi2Error. */
Status glider_fail(Ctx *x, const char *fmt, ...);
int glider_category_index(const Instance *inst, const char *name);
/* Register the log categories of a model (FMI's standard ones and logFmiCalls). */
void glider_set_categories(Instance *inst, const char *const names[], int n);
char *glider_dup_text(const char *s);

/* ------------------------------------------------------------------ the operations
 * What the front ends (fmi2_layer.c, fmi3_layer.c) call: each checks the instance and the
 * state machine, runs the back end and reports, once for both versions. Statuses are
 * FMI's numbers (OK 0, Warning 1, Discard 2, Error 3, Fatal 4), the same in both. */
void *glider_op_instantiate(const char *name, const char *resources, int visible,
                            int logging_on, const HostLogger *logger);
void glider_log_orphan(const HostLogger *logger, const char *name, int status, const char *text);
/* fmuResourceLocation (file: URI) -> a path (malloc'ed), NULL if it is none */
char *glider_resource_path(const char *uri);
int glider_op_set_debug_logging(void *c, int on, size_t n, const char *const categories[]);
void glider_op_free(void *c);
/* setup (FMI 2's fmi2SetupExperiment, or with enter = 1 FMI 3's
 * fmi3EnterInitializationMode: the experiment, then initialisation mode) */
int glider_op_setup(void *c, int call, int tolerance_defined, double tolerance, double start,
                    int stop_defined, double stop, int enter);
int glider_op_transition(void *c, int call, unsigned next);
int glider_op_reset(void *c);
/* get (out) or set (in) nvr values of a type; nvalues must equal nvr (scalars only) */
int glider_op_access(void *c, int call, char type, const unsigned vr[], size_t nvr,
                     size_t nvalues, const void *in, void *out);
int glider_op_get_state(void *c, void **state);
int glider_op_set_state(void *c, void *state);
int glider_op_free_state(void *c, void **state);
int glider_op_state_size(void *c, void *state, size_t *size);
int glider_op_serialize(void *c, void *state, char buffer[], size_t size);
int glider_op_deserialize(void *c, const char data[], size_t size, void **state);
int glider_op_unsupported(void *c, int call);
/* fmi2GetDirectionalDerivative / fmi3GetDirectionalDerivative: sensitivity = J seed with J
 * the partial derivatives of the unknowns with respect to the knowns at the current point
 * (nseed must equal nknown and nsensitivity nunknown) */
int glider_op_directional(void *c, const unsigned unknown[], size_t nunknown,
                          const unsigned known[], size_t nknown, const double seed[],
                          size_t nseed, double sensitivity[], size_t nsensitivity);
/* one step; *terminated: the model stopped (the status is Discard), *last: the last
 * successful time */
int glider_op_do_step(void *c, double t, double h, int *terminated, double *last);
/* a status query (FMI 2's fmi2Get*Status): store() fills value when kind is want */
int glider_op_query(void *c, int call, int kind, int want,
                    void (*store)(const Instance *, void *), void *value);

/* ------------------------------------------------------------------ a back end */
typedef struct {
    /* the model identifier (the binary's file name without its suffix) */
    const char *(*model_identifier)(void);
    /* make the back end usable in this process (once; thread-safe); 0 + err on failure,
     * which fmi2Instantiate reports as fmi2Fatal */
    int (*start)(const char *resources, char *err, size_t errsize);
    /* take and give back what a call needs (the GIL); enter returns ST_GONE when the
     * back end cannot be called any more (Python finalized: nothing taken, nothing
     * said). NULL, both: nothing to take (the native back end), every call is entered */
    Status (*enter)(Ctx *x);
    void (*leave)(Ctx *x);
    /* instantiate: create the model, fill inst->nvars, var_type, var_names and the
     * categories; reset: a fresh model with start values */
    Status (*create)(Ctx *x);
    Status (*reset)(Ctx *x);
    /* free the model and every state's value (inside enter/leave when possible: alive
     * says whether the back end can still be called) */
    void (*destroy)(Instance *inst, int alive);
    int (*alive)(void);
    Status (*setup)(Ctx *x, int tolerance_defined, double tolerance, double start,
                    int stop_defined, double stop);
    /* fmi2EnterInitializationMode, fmi2ExitInitializationMode, fmi2Terminate */
    Status (*transition)(Ctx *x, int call);
    /* value access; references are checked against var_type by the layer */
    Status (*get)(Ctx *x, char type, const ValueRef vr[], size_t nvr, void *out);
    Status (*set)(Ctx *x, char type, const ValueRef vr[], size_t nvr, const void *values);
    /* one communication step; *go_on = 0: the model stopped cleanly (fmi2Discard) */
    Status (*step)(Ctx *x, double t, double h, int *go_on);
    /* FMU state: save into s->value (replacing what is there), restore, release value and
     * bytes, serialize (cached in s->bytes) and deserialize into s->value */
    Status (*state_get)(Ctx *x, FmuState *s);
    Status (*state_set)(Ctx *x, const FmuState *s);
    void (*state_release)(FmuState *s, int alive);
    Status (*state_bytes)(Ctx *x, FmuState *s, const char **data, size_t *n);
    Status (*state_from_bytes)(Ctx *x, FmuState *s, const char *data, size_t n);
    /* optional (NULL: none): a Real get (out) or set (in) of the step's kind that needs
     * nothing of a call's framing. The layer offers it a call that no check of its own
     * would refuse or log (instance live in a state that allows the call, no call
     * logging, nValues = nvr); it returns 1 having done the call as get/set would, with
     * nothing to report, or 0 without touching anything, when any reference needs
     * get/set's checks or messages (then the call takes the full path) */
    int (*quick_real)(Instance *inst, const ValueRef vr[], size_t nvr, const double *in,
                      double *out);
    /* optional (NULL: none): the Jacobian at the current point, inst->jac_nrows x
     * inst->jac_ncols row-major into J (the layer checks the references and forms the
     * directional derivative) */
    Status (*jacobian)(Ctx *x, double *J);
} Backend;

/* defined once per binary by its back end; internal to the binary (its definition is
 * hidden by -fvisibility=hidden; hidden here too, the layer reaches it without the GOT) */
#if (defined(__GNUC__) || defined(__clang__)) && !defined(_WIN32)
__attribute__((visibility("hidden")))
#endif
extern const Backend GLIDER_BACKEND;

#endif
