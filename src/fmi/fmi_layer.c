/* glider-cosim's FMI layer: one state machine for every FMU, FMI 2.0 and 3.0 alike.
 *
 * The front ends (fmi2_layer.c, fmi3_layer.c) export the FMI functions of their version
 * and call the operations here (glider_op_*). Every operation checks that its instance
 * is live and in a state where FMI allows the call (GLIDER_CALLS), enters the back end (the Python back end takes the GIL),
 * calls it, records what happened and leaves the back end before the host's logger is
 * called. Errors are fmi2Error with a message that is passed to the logger whatever
 * loggingOn says; fmi2Fatal is kept for the back end itself failing. After fmi2Error
 * only getters, FMU-state functions, fmi2Reset and fmi2FreeInstance are accepted. A
 * forged or freed instance or state pointer gets a status, never a crash.
 *
 * C99, libc only; the registry lock is a pthread mutex (an SRW lock on Windows), taken
 * only when an instance is not in the table of slots (FAST_SLOTS). Written
 * from the FMI 2.0.4 standard and the FMI headers that fmpy ships.
 */
#if !defined(_WIN32) && !defined(_POSIX_C_SOURCE)
#define _POSIX_C_SOURCE 200809L
#endif
#include "glider_fp.h" /* first: no fused multiply-add (the directional derivatives' sums) */
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

/* Instances are found without the lock in a small table of live ones (FAST_SLOTS),
 * compared by address with atomic loads: a loop calling a few instances takes no lock.
 * More instances than slots, or compilers without atomics, use the list under the lock. */
#if defined(__GNUC__) || defined(__clang__)
#define FAST_SLOTS 64
#define SLOT_LOAD(p) __atomic_load_n((p), __ATOMIC_ACQUIRE)
#define SLOT_STORE(p, v) __atomic_store_n((p), (v), __ATOMIC_RELEASE)
#elif defined(_MSC_VER)
#define FAST_SLOTS 64
#define SLOT_LOAD(p)                                                                       \
    ((Instance *)InterlockedCompareExchangePointer((PVOID volatile *)(p), NULL, NULL))
#define SLOT_STORE(p, v) InterlockedExchangePointer((PVOID volatile *)(p), (v))
#else
#define FAST_SLOTS 0
#endif

#define B GLIDER_BACKEND
#define INSTANCE_MAGIC 0x474c4944u /* "GLID" */
#define STATE_MAGIC 0x53544154u    /* "STAT" */
#define FAIL glider_fail

#define CALL_SPEC(id, name2, name3, allowed) {{name2, name3}, allowed},
const CallSpec GLIDER_CALLS[C_COUNT] = {CALL_TABLE(CALL_SPEC)};
#undef CALL_SPEC

/* A state's name; fmi3: in the FMI 3.0 front end's words (fmi3Discard, not fmi2Discard). */
static const char *state_name(unsigned s, int fmi3) {
    switch (s) {
    case S_INSTANTIATED: return "instantiated";
    case S_INIT: return "initialization mode";
    case S_STEP_COMPLETE: return "step complete";
    case S_STEP_FAILED: return fmi3 ? "step failed (after fmi3Discard)" : "step failed (after fmi2Discard)";
    case S_TERMINATED: return "terminated";
    case S_ERROR: return "error";
    default: return "fatal";
    }
}

/* ------------------------------------------------------------------ instances */
static Instance *g_instances;
#if FAST_SLOTS
static Instance *g_slots[FAST_SLOTS]; /* live instances (NULL: free), written under the lock */
#endif

/* Under the lock: an instance joins or leaves the table of slots (it may find none). */
static void fast_slot(Instance *joining, Instance *leaving) {
#if FAST_SLOTS
    int k;
    for (k = 0; k < FAST_SLOTS; ++k) {
        if (g_slots[k] == leaving) {
            SLOT_STORE(&g_slots[k], joining);
            return;
        }
    }
#else
    (void)joining, (void)leaving;
#endif
}

/* The instance c in the table of slots (no lock), or NULL: not there (or not valid). */
static Instance *slot_lookup(void *c) {
#if FAST_SLOTS
    int k;
    if (!c) return NULL;
    for (k = 0; k < FAST_SLOTS; ++k) {
        Instance *s = SLOT_LOAD(&g_slots[k]);
        if ((void *)s == c) return s->magic == INSTANCE_MAGIC ? s : NULL;
    }
#else
    (void)c;
#endif
    return NULL;
}

static Instance *lookup(void *c) {
    Instance *found = slot_lookup(c), *i;
    if (found || !c) return found;
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

static void add_text(Ctx *x, Status status, int category, const char *text) {
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

void glider_add_msg(Ctx *x, Status status, int category, const char *fmt, ...) {
    char buf[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    add_text(x, status, category, buf);
}

Status glider_fail(Ctx *x, const char *fmt, ...) {
    char buf[1800];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if (x->inst) /* the instance named in every message: FMI 3's logger is not told it */
        glider_add_msg(x, ST_ERROR, x->inst->cat_error, "%s: %s: %s", x->inst->name,
                       glider_call_name(x), buf);
    else
        glider_add_msg(x, ST_ERROR, -1, "%s: %s", glider_call_name(x), buf);
    return ST_ERROR;
}

const char *glider_call_name(const Ctx *x) {
    return GLIDER_CALLS[x->call].name[x->inst && x->inst->logger.fmi3 ? 1 : 0];
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
static int should_log(const Instance *inst, Status status, int category) {
    uint64_t bit, all;
    if (status >= ST_ERROR) return 1;
    bit = category >= 0 ? (uint64_t)1 << category : 0;
    if (inst->cat_off & bit) return 0;
    if (status == ST_WARNING || status == ST_DISCARD) return 1;
    all = inst->cat_all >= 0 && category != inst->cat_calls ? (uint64_t)1 << inst->cat_all : 0;
    return inst->logging_on && (inst->cat_on & (bit | all)) != 0;
}

/* What reaches the host's logger follows FMI's '#' rule (FMI 2.0 section 2.1.5, FMI 3.0
 * logMessage): '#' opens a variable reference (#r12# in FMI 2, #12# in FMI 3), so every
 * literal '#' goes doubled ("##"); our messages reference no variable. FMI 2's logger
 * takes a printf format besides: every '%' goes doubled too. */
static void emit(const HostLogger *logger, const char *name, int status, const char *category,
                 const char *text) {
    size_t n = strlen(text), extra = 0, i;
    char *msg, *o;
    if (logger->fmi3 ? !logger->log3 : !logger->log2) return;
    for (i = 0; i < n; ++i) extra += text[i] == '#' || (!logger->fmi3 && text[i] == '%');
    if (!(msg = malloc(n + extra + 1))) return;
    o = msg;
    for (i = 0; i < n; ++i) {
        *o++ = text[i];
        if (text[i] == '#' || (!logger->fmi3 && text[i] == '%')) *o++ = text[i];
    }
    *o = '\0';
    if (logger->fmi3)
        logger->log3(logger->env, status, category, msg);
    else
        logger->log2(logger->env, name, status, category, msg);
    free(msg);
}

/* ------------------------------------------------------------------ call framing */
/* Enter the back end for a call (a back end without enter has nothing to take):
 * ST_OK, ST_GONE (it cannot be called any more) or an error the back end logged. */
static Status enter(Ctx *x) {
    if (!B.enter) {
        x->have_token = 1;
        return ST_OK;
    }
    return B.enter(x);
}

static void leave(Ctx *x) {
    if (B.leave) B.leave(x);
    x->have_token = 0;
}

/* Every call is logged (category logFmiCalls switched on). */
static int calls_logged(const Instance *inst) {
    return inst->cat_calls >= 0 && inst->logging_on && (inst->cat_on >> inst->cat_calls & 1);
}

/* What a call does when the back end is gone (enter said ST_GONE: the host's Python
 * finalized, a tool ending its instances at process exit). The slave cannot be called
 * and need not be, and nothing is logged (the host's logger may be Python's too):
 * fmi2Terminate/fmi3Terminate of a stepping instance marks it terminated, OK;
 * FreeInstance frees the C memory alone (glider_op_free), OK; any other call is refused,
 * fmi2Error, and the instance's state stays as it was. */
static Status after_exit(Instance *inst, int call) {
    if (call == C_TERMINATE && (GLIDER_CALLS[C_TERMINATE].allowed & inst->state)) {
        inst->state = S_TERMINATED;
        return ST_OK;
    }
    return call == C_FREE ? ST_OK : ST_ERROR;
}

/* Frame a call: its instance, the back end entered and the state machine's word. Not
 * ST_OK: the call goes straight to end() with it (ST_GONE too: end() applies the
 * per-call policy, after_exit). */
static Status begin(Ctx *x, void *c, int call) {
    Instance *inst;
    Status st;
    memset(x, 0, sizeof *x);
    x->call = call;
    x->inst = inst = lookup(c);
    if (!inst) return ST_ERROR; /* not an instance of this FMU: nobody to log to */
    if ((st = enter(x)) != ST_OK) return st; /* ST_GONE included */
    if (inst->state == S_FATAL) {
        glider_add_msg(x, ST_FATAL, inst->cat_error, "%s: %s: the instance failed fatally earlier",
                       inst->name, glider_call_name(x));
        return ST_FATAL;
    }
    if (!(GLIDER_CALLS[call].allowed & inst->state)) {
        if (!GLIDER_CALLS[call].allowed) return FAIL(x, "not supported by this FMU");
        if (inst->state == S_ERROR) /* the calls named as the front end that was called */
            return FAIL(x, "not allowed after an error: only getters, FMU-state functions, "
                           "%s and %s are allowed then",
                        GLIDER_CALLS[C_RESET].name[inst->logger.fmi3 ? 1 : 0],
                        GLIDER_CALLS[C_FREE].name[inst->logger.fmi3 ? 1 : 0]);
        return FAIL(x, "not allowed in state '%s'", state_name(inst->state, inst->logger.fmi3));
    }
    if (calls_logged(inst)) glider_add_msg(x, ST_OK, inst->cat_calls, "%s", glider_call_name(x));
    return ST_OK;
}

static Status end(Ctx *x, Status status) {
    Instance *inst = x->inst;
    size_t i;
    if (!inst) return status;
    if (status == ST_GONE) return after_exit(inst, x->call); /* nothing entered or said */
    if (status == ST_FATAL) inst->state = S_FATAL;
    else if (status == ST_ERROR && inst->state != S_FATAL) inst->state = S_ERROR;
    for (i = 0; i < x->nmsgs; ++i) {
        if (!should_log(inst, x->msgs[i].status, x->msgs[i].category)) {
            free(x->msgs[i].text);
            x->msgs[i].text = NULL;
        }
    }
    /* leave the back end (release the GIL) before the host's logger is called */
    if (x->have_token) leave(x);
    for (i = 0; i < x->nmsgs; ++i) {
        int ci = x->msgs[i].category;
        const char *category = ci >= 0 && ci < inst->ncat ? inst->cat_names[ci] : "logAll";
        if (!x->msgs[i].text) continue;
        emit(&inst->logger, inst->name, x->msgs[i].status, category, x->msgs[i].text);
        free(x->msgs[i].text);
    }
    free(x->msgs);
    x->msgs = NULL;
    x->nmsgs = x->cap = 0;
    return status;
}

/* ------------------------------------------------------------------ FMU states */
static FmuState *owned_state(Instance *inst, void *s) {
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
char *glider_resource_path(const char *uri) {
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

/* ------------------------------------------------------------------ operations */
int glider_op_set_debug_logging(void *c, int on, size_t n, const char *const categories[]) {
    Ctx x;
    Instance *inst;
    uint64_t bits = 0;
    size_t i;
    Status st = begin(&x, c, C_SET_DEBUG_LOGGING);
    if (st != ST_OK) return end(&x, st);
    inst = x.inst;
    if (n == 0) {
        inst->logging_on = on != 0;
        inst->cat_on = inst->logging_on ? all_categories(inst) : 0;
        inst->cat_off = 0;
        return end(&x, ST_OK);
    }
    if (!categories)
        return end(&x, FAIL(&x, "NULL categories with nCategories = %lu", (unsigned long)n));
    for (i = 0; i < n; ++i) {
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
    if (on) { /* only these categories (all of them if logAll is named) */
        uint64_t all = inst->cat_all >= 0 ? (uint64_t)1 << inst->cat_all : 0;
        inst->logging_on = 1;
        inst->cat_on = bits;
        inst->cat_off = bits & all ? 0 : ~bits;
    } else {
        inst->cat_on &= ~bits;
        inst->cat_off |= bits;
    }
    return end(&x, ST_OK);
}

void glider_log_orphan(const HostLogger *logger, const char *name, int status, const char *text) {
    if (logger)
        emit(logger, name ? name : "?", status,
             status == ST_FATAL ? "logStatusFatal" : "logStatusError", text);
}

void *glider_op_instantiate(const char *name, const char *resources, int visible,
                            int logging_on, const HostLogger *logger) {
    const char *call = GLIDER_CALLS[C_INSTANTIATE].name[logger->fmi3 ? 1 : 0];
    char text[4400], err[4096] = "";
    Instance *inst;
    Ctx x;
    Status st;
    if (!B.start(resources, err, sizeof err)) {
        snprintf(text, sizeof text, "%s: %s: %s", name, call, err);
        glider_log_orphan(logger, name, ST_FATAL, text);
        return NULL;
    }
    inst = calloc(1, sizeof *inst);
    if (!inst || !(inst->name = glider_dup_text(name)) ||
        !(inst->resources = glider_dup_text(resources))) {
        if (inst) free(inst->name);
        free(inst);
        snprintf(text, sizeof text, "%s: %s: out of memory", name, call);
        glider_log_orphan(logger, name, ST_FATAL, text);
        return NULL;
    }
    inst->magic = INSTANCE_MAGIC;
    inst->logger = *logger;
    inst->logging_on = logging_on != 0;
    inst->visible = visible != 0;
    inst->cat_calls = inst->cat_all = inst->cat_error = inst->cat_discard = -1;
    inst->cat_warning = -1;
    inst->state = S_INSTANTIATED;
    memset(&x, 0, sizeof x);
    x.call = C_INSTANTIATE;
    x.inst = inst;
    st = enter(&x);
    if (st == ST_OK) st = B.create(&x);
    inst->cat_on = inst->logging_on ? all_categories(inst) : 0;
    if (st != ST_OK) {
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
    inst->has_time = logger->fmi3 != 0;
    end(&x, ST_OK);
    LOCK();
    inst->next = g_instances;
    g_instances = inst;
    fast_slot(inst, NULL);
    UNLOCK();
    return inst;
}

void glider_op_free(void *c) {
    Instance *inst = lookup(c), **p;
    Ctx x;
    if (!inst) return;
    LOCK();
    for (p = &g_instances; *p; p = &(*p)->next) {
        if (*p == inst) {
            *p = inst->next;
            fast_slot(NULL, inst); /* no thread finds it without the lock any more */
            break;
        }
    }
    UNLOCK();
    /* at process exit the back end may be gone already (Python finalized: after_exit):
     * then only the C memory is freed */
    memset(&x, 0, sizeof x);
    x.call = C_FREE;
    x.inst = inst;
    if (enter(&x) == ST_OK) {
        free_instance(inst, 1);
        x.inst = NULL;
        leave(&x);
    } else {
        free_instance(inst, 0);
    }
    free(x.msgs);
}

int glider_op_setup(void *c, int call, int tolerance_defined, double tolerance, double start,
                    int stop_defined, double stop, int enter) {
    Ctx x;
    Status st = begin(&x, c, call);
    if (st != ST_OK) return end(&x, st);
    if (!isfinite(start))
        return end(&x, FAIL(&x, "startTime = %g is invalid: expected a finite time", start));
    st = B.setup(&x, tolerance_defined, tolerance, start, stop_defined, stop);
    if (st == ST_OK) x.inst->time = start;
    if (st == ST_OK && enter && (st = B.transition(&x, call)) == ST_OK) x.inst->state = S_INIT;
    return end(&x, st);
}

int glider_op_transition(void *c, int call, unsigned next) {
    Ctx x;
    Status st;
    st = begin(&x, c, call);
    if (st == ST_OK && (st = B.transition(&x, call)) == ST_OK) x.inst->state = next;
    return end(&x, st);
}

int glider_op_reset(void *c) {
    Ctx x;
    Status st = begin(&x, c, C_RESET);
    if (st == ST_OK && (st = B.reset(&x)) == ST_OK) {
        x.inst->state = S_INSTANTIATED;
        x.inst->time = 0.0;
        x.inst->terminated = 0;
    }
    return end(&x, st);
}

/* ------------------------------------------------------------------ values */
/* A type's name in the instance's FMI version (FMI 3's other types, which our models
 * have none of, come with codes of their own from fmi3_layer.c). */
const char *glider_type_name(const Ctx *x, char t) {
    static const struct {
        char code;
        const char *name[2];
    } names[] = {{T_REAL, {"Real", "Float64"}}, {T_INTEGER, {"Integer", "Int32"}},
                 {T_BOOLEAN, {"Boolean", "Boolean"}}, {T_STRING, {"String", "String"}},
                 {'f', {"-", "Float32"}}, {'1', {"-", "Int8"}}, {'2', {"-", "UInt8"}},
                 {'3', {"-", "Int16"}}, {'4', {"-", "UInt16"}}, {'5', {"-", "UInt32"}},
                 {'6', {"-", "Int64"}}, {'7', {"-", "UInt64"}}, {'y', {"-", "Binary"}},
                 {'c', {"-", "Clock"}}};
    size_t i;
    for (i = 0; i < sizeof names / sizeof *names; ++i)
        if (names[i].code == t) return names[i].name[x->inst && x->inst->logger.fmi3 ? 1 : 0];
    return "unknown";
}

static int is_time(const Instance *inst, unsigned vr) {
    return inst->has_time && vr == inst->nvars;
}

static Status check_refs(Ctx *x, const unsigned vr[], size_t nvr, const void *values,
                         char type, int set) {
    Instance *inst = x->inst;
    size_t i;
    if (!vr || !values)
        return FAIL(x, "NULL %s array with nvr = %lu", vr ? "value" : "vr", (unsigned long)nvr);
    for (i = 0; i < nvr; ++i) {
        if (is_time(inst, vr[i])) {
            if (type != T_REAL)
                return FAIL(x, "value reference %u (time) is %s, not %s", vr[i],
                            glider_type_name(x, T_REAL), glider_type_name(x, type));
            if (set)
                return FAIL(x, "value reference %u (time) is the independent variable: it "
                               "cannot be set", vr[i]);
            continue;
        }
        if (vr[i] >= inst->nvars)
            return FAIL(x, "value reference %u does not exist: expected 0..%lu", vr[i],
                        (unsigned long)(inst->nvars + (inst->has_time ? 1 : 0) - 1));
        if (inst->var_type[vr[i]] != type)
            return FAIL(x, "value reference %u (%s) is %s, not %s", vr[i],
                        inst->var_names[vr[i]], glider_type_name(x, inst->var_type[vr[i]]),
                        glider_type_name(x, type));
    }
    return ST_OK;
}

/* A get that names time: the model's variables from the back end, in runs between the
 * references to time, and time from the instance (the request is of Float64, checked). */
static Status get_with_time(Ctx *x, const unsigned vr[], size_t nvr, double out[]) {
    size_t i = 0, j;
    Status st = ST_OK, s;
    while (i < nvr && st <= ST_WARNING) {
        if (is_time(x->inst, vr[i])) {
            out[i++] = x->inst->time;
            continue;
        }
        for (j = i; j < nvr && !is_time(x->inst, vr[j]); ++j) continue;
        if ((s = B.get(x, T_REAL, vr + i, j - i, out + i)) > st) st = s;
        i = j;
    }
    return st;
}

int glider_op_access(void *c, int call, char type, const unsigned vr[], size_t nvr,
                     size_t nvalues, const void *in, void *out) {
    Ctx x;
    size_t i;
    Status st;
    Instance *quick;
    /* the exchange's calls: what begin, check_refs and end would pass without a word is
     * the back end's alone (Backend.quick_real); it takes the call or leaves it untouched */
    if (B.quick_real && type == T_REAL && vr && (in || out) && nvalues == nvr &&
        (quick = slot_lookup(c)) && (GLIDER_CALLS[call].allowed & quick->state) &&
        !calls_logged(quick) &&
        B.quick_real(quick, vr, nvr, out ? NULL : (const double *)in, (double *)out))
        return ST_OK;
    st = begin(&x, c, call);
    if (st != ST_OK || nvr == 0) return end(&x, st);
    if (nvalues != nvr)
        return end(&x, FAIL(&x, "nValues = %lu is invalid: expected %lu (every variable is a "
                                "scalar)", (unsigned long)nvalues, (unsigned long)nvr));
    if ((st = check_refs(&x, vr, nvr, out ? out : in, type, out == NULL)) != ST_OK)
        return end(&x, st);
    if (!out) return end(&x, B.set(&x, type, vr, nvr, in));
    for (i = 0; x.inst->has_time && i < nvr; ++i)
        if (is_time(x.inst, vr[i])) return end(&x, get_with_time(&x, vr, nvr, out));
    return end(&x, B.get(&x, type, vr, nvr, out));
}

/* ------------------------------------------------------------------ FMU state */
int glider_op_get_state(void *c, void **state) {
    Ctx x;
    Instance *inst;
    FmuState *s, *fresh = NULL;
    Status st = begin(&x, c, C_GET_FMU_STATE);
    if (st != ST_OK) return end(&x, st);
    inst = x.inst;
    if (!state) return end(&x, FAIL(&x, "FMUstate is NULL"));
    s = *state ? owned_state(inst, *state) : NULL;
    if (*state && !s) return end(&x, FAIL(&x, "*FMUstate is not a state of this instance"));
    if (!s && !(s = fresh = new_state(inst))) return end(&x, FAIL(&x, "out of memory"));
    if ((st = B.state_get(&x, s)) != ST_OK) {
        if (fresh) {
            inst->states = fresh->next;
            drop_state(fresh, 1);
        }
        return end(&x, st);
    }
    s->machine = inst->state;
    s->time = inst->time;
    s->terminated = inst->terminated;
    *state = s;
    return end(&x, ST_OK);
}

int glider_op_set_state(void *c, void *state) {
    Ctx x;
    FmuState *s;
    Status st = begin(&x, c, C_SET_FMU_STATE);
    if (st != ST_OK) return end(&x, st);
    if (!(s = owned_state(x.inst, state)))
        return end(&x, FAIL(&x, "FMUstate is not a state of this instance"));
    if ((st = B.state_set(&x, s)) == ST_OK) {
        x.inst->state = s->machine;
        x.inst->time = s->time;
        x.inst->terminated = s->terminated;
    }
    return end(&x, st);
}

int glider_op_free_state(void *c, void **state) {
    Ctx x;
    FmuState **p;
    Status st = begin(&x, c, C_FREE_FMU_STATE);
    if (st != ST_OK || !state || !*state) return end(&x, st);
    for (p = &x.inst->states; *p; p = &(*p)->next) {
        if ((void *)*p == *state) {
            FmuState *s = *p;
            *p = s->next;
            drop_state(s, 1);
            *state = NULL;
            return end(&x, ST_OK);
        }
    }
    return end(&x, FAIL(&x, "*FMUstate is not a state of this instance"));
}

/* Serialized layout: magic, FMI state, terminated flag, time, model identifier, then the
 * back end's bytes (the same in FMI 2 and 3). */
static const char SER_MAGIC[8] = {'G', 'F', 'M', 'I', 'S', 'T', '0', '1'};
#define SER_HEADER (8 + 4 + 4 + 8 + MODEL_ID_SIZE)

int glider_op_state_size(void *c, void *state, size_t *size) {
    Ctx x;
    FmuState *s;
    const char *data;
    size_t n;
    Status st = begin(&x, c, C_STATE_SIZE);
    if (st != ST_OK) return end(&x, st);
    s = owned_state(x.inst, state);
    if (!s || !size)
        return end(&x, FAIL(&x, s ? "size is NULL" : "FMUstate is not a state of this instance"));
    if ((st = B.state_bytes(&x, s, &data, &n)) == ST_OK) *size = SER_HEADER + n;
    return end(&x, st);
}

int glider_op_serialize(void *c, void *state, char buffer[], size_t size) {
    Ctx x;
    FmuState *s;
    const char *data, *model = B.model_identifier();
    size_t n;
    uint32_t machine, term;
    Status st = begin(&x, c, C_SERIALIZE);
    if (st != ST_OK) return end(&x, st);
    s = owned_state(x.inst, state);
    if (!s || !buffer)
        return end(&x, FAIL(&x, s ? "buffer is NULL" : "FMUstate is not a state of this instance"));
    if ((st = B.state_bytes(&x, s, &data, &n)) != ST_OK) return end(&x, st);
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
    return end(&x, ST_OK);
}

int glider_op_deserialize(void *c, const char data[], size_t size, void **state) {
    Ctx x;
    FmuState *s;
    char model[MODEL_ID_SIZE + 1] = "";
    uint32_t machine, term;
    double time;
    Status st = begin(&x, c, C_DESERIALIZE);
    if (st != ST_OK) return end(&x, st);
    if (!data || !state)
        return end(&x, FAIL(&x, "%s is NULL", state ? "serializedState" : "FMUstate"));
    if (size < SER_HEADER || memcmp(data, SER_MAGIC, 8))
        return end(&x, FAIL(&x, "the %lu bytes are not a serialized state of this runtime",
                            (unsigned long)size));
    memcpy(model, data + 24, MODEL_ID_SIZE);
    if (strcmp(model, B.model_identifier()))
        return end(&x, FAIL(&x, "the state is one of model %.100s: expected %s", model,
                            B.model_identifier()));
    memcpy(&machine, data + 8, 4);
    memcpy(&term, data + 12, 4);
    memcpy(&time, data + 16, 8);
    if (!(machine & S_LIVE) || (machine & (machine - 1)))
        return end(&x, FAIL(&x, "the state records an invalid FMI state %u", machine));
    if (!(s = new_state(x.inst))) return end(&x, FAIL(&x, "out of memory"));
    st = B.state_from_bytes(&x, s, data + SER_HEADER, size - SER_HEADER);
    if (st != ST_OK) {
        x.inst->states = s->next;
        drop_state(s, 1);
        return end(&x, st);
    }
    s->machine = machine;
    s->terminated = term != 0;
    s->time = time;
    *state = s;
    return end(&x, ST_OK);
}

/* ------------------------------------------------------------------ the rest */
int glider_op_unsupported(void *c, int call) {
    Ctx x;
    return end(&x, begin(&x, c, call));
}

/* A value reference of a directional derivative: an unknown (row >= 0, or a state that is
 * an output: a column) or a known (column), named in the message if it is neither. */
static Status check_jacobian_refs(Ctx *x, const unsigned vr[], size_t n, int unknowns) {
    const Instance *inst = x->inst;
    size_t i;
    for (i = 0; i < n; ++i) {
        unsigned r = vr[i];
        if (is_time(inst, r))
            return FAIL(x, "value reference %u (time) is not %s", r,
                        unknowns ? "an unknown: expected an output or a state derivative"
                                 : "a known: expected a continuous state or an input");
        if (r >= inst->nvars)
            return FAIL(x, "value reference %u does not exist: expected 0..%lu", r,
                        (unsigned long)(inst->nvars - 1));
        if (inst->jac_col[r] >= 0 || (unknowns && inst->jac_row[r] >= 0)) continue;
        return FAIL(x, unknowns ? "value reference %u (%s) is not an unknown: expected an "
                                  "output or a state derivative"
                                : "value reference %u (%s) is not a known: expected a "
                                  "continuous state or an input",
                    r, inst->var_names[r]);
    }
    return ST_OK;
}

int glider_op_directional(void *c, const unsigned unknown[], size_t nunknown,
                          const unsigned known[], size_t nknown, const double seed[],
                          size_t nseed, double sensitivity[], size_t nsensitivity) {
    Ctx x;
    Instance *inst;
    double *J;
    size_t i, k;
    Status st = begin(&x, c, C_DIRECTIONAL);
    if (st != ST_OK) return end(&x, st);
    inst = x.inst;
    if (!inst->jac_row || !B.jacobian) return end(&x, FAIL(&x, "not supported by this FMU"));
    if (nseed != nknown || nsensitivity != nunknown)
        return end(&x, FAIL(&x, "%s = %lu is invalid: expected %lu (one per %s)",
                            nseed != nknown ? "nSeed" : "nSensitivity",
                            (unsigned long)(nseed != nknown ? nseed : nsensitivity),
                            (unsigned long)(nseed != nknown ? nknown : nunknown),
                            nseed != nknown ? "known" : "unknown"));
    if (nunknown == 0) return end(&x, ST_OK);
    if (!unknown || !sensitivity || (nknown && (!known || !seed)))
        return end(&x, FAIL(&x, "NULL %s array with %lu unknowns and %lu knowns",
                            !unknown ? "unknown" : !sensitivity ? "sensitivity"
                            : !known ? "known" : "seed",
                            (unsigned long)nunknown, (unsigned long)nknown));
    if ((st = check_jacobian_refs(&x, unknown, nunknown, 1)) != ST_OK ||
        (st = check_jacobian_refs(&x, known, nknown, 0)) != ST_OK)
        return end(&x, st);
    if (!(J = malloc(inst->jac_nrows * inst->jac_ncols * sizeof *J)))
        return end(&x, FAIL(&x, "out of memory"));
    if ((st = B.jacobian(&x, J)) == ST_OK) {
        for (i = 0; i < nunknown; ++i) {
            int row = inst->jac_row[unknown[i]], col = inst->jac_col[unknown[i]];
            double s = 0.0;
            for (k = 0; k < nknown; ++k) {
                int kc = inst->jac_col[known[k]];
                s += (row >= 0 ? J[(size_t)row * inst->jac_ncols + (size_t)kc]
                               : (double)(kc == col)) * seed[k];
            }
            sensitivity[i] = s;
        }
    }
    free(J);
    return end(&x, st);
}

int glider_op_do_step(void *c, double t, double h, int *terminated, double *last) {
    Ctx x;
    Instance *inst;
    int go_on = 1;
    Status st = begin(&x, c, C_DO_STEP);
    if (st != ST_OK) return end(&x, st);
    if (!(h > 0.0) || !isfinite(h) || !isfinite(t))
        return end(&x, FAIL(&x, "step of %g s at t = %g s is invalid: expected a finite step > 0",
                            h, t));
    if ((st = B.step(&x, t, h, &go_on)) != ST_OK) return end(&x, st);
    inst = x.inst;
    if (go_on) {
        inst->time = t + h;
    } else {
        inst->state = S_STEP_FAILED;
        inst->terminated = 1;
        inst->time = t;
        glider_add_msg(&x, ST_DISCARD, inst->cat_discard,
                       "%s: %s: the model stopped the simulation at t = %.17g s", inst->name,
                       glider_call_name(&x), t);
    }
    if (terminated) *terminated = !go_on;
    if (last) *last = inst->time;
    return end(&x, go_on ? ST_OK : ST_DISCARD);
}

int glider_op_query(void *c, int call, int kind, int want,
                    void (*store)(const Instance *, void *), void *value) {
    Ctx x;
    Status st = begin(&x, c, call);
    if (st != ST_OK) return end(&x, st);
    if (!value) return end(&x, FAIL(&x, "value is NULL"));
    if (kind != want || !store) return end(&x, FAIL(&x, "status kind %d is not provided", kind));
    store(x.inst, value);
    return end(&x, ST_OK);
}
