/* glider-cosim's FMI 2.0 co-simulation runtime: hosts a pythonfmu Fmi2Slave in an FMU.
 *
 * One binary for every FMU and every Python >= 3.11: it links no libpython and calls
 * only functions of Python's stable ABI, resolved with dlsym when an FMU is first
 * instantiated (from the host process if it already has Python, else from the libpython
 * recorded at build time, which the runtime then starts itself).
 *
 * The FMI state machine is written once (CALLS, begin(), end()): every function checks
 * that its instance is live and in a state where FMI 2.0 allows the call, takes the GIL,
 * calls the slave, drains the slave's log queue, records what happened and releases the
 * GIL before the host's logger is called. Errors are fmi2Error with a message that is
 * passed to the logger whatever loggingOn says; fmi2Fatal is kept for the runtime itself
 * failing. After fmi2Error only getters, FMU-state functions, fmi2Reset and
 * fmi2FreeInstance are accepted.
 *
 * The slave protocol is pythonfmu's Fmi2Slave: a class named after the model identifier
 * in the module named by resources/slavemodule.txt, constructed with instance_name,
 * resources and visible; methods setup_experiment, enter_initialization_mode,
 * exit_initialization_mode, do_step (truthy: fmi2OK, falsy: fmi2Discard), terminate,
 * get_/set_real|integer|boolean|string, _get_fmu_state, _set_fmu_state,
 * _fmu_state_to_bytes, _fmu_state_from_bytes; attributes vars (value reference ->
 * variable), log_queue (messages with status, category, msg) and log_categories. A
 * Python exception becomes fmi2Error with "<call>: <type>: <message>", or
 * "<call>: <message>" if its class has a true attribute fmi_message_only.
 *
 * Written from the FMI 2.0.4 standard and the FMI headers that fmpy ships.
 */
#define _GNU_SOURCE
#define Py_LIMITED_API 0x030B0000
#include <Python.h>

#include <dlfcn.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "python_find.h"
#include "python_threads.h"

/* ------------------------------------------------------------------ Python API table */
/* Every Python function is called through a pointer of the exact type Python.h
 * declares: the binary has no undefined Python symbol (checked by the build). */
#define PY_FUNCTIONS(X)                                                                    \
    X(Py_IsInitialized) X(Py_InitializeEx) X(PyEval_SaveThread) X(PyGILState_Ensure)       \
    X(PyGILState_Release) X(PyGILState_GetThisThreadState) X(PyEval_RestoreThread) \
    X(PyThreadState_Clear) X(PyThreadState_Delete) X(PyObject_Size) X(Py_IncRef) X(Py_DecRef) X(PyErr_Occurred) X(PyErr_Fetch) X(PyErr_Restore) \
    X(PyErr_NormalizeException) X(PyErr_Clear) X(PyObject_Str) X(PyUnicode_AsUTF8AndSize) \
    X(PyUnicode_FromString) X(PyUnicode_InternFromString) X(PyType_GetName)              \
    X(PyImport_ImportModule) X(PyObject_GetAttr) X(PyObject_GetAttrString)                \
    X(PyObject_Call) X(PyObject_CallFunctionObjArgs) X(PyList_New) X(PyList_SetItem)      \
    X(PyList_Insert) X(PyList_SetSlice) X(PySequence_Size) X(PySequence_GetItem)          \
    X(PySequence_Contains) X(PyLong_FromLong) X(PyLong_AsLong) X(PyFloat_FromDouble)      \
    X(PyFloat_AsDouble) X(PyBool_FromLong) X(PyObject_IsTrue) X(PyBytes_FromStringAndSize) \
    X(PyBytes_AsStringAndSize) X(PyDict_New) X(PyDict_SetItemString) X(PyTuple_New) X(PyTuple_SetItem)        \
    X(PySys_GetObject) X(PySys_SetObject) X(PyObject_GetIter) X(PyIter_Next)

#define DECLARE(name) static __typeof__(&name) p##name;
PY_FUNCTIONS(DECLARE)
#undef DECLARE
static PyObject *pNone;

#define INCREF(o) pPy_IncRef((PyObject *)(o))
#define DECREF(o) pPy_DecRef((PyObject *)(o))
#define XDECREF(o)                                                                          \
    do {                                                                                    \
        if (o) DECREF(o);                                                                   \
    } while (0)
#define CLEAR(o)                                                                            \
    do {                                                                                    \
        if (o) {                                                                            \
            PyObject *tmp_ = (PyObject *)(o);                                               \
            (o) = NULL;                                                                     \
            DECREF(tmp_);                                                                   \
        }                                                                                   \
    } while (0)

/* ------------------------------------------------------------------ process state */
static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER; /* Python start, registry */
static int g_python_ready = 0;
static char g_python_error[4096];
static char g_model[256]; /* model identifier: this binary's file name without .so */

#define SLAVE_METHODS(X)                                                                   \
    X(M_SETUP, "setup_experiment") X(M_ENTER, "enter_initialization_mode")                 \
    X(M_EXIT, "exit_initialization_mode") X(M_STEP, "do_step") X(M_TERMINATE, "terminate") \
    X(M_GET_REAL, "get_real") X(M_GET_INTEGER, "get_integer")                               \
    X(M_GET_BOOLEAN, "get_boolean") X(M_GET_STRING, "get_string")                           \
    X(M_SET_REAL, "set_real") X(M_SET_INTEGER, "set_integer")                               \
    X(M_SET_BOOLEAN, "set_boolean") X(M_SET_STRING, "set_string")                           \
    X(M_GET_STATE, "_get_fmu_state") X(M_SET_STATE, "_set_fmu_state")                       \
    X(M_TO_BYTES, "_fmu_state_to_bytes") X(M_FROM_BYTES, "_fmu_state_from_bytes")
#define ENUM_ITEM(id, name) id,
enum { SLAVE_METHODS(ENUM_ITEM) M_COUNT };
#undef ENUM_ITEM
#define NAME_ITEM(id, name) name,
static const char *const METHOD_NAMES[M_COUNT] = {SLAVE_METHODS(NAME_ITEM)};
#undef NAME_ITEM
static PyObject *g_method_names[M_COUNT]; /* interned, process lifetime */
static PyObject *g_str_log_queue, *g_str_status, *g_str_category, *g_str_msg;

/* ------------------------------------------------------------------ the state machine */
enum {
    S_INSTANTIATED = 1 << 0,
    S_INIT = 1 << 1,
    S_STEP_COMPLETE = 1 << 2,
    S_STEP_FAILED = 1 << 3, /* doStep returned fmi2Discard */
    S_TERMINATED = 1 << 4,
    S_ERROR = 1 << 5,
    S_FATAL = 1 << 6,
};
#define S_LIVE (S_INSTANTIATED | S_INIT | S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR)
#define S_STEPPING (S_STEP_COMPLETE | S_STEP_FAILED)
#define S_GETTABLE (S_INSTANTIATED | S_INIT | S_STEPPING | S_TERMINATED | S_ERROR)

/* Allowed states per call, after the FMI 2.0 co-simulation state table (getters are
 * also accepted right after instantiation: they return the start values). */
#define CALL_TABLE(X)                                                                     \
    X(C_INSTANTIATE, "fmi2Instantiate", 0)                                                \
    X(C_SET_DEBUG_LOGGING, "fmi2SetDebugLogging", S_LIVE)                                 \
    X(C_SETUP_EXPERIMENT, "fmi2SetupExperiment", S_INSTANTIATED)                          \
    X(C_ENTER_INIT, "fmi2EnterInitializationMode", S_INSTANTIATED)                        \
    X(C_EXIT_INIT, "fmi2ExitInitializationMode", S_INIT)                                  \
    X(C_TERMINATE, "fmi2Terminate", S_STEPPING)                                           \
    X(C_RESET, "fmi2Reset", S_LIVE)                                                       \
    X(C_FREE, "fmi2FreeInstance", S_LIVE | S_FATAL)                                       \
    X(C_GET_REAL, "fmi2GetReal", S_GETTABLE)                                              \
    X(C_GET_INTEGER, "fmi2GetInteger", S_GETTABLE)                                        \
    X(C_GET_BOOLEAN, "fmi2GetBoolean", S_GETTABLE)                                        \
    X(C_GET_STRING, "fmi2GetString", S_GETTABLE)                                          \
    X(C_SET_REAL, "fmi2SetReal", S_INSTANTIATED | S_INIT | S_STEP_COMPLETE)               \
    X(C_SET_INTEGER, "fmi2SetInteger", S_INSTANTIATED | S_INIT | S_STEP_COMPLETE)         \
    X(C_SET_BOOLEAN, "fmi2SetBoolean", S_INSTANTIATED | S_INIT | S_STEP_COMPLETE)         \
    X(C_SET_STRING, "fmi2SetString", S_INSTANTIATED | S_INIT | S_STEP_COMPLETE)           \
    X(C_GET_FMU_STATE, "fmi2GetFMUstate", S_LIVE)                                         \
    X(C_SET_FMU_STATE, "fmi2SetFMUstate", S_LIVE)                                         \
    X(C_FREE_FMU_STATE, "fmi2FreeFMUstate", S_LIVE)                                       \
    X(C_STATE_SIZE, "fmi2SerializedFMUstateSize", S_LIVE)                                 \
    X(C_SERIALIZE, "fmi2SerializeFMUstate", S_LIVE)                                       \
    X(C_DESERIALIZE, "fmi2DeSerializeFMUstate", S_LIVE)                                   \
    X(C_DIRECTIONAL, "fmi2GetDirectionalDerivative", 0)                                   \
    X(C_SET_INPUT_DERIVATIVES, "fmi2SetRealInputDerivatives", 0)                          \
    X(C_GET_OUTPUT_DERIVATIVES, "fmi2GetRealOutputDerivatives", 0)                        \
    X(C_DO_STEP, "fmi2DoStep", S_STEP_COMPLETE)                                           \
    X(C_CANCEL_STEP, "fmi2CancelStep", 0)                                                 \
    X(C_GET_STATUS, "fmi2GetStatus", S_STEPPING | S_TERMINATED | S_ERROR)                 \
    X(C_GET_REAL_STATUS, "fmi2GetRealStatus", S_STEPPING | S_TERMINATED | S_ERROR)        \
    X(C_GET_INTEGER_STATUS, "fmi2GetIntegerStatus", S_STEPPING | S_TERMINATED | S_ERROR)  \
    X(C_GET_BOOLEAN_STATUS, "fmi2GetBooleanStatus", S_STEPPING | S_TERMINATED | S_ERROR)  \
    X(C_GET_STRING_STATUS, "fmi2GetStringStatus", S_STEPPING | S_TERMINATED | S_ERROR)
#define CALL_ID(id, name, allowed) id,
enum { CALL_TABLE(CALL_ID) C_COUNT };
#undef CALL_ID
typedef struct {
    const char *name;
    unsigned allowed;
} CallSpec;
#define CALL_SPEC(id, name, allowed) {name, allowed},
static const CallSpec CALLS[C_COUNT] = {CALL_TABLE(CALL_SPEC)};
#undef CALL_SPEC

static const char *state_name(unsigned s) {
    switch (s) {
    case S_INSTANTIATED: return "instantiated";
    case S_INIT: return "initialization mode";
    case S_STEP_COMPLETE: return "step complete";
    case S_STEP_FAILED: return "step failed (after fmi2Discard)";
    case S_TERMINATED: return "terminated";
    case S_ERROR: return "error";
    default: return "fatal";
    }
}

/* ------------------------------------------------------------------ instances */
#define INSTANCE_MAGIC 0x474c4944u /* "GLID" */
#define STATE_MAGIC 0x53544154u    /* "STAT" */
#define MAX_CATEGORIES 64

typedef struct FmuState {
    uint32_t magic;
    struct FmuState *next;
    PyObject *value;   /* what the slave's _get_fmu_state returned */
    PyObject *bytes;   /* its serialization, cached between Size and Serialize */
    unsigned machine;  /* the FMI state it was taken in */
    double time;       /* last successful time */
    int terminated;    /* the slave had asked to stop */
} FmuState;

typedef enum { T_REAL = 'R', T_INTEGER = 'I', T_BOOLEAN = 'B', T_STRING = 'S' } VarType;

/* The value-reference tuple last passed for a call, reused while the host passes the
 * same references. */
typedef struct {
    size_t n;
    fmi2ValueReference *vr;
    PyObject *list;
} RefCache;

typedef struct Instance {
    uint32_t magic;
    struct Instance *next; /* registry of live instances */
    char *name, *resources;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging_on;
    uint64_t cat_on, cat_off; /* debug categories on, categories switched off */
    int ncat, cat_calls, cat_all, cat_error;
    char *cat_names[MAX_CATEGORIES];
    unsigned state;
    double time;        /* time of the last successful step end (or start time) */
    int terminated;     /* do_step returned falsy */
    int visible;
    PyObject *cls, *slave, *method[M_COUNT];
    size_t nvars;
    char *var_type;     /* VarType per value reference */
    char **var_names;
    char **strings;     /* buffers returned by fmi2GetString, valid until the next call */
    size_t nstrings;
    FmuState *states;
    RefCache refs[C_COUNT];
} Instance;

static Instance *g_instances;

static Instance *lookup(fmi2Component c) {
    Instance *found = NULL;
    pthread_mutex_lock(&g_lock);
    for (Instance *i = g_instances; i; i = i->next) {
        if ((void *)i == c) {
            found = i;
            break;
        }
    }
    pthread_mutex_unlock(&g_lock);
    return found && found->magic == INSTANCE_MAGIC ? found : NULL;
}

/* ------------------------------------------------------------------ messages */
typedef struct {
    fmi2Status status;
    int category; /* index into the instance's categories, -1: none */
    char *text;
} Msg;

typedef struct {
    Instance *inst;
    int call;
    PyGILState_STATE gil;
    int have_gil;
    Msg *msgs;
    size_t nmsgs, cap;
} Ctx;

static char *dup_text(const char *s) {
    size_t n = strlen(s);
    char *d = malloc(n + 1);
    if (d) memcpy(d, s, n + 1);
    return d;
}

static void add_msg(Ctx *x, fmi2Status status, int category, const char *fmt, ...) {
    char buf[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if (x->nmsgs == x->cap) {
        size_t cap = x->cap ? 2 * x->cap : 4;
        Msg *m = realloc(x->msgs, cap * sizeof *m);
        if (!m) return;
        x->msgs = m;
        x->cap = cap;
    }
    char *text = dup_text(buf);
    if (!text) return;
    x->msgs[x->nmsgs++] = (Msg){status, category, text};
}

/* An error of this call: message "<call>: <what>". */
#define FAIL(x, ...) fail_msg((x), __VA_ARGS__)
static fmi2Status fail_msg(Ctx *x, const char *fmt, ...) {
    char buf[1800];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    add_msg(x, fmi2Error, x->inst ? x->inst->cat_error : -1, "%s: %s", CALLS[x->call].name,
            buf);
    return fmi2Error;
}

/* Errors are always passed on. Warnings and discards too, unless their category was
 * switched off (fmi2SetDebugLogging(false, [it]) or another list given with true). Debug
 * messages (fmi2OK) only with logging on and their category, or logAll, enabled;
 * logFmiCalls only when named. */
static int should_log(const Instance *inst, fmi2Status status, int category) {
    if (status >= fmi2Error) return 1;
    uint64_t bit = category >= 0 ? (uint64_t)1 << category : 0;
    if (inst->cat_off & bit) return 0;
    if (status == fmi2Warning || status == fmi2Discard) return 1;
    uint64_t all = inst->cat_all >= 0 && category != inst->cat_calls ? (uint64_t)1 << inst->cat_all
                                                                      : 0;
    return inst->logging_on && (inst->cat_on & (bit | all)) != 0;
}

/* The logger takes a printf format: pass the text with every '%' doubled. */
static void emit(fmi2CallbackLogger logger, fmi2ComponentEnvironment env, const char *name,
                 fmi2Status status, const char *category, const char *text) {
    size_t n = strlen(text), extra = 0;
    for (size_t i = 0; i < n; ++i) extra += text[i] == '%';
    char *fmt = malloc(n + extra + 1);
    if (!fmt) return;
    char *o = fmt;
    for (size_t i = 0; i < n; ++i) {
        *o++ = text[i];
        if (text[i] == '%') *o++ = '%';
    }
    *o = '\0';
    logger(env, name, status, category, fmt);
    free(fmt);
}

/* ------------------------------------------------------------------ Python errors */
static int py_text(PyObject *o, char *buf, size_t size) {
    /* str(o) into buf; 0 if that failed (the exception is cleared) */
    PyObject *s = o ? pPyObject_Str(o) : NULL;
    Py_ssize_t n = 0;
    const char *t = s ? pPyUnicode_AsUTF8AndSize(s, &n) : NULL;
    if (!t) {
        pPyErr_Clear();
        XDECREF(s);
        return 0;
    }
    snprintf(buf, size, "%s", t);
    DECREF(s);
    return 1;
}

/* The pending Python exception as an fmi2Error of this call (traceback as a debug
 * message in category logAll). */
static fmi2Status py_error(Ctx *x) {
    PyObject *type = NULL, *value = NULL, *tb = NULL;
    pPyErr_Fetch(&type, &value, &tb);
    if (!type) return FAIL(x, "the slave failed without a Python exception");
    pPyErr_NormalizeException(&type, &value, &tb);
    char tname[128] = "Exception", text[1600] = "";
    PyObject *n = pPyType_GetName((PyTypeObject *)type);
    if (n) {
        py_text(n, tname, sizeof tname);
        DECREF(n);
    } else {
        pPyErr_Clear();
    }
    if (!py_text(value, text, sizeof text)) snprintf(text, sizeof text, "(unprintable)");
    /* an exception class with a true fmi_message_only speaks for itself */
    PyObject *plain = pPyObject_GetAttrString(type, "fmi_message_only");
    int message_only = plain ? pPyObject_IsTrue(plain) > 0 : 0;
    XDECREF(plain);
    pPyErr_Clear();
    fmi2Status st = message_only ? FAIL(x, "%s", text) : FAIL(x, "%s: %s", tname, text);
    if (x->inst && x->inst->logging_on && tb && !message_only) {
        PyObject *mod = pPyImport_ImportModule("traceback");
        PyObject *fmt = mod ? pPyObject_GetAttrString(mod, "format_exception") : NULL;
        PyObject *lines = fmt ? pPyObject_CallFunctionObjArgs(fmt, type, value, tb, NULL) : NULL;
        PyObject *sep = lines ? pPyUnicode_FromString("") : NULL;
        PyObject *join = sep ? pPyObject_GetAttrString(sep, "join") : NULL;
        PyObject *whole = join ? pPyObject_CallFunctionObjArgs(join, lines, NULL) : NULL;
        char buf[2000];
        if (whole && py_text(whole, buf, sizeof buf))
            add_msg(x, fmi2OK, x->inst->cat_all, "%s", buf);
        pPyErr_Clear();
        XDECREF(whole);
        XDECREF(join);
        XDECREF(sep);
        XDECREF(lines);
        XDECREF(fmt);
        XDECREF(mod);
    }
    XDECREF(type);
    XDECREF(value);
    XDECREF(tb);
    return st;
}

/* ------------------------------------------------------------------ starting Python */
static void trim(char *s) {
    size_t n = strlen(s);
    while (n && (s[n - 1] == '\n' || s[n - 1] == '\r' || s[n - 1] == ' ')) s[--n] = '\0';
}

static int resolve_api(void *h, char *err, size_t errsize) {
#define RESOLVE(name)                                                                      \
    *(void **)(&p##name) = dlsym(h, #name);                                                \
    if (!p##name) {                                                                        \
        snprintf(err, errsize, "Python function %s not found", #name);                     \
        return 0;                                                                          \
    }
    PY_FUNCTIONS(RESOLVE)
#undef RESOLVE
    pNone = (PyObject *)dlsym(h, "_Py_NoneStruct");
    if (!pNone) {
        snprintf(err, errsize, "Python object None not found");
        return 0;
    }
    return 1;
}

/* Called once the interpreter runs, with the GIL held: add the recorded site folders
 * (with their .pth files) and set sys.executable. */
static int configure_started_python(const FoundPython *cfg, char *err, size_t errsize) {
    PyObject *site = pPyImport_ImportModule("site");
    PyObject *add = site ? pPyObject_GetAttrString(site, "addsitedir") : NULL;
    int ok = add != NULL;
    for (int i = 0; ok && i < cfg->nsite; ++i) {
        PyObject *dir = pPyUnicode_FromString(cfg->site[i]);
        PyObject *r = dir ? pPyObject_CallFunctionObjArgs(add, dir, NULL) : NULL;
        ok = r != NULL;
        XDECREF(r);
        XDECREF(dir);
    }
    if (ok && cfg->executable[0]) {
        PyObject *exe = pPyUnicode_FromString(cfg->executable);
        ok = exe && pPySys_SetObject("executable", exe) == 0;
        XDECREF(exe);
    }
    XDECREF(add);
    XDECREF(site);
    if (!ok) {
        snprintf(err, errsize, "configuring the started Python failed");
        pPyErr_Clear();
    }
    return ok;
}

/* Make Python usable in this process: the host's, or one we find, load and start
 * (python_find.c). */
static int ensure_python(const char *resources) {
    int ok;
    pthread_mutex_lock(&g_lock);
    if (g_python_ready) {
        pthread_mutex_unlock(&g_lock);
        return 1;
    }
    char *err = g_python_error;
    size_t es = sizeof g_python_error;
    void *h = RTLD_DEFAULT;
    FoundPython cfg;
    int have_cfg = 0;
    char recorded[1200];
    snprintf(recorded, sizeof recorded, "%s/glider_fmi_python.cfg", resources);
    if (!dlsym(RTLD_DEFAULT, "Py_IsInitialized")) {
        /* a host without Python: find one and load it globally (extension modules
         * resolve their Python symbols from the process) */
        if (!(have_cfg = glider_find_python(resources, recorded, &cfg, err, es))) goto done;
        h = cfg.handle;
    }
    if (!resolve_api(h, err, es)) goto done;
    if (!pPy_IsInitialized()) {
        if (!have_cfg) { /* libpython preloaded by the host but not started */
            const char *override = getenv("GLIDER_FMI_PYTHON_CONFIG");
            const char *path = override && override[0] ? override : recorded;
            if (!(have_cfg = glider_read_python_config(path, &cfg, err, es))) goto done;
        }
        /* the standard library is found from PYTHONHOME: the found prefix unless the
         * user set one; the host's environment is restored afterwards */
        const char *user_home = getenv("PYTHONHOME");
        int set_home = !(user_home && user_home[0]) && cfg.home[0];
        if (set_home) setenv("PYTHONHOME", cfg.home, 1);
        pPy_InitializeEx(0); /* no signal handlers: the host owns them */
        if (set_home) unsetenv("PYTHONHOME");
        if (!pPy_IsInitialized()) {
            snprintf(err, es, "Python (%s) failed to start", cfg.libpython);
            goto done;
        }
        int configured = configure_started_python(&cfg, err, es);
        pPyEval_SaveThread(); /* release the GIL: every call takes it when it needs it */
        if (!configured) goto done;
    }
    {
        const GliderGilApi gil = {pPyGILState_Ensure, pPyGILState_Release,
                                  pPyGILState_GetThisThreadState, pPyEval_SaveThread,
                                  pPyEval_RestoreThread, pPyThreadState_Clear,
                                  pPyThreadState_Delete, pPy_IsInitialized};
        glider_threads_init(&gil);
        PyGILState_STATE g = pPyGILState_Ensure();
        int interned = 1;
        for (int i = 0; i < M_COUNT; ++i)
            interned &= (g_method_names[i] = pPyUnicode_InternFromString(METHOD_NAMES[i])) != NULL;
        interned &= (g_str_log_queue = pPyUnicode_InternFromString("log_queue")) != NULL;
        interned &= (g_str_status = pPyUnicode_InternFromString("status")) != NULL;
        interned &= (g_str_category = pPyUnicode_InternFromString("category")) != NULL;
        interned &= (g_str_msg = pPyUnicode_InternFromString("msg")) != NULL;
        pPyGILState_Release(g);
        if (!interned) {
            snprintf(err, es, "Python is out of memory");
            goto done;
        }
    }
    g_python_ready = 1;
done:
    ok = g_python_ready;
    pthread_mutex_unlock(&g_lock);
    return ok;
}

static void find_model_identifier(void) {
    Dl_info info;
    if (g_model[0]) return;
    if (dladdr((void *)&find_model_identifier, &info) && info.dli_fname) {
        const char *base = strrchr(info.dli_fname, '/');
        snprintf(g_model, sizeof g_model, "%s", base ? base + 1 : info.dli_fname);
        char *dot = strrchr(g_model, '.');
        if (dot) *dot = '\0';
    }
}

/* ------------------------------------------------------------------ call framing */
static fmi2Status begin(Ctx *x, fmi2Component c, int call) {
    memset(x, 0, sizeof *x);
    x->call = call;
    x->inst = lookup(c);
    if (!x->inst) return fmi2Error; /* not an instance of this FMU: nobody to log to */
    Instance *inst = x->inst;
    if (!pPy_IsInitialized())
        return FAIL(x, "the process's Python is finalizing: the slave cannot be called any "
                       "more (free instances before the interpreter exits)");
    x->gil = glider_gil_ensure(); /* one thread state per host thread, kept */
    x->have_gil = 1;
    if (inst->state == S_FATAL) {
        add_msg(x, fmi2Fatal, inst->cat_error, "%s: the instance failed fatally earlier",
                CALLS[call].name);
        return fmi2Fatal;
    }
    if (!(CALLS[call].allowed & inst->state)) {
        if (!CALLS[call].allowed) return FAIL(x, "not supported by this FMU");
        if (inst->state == S_ERROR)
            return FAIL(x, "not allowed after an error: only getters, FMU-state functions, "
                           "fmi2Reset and fmi2FreeInstance are");
        return FAIL(x, "not allowed in state '%s'", state_name(inst->state));
    }
    if (inst->cat_calls >= 0 && inst->logging_on && (inst->cat_on >> inst->cat_calls & 1))
        add_msg(x, fmi2OK, inst->cat_calls, "%s", CALLS[call].name);
    return fmi2OK;
}

static int category_index(const Instance *inst, const char *name) {
    for (int i = 0; i < inst->ncat; ++i)
        if (!strcmp(inst->cat_names[i], name)) return i;
    return -1;
}

/* Move the slave's queued log messages into the call's messages. */
static void drain_log_queue(Ctx *x) {
    Instance *inst = x->inst;
    if (!inst || !inst->slave) return;
    PyObject *q = pPyObject_GetAttr(inst->slave, g_str_log_queue);
    Py_ssize_t n = q ? pPySequence_Size(q) : -1;
    for (Py_ssize_t i = 0; i < n; ++i) {
        PyObject *m = pPySequence_GetItem(q, i);
        PyObject *st = m ? pPyObject_GetAttr(m, g_str_status) : NULL;
        PyObject *cat = m ? pPyObject_GetAttr(m, g_str_category) : NULL;
        PyObject *msg = m ? pPyObject_GetAttr(m, g_str_msg) : NULL;
        long status = st ? pPyLong_AsLong(st) : 0;
        char cname[128] = "", text[1800] = "";
        if (cat) py_text(cat, cname, sizeof cname);
        if (msg && py_text(msg, text, sizeof text)) {
            int ci = category_index(inst, cname);
            if (status < fmi2OK || status > fmi2Fatal) status = fmi2OK;
            add_msg(x, (fmi2Status)status, ci >= 0 ? ci : inst->cat_all, "%s", text);
        }
        pPyErr_Clear();
        XDECREF(msg);
        XDECREF(cat);
        XDECREF(st);
        XDECREF(m);
    }
    if (n > 0) pPyList_SetSlice(q, 0, n, NULL);
    pPyErr_Clear();
    XDECREF(q);
}

static fmi2Status end(Ctx *x, fmi2Status status) {
    Instance *inst = x->inst;
    if (!inst) return status;
    if (status == fmi2Fatal) inst->state = S_FATAL;
    else if (status == fmi2Error && inst->state != S_FATAL) inst->state = S_ERROR;
    /* decide under the GIL, call the host's logger without it */
    for (size_t i = 0; i < x->nmsgs; ++i) {
        if (!should_log(inst, x->msgs[i].status, x->msgs[i].category)) {
            free(x->msgs[i].text);
            x->msgs[i].text = NULL;
        }
    }
    if (x->have_gil) glider_gil_release(x->gil);
    x->have_gil = 0;
    for (size_t i = 0; i < x->nmsgs; ++i) {
        if (!x->msgs[i].text) continue;
        int ci = x->msgs[i].category;
        const char *category = ci >= 0 && ci < inst->ncat ? inst->cat_names[ci] : "logAll";
        if (inst->logger)
            emit(inst->logger, inst->env, inst->name, x->msgs[i].status, category,
                 x->msgs[i].text);
        free(x->msgs[i].text);
    }
    free(x->msgs);
    x->msgs = NULL;
    x->nmsgs = x->cap = 0;
    return status;
}

/* Call a bound slave method with 0-3 arguments (new reference, or NULL with the Python
 * exception pending); the slave's log queue is drained either way. */
static PyObject *call_slave(Ctx *x, int method, PyObject *a, PyObject *b, PyObject *c) {
    PyObject *r = pPyObject_CallFunctionObjArgs(x->inst->method[method], a, b, c, NULL);
    PyObject *t = NULL, *v = NULL, *tb = NULL;
    if (!r) pPyErr_Fetch(&t, &v, &tb); /* keep the exception while the queue is read */
    drain_log_queue(x);
    if (!r) pPyErr_Restore(t, v, tb);
    return r;
}

/* A call whose result only matters as success or failure (steals a, b, c). */
static fmi2Status call_void(Ctx *x, int method, PyObject *a, PyObject *b, PyObject *c) {
    PyObject *r = call_slave(x, method, a, b, c);
    XDECREF(a);
    XDECREF(b);
    XDECREF(c);
    if (!r) return py_error(x);
    DECREF(r);
    return fmi2OK;
}

/* ------------------------------------------------------------------ slave objects */
static void release_slave(Instance *inst) {
    for (int i = 0; i < M_COUNT; ++i) CLEAR(inst->method[i]);
    CLEAR(inst->slave);
}

/* Construct a slave object, bind its methods; it replaces the current one on success. */
static fmi2Status make_slave(Ctx *x) {
    Instance *inst = x->inst;
    PyObject *kwargs = pPyDict_New(), *args = pPyTuple_New(0);
    PyObject *name = pPyUnicode_FromString(inst->name);
    PyObject *res = pPyUnicode_FromString(inst->resources);
    PyObject *vis = pPyBool_FromLong(inst->visible);
    PyObject *slave = NULL, *method[M_COUNT] = {0};
    if (kwargs && args && name && res && vis &&
        !pPyDict_SetItemString(kwargs, "instance_name", name) &&
        !pPyDict_SetItemString(kwargs, "resources", res) &&
        !pPyDict_SetItemString(kwargs, "visible", vis))
        slave = pPyObject_Call(inst->cls, args, kwargs);
    XDECREF(vis);
    XDECREF(res);
    XDECREF(name);
    XDECREF(args);
    XDECREF(kwargs);
    if (!slave) return py_error(x);
    for (int i = 0; i < M_COUNT; ++i) {
        method[i] = pPyObject_GetAttr(slave, g_method_names[i]);
        if (!method[i]) {
            pPyErr_Clear();
            for (int j = 0; j < i; ++j) DECREF(method[j]);
            DECREF(slave);
            return FAIL(x, "the slave class %s has no method %s", g_model, METHOD_NAMES[i]);
        }
    }
    release_slave(inst);
    inst->slave = slave;
    memcpy(inst->method, method, sizeof method);
    drain_log_queue(x);
    return fmi2OK;
}

/* str(getattr(o, name)) into buf */
static int attr_text(PyObject *o, const char *name, char *buf, size_t size) {
    PyObject *a = pPyObject_GetAttrString(o, name);
    int ok = a && py_text(a, buf, size);
    XDECREF(a);
    pPyErr_Clear();
    return ok;
}

/* The variable table (type and name per value reference) from slave.vars. */
static fmi2Status read_variables(Ctx *x) {
    Instance *inst = x->inst;
    PyObject *vars = pPyObject_GetAttrString(inst->slave, "vars");
    PyObject *values_fn = vars ? pPyObject_GetAttrString(vars, "values") : NULL;
    PyObject *values = values_fn ? pPyObject_CallFunctionObjArgs(values_fn, NULL) : NULL;
    Py_ssize_t n = values ? pPyObject_Size(vars) : -1;
    PyObject *it = n >= 0 ? pPyObject_GetIter(values) : NULL;
    fmi2Status st = fmi2OK;
    if (!it) {
        st = py_error(x);
        goto done;
    }
    inst->nvars = (size_t)n;
    inst->var_type = calloc((size_t)n + 1, 1);
    inst->var_names = calloc((size_t)n + 1, sizeof(char *));
    if (!inst->var_type || !inst->var_names) {
        st = FAIL(x, "out of memory");
        goto done;
    }
    for (PyObject *v; (v = pPyIter_Next(it)) != NULL; DECREF(v)) {
        PyObject *vr = pPyObject_GetAttrString(v, "value_reference");
        long r = vr ? pPyLong_AsLong(vr) : -1;
        XDECREF(vr);
        PyObject *cls = pPyObject_GetAttrString(v, "__class__");
        char tname[32] = "", vname[256] = "?";
        int typed = cls && attr_text(cls, "__name__", tname, sizeof tname);
        XDECREF(cls);
        attr_text(v, "name", vname, sizeof vname);
        pPyErr_Clear();
        if (r < 0 || r >= n || !typed) {
            DECREF(v);
            st = FAIL(x, "variable %s has value reference %ld: expected 0..%zd", vname, r, n - 1);
            goto done;
        }
        inst->var_type[r] = !strcmp(tname, "Real")      ? T_REAL
                            : !strcmp(tname, "Integer") ? T_INTEGER
                            : !strcmp(tname, "Boolean") ? T_BOOLEAN
                            : !strcmp(tname, "String")  ? T_STRING
                                                        : '?';
        free(inst->var_names[r]);
        inst->var_names[r] = dup_text(vname);
    }
    if (pPyErr_Occurred()) st = py_error(x);
done:
    XDECREF(it);
    XDECREF(values);
    XDECREF(values_fn);
    XDECREF(vars);
    return st;
}

/* Log categories from the slave class's log_categories (its keys, in order). */
static void read_categories(Instance *inst) {
    PyObject *cats = pPyObject_GetAttrString(inst->cls, "log_categories");
    PyObject *it = cats ? pPyObject_GetIter(cats) : NULL;
    for (PyObject *k; it && (k = pPyIter_Next(it)) != NULL; DECREF(k)) {
        char buf[128];
        if (inst->ncat < MAX_CATEGORIES && py_text(k, buf, sizeof buf))
            inst->cat_names[inst->ncat++] = dup_text(buf);
    }
    pPyErr_Clear();
    XDECREF(it);
    XDECREF(cats);
    inst->cat_calls = category_index(inst, "logFmiCalls");
    inst->cat_all = category_index(inst, "logAll");
    inst->cat_error = category_index(inst, "logStatusError");
}

/* What "all categories" means: every one but logFmiCalls, which traces every call and
 * is switched on only when named. */
static uint64_t all_categories(const Instance *inst) {
    return inst->cat_calls >= 0 ? ~((uint64_t)1 << inst->cat_calls) : ~(uint64_t)0;
}

/* The slave class: resources/slavemodule.txt names its module (imported once per
 * process, from resources/ put on sys.path), the model identifier names the class. */
static fmi2Status find_class(Ctx *x) {
    Instance *inst = x->inst;
    char path[1200], module[256] = "";
    snprintf(path, sizeof path, "%s/slavemodule.txt", inst->resources);
    FILE *f = fopen(path, "r");
    if (!f) return FAIL(x, "%s is missing: the FMU does not name its slave module", path);
    if (!fgets(module, sizeof module, f)) module[0] = '\0';
    fclose(f);
    trim(module);
    if (!module[0]) return FAIL(x, "%s is empty: expected the slave module's name", path);
    PyObject *sys_path = pPySys_GetObject("path"); /* borrowed */
    PyObject *res = pPyUnicode_FromString(inst->resources);
    int present = sys_path && res ? pPySequence_Contains(sys_path, res) : -1;
    if (present == 0) present = pPyList_Insert(sys_path, 0, res) == 0 ? 1 : -1;
    XDECREF(res);
    if (present < 0) return py_error(x);
    PyObject *mod = pPyImport_ImportModule(module);
    if (!mod) return py_error(x);
    inst->cls = pPyObject_GetAttrString(mod, g_model);
    DECREF(mod);
    if (!inst->cls) {
        pPyErr_Clear();
        return FAIL(x, "module %s defines no class %s (the model identifier)", module, g_model);
    }
    return fmi2OK;
}

static void free_instance(Instance *inst, int python_alive) {
    while (inst->states) {
        FmuState *s = inst->states;
        inst->states = s->next;
        if (python_alive) {
            XDECREF(s->value);
            XDECREF(s->bytes);
        }
        s->magic = 0;
        free(s);
    }
    if (python_alive) {
        release_slave(inst);
        CLEAR(inst->cls);
        for (int i = 0; i < C_COUNT; ++i) CLEAR(inst->refs[i].list);
    }
    for (int i = 0; i < C_COUNT; ++i) free(inst->refs[i].vr);
    for (size_t i = 0; i < inst->nvars; ++i) free(inst->var_names ? inst->var_names[i] : NULL);
    for (size_t i = 0; i < inst->nstrings; ++i) free(inst->strings[i]);
    for (int i = 0; i < inst->ncat; ++i) free(inst->cat_names[i]);
    free(inst->strings);
    free(inst->var_names);
    free(inst->var_type);
    free(inst->resources);
    free(inst->name);
    inst->magic = 0;
    free(inst);
}

/* fmuResourceLocation (file:///path, file:/path, file://localhost/path) -> a path */
static char *resource_path(const char *uri) {
    const char *p = uri;
    if (!strncmp(p, "file://localhost/", 17)) p += 16;
    else if (!strncmp(p, "file:///", 8)) p += 7;
    else if (!strncmp(p, "file:/", 6)) p += 5;
    else return NULL;
    size_t n = strlen(p);
    char *out = malloc(n + 1), *o = out;
    if (!out) return NULL;
    for (size_t i = 0; i < n; ++i) {
        unsigned hex;
        if (p[i] == '%' && i + 2 < n && sscanf(p + i + 1, "%2x", &hex) == 1) {
            *o++ = (char)hex;
            i += 2;
        } else {
            *o++ = p[i];
        }
    }
    while (o > out + 1 && o[-1] == '/') --o;
    *o = '\0';
    return out;
}

/* ------------------------------------------------------------------ value access */
static const char *type_name(char t) {
    return t == T_REAL ? "Real" : t == T_INTEGER ? "Integer" : t == T_BOOLEAN ? "Boolean"
         : t == T_STRING ? "String" : "unknown";
}

static fmi2Status check_refs(Ctx *x, const fmi2ValueReference vr[], size_t nvr,
                             const void *values, char type) {
    Instance *inst = x->inst;
    if (!vr || !values) return FAIL(x, "NULL %s array with nvr = %zu", vr ? "value" : "vr", nvr);
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] >= inst->nvars)
            return FAIL(x, "value reference %u does not exist: expected 0..%zu", vr[i],
                        inst->nvars - 1);
        if (inst->var_type[vr[i]] != type)
            return FAIL(x, "value reference %u (%s) is %s, not %s", vr[i],
                        inst->var_names[vr[i]], type_name(inst->var_type[vr[i]]),
                        type_name(type));
    }
    return fmi2OK;
}

/* The references as a tuple: immutable, so a slave may key a cache on its identity. */
static PyObject *ref_tuple(const fmi2ValueReference vr[], size_t nvr) {
    PyObject *l = pPyTuple_New((Py_ssize_t)nvr);
    for (size_t i = 0; l && i < nvr; ++i) {
        PyObject *o = pPyLong_FromLong((long)vr[i]);
        if (!o || pPyTuple_SetItem(l, (Py_ssize_t)i, o)) CLEAR(l);
    }
    return l;
}

/* The references as a Python tuple (new reference), from the call's cache if unchanged. */
static PyObject *call_refs(Instance *inst, int call, const fmi2ValueReference vr[], size_t nvr) {
    RefCache *rc = &inst->refs[call];
    if (rc->list && rc->n == nvr && !memcmp(rc->vr, vr, nvr * sizeof *vr)) {
        INCREF(rc->list);
        return rc->list;
    }
    PyObject *l = ref_tuple(vr, nvr);
    fmi2ValueReference *copy = l ? malloc(nvr * sizeof *vr) : NULL;
    if (!copy) return l; /* not cached */
    memcpy(copy, vr, nvr * sizeof *vr);
    free(rc->vr);
    XDECREF(rc->list);
    rc->vr = copy;
    rc->n = nvr;
    INCREF(l);
    rc->list = l;
    return l;
}

static void clear_strings(Instance *inst) {
    for (size_t i = 0; i < inst->nstrings; ++i) free(inst->strings[i]);
    inst->nstrings = 0;
}

static fmi2Status store_value(Ctx *x, PyObject *o, char type, void *out, size_t i,
                              fmi2ValueReference vr) {
    Instance *inst = x->inst;
    switch (type) {
    case T_REAL: {
        double d = pPyFloat_AsDouble(o);
        if (d == -1.0 && pPyErr_Occurred()) return py_error(x);
        ((fmi2Real *)out)[i] = d;
        return fmi2OK;
    }
    case T_INTEGER: {
        long v = pPyLong_AsLong(o);
        if (v == -1 && pPyErr_Occurred()) return py_error(x);
        if (v < INT_MIN || v > INT_MAX)
            return FAIL(x, "%s = %ld does not fit an fmi2Integer", inst->var_names[vr], v);
        ((fmi2Integer *)out)[i] = (fmi2Integer)v;
        return fmi2OK;
    }
    case T_BOOLEAN: {
        int b = pPyObject_IsTrue(o);
        if (b < 0) return py_error(x);
        ((fmi2Boolean *)out)[i] = b ? fmi2True : fmi2False;
        return fmi2OK;
    }
    default: {
        PyObject *s = pPyObject_Str(o);
        Py_ssize_t n;
        const char *t = s ? pPyUnicode_AsUTF8AndSize(s, &n) : NULL;
        char *copy = t ? malloc((size_t)n + 1) : NULL;
        if (copy) memcpy(copy, t, (size_t)n + 1);
        XDECREF(s);
        if (!copy) return t ? FAIL(x, "out of memory") : py_error(x);
        inst->strings[inst->nstrings++] = copy;
        ((fmi2String *)out)[i] = copy;
        return fmi2OK;
    }
    }
}

static fmi2Status get_values(fmi2Component c, int call, int method, char type,
                             const fmi2ValueReference vr[], size_t nvr, void *out) {
    Ctx x;
    fmi2Status st = begin(&x, c, call);
    if (st != fmi2OK || nvr == 0) return end(&x, st);
    if ((st = check_refs(&x, vr, nvr, out, type)) != fmi2OK) return end(&x, st);
    Instance *inst = x.inst;
    if (type == T_STRING) {
        clear_strings(inst);
        char **s = realloc(inst->strings, nvr * sizeof *s);
        if (!s) return end(&x, FAIL(&x, "out of memory"));
        inst->strings = s;
    }
    PyObject *refs = call_refs(inst, call, vr, nvr);
    PyObject *r = refs ? call_slave(&x, method, refs, NULL, NULL) : NULL;
    XDECREF(refs);
    if (!r) return end(&x, py_error(&x));
    Py_ssize_t n = pPySequence_Size(r);
    if (n != (Py_ssize_t)nvr) {
        pPyErr_Clear();
        st = FAIL(&x, "the slave returned %zd values for %zu value references", n, nvr);
    }
    for (size_t i = 0; st == fmi2OK && i < nvr; ++i) {
        PyObject *o = pPySequence_GetItem(r, (Py_ssize_t)i);
        st = o ? store_value(&x, o, type, out, i, vr[i]) : py_error(&x);
        XDECREF(o);
    }
    DECREF(r);
    return end(&x, st);
}

static PyObject *value_object(char type, const void *values, size_t i) {
    switch (type) {
    case T_REAL: return pPyFloat_FromDouble(((const fmi2Real *)values)[i]);
    case T_INTEGER: return pPyLong_FromLong(((const fmi2Integer *)values)[i]);
    case T_BOOLEAN: return pPyBool_FromLong(((const fmi2Boolean *)values)[i] != fmi2False);
    default: {
        const char *s = ((const fmi2String *)values)[i];
        return s ? pPyUnicode_FromString(s) : NULL;
    }
    }
}

static fmi2Status set_values(fmi2Component c, int call, int method, char type,
                             const fmi2ValueReference vr[], size_t nvr, const void *values) {
    Ctx x;
    fmi2Status st = begin(&x, c, call);
    if (st != fmi2OK || nvr == 0) return end(&x, st);
    if ((st = check_refs(&x, vr, nvr, values, type)) != fmi2OK) return end(&x, st);
    PyObject *l = pPyList_New((Py_ssize_t)nvr);
    for (size_t i = 0; l && i < nvr; ++i) {
        PyObject *o = value_object(type, values, i);
        if (!o) {
            CLEAR(l);
            if (!pPyErr_Occurred())
                return end(&x, FAIL(&x, "value %zu (%s) is a NULL string", i,
                                    x.inst->var_names[vr[i]]));
        } else if (pPyList_SetItem(l, (Py_ssize_t)i, o)) {
            CLEAR(l);
        }
    }
    PyObject *refs = l ? call_refs(x.inst, call, vr, nvr) : NULL;
    if (!refs) {
        XDECREF(l);
        return end(&x, py_error(&x));
    }
    return end(&x, call_void(&x, method, refs, l, NULL));
}

/* ------------------------------------------------------------------ FMI: common */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_SET_DEBUG_LOGGING);
    if (st != fmi2OK) return end(&x, st);
    Instance *inst = x.inst;
    if (nCategories == 0) {
        inst->logging_on = loggingOn != fmi2False;
        inst->cat_on = inst->logging_on ? all_categories(inst) : 0;
        inst->cat_off = 0;
        return end(&x, fmi2OK);
    }
    if (!categories) return end(&x, FAIL(&x, "NULL categories with nCategories = %zu", nCategories));
    uint64_t bits = 0;
    for (size_t i = 0; i < nCategories; ++i) {
        int ci = categories[i] ? category_index(inst, categories[i]) : -1;
        if (ci < 0) {
            char known[1024] = "";
            for (int k = 0; k < inst->ncat; ++k)
                snprintf(known + strlen(known), sizeof known - strlen(known), "%s%s",
                         k ? ", " : "", inst->cat_names[k]);
            return end(&x, FAIL(&x, "log category '%.200s' is unknown: expected one of %s",
                                categories[i] ? categories[i] : "(null)", known));
        }
        bits |= (uint64_t)1 << ci;
    }
    if (loggingOn) { /* only these categories (all of them if logAll is named) */
        uint64_t all = inst->cat_all >= 0 ? (uint64_t)1 << inst->cat_all : 0;
        inst->logging_on = 1;
        inst->cat_on = bits;
        inst->cat_off = bits & all ? 0 : ~bits;
    } else {
        inst->cat_on &= ~bits;
        inst->cat_off |= bits;
    }
    return end(&x, fmi2OK);
}

static void log_orphan(const fmi2CallbackFunctions *f, const char *name, fmi2Status status,
                       const char *text) {
    if (f && f->logger)
        emit(f->logger, f->componentEnvironment, name ? name : "?", status,
             status == fmi2Fatal ? "logStatusFatal" : "logStatusError", text);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    char text[4400];
    (void)fmuGUID;
    find_model_identifier();
    if (!instanceName || !instanceName[0]) {
        log_orphan(functions, "?", fmi2Error, "fmi2Instantiate: instanceName is NULL or empty");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        snprintf(text, sizeof text, "fmi2Instantiate: %s supports co-simulation only", g_model);
        log_orphan(functions, instanceName, fmi2Error, text);
        return NULL;
    }
    char *resources = fmuResourceLocation ? resource_path(fmuResourceLocation) : NULL;
    if (!resources) {
        snprintf(text, sizeof text,
                 "fmi2Instantiate: fmuResourceLocation '%.200s' is invalid: expected a file: URI",
                 fmuResourceLocation ? fmuResourceLocation : "(null)");
        log_orphan(functions, instanceName, fmi2Error, text);
        return NULL;
    }
    if (!ensure_python(resources)) {
        snprintf(text, sizeof text, "fmi2Instantiate: Python is not available: %s",
                 g_python_error);
        log_orphan(functions, instanceName, fmi2Fatal, text);
        free(resources);
        return NULL;
    }
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst || !(inst->name = dup_text(instanceName))) {
        free(inst);
        free(resources);
        log_orphan(functions, instanceName, fmi2Fatal, "fmi2Instantiate: out of memory");
        return NULL;
    }
    inst->magic = INSTANCE_MAGIC;
    inst->resources = resources;
    inst->logger = functions ? functions->logger : NULL;
    inst->env = functions ? functions->componentEnvironment : NULL;
    inst->logging_on = loggingOn != fmi2False;
    inst->visible = visible != fmi2False;
    inst->cat_calls = inst->cat_all = inst->cat_error = -1;
    inst->state = S_INSTANTIATED;
    Ctx x;
    memset(&x, 0, sizeof x);
    x.call = C_INSTANTIATE;
    x.inst = inst;
    x.gil = pPyGILState_Ensure();
    x.have_gil = 1;
    fmi2Status st = find_class(&x);
    if (st == fmi2OK) {
        read_categories(inst);
        inst->cat_on = inst->logging_on ? all_categories(inst) : 0;
    }
    if (st == fmi2OK) st = make_slave(&x);
    if (st == fmi2OK) st = read_variables(&x);
    if (st != fmi2OK) {
        inst->state = S_ERROR;
        release_slave(inst);
        CLEAR(inst->cls);
        end(&x, st);
        free_instance(inst, 0);
        return NULL;
    }
    end(&x, fmi2OK);
    pthread_mutex_lock(&g_lock);
    inst->next = g_instances;
    g_instances = inst;
    pthread_mutex_unlock(&g_lock);
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = lookup(c);
    if (!inst) return;
    pthread_mutex_lock(&g_lock);
    for (Instance **p = &g_instances; *p; p = &(*p)->next) {
        if (*p == inst) {
            *p = inst->next;
            break;
        }
    }
    pthread_mutex_unlock(&g_lock);
    /* at process exit Python may be gone already: then only the C memory is freed */
    int alive = pPy_IsInitialized();
    PyGILState_STATE g = alive ? pPyGILState_Ensure() : PyGILState_UNLOCKED;
    free_instance(inst, alive);
    if (alive) pPyGILState_Release(g);
    pthread_mutex_lock(&g_lock);
    int last = g_instances == NULL;
    pthread_mutex_unlock(&g_lock);
    if (last && alive) glider_thread_unpin(); /* this thread's kept thread state */
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_SETUP_EXPERIMENT);
    if (st != fmi2OK) return end(&x, st);
    if (!isfinite(startTime)) return end(&x, FAIL(&x, "startTime = %g is invalid: expected a finite time", startTime));
    PyObject *start = pPyFloat_FromDouble(startTime);
    PyObject *stop = stopTimeDefined ? pPyFloat_FromDouble(stopTime) : (INCREF(pNone), pNone);
    PyObject *tol = toleranceDefined ? pPyFloat_FromDouble(tolerance) : (INCREF(pNone), pNone);
    if (!start || !stop || !tol) {
        XDECREF(start);
        XDECREF(stop);
        XDECREF(tol);
        return end(&x, py_error(&x));
    }
    st = call_void(&x, M_SETUP, start, stop, tol);
    if (st == fmi2OK) x.inst->time = startTime;
    return end(&x, st);
}

/* A call without arguments that moves the instance to `next` when the slave succeeds. */
static fmi2Status transition(fmi2Component c, int call, int method, unsigned next) {
    Ctx x;
    fmi2Status st = begin(&x, c, call);
    if (st == fmi2OK && (st = call_void(&x, method, NULL, NULL, NULL)) == fmi2OK)
        x.inst->state = next;
    return end(&x, st);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    return transition(c, C_ENTER_INIT, M_ENTER, S_INIT);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return transition(c, C_EXIT_INIT, M_EXIT, S_STEP_COMPLETE);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    return transition(c, C_TERMINATE, M_TERMINATE, S_TERMINATED);
}

fmi2Status fmi2Reset(fmi2Component c) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_RESET);
    if (st == fmi2OK && (st = make_slave(&x)) == fmi2OK) {
        x.inst->state = S_INSTANTIATED;
        x.inst->time = 0.0;
        x.inst->terminated = 0;
    }
    return end(&x, st);
}

/* ------------------------------------------------------------------ FMI: values */
/* fmi2Get<Type> and fmi2Set<Type> for the four types, all through get_values/set_values */
#define VALUE_ACCESS(Type, TYPE)                                                           \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,   \
                             fmi2##Type value[]) {                                         \
        return get_values(c, C_GET_##TYPE, M_GET_##TYPE, T_##TYPE, vr, nvr, (void *)value); \
    }                                                                                      \
    fmi2Status fmi2Set##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,   \
                             const fmi2##Type value[]) {                                   \
        return set_values(c, C_SET_##TYPE, M_SET_##TYPE, T_##TYPE, vr, nvr, value);         \
    }
VALUE_ACCESS(Real, REAL)
VALUE_ACCESS(Integer, INTEGER)
VALUE_ACCESS(Boolean, BOOLEAN)
VALUE_ACCESS(String, STRING)
#undef VALUE_ACCESS

/* ------------------------------------------------------------------ FMI: FMU state */
static FmuState *owned_state(Instance *inst, fmi2FMUstate s) {
    for (FmuState *p = inst->states; p; p = p->next)
        if ((void *)p == s) return p->magic == STATE_MAGIC ? p : NULL;
    return NULL;
}

static FmuState *new_state(Instance *inst) {
    FmuState *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->magic = STATE_MAGIC;
    s->next = inst->states;
    inst->states = s;
    return s;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_GET_FMU_STATE);
    if (st != fmi2OK) return end(&x, st);
    Instance *inst = x.inst;
    if (!FMUstate) return end(&x, FAIL(&x, "FMUstate is NULL"));
    FmuState *s = *FMUstate ? owned_state(inst, *FMUstate) : NULL;
    if (*FMUstate && !s) return end(&x, FAIL(&x, "*FMUstate is not a state of this instance"));
    PyObject *value = call_slave(&x, M_GET_STATE, NULL, NULL, NULL);
    if (!value) return end(&x, py_error(&x));
    if (!s && !(s = new_state(inst))) {
        DECREF(value);
        return end(&x, FAIL(&x, "out of memory"));
    }
    XDECREF(s->value);
    CLEAR(s->bytes);
    s->value = value;
    s->machine = inst->state;
    s->time = inst->time;
    s->terminated = inst->terminated;
    *FMUstate = s;
    return end(&x, fmi2OK);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_SET_FMU_STATE);
    if (st != fmi2OK) return end(&x, st);
    FmuState *s = owned_state(x.inst, FMUstate);
    if (!s) return end(&x, FAIL(&x, "FMUstate is not a state of this instance"));
    INCREF(s->value);
    if ((st = call_void(&x, M_SET_STATE, s->value, NULL, NULL)) == fmi2OK) {
        x.inst->state = s->machine;
        x.inst->time = s->time;
        x.inst->terminated = s->terminated;
    }
    return end(&x, st);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_FREE_FMU_STATE);
    if (st != fmi2OK || !FMUstate || !*FMUstate) return end(&x, st);
    Instance *inst = x.inst;
    for (FmuState **p = &inst->states; *p; p = &(*p)->next) {
        if ((void *)*p == *FMUstate) {
            FmuState *s = *p;
            *p = s->next;
            XDECREF(s->value);
            XDECREF(s->bytes);
            s->magic = 0;
            free(s);
            *FMUstate = NULL;
            return end(&x, fmi2OK);
        }
    }
    return end(&x, FAIL(&x, "*FMUstate is not a state of this instance"));
}

/* Serialized layout: magic, FMI state, terminated flag, time, model identifier, then the
 * bytes of the slave's _fmu_state_to_bytes. */
static const char SER_MAGIC[8] = {'G', 'F', 'M', 'I', 'S', 'T', '0', '1'};
#define SER_HEADER (8 + 4 + 4 + 8 + sizeof g_model)

static fmi2Status state_bytes(Ctx *x, FmuState *s, const char **data, Py_ssize_t *n) {
    if (!s->bytes) {
        INCREF(s->value);
        PyObject *b = call_slave(x, M_TO_BYTES, s->value, NULL, NULL);
        DECREF(s->value);
        if (!b) return py_error(x);
        s->bytes = b;
    }
    char *p;
    if (pPyBytes_AsStringAndSize(s->bytes, &p, n) < 0) {
        CLEAR(s->bytes);
        return py_error(x);
    }
    *data = p;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_STATE_SIZE);
    if (st != fmi2OK) return end(&x, st);
    FmuState *s = owned_state(x.inst, FMUstate);
    if (!s || !size) return end(&x, FAIL(&x, s ? "size is NULL" : "FMUstate is not a state of this instance"));
    const char *data;
    Py_ssize_t n;
    if ((st = state_bytes(&x, s, &data, &n)) == fmi2OK) *size = SER_HEADER + (size_t)n;
    return end(&x, st);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte buffer[],
                                 size_t size) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_SERIALIZE);
    if (st != fmi2OK) return end(&x, st);
    FmuState *s = owned_state(x.inst, FMUstate);
    if (!s || !buffer) return end(&x, FAIL(&x, s ? "buffer is NULL" : "FMUstate is not a state of this instance"));
    const char *data;
    Py_ssize_t n;
    if ((st = state_bytes(&x, s, &data, &n)) != fmi2OK) return end(&x, st);
    if (size < SER_HEADER + (size_t)n)
        return end(&x, FAIL(&x, "size = %zu is too small: expected %zu bytes", size,
                            SER_HEADER + (size_t)n));
    uint32_t machine = s->machine, term = (uint32_t)s->terminated;
    char *o = buffer;
    memcpy(o, SER_MAGIC, 8);
    memcpy(o + 8, &machine, 4);
    memcpy(o + 12, &term, 4);
    memcpy(o + 16, &s->time, 8);
    memset(o + 24, 0, sizeof g_model);
    memcpy(o + 24, g_model, strlen(g_model));
    memcpy(o + SER_HEADER, data, (size_t)n);
    return end(&x, fmi2OK);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_DESERIALIZE);
    if (st != fmi2OK) return end(&x, st);
    if (!serializedState || !FMUstate)
        return end(&x, FAIL(&x, "%s is NULL", FMUstate ? "serializedState" : "FMUstate"));
    if (size < SER_HEADER || memcmp(serializedState, SER_MAGIC, 8))
        return end(&x, FAIL(&x, "the %zu bytes are not a serialized state of this runtime", size));
    char model[sizeof g_model + 1] = "";
    memcpy(model, serializedState + 24, sizeof g_model);
    if (strcmp(model, g_model))
        return end(&x, FAIL(&x, "the state is one of model %.100s: expected %s", model, g_model));
    uint32_t machine, term;
    double time;
    memcpy(&machine, serializedState + 8, 4);
    memcpy(&term, serializedState + 12, 4);
    memcpy(&time, serializedState + 16, 8);
    if (!(machine & S_LIVE) || (machine & (machine - 1)))
        return end(&x, FAIL(&x, "the state records an invalid FMI state %u", machine));
    PyObject *b = pPyBytes_FromStringAndSize(serializedState + SER_HEADER,
                                             (Py_ssize_t)(size - SER_HEADER));
    PyObject *value = b ? call_slave(&x, M_FROM_BYTES, b, NULL, NULL) : NULL;
    XDECREF(b);
    if (!value) return end(&x, py_error(&x));
    FmuState *s = new_state(x.inst);
    if (!s) {
        DECREF(value);
        return end(&x, FAIL(&x, "out of memory"));
    }
    s->value = value;
    s->machine = machine;
    s->terminated = term != 0;
    s->time = time;
    *FMUstate = s;
    return end(&x, fmi2OK);
}

/* ------------------------------------------------------------------ FMI: not provided */
static fmi2Status unsupported(fmi2Component c, int call) {
    Ctx x;
    return end(&x, begin(&x, c, call));
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown,
        (void)dvUnknown;
    return unsupported(c, C_DIRECTIONAL);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, C_SET_INPUT_DERIVATIVES);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, C_GET_OUTPUT_DERIVATIVES);
}

fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, C_CANCEL_STEP); }

/* ------------------------------------------------------------------ FMI: stepping */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    Ctx x;
    fmi2Status st = begin(&x, c, C_DO_STEP);
    if (st != fmi2OK) return end(&x, st);
    if (!(communicationStepSize > 0.0) || !isfinite(communicationStepSize) ||
        !isfinite(currentCommunicationPoint))
        return end(&x, FAIL(&x, "step of %g s at t = %g s is invalid: expected a finite step > 0",
                            communicationStepSize, currentCommunicationPoint));
    PyObject *t = pPyFloat_FromDouble(currentCommunicationPoint);
    PyObject *h = pPyFloat_FromDouble(communicationStepSize);
    PyObject *r = t && h ? call_slave(&x, M_STEP, t, h, NULL) : NULL;
    XDECREF(t);
    XDECREF(h);
    if (!r) return end(&x, py_error(&x));
    int go_on = pPyObject_IsTrue(r);
    DECREF(r);
    if (go_on < 0) return end(&x, py_error(&x));
    Instance *inst = x.inst;
    if (go_on) {
        inst->time = currentCommunicationPoint + communicationStepSize;
        return end(&x, fmi2OK);
    }
    inst->state = S_STEP_FAILED;
    inst->terminated = 1;
    inst->time = currentCommunicationPoint;
    add_msg(&x, fmi2Discard, category_index(inst, "logStatusDiscard"),
            "fmi2DoStep: the slave stopped the simulation at t = %.17g s",
            currentCommunicationPoint);
    return end(&x, fmi2Discard);
}

static fmi2Status get_status(fmi2Component c, int call, fmi2StatusKind s, fmi2StatusKind want,
                             void *value, void (*store)(const Instance *, void *)) {
    Ctx x;
    fmi2Status st = begin(&x, c, call);
    if (st != fmi2OK) return end(&x, st);
    if (!value) return end(&x, FAIL(&x, "value is NULL"));
    if (s != want || !store) return end(&x, FAIL(&x, "status kind %d is not provided", (int)s));
    store(x.inst, value);
    return end(&x, fmi2OK);
}

static void store_step_status(const Instance *i, void *v) {
    *(fmi2Status *)v = i->state == S_STEP_FAILED ? fmi2Discard : fmi2OK;
}
static void store_last_time(const Instance *i, void *v) { *(fmi2Real *)v = i->time; }
static void store_terminated(const Instance *i, void *v) {
    *(fmi2Boolean *)v = i->terminated ? fmi2True : fmi2False;
}
static void store_pending(const Instance *i, void *v) {
    (void)i;
    *(fmi2String *)v = "no asynchronous step is pending";
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    return get_status(c, C_GET_STATUS, s, fmi2DoStepStatus, value, store_step_status);
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    return get_status(c, C_GET_REAL_STATUS, s, fmi2LastSuccessfulTime, value, store_last_time);
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    return get_status(c, C_GET_INTEGER_STATUS, s, fmi2DoStepStatus, value, NULL);
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    return get_status(c, C_GET_BOOLEAN_STATUS, s, fmi2Terminated, value, store_terminated);
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    return get_status(c, C_GET_STRING_STATUS, s, fmi2PendingStatus, value, store_pending);
}
