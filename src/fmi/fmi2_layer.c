/* glider-cosim's FMI 2.0 co-simulation front end: one state machine for every FMU.
 *
 * Every function checks that its instance is live and in a state where FMI 2.0 allows
 * the call (GLIDER_CALLS), enters the back end (the Python back end takes the GIL),
 * calls it, records what happened and leaves the back end before the host's logger is
 * called. Errors are fmi2Error with a message that is passed to the logger whatever
 * loggingOn says; fmi2Fatal is kept for the back end itself failing. After fmi2Error
 * only getters, FMU-state functions, fmi2Reset and fmi2FreeInstance are accepted. A
 * forged or freed instance or state pointer gets a status, never a crash.
 *
 * C99, libc only; the registry lock is a pthread mutex (an SRW lock on Windows). Written
 * from the FMI 2.0.4 standard and the FMI headers that fmpy ships.
 */
#if !defined(_WIN32) && !defined(_POSIX_C_SOURCE)
#define _POSIX_C_SOURCE 200809L
#endif
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi_layer.h"

#ifdef _WIN32
#include <windows.h>
static SRWLOCK g_lock = SRWLOCK_INIT;
#define LOCK() AcquireSRWLockExclusive(&g_lock)
#define UNLOCK() ReleaseSRWLockExclusive(&g_lock)
#else
#include <pthread.h>
static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
#define LOCK() pthread_mutex_lock(&g_lock)
#define UNLOCK() pthread_mutex_unlock(&g_lock)
#endif

#define B GLIDER_BACKEND
#define INSTANCE_MAGIC 0x474c4944u /* "GLID" */
#define STATE_MAGIC 0x53544154u    /* "STAT" */
#define FAIL glider_fail

#define CALL_SPEC(id, name, allowed) {name, allowed},
const CallSpec GLIDER_CALLS[C_COUNT] = {CALL_TABLE(CALL_SPEC)};
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
static Instance *g_instances;

static Instance *lookup(fmi2Component c) {
    Instance *found = NULL, *i;
    LOCK();
    for (i = g_instances; i; i = i->next) {
        if ((void *)i == c) {
            found = i;
            break;
        }
    }
    UNLOCK();
    return found && found->magic == INSTANCE_MAGIC ? found : NULL;
}

/* ------------------------------------------------------------------ messages */
char *glider_dup_text(const char *s) {
    size_t n = strlen(s);
    char *d = malloc(n + 1);
    if (d) memcpy(d, s, n + 1);
    return d;
}

static void add_text(Ctx *x, fmi2Status status, int category, const char *text) {
    char *copy;
    if (x->nmsgs == x->cap) {
        size_t cap = x->cap ? 2 * x->cap : 4;
        Msg *m = realloc(x->msgs, cap * sizeof *m);
        if (!m) return;
        x->msgs = m;
        x->cap = cap;
    }
    if (!(copy = glider_dup_text(text))) return;
    x->msgs[x->nmsgs].status = status;
    x->msgs[x->nmsgs].category = category;
    x->msgs[x->nmsgs].text = copy;
    x->nmsgs++;
}

void glider_add_msg(Ctx *x, fmi2Status status, int category, const char *fmt, ...) {
    char buf[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    add_text(x, status, category, buf);
}

fmi2Status glider_fail(Ctx *x, const char *fmt, ...) {
    char buf[1800];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    glider_add_msg(x, fmi2Error, x->inst ? x->inst->cat_error : -1, "%s: %s",
                   GLIDER_CALLS[x->call].name, buf);
    return fmi2Error;
}

int glider_category_index(const Instance *inst, const char *name) {
    int i;
    for (i = 0; i < inst->ncat; ++i)
        if (!strcmp(inst->cat_names[i], name)) return i;
    return -1;
}

void glider_set_categories(Instance *inst, const char *const names[], int n) {
    int i;
    for (i = 0; i < n && inst->ncat < MAX_CATEGORIES; ++i) {
        char *copy = glider_dup_text(names[i]);
        if (copy) inst->cat_names[inst->ncat++] = copy;
    }
    inst->cat_calls = glider_category_index(inst, "logFmiCalls");
    inst->cat_all = glider_category_index(inst, "logAll");
    inst->cat_error = glider_category_index(inst, "logStatusError");
    inst->cat_discard = glider_category_index(inst, "logStatusDiscard");
    inst->cat_warning = glider_category_index(inst, "logStatusWarning");
}

/* What "all categories" means: every one but logFmiCalls, which traces every call and
 * is switched on only when named. */
static uint64_t all_categories(const Instance *inst) {
    return inst->cat_calls >= 0 ? ~((uint64_t)1 << inst->cat_calls) : ~(uint64_t)0;
}

/* Errors are always passed on. Warnings and discards too, unless their category was
 * switched off (fmi2SetDebugLogging(false, [it]) or another list given with true). Debug
 * messages (fmi2OK) only with logging on and their category, or logAll, enabled;
 * logFmiCalls only when named. */
static int should_log(const Instance *inst, fmi2Status status, int category) {
    uint64_t bit, all;
    if (status >= fmi2Error) return 1;
    bit = category >= 0 ? (uint64_t)1 << category : 0;
    if (inst->cat_off & bit) return 0;
    if (status == fmi2Warning || status == fmi2Discard) return 1;
    all = inst->cat_all >= 0 && category != inst->cat_calls ? (uint64_t)1 << inst->cat_all : 0;
    return inst->logging_on && (inst->cat_on & (bit | all)) != 0;
}

/* The logger takes a printf format: pass the text with every '%' doubled. */
static void emit(fmi2CallbackLogger logger, fmi2ComponentEnvironment env, const char *name,
                 fmi2Status status, const char *category, const char *text) {
    size_t n = strlen(text), extra = 0, i;
    char *fmt, *o;
    for (i = 0; i < n; ++i) extra += text[i] == '%';
    if (!(fmt = malloc(n + extra + 1))) return;
    o = fmt;
    for (i = 0; i < n; ++i) {
        *o++ = text[i];
        if (text[i] == '%') *o++ = '%';
    }
    *o = '\0';
    logger(env, name, status, category, fmt);
    free(fmt);
}

/* ------------------------------------------------------------------ call framing */
static fmi2Status begin(Ctx *x, fmi2Component c, int call) {
    Instance *inst;
    fmi2Status st;
    memset(x, 0, sizeof *x);
    x->call = call;
    x->inst = inst = lookup(c);
    if (!inst) return fmi2Error; /* not an instance of this FMU: nobody to log to */
    if ((st = B.enter(x)) != fmi2OK) return st;
    if (inst->state == S_FATAL) {
        glider_add_msg(x, fmi2Fatal, inst->cat_error, "%s: the instance failed fatally earlier",
                       GLIDER_CALLS[call].name);
        return fmi2Fatal;
    }
    if (!(GLIDER_CALLS[call].allowed & inst->state)) {
        if (!GLIDER_CALLS[call].allowed) return FAIL(x, "not supported by this FMU");
        if (inst->state == S_ERROR)
            return FAIL(x, "not allowed after an error: only getters, FMU-state functions, "
                           "fmi2Reset and fmi2FreeInstance are");
        return FAIL(x, "not allowed in state '%s'", state_name(inst->state));
    }
    if (inst->cat_calls >= 0 && inst->logging_on && (inst->cat_on >> inst->cat_calls & 1))
        glider_add_msg(x, fmi2OK, inst->cat_calls, "%s", GLIDER_CALLS[call].name);
    return fmi2OK;
}

static fmi2Status end(Ctx *x, fmi2Status status) {
    Instance *inst = x->inst;
    size_t i;
    if (!inst) return status;
    if (status == fmi2Fatal) inst->state = S_FATAL;
    else if (status == fmi2Error && inst->state != S_FATAL) inst->state = S_ERROR;
    for (i = 0; i < x->nmsgs; ++i) {
        if (!should_log(inst, x->msgs[i].status, x->msgs[i].category)) {
            free(x->msgs[i].text);
            x->msgs[i].text = NULL;
        }
    }
    /* leave the back end (release the GIL) before the host's logger is called */
    if (x->have_token) B.leave(x);
    x->have_token = 0;
    for (i = 0; i < x->nmsgs; ++i) {
        int ci = x->msgs[i].category;
        const char *category = ci >= 0 && ci < inst->ncat ? inst->cat_names[ci] : "logAll";
        if (!x->msgs[i].text) continue;
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

/* ------------------------------------------------------------------ FMU states */
static FmuState *owned_state(Instance *inst, fmi2FMUstate s) {
    FmuState *p;
    for (p = inst->states; p; p = p->next)
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

static void drop_state(FmuState *s, int alive) {
    B.state_release(s, alive);
    s->magic = 0;
    free(s);
}

static void free_instance(Instance *inst, int alive) {
    int i;
    while (inst->states) {
        FmuState *s = inst->states;
        inst->states = s->next;
        drop_state(s, alive);
    }
    B.destroy(inst, alive);
    for (i = 0; i < inst->ncat; ++i) free(inst->cat_names[i]);
    free(inst->resources);
    free(inst->name);
    inst->magic = 0;
    free(inst);
}

/* fmuResourceLocation (file:///path, file:/path, file://localhost/path) -> a path; on
 * Windows file:///C:/x gives C:/x */
static char *resource_path(const char *uri) {
    const char *p = uri;
    size_t n, i;
    char *out, *o;
    if (!strncmp(p, "file://localhost/", 17)) p += 16;
    else if (!strncmp(p, "file:///", 8)) p += 7;
    else if (!strncmp(p, "file:/", 6)) p += 5;
    else return NULL;
#ifdef _WIN32
    if (p[0] == '/' && p[1] && p[2] == ':') ++p;
#endif
    n = strlen(p);
    if (!(out = malloc(n + 1))) return NULL;
    o = out;
    for (i = 0; i < n; ++i) {
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

/* ------------------------------------------------------------------ FMI: common */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Ctx x;
    Instance *inst;
    uint64_t bits = 0;
    size_t i;
    fmi2Status st = begin(&x, c, C_SET_DEBUG_LOGGING);
    if (st != fmi2OK) return end(&x, st);
    inst = x.inst;
    if (nCategories == 0) {
        inst->logging_on = loggingOn != fmi2False;
        inst->cat_on = inst->logging_on ? all_categories(inst) : 0;
        inst->cat_off = 0;
        return end(&x, fmi2OK);
    }
    if (!categories)
        return end(&x, FAIL(&x, "NULL categories with nCategories = %lu",
                            (unsigned long)nCategories));
    for (i = 0; i < nCategories; ++i) {
        int ci = categories[i] ? glider_category_index(inst, categories[i]) : -1;
        if (ci < 0) {
            char known[1024] = "";
            int k;
            for (k = 0; k < inst->ncat; ++k)
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
    char text[4400], err[4096] = "";
    char *resources;
    Instance *inst;
    Ctx x;
    fmi2Status st;
    (void)fmuGUID;
    if (!instanceName || !instanceName[0]) {
        log_orphan(functions, "?", fmi2Error, "fmi2Instantiate: instanceName is NULL or empty");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        snprintf(text, sizeof text, "fmi2Instantiate: %s supports co-simulation only",
                 B.model_identifier());
        log_orphan(functions, instanceName, fmi2Error, text);
        return NULL;
    }
    resources = fmuResourceLocation ? resource_path(fmuResourceLocation) : NULL;
    if (!resources) {
        snprintf(text, sizeof text,
                 "fmi2Instantiate: fmuResourceLocation '%.200s' is invalid: expected a file: URI",
                 fmuResourceLocation ? fmuResourceLocation : "(null)");
        log_orphan(functions, instanceName, fmi2Error, text);
        return NULL;
    }
    if (!B.start(resources, err, sizeof err)) {
        snprintf(text, sizeof text, "fmi2Instantiate: %s", err);
        log_orphan(functions, instanceName, fmi2Fatal, text);
        free(resources);
        return NULL;
    }
    inst = calloc(1, sizeof *inst);
    if (!inst || !(inst->name = glider_dup_text(instanceName))) {
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
    inst->cat_calls = inst->cat_all = inst->cat_error = inst->cat_discard = -1;
    inst->cat_warning = -1;
    inst->state = S_INSTANTIATED;
    memset(&x, 0, sizeof x);
    x.call = C_INSTANTIATE;
    x.inst = inst;
    st = B.enter(&x);
    if (st == fmi2OK) st = B.create(&x);
    inst->cat_on = inst->logging_on ? all_categories(inst) : 0;
    if (st != fmi2OK) {
        inst->state = S_ERROR;
        B.destroy(inst, x.have_token);
        end(&x, st);
        free(inst->resources);
        free(inst->name);
        while (inst->ncat) free(inst->cat_names[--inst->ncat]);
        inst->magic = 0;
        free(inst);
        return NULL;
    }
    end(&x, fmi2OK);
    LOCK();
    inst->next = g_instances;
    g_instances = inst;
    UNLOCK();
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = lookup(c), **p;
    Ctx x;
    if (!inst) return;
    LOCK();
    for (p = &g_instances; *p; p = &(*p)->next) {
        if (*p == inst) {
            *p = inst->next;
            break;
        }
    }
    UNLOCK();
    /* at process exit the back end may be gone already (Python finalized): then only the
     * C memory is freed */
    memset(&x, 0, sizeof x);
    x.call = C_FREE;
    x.inst = inst;
    if (B.alive() && B.enter(&x) == fmi2OK) {
        free_instance(inst, 1);
        x.inst = NULL;
        B.leave(&x);
    } else {
        free_instance(inst, 0);
    }
    free(x.msgs);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_SETUP_EXPERIMENT);
    if (st != fmi2OK) return end(&x, st);
    if (!isfinite(startTime))
        return end(&x, FAIL(&x, "startTime = %g is invalid: expected a finite time", startTime));
    st = B.setup(&x, toleranceDefined != fmi2False, tolerance, startTime,
                 stopTimeDefined != fmi2False, stopTime);
    if (st == fmi2OK) x.inst->time = startTime;
    return end(&x, st);
}

/* A call without arguments that moves the instance to `next` when the model succeeds. */
static fmi2Status transition(fmi2Component c, int call, unsigned next) {
    Ctx x;
    fmi2Status st = begin(&x, c, call);
    if (st == fmi2OK && (st = B.transition(&x, call)) == fmi2OK) x.inst->state = next;
    return end(&x, st);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    return transition(c, C_ENTER_INIT, S_INIT);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return transition(c, C_EXIT_INIT, S_STEP_COMPLETE);
}

fmi2Status fmi2Terminate(fmi2Component c) { return transition(c, C_TERMINATE, S_TERMINATED); }

fmi2Status fmi2Reset(fmi2Component c) {
    Ctx x;
    fmi2Status st = begin(&x, c, C_RESET);
    if (st == fmi2OK && (st = B.reset(&x)) == fmi2OK) {
        x.inst->state = S_INSTANTIATED;
        x.inst->time = 0.0;
        x.inst->terminated = 0;
    }
    return end(&x, st);
}

/* ------------------------------------------------------------------ FMI: values */
static const char *type_name(char t) {
    return t == T_REAL ? "Real" : t == T_INTEGER ? "Integer" : t == T_BOOLEAN ? "Boolean"
         : t == T_STRING ? "String" : "unknown";
}

static fmi2Status check_refs(Ctx *x, const fmi2ValueReference vr[], size_t nvr,
                             const void *values, char type) {
    Instance *inst = x->inst;
    size_t i;
    if (!vr || !values)
        return FAIL(x, "NULL %s array with nvr = %lu", vr ? "value" : "vr", (unsigned long)nvr);
    for (i = 0; i < nvr; ++i) {
        if (vr[i] >= inst->nvars)
            return FAIL(x, "value reference %u does not exist: expected 0..%lu", vr[i],
                        (unsigned long)(inst->nvars - 1));
        if (inst->var_type[vr[i]] != type)
            return FAIL(x, "value reference %u (%s) is %s, not %s", vr[i],
                        inst->var_names[vr[i]], type_name(inst->var_type[vr[i]]),
                        type_name(type));
    }
    return fmi2OK;
}

static fmi2Status value_access(fmi2Component c, int call, char type, const fmi2ValueReference vr[],
                         size_t nvr, const void *in, void *out) {
    Ctx x;
    fmi2Status st = begin(&x, c, call);
    if (st != fmi2OK || nvr == 0) return end(&x, st);
    if ((st = check_refs(&x, vr, nvr, out ? out : in, type)) != fmi2OK) return end(&x, st);
    return end(&x, out ? B.get(&x, type, vr, nvr, out) : B.set(&x, type, vr, nvr, in));
}

/* fmi2Get<Type> and fmi2Set<Type> for the four types, all through access() */
#define VALUE_ACCESS(Type, TYPE)                                                           \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,   \
                             fmi2##Type value[]) {                                         \
        return value_access(c, C_GET_##TYPE, T_##TYPE, vr, nvr, NULL, (void *)value);            \
    }                                                                                      \
    fmi2Status fmi2Set##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,   \
                             const fmi2##Type value[]) {                                   \
        return value_access(c, C_SET_##TYPE, T_##TYPE, vr, nvr, (const void *)value, NULL);      \
    }
VALUE_ACCESS(Real, REAL)
VALUE_ACCESS(Integer, INTEGER)
VALUE_ACCESS(Boolean, BOOLEAN)
VALUE_ACCESS(String, STRING)
#undef VALUE_ACCESS

/* ------------------------------------------------------------------ FMI: FMU state */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Ctx x;
    Instance *inst;
    FmuState *s, *fresh = NULL;
    fmi2Status st = begin(&x, c, C_GET_FMU_STATE);
    if (st != fmi2OK) return end(&x, st);
    inst = x.inst;
    if (!FMUstate) return end(&x, FAIL(&x, "FMUstate is NULL"));
    s = *FMUstate ? owned_state(inst, *FMUstate) : NULL;
    if (*FMUstate && !s) return end(&x, FAIL(&x, "*FMUstate is not a state of this instance"));
    if (!s && !(s = fresh = new_state(inst))) return end(&x, FAIL(&x, "out of memory"));
    if ((st = B.state_get(&x, s)) != fmi2OK) {
        if (fresh) {
            inst->states = fresh->next;
            drop_state(fresh, 1);
        }
        return end(&x, st);
    }
    s->machine = inst->state;
    s->time = inst->time;
    s->terminated = inst->terminated;
    *FMUstate = s;
    return end(&x, fmi2OK);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Ctx x;
    FmuState *s;
    fmi2Status st = begin(&x, c, C_SET_FMU_STATE);
    if (st != fmi2OK) return end(&x, st);
    if (!(s = owned_state(x.inst, FMUstate)))
        return end(&x, FAIL(&x, "FMUstate is not a state of this instance"));
    if ((st = B.state_set(&x, s)) == fmi2OK) {
        x.inst->state = s->machine;
        x.inst->time = s->time;
        x.inst->terminated = s->terminated;
    }
    return end(&x, st);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Ctx x;
    FmuState **p;
    fmi2Status st = begin(&x, c, C_FREE_FMU_STATE);
    if (st != fmi2OK || !FMUstate || !*FMUstate) return end(&x, st);
    for (p = &x.inst->states; *p; p = &(*p)->next) {
        if ((void *)*p == *FMUstate) {
            FmuState *s = *p;
            *p = s->next;
            drop_state(s, 1);
            *FMUstate = NULL;
            return end(&x, fmi2OK);
        }
    }
    return end(&x, FAIL(&x, "*FMUstate is not a state of this instance"));
}

/* Serialized layout: magic, FMI state, terminated flag, time, model identifier, then the
 * back end's bytes. */
static const char SER_MAGIC[8] = {'G', 'F', 'M', 'I', 'S', 'T', '0', '1'};
#define SER_HEADER (8 + 4 + 4 + 8 + MODEL_ID_SIZE)

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    Ctx x;
    FmuState *s;
    const char *data;
    size_t n;
    fmi2Status st = begin(&x, c, C_STATE_SIZE);
    if (st != fmi2OK) return end(&x, st);
    s = owned_state(x.inst, FMUstate);
    if (!s || !size)
        return end(&x, FAIL(&x, s ? "size is NULL" : "FMUstate is not a state of this instance"));
    if ((st = B.state_bytes(&x, s, &data, &n)) == fmi2OK) *size = SER_HEADER + n;
    return end(&x, st);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte buffer[],
                                 size_t size) {
    Ctx x;
    FmuState *s;
    const char *data, *model = B.model_identifier();
    size_t n;
    uint32_t machine, term;
    fmi2Status st = begin(&x, c, C_SERIALIZE);
    if (st != fmi2OK) return end(&x, st);
    s = owned_state(x.inst, FMUstate);
    if (!s || !buffer)
        return end(&x, FAIL(&x, s ? "buffer is NULL" : "FMUstate is not a state of this instance"));
    if ((st = B.state_bytes(&x, s, &data, &n)) != fmi2OK) return end(&x, st);
    if (size < SER_HEADER + n)
        return end(&x, FAIL(&x, "size = %lu is too small: expected %lu bytes",
                            (unsigned long)size, (unsigned long)(SER_HEADER + n)));
    machine = s->machine;
    term = (uint32_t)s->terminated;
    memcpy(buffer, SER_MAGIC, 8);
    memcpy(buffer + 8, &machine, 4);
    memcpy(buffer + 12, &term, 4);
    memcpy(buffer + 16, &s->time, 8);
    memset(buffer + 24, 0, MODEL_ID_SIZE);
    memcpy(buffer + 24, model, strlen(model) < MODEL_ID_SIZE ? strlen(model) : MODEL_ID_SIZE - 1);
    memcpy(buffer + SER_HEADER, data, n);
    return end(&x, fmi2OK);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    Ctx x;
    FmuState *s;
    char model[MODEL_ID_SIZE + 1] = "";
    uint32_t machine, term;
    double time;
    fmi2Status st = begin(&x, c, C_DESERIALIZE);
    if (st != fmi2OK) return end(&x, st);
    if (!serializedState || !FMUstate)
        return end(&x, FAIL(&x, "%s is NULL", FMUstate ? "serializedState" : "FMUstate"));
    if (size < SER_HEADER || memcmp(serializedState, SER_MAGIC, 8))
        return end(&x, FAIL(&x, "the %lu bytes are not a serialized state of this runtime",
                            (unsigned long)size));
    memcpy(model, serializedState + 24, MODEL_ID_SIZE);
    if (strcmp(model, B.model_identifier()))
        return end(&x, FAIL(&x, "the state is one of model %.100s: expected %s", model,
                            B.model_identifier()));
    memcpy(&machine, serializedState + 8, 4);
    memcpy(&term, serializedState + 12, 4);
    memcpy(&time, serializedState + 16, 8);
    if (!(machine & S_LIVE) || (machine & (machine - 1)))
        return end(&x, FAIL(&x, "the state records an invalid FMI state %u", machine));
    if (!(s = new_state(x.inst))) return end(&x, FAIL(&x, "out of memory"));
    st = B.state_from_bytes(&x, s, serializedState + SER_HEADER, size - SER_HEADER);
    if (st != fmi2OK) {
        x.inst->states = s->next;
        drop_state(s, 1);
        return end(&x, st);
    }
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
    Ctx x;
    Instance *inst;
    int go_on = 1;
    fmi2Status st = begin(&x, c, C_DO_STEP);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (st != fmi2OK) return end(&x, st);
    if (!(communicationStepSize > 0.0) || !isfinite(communicationStepSize) ||
        !isfinite(currentCommunicationPoint))
        return end(&x, FAIL(&x, "step of %g s at t = %g s is invalid: expected a finite step > 0",
                            communicationStepSize, currentCommunicationPoint));
    if ((st = B.step(&x, currentCommunicationPoint, communicationStepSize, &go_on)) != fmi2OK)
        return end(&x, st);
    inst = x.inst;
    if (go_on) {
        inst->time = currentCommunicationPoint + communicationStepSize;
        return end(&x, fmi2OK);
    }
    inst->state = S_STEP_FAILED;
    inst->terminated = 1;
    inst->time = currentCommunicationPoint;
    glider_add_msg(&x, fmi2Discard, inst->cat_discard,
                   "fmi2DoStep: the slave stopped the simulation at t = %.17g s",
                   currentCommunicationPoint);
    return end(&x, fmi2Discard);
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
