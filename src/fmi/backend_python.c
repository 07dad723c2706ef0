/* glider-cosim's Python back end: hosts a pythonfmu Fmi2Slave behind the FMI layer.
 *
 * One binary for every FMU and every Python >= 3.11: it links no libpython and calls
 * only functions of Python's stable ABI, resolved with dlsym when an FMU is first
 * instantiated (from the host process if it already has Python, else from the libpython
 * recorded at build time, which the back end then starts itself).
 *
 * The FMI state machine, statuses, messages and FMU-state handles are the layer's
 * (fmi2_layer.c, fmi_layer.h); this file only turns the layer's calls into calls of the
 * slave, with the GIL held (taken in enter(), released in leave()), and drains the
 * slave's log queue into the call's messages.
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
 */
#define _GNU_SOURCE
#include "glider_python.h"

#include <dlfcn.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bundle_loader.h"
#include "fmi_layer.h"
#include "python_find.h"
#include "python_threads.h"

/* This back end is compiled into the Python flavor's runtime only (never shipped as
 * source) and is written with FMI 2.0's names: they stand for the layer's own. */
typedef Status fmi2Status;
typedef ValueRef fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef const char *fmi2String;
#define fmi2OK ST_OK
#define fmi2Warning ST_WARNING
#define fmi2Discard ST_DISCARD
#define fmi2Error ST_ERROR
#define fmi2Fatal ST_FATAL
#define fmi2True 1
#define fmi2False 0

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
    X(PyList_SetSlice) X(PySequence_Size) X(PySequence_GetItem)                           \
    X(PyLong_FromLong) X(PyLong_AsLong) X(PyFloat_FromDouble)      \
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


#define FAIL glider_fail
#define add_msg glider_add_msg
#define category_index glider_category_index
#define dup_text glider_dup_text

/* ------------------------------------------------------------------ process state */
static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER; /* Python start */
static int g_python_ready = 0;
static char g_python_error[4096];
static char g_model[MODEL_ID_SIZE]; /* model identifier: this binary's file name without .so */

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

/* ------------------------------------------------------------------ instances */
/* The value-reference tuple last passed for a call, reused while the host passes the
 * same references. */
typedef struct {
    size_t n;
    fmi2ValueReference *vr;
    PyObject *list;
} RefCache;

typedef struct {
    PyObject *cls, *slave, *method[M_COUNT];
    char *var_type;     /* VarType per value reference */
    char **var_names;
    size_t nvars;
    char **strings;     /* buffers returned by fmi2GetString, valid until the next call */
    size_t nstrings;
    RefCache refs[C_COUNT];
    int *jac_row, *jac_col; /* Instance.jac_row, jac_col (NULL: no directional derivatives) */
    int counted; /* in g_live */
} PyInstance;

#define PY(inst) ((PyInstance *)(inst)->backend)

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

static const char *py_model_identifier(void) {
    find_model_identifier();
    return g_model;
}

static int py_start(const char *resources, char *err, size_t errsize) {
    find_model_identifier();
    if (ensure_python(resources)) return 1;
    snprintf(err, errsize, "Python is not available: %s", g_python_error);
    return 0;
}

static int py_alive(void) { return g_python_ready && pPy_IsInitialized(); }

/* ------------------------------------------------------------------ call framing */
static fmi2Status py_enter(Ctx *x) {
    if (!py_alive()) return ST_GONE; /* the host's Python finalized: fmi_layer.c's after_exit */
    x->token = (int)glider_gil_ensure(); /* one thread state per host thread, kept */
    x->have_token = 1;
    return fmi2OK;
}

static int g_live; /* live instances of this FMU (under g_lock) */

static void py_leave(Ctx *x) {
    glider_gil_release((PyGILState_STATE)x->token);
    if (x->call == C_FREE) {
        pthread_mutex_lock(&g_lock);
        int last = g_live == 0;
        pthread_mutex_unlock(&g_lock);
        if (last) glider_thread_unpin(); /* this thread's kept thread state */
    }
}

/* Move the slave's queued log messages into the call's messages. */
static void drain_log_queue(Ctx *x) {
    Instance *inst = x->inst;
    if (!inst || !PY(inst) || !PY(inst)->slave) return;
    PyObject *q = pPyObject_GetAttr(PY(inst)->slave, g_str_log_queue);
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

/* Call fn with 0-3 arguments (new reference, or NULL with the Python exception pending);
 * the slave's log queue is drained either way. */
static PyObject *call_object(Ctx *x, PyObject *fn, PyObject *a, PyObject *b, PyObject *c) {
    PyObject *r = pPyObject_CallFunctionObjArgs(fn, a, b, c, NULL);
    PyObject *t = NULL, *v = NULL, *tb = NULL;
    if (!r) pPyErr_Fetch(&t, &v, &tb); /* keep the exception while the queue is read */
    drain_log_queue(x);
    if (!r) pPyErr_Restore(t, v, tb);
    return r;
}

/* A bound slave method (SLAVE_METHODS) called as call_object does. */
static PyObject *call_slave(Ctx *x, int method, PyObject *a, PyObject *b, PyObject *c) {
    return call_object(x, PY(x->inst)->method[method], a, b, c);
}

/* slave.<name>() for the optional protocol (directional derivatives): NULL with the
 * exception pending if it fails; *absent = 1 (and NULL) if the slave has no such method */
static PyObject *call_optional(Ctx *x, const char *name, int *absent) {
    PyObject *fn = pPyObject_GetAttrString(PY(x->inst)->slave, name);
    *absent = fn == NULL;
    if (!fn) {
        pPyErr_Clear();
        return NULL;
    }
    PyObject *r = call_object(x, fn, NULL, NULL, NULL);
    DECREF(fn);
    return r;
}

/* n floats (ints when ints is set) of a Python sequence into out; fmi2OK, or an error
 * naming what (the sequence's length, a value) */
static fmi2Status read_numbers(Ctx *x, PyObject *seq, size_t n, int ints, void *out,
                               const char *what) {
    Py_ssize_t len = seq ? pPySequence_Size(seq) : -1;
    if (len != (Py_ssize_t)n) {
        pPyErr_Clear();
        return FAIL(x, "%s has %zd values: expected %zu", what, len, n);
    }
    for (size_t i = 0; i < n; ++i) {
        PyObject *o = pPySequence_GetItem(seq, (Py_ssize_t)i);
        if (ints) {
            long v = o ? pPyLong_AsLong(o) : -1;
            ((int *)out)[i] = (int)v;
        } else {
            ((double *)out)[i] = o ? pPyFloat_AsDouble(o) : -1.0;
        }
        XDECREF(o);
        if (pPyErr_Occurred()) return py_error(x);
    }
    return fmi2OK;
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
static void release_slave(PyInstance *p) {
    for (int i = 0; i < M_COUNT; ++i) CLEAR(p->method[i]);
    CLEAR(p->slave);
}

/* Construct a slave object, bind its methods; it replaces the current one on success. */
static fmi2Status make_slave(Ctx *x) {
    Instance *inst = x->inst;
    PyInstance *p = PY(inst);
    PyObject *kwargs = pPyDict_New(), *args = pPyTuple_New(0);
    PyObject *name = pPyUnicode_FromString(inst->name);
    PyObject *res = pPyUnicode_FromString(inst->resources);
    PyObject *vis = pPyBool_FromLong(inst->visible);
    PyObject *slave = NULL, *method[M_COUNT] = {0};
    if (kwargs && args && name && res && vis &&
        !pPyDict_SetItemString(kwargs, "instance_name", name) &&
        !pPyDict_SetItemString(kwargs, "resources", res) &&
        !pPyDict_SetItemString(kwargs, "visible", vis))
        slave = pPyObject_Call(p->cls, args, kwargs);
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
    release_slave(p);
    p->slave = slave;
    memcpy(p->method, method, sizeof method);
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
    PyInstance *p = PY(inst);
    PyObject *vars = pPyObject_GetAttrString(p->slave, "vars");
    PyObject *values_fn = vars ? pPyObject_GetAttrString(vars, "values") : NULL;
    PyObject *values = values_fn ? pPyObject_CallFunctionObjArgs(values_fn, NULL) : NULL;
    Py_ssize_t n = values ? pPyObject_Size(vars) : -1;
    PyObject *it = n >= 0 ? pPyObject_GetIter(values) : NULL;
    fmi2Status st = fmi2OK;
    if (!it) {
        st = py_error(x);
        goto done;
    }
    p->nvars = (size_t)n;
    p->var_type = calloc((size_t)n + 1, 1);
    p->var_names = calloc((size_t)n + 1, sizeof(char *));
    if (!p->var_type || !p->var_names) {
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
        p->var_type[r] = !strcmp(tname, "Real")      ? T_REAL
                         : !strcmp(tname, "Integer") ? T_INTEGER
                         : !strcmp(tname, "Boolean") ? T_BOOLEAN
                         : !strcmp(tname, "String")  ? T_STRING
                                                     : '?';
        free(p->var_names[r]);
        p->var_names[r] = dup_text(vname);
    }
    if (pPyErr_Occurred()) st = py_error(x);
    inst->nvars = p->nvars;
    inst->var_type = p->var_type;
    inst->var_names = (const char *const *)p->var_names;
done:
    XDECREF(it);
    XDECREF(values);
    XDECREF(values_fn);
    XDECREF(vars);
    return st;
}

/* The directional derivatives' tables from slave._jacobian_tables() (rows and columns
 * per value reference, their numbers; None or no such method: not provided). */
static fmi2Status read_jacobian(Ctx *x) {
    Instance *inst = x->inst;
    PyInstance *p = PY(inst);
    int absent;
    PyObject *t = call_optional(x, "_jacobian_tables", &absent);
    if (absent) return fmi2OK;
    if (!t) return py_error(x);
    fmi2Status st = fmi2OK;
    if (t != pNone) {
        PyObject *item[4];
        for (int i = 0; i < 4; ++i) item[i] = pPySequence_GetItem(t, i);
        long nr = item[2] ? pPyLong_AsLong(item[2]) : -1;
        long nc = item[3] ? pPyLong_AsLong(item[3]) : -1;
        pPyErr_Clear();
        if (!item[0] || !item[1] || nr <= 0 || nc <= 0 || nr > INT_MAX || nc > INT_MAX)
            st = FAIL(x, "_jacobian_tables() is not (rows, columns, nrows, ncolumns)");
        else if (!(p->jac_row = calloc(p->nvars + 1, sizeof(int))) ||
                 !(p->jac_col = calloc(p->nvars + 1, sizeof(int))))
            st = FAIL(x, "out of memory");
        if (st == fmi2OK) st = read_numbers(x, item[0], p->nvars, 1, p->jac_row, "the rows");
        if (st == fmi2OK) st = read_numbers(x, item[1], p->nvars, 1, p->jac_col, "the columns");
        for (size_t i = 0; st == fmi2OK && i < p->nvars; ++i)
            if (p->jac_row[i] < -1 || p->jac_row[i] >= nr || p->jac_col[i] < -1 ||
                p->jac_col[i] >= nc)
                st = FAIL(x, "_jacobian_tables(): value reference %zu is outside the %ldx%ld "
                             "Jacobian", i, nr, nc);
        if (st == fmi2OK) {
            inst->jac_row = p->jac_row;
            inst->jac_col = p->jac_col;
            inst->jac_nrows = (size_t)nr;
            inst->jac_ncols = (size_t)nc;
        }
        for (int i = 0; i < 4; ++i) XDECREF(item[i]);
    }
    DECREF(t);
    return st;
}

/* Log categories from the slave class's log_categories (its keys, in order). */
static void read_categories(Instance *inst) {
    PyObject *cats = pPyObject_GetAttrString(PY(inst)->cls, "log_categories");
    PyObject *it = cats ? pPyObject_GetIter(cats) : NULL;
    const char *names[MAX_CATEGORIES];
    char bufs[MAX_CATEGORIES][128];
    int n = 0;
    for (PyObject *k; it && (k = pPyIter_Next(it)) != NULL; DECREF(k)) {
        if (n < MAX_CATEGORIES && py_text(k, bufs[n], sizeof bufs[n])) {
            names[n] = bufs[n];
            ++n;
        }
    }
    pPyErr_Clear();
    XDECREF(it);
    XDECREF(cats);
    glider_set_categories(inst, names, n);
}

/* glider_load (bundle_loader.h), defined once per process with the GIL held; a
 * reference kept for the process's life, as an imported module is. */
static PyObject *g_loader;

static PyObject *bundle_loader(void) {
    if (g_loader) return g_loader;
    PyObject *builtins = pPyImport_ImportModule("builtins");
    PyObject *exec = builtins ? pPyObject_GetAttrString(builtins, "exec") : NULL;
    PyObject *code = exec ? pPyUnicode_FromString(GLIDER_BUNDLE_LOADER) : NULL;
    PyObject *ns = code ? pPyDict_New() : NULL;
    PyObject *done = ns ? pPyObject_CallFunctionObjArgs(exec, code, ns, NULL) : NULL;
    PyObject *get = done ? pPyObject_GetAttrString(ns, "get") : NULL;
    PyObject *key = get ? pPyUnicode_FromString("glider_load") : NULL;
    PyObject *loader = key ? pPyObject_CallFunctionObjArgs(get, key, NULL) : NULL;
    XDECREF(key);
    XDECREF(get);
    XDECREF(done);
    XDECREF(ns);
    XDECREF(code);
    XDECREF(exec);
    XDECREF(builtins);
    if (loader && !g_loader) g_loader = loader; /* else another thread was first */
    else XDECREF(loader);
    return g_loader;
}

/* The slave class: resources/slavemodule.txt names its module, the model identifier
 * names the class; imported by glider_load from the FMU's own resources/ only. */
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
    PyObject *load = bundle_loader();
    if (!load) return py_error(x);
    PyObject *res = pPyUnicode_FromString(inst->resources);
    PyObject *mod = res ? pPyUnicode_FromString(module) : NULL;
    PyObject *name = mod ? pPyUnicode_FromString(g_model) : NULL;
    PyObject *cls = name ? pPyObject_CallFunctionObjArgs(load, res, mod, name, NULL) : NULL;
    XDECREF(name);
    XDECREF(mod);
    XDECREF(res);
    if (!cls) return py_error(x);
    if (cls == pNone) {
        DECREF(cls);
        return FAIL(x, "module %s defines no class %s (the model identifier)", module, g_model);
    }
    PY(inst)->cls = cls;
    return fmi2OK;
}

static fmi2Status py_create(Ctx *x) {
    Instance *inst = x->inst;
    if (!(inst->backend = calloc(1, sizeof(PyInstance)))) return FAIL(x, "out of memory");
    fmi2Status st = find_class(x);
    if (st == fmi2OK) read_categories(inst);
    if (st == fmi2OK) st = make_slave(x);
    if (st == fmi2OK) st = read_variables(x);
    if (st == fmi2OK) st = read_jacobian(x);
    if (st == fmi2OK) {
        pthread_mutex_lock(&g_lock);
        ++g_live;
        pthread_mutex_unlock(&g_lock);
        PY(inst)->counted = 1;
    }
    return st;
}

static fmi2Status py_reset(Ctx *x) { return make_slave(x); }

static void py_destroy(Instance *inst, int alive) {
    PyInstance *p = PY(inst);
    if (!p) return;
    if (p->counted) {
        pthread_mutex_lock(&g_lock);
        --g_live;
        pthread_mutex_unlock(&g_lock);
    }
    if (alive) {
        release_slave(p);
        CLEAR(p->cls);
        for (int i = 0; i < C_COUNT; ++i) CLEAR(p->refs[i].list);
    }
    for (int i = 0; i < C_COUNT; ++i) free(p->refs[i].vr);
    for (size_t i = 0; i < p->nvars; ++i) free(p->var_names ? p->var_names[i] : NULL);
    for (size_t i = 0; i < p->nstrings; ++i) free(p->strings[i]);
    free(p->strings);
    free(p->var_names);
    free(p->var_type);
    free(p->jac_row);
    free(p->jac_col);
    free(p);
    inst->backend = NULL;
    inst->nvars = 0;
    inst->var_type = NULL;
    inst->var_names = NULL;
}

static fmi2Status py_setup(Ctx *x, int tolerance_defined, double tolerance, double start,
                           int stop_defined, double stop_time) {
    PyObject *t0 = pPyFloat_FromDouble(start);
    PyObject *stop = stop_defined ? pPyFloat_FromDouble(stop_time) : (INCREF(pNone), pNone);
    PyObject *tol = tolerance_defined ? pPyFloat_FromDouble(tolerance) : (INCREF(pNone), pNone);
    if (!t0 || !stop || !tol) {
        XDECREF(t0);
        XDECREF(stop);
        XDECREF(tol);
        return py_error(x);
    }
    return call_void(x, M_SETUP, t0, stop, tol);
}

static fmi2Status py_transition(Ctx *x, int call) {
    int method = call == C_ENTER_INIT ? M_ENTER : call == C_EXIT_INIT ? M_EXIT : M_TERMINATE;
    return call_void(x, method, NULL, NULL, NULL);
}

/* ------------------------------------------------------------------ value access */
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
static PyObject *call_refs(PyInstance *p, int call, const fmi2ValueReference vr[], size_t nvr) {
    RefCache *rc = &p->refs[call];
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

static void clear_strings(PyInstance *p) {
    for (size_t i = 0; i < p->nstrings; ++i) free(p->strings[i]);
    p->nstrings = 0;
}

static fmi2Status store_value(Ctx *x, PyObject *o, char type, void *out, size_t i,
                              fmi2ValueReference vr) {
    PyInstance *p = PY(x->inst);
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
            return FAIL(x, "%s = %ld does not fit an fmi%c%s", p->var_names[vr], v,
                        x->inst->logger.fmi3 ? '3' : '2', glider_type_name(x, T_INTEGER));
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
        p->strings[p->nstrings++] = copy;
        ((fmi2String *)out)[i] = copy;
        return fmi2OK;
    }
    }
}

static int get_method(char type) {
    return type == T_REAL ? M_GET_REAL : type == T_INTEGER ? M_GET_INTEGER
         : type == T_BOOLEAN ? M_GET_BOOLEAN : M_GET_STRING;
}

static fmi2Status py_get(Ctx *x, char type, const fmi2ValueReference vr[], size_t nvr,
                         void *out) {
    PyInstance *p = PY(x->inst);
    fmi2Status st = fmi2OK;
    if (type == T_STRING) {
        clear_strings(p);
        char **s = realloc(p->strings, nvr * sizeof *s);
        if (!s) return FAIL(x, "out of memory");
        p->strings = s;
    }
    PyObject *refs = call_refs(p, x->call, vr, nvr);
    PyObject *r = refs ? call_slave(x, get_method(type), refs, NULL, NULL) : NULL;
    XDECREF(refs);
    if (!r) return py_error(x);
    Py_ssize_t n = pPySequence_Size(r);
    if (n != (Py_ssize_t)nvr) {
        pPyErr_Clear();
        st = FAIL(x, "the slave returned %zd values for %zu value references", n, nvr);
    }
    for (size_t i = 0; st == fmi2OK && i < nvr; ++i) {
        PyObject *o = pPySequence_GetItem(r, (Py_ssize_t)i);
        st = o ? store_value(x, o, type, out, i, vr[i]) : py_error(x);
        XDECREF(o);
    }
    DECREF(r);
    return st;
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

static fmi2Status py_set(Ctx *x, char type, const fmi2ValueReference vr[], size_t nvr,
                         const void *values) {
    int method = type == T_REAL ? M_SET_REAL : type == T_INTEGER ? M_SET_INTEGER
               : type == T_BOOLEAN ? M_SET_BOOLEAN : M_SET_STRING;
    PyObject *l = pPyList_New((Py_ssize_t)nvr);
    for (size_t i = 0; l && i < nvr; ++i) {
        PyObject *o = value_object(type, values, i);
        if (!o) {
            CLEAR(l);
            if (!pPyErr_Occurred())
                return FAIL(x, "value %zu (%s) is a NULL string", i, x->inst->var_names[vr[i]]);
        } else if (pPyList_SetItem(l, (Py_ssize_t)i, o)) {
            CLEAR(l);
        }
    }
    PyObject *refs = l ? call_refs(PY(x->inst), x->call, vr, nvr) : NULL;
    if (!refs) {
        XDECREF(l);
        return py_error(x);
    }
    return call_void(x, method, refs, l, NULL);
}

/* ------------------------------------------------------------------ stepping */
static fmi2Status py_step(Ctx *x, double t, double h, int *go_on) {
    PyObject *pt = pPyFloat_FromDouble(t);
    PyObject *ph = pPyFloat_FromDouble(h);
    PyObject *r = pt && ph ? call_slave(x, M_STEP, pt, ph, NULL) : NULL;
    XDECREF(pt);
    XDECREF(ph);
    if (!r) return py_error(x);
    int truth = pPyObject_IsTrue(r);
    DECREF(r);
    if (truth < 0) return py_error(x);
    *go_on = truth;
    return fmi2OK;
}

/* ------------------------------------------------------------------ derivatives */
static fmi2Status py_jacobian(Ctx *x, double *J) {
    int absent;
    PyObject *r = call_optional(x, "jacobian", &absent);
    if (!r) return absent ? FAIL(x, "the slave class %s has no method jacobian", g_model)
                          : py_error(x);
    fmi2Status st = read_numbers(x, r, x->inst->jac_nrows * x->inst->jac_ncols, 0, J,
                                 "the slave's jacobian()");
    DECREF(r);
    return st;
}

/* ------------------------------------------------------------------ FMU state */
static fmi2Status py_state_get(Ctx *x, FmuState *s) {
    PyObject *value = call_slave(x, M_GET_STATE, NULL, NULL, NULL);
    if (!value) return py_error(x);
    XDECREF(s->value);
    CLEAR(s->bytes);
    s->value = value;
    return fmi2OK;
}

static fmi2Status py_state_set(Ctx *x, const FmuState *s) {
    INCREF(s->value);
    return call_void(x, M_SET_STATE, s->value, NULL, NULL);
}

static void py_state_release(FmuState *s, int alive) {
    if (alive) {
        CLEAR(s->value);
        CLEAR(s->bytes);
    }
}

static fmi2Status py_state_bytes(Ctx *x, FmuState *s, const char **data, size_t *n) {
    if (!s->bytes) {
        INCREF(s->value);
        PyObject *b = call_slave(x, M_TO_BYTES, s->value, NULL, NULL);
        DECREF(s->value);
        if (!b) return py_error(x);
        s->bytes = b;
    }
    char *p;
    Py_ssize_t size;
    if (pPyBytes_AsStringAndSize(s->bytes, &p, &size) < 0) {
        CLEAR(s->bytes);
        return py_error(x);
    }
    *data = p;
    *n = (size_t)size;
    return fmi2OK;
}

static fmi2Status py_state_from_bytes(Ctx *x, FmuState *s, const char *data, size_t n) {
    PyObject *b = pPyBytes_FromStringAndSize(data, (Py_ssize_t)n);
    PyObject *value = b ? call_slave(x, M_FROM_BYTES, b, NULL, NULL) : NULL;
    XDECREF(b);
    if (!value) return py_error(x);
    s->value = value;
    return fmi2OK;
}

const Backend GLIDER_BACKEND = {
    py_model_identifier, py_start,     py_enter,       py_leave,         py_create,
    py_reset,            py_destroy,   py_alive,       py_setup,         py_transition,
    py_get,              py_set,       py_step,        py_state_get,     py_state_set,
    py_state_release,    py_state_bytes, py_state_from_bytes, NULL,
    py_jacobian,
};
