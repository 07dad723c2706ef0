/*
 * The one-FMU export's binary: forwards every FMI 2.0 co-simulation call to the
 * fmu-manipulation-toolbox container (binaries/<platform>/<id>.container.so) and drops,
 * while the container is being instantiated, exactly the three lines its 2.0 binary
 * sends to the host's logger whatever loggingOn says:
 *
 *   fmi2Warning "FMUContainer 'V2.0'"
 *   fmi2Error   "Solver configure...."
 *   fmi2Warning "Container use PARALLEL mode with MONO thread."
 *
 * (container_configure(), called from fmi2Instantiate; its logger() forwards every
 * warning and error). Every other message, from the container or an embedded FMU, at
 * any time, reaches the host, written by FMI's '#' rule (FMI 2.0 section 2.1.5: '#'
 * opens a variable reference such as #r12#, a literal '#' is "##"). The container
 * writes plain text ("FMU#0: loading ..."): each of its '#' goes doubled. It passes an
 * embedded FMU's message on as "%s: %s" (the FMU's name, its message, which is written
 * by the rule): that message is read by the rule first ("##" a '#'; a reference kept as
 * its text, since it names a variable of the embedded FMU, not of this one), then
 * written again. See glider_cosim/onefmu.py.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#ifndef CONTAINER_SUFFIX
#define CONTAINER_SUFFIX ".container.so"
#endif

typedef struct wrap {
    fmi2CallbackFunctions cb;       /* handed to the container */
    fmi2CallbackLogger logger;      /* the host's */
    fmi2ComponentEnvironment env;   /* the host's */
    fmi2Component component;        /* the container's instance */
    struct wrap *next;
} wrap_t;

static void *lib = NULL;
static char lib_error[1200] = "";
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static wrap_t *wraps = NULL;
static __thread int instantiating = 0;

static const struct { fmi2Status status; const char *text; int prefix; } boot_lines[] = {
    {fmi2Warning, "FMUContainer '", 1},
    {fmi2Error, "Solver configure....", 0},
    {fmi2Warning, "Container use PARALLEL mode with MONO thread.", 0},
};

static int is_boot_line(fmi2Status status, const char *text) {
    for (size_t i = 0; i < sizeof(boot_lines) / sizeof(boot_lines[0]); i += 1) {
        if (boot_lines[i].status != status)
            continue;
        if (boot_lines[i].prefix ? strncmp(text, boot_lines[i].text, strlen(boot_lines[i].text)) == 0
                                 : strcmp(text, boot_lines[i].text) == 0)
            return 1;
    }
    return 0;
}

/* Is in[i..] a variable reference of FMI 2's rule, '#' [ribs] digits '#'? Its length. */
static size_t reference_length(const char *in) {
    size_t n = 2;
    if (in[0] != '#' || in[1] == '\0' || !strchr("ribs", in[1]) || in[2] < '0' || in[2] > '9')
        return 0;
    while (in[n] >= '0' && in[n] <= '9')
        n += 1;
    return in[n] == '#' ? n + 1 : 0;
}

/* Append `in` to out[0..*used] (size `size`, kept NUL-terminated) with every '#' doubled;
 * `decode`: `in` is written by the rule, so its "##" is one '#' and a reference is text.
 * A '#' is never cut from its pair at the end of the buffer. */
static void append_escaped(char *out, size_t size, size_t *used, const char *in, int decode) {
    size_t i = 0, ref = 0;
    while (in[i] != '\0') {
        char c = in[i];
        size_t need = c == '#' ? 2 : 1;
        if (*used + need >= size)
            break;
        if (decode && ref == 0 && c == '#') {
            if (in[i + 1] == '#')
                i += 1; /* "##": one literal '#' */
            else
                ref = reference_length(in + i); /* its characters go as text */
        }
        if (ref > 0)
            ref -= 1;
        out[(*used)++] = c;
        if (c == '#')
            out[(*used)++] = '#';
        i += 1;
    }
    out[*used] = '\0';
}

static void quiet_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                         fmi2String category, fmi2String message, ...) {
    const wrap_t *w = (const wrap_t *)env;
    char text[4096], out[8192];
    size_t used = 0;
    va_list ap;
    out[0] = '\0';
    va_start(ap, message);
    if (message && strcmp(message, "%s: %s") == 0) { /* an embedded FMU's message */
        const char *name = va_arg(ap, const char *);
        const char *msg = va_arg(ap, const char *);
        append_escaped(out, sizeof(out), &used, name ? name : "", 0);
        append_escaped(out, sizeof(out), &used, ": ", 0);
        append_escaped(out, sizeof(out), &used, msg ? msg : "", 1);
        va_end(ap);
    } else { /* the container's own: plain text */
        vsnprintf(text, sizeof(text), message ? message : "", ap);
        va_end(ap);
        if (instantiating && is_boot_line(status, text))
            return;
        append_escaped(out, sizeof(out), &used, text, 0);
    }
    if (w && w->logger)
        w->logger(w->env, instance, status, category, "%s", out);
}

static void *load(void) {
    pthread_mutex_lock(&lock);
    if (!lib) {
        Dl_info info;
        char path[1024];
        if (!dladdr((void *)&load, &info) || !info.dli_fname) {
            snprintf(lib_error, sizeof(lib_error), "cannot find the path of the FMU's binary");
        } else {
            const char *dot = strrchr(info.dli_fname, '.');
            size_t stem = dot ? (size_t)(dot - info.dli_fname) : strlen(info.dli_fname);
            snprintf(path, sizeof(path), "%.*s%s", (int)stem, info.dli_fname, CONTAINER_SUFFIX);
            lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
            if (!lib)
                snprintf(lib_error, sizeof(lib_error), "cannot load the container %s: %s", path, dlerror());
        }
    }
    pthread_mutex_unlock(&lock);
    return lib;
}

/* the container's function, looked up once */
#define REAL(name) \
    ({ static name##TYPE *f_ = NULL; if (!f_ && load()) f_ = (name##TYPE *)dlsym(lib, #name); f_; })

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String guid,
                              fmi2String resourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    fmi2InstantiateTYPE *real = REAL(fmi2Instantiate);
    if (!functions)
        return NULL;
    if (!real) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Fatal, "logStatusFatal",
                              "%s", lib_error[0] ? lib_error : "the container has no fmi2Instantiate");
        return NULL;
    }
    wrap_t *w = calloc(1, sizeof(*w));
    if (!w)
        return NULL;
    w->cb = *functions;
    w->logger = functions->logger;
    w->env = functions->componentEnvironment;
    w->cb.logger = quiet_logger;
    w->cb.componentEnvironment = w;
    instantiating = 1;
    fmi2Component c = real(instanceName, fmuType, guid, resourceLocation, &w->cb, visible, loggingOn);
    instantiating = 0;
    if (!c) {
        free(w);
        return NULL;
    }
    w->component = c;
    pthread_mutex_lock(&lock);
    w->next = wraps;
    wraps = w;
    pthread_mutex_unlock(&lock);
    return c;
}

void fmi2FreeInstance(fmi2Component c) {
    fmi2FreeInstanceTYPE *real = REAL(fmi2FreeInstance);
    if (!c)
        return;
    if (real)
        real(c);
    pthread_mutex_lock(&lock);
    for (wrap_t **p = &wraps; *p; p = &(*p)->next) {
        if ((*p)->component == c) {
            wrap_t *w = *p;
            *p = w->next;
            free(w);
            break;
        }
    }
    pthread_mutex_unlock(&lock);
}

#define FORWARD(name, params, args)            \
    fmi2Status name params {                   \
        name##TYPE *real = REAL(name);         \
        return real ? real args : fmi2Error;   \
    }

FORWARD(fmi2SetDebugLogging, (fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]), (c, on, n, cats))
FORWARD(fmi2SetupExperiment, (fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real t0, fmi2Boolean sd, fmi2Real t1),
        (c, td, tol, t0, sd, t1))
FORWARD(fmi2EnterInitializationMode, (fmi2Component c), (c))
FORWARD(fmi2ExitInitializationMode, (fmi2Component c), (c))
FORWARD(fmi2Terminate, (fmi2Component c), (c))
FORWARD(fmi2Reset, (fmi2Component c), (c))
FORWARD(fmi2GetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]), (c, vr, n, v))
FORWARD(fmi2GetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]), (c, vr, n, v))
FORWARD(fmi2GetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]), (c, vr, n, v))
FORWARD(fmi2GetString, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]), (c, vr, n, v))
FORWARD(fmi2SetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]), (c, vr, n, v))
FORWARD(fmi2SetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]),
        (c, vr, n, v))
FORWARD(fmi2SetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]),
        (c, vr, n, v))
FORWARD(fmi2SetString, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]),
        (c, vr, n, v))
FORWARD(fmi2GetFMUstate, (fmi2Component c, fmi2FMUstate *s), (c, s))
FORWARD(fmi2SetFMUstate, (fmi2Component c, fmi2FMUstate s), (c, s))
FORWARD(fmi2FreeFMUstate, (fmi2Component c, fmi2FMUstate *s), (c, s))
FORWARD(fmi2SerializedFMUstateSize, (fmi2Component c, fmi2FMUstate s, size_t *n), (c, s, n))
FORWARD(fmi2SerializeFMUstate, (fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n), (c, s, b, n))
FORWARD(fmi2DeSerializeFMUstate, (fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s), (c, b, n, s))
FORWARD(fmi2GetDirectionalDerivative,
        (fmi2Component c, const fmi2ValueReference u[], size_t nu, const fmi2ValueReference z[], size_t nz,
         const fmi2Real dv[], fmi2Real dz[]),
        (c, u, nu, z, nz, dv, dz))
FORWARD(fmi2SetRealInputDerivatives,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], const fmi2Real v[]),
        (c, vr, n, o, v))
FORWARD(fmi2GetRealOutputDerivatives,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], fmi2Real v[]),
        (c, vr, n, o, v))
FORWARD(fmi2DoStep, (fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noPrior), (c, t, h, noPrior))
FORWARD(fmi2CancelStep, (fmi2Component c), (c))
FORWARD(fmi2GetStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Status *v), (c, k, v))
FORWARD(fmi2GetRealStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Real *v), (c, k, v))
FORWARD(fmi2GetIntegerStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Integer *v), (c, k, v))
FORWARD(fmi2GetBooleanStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v), (c, k, v))
FORWARD(fmi2GetStringStatus, (fmi2Component c, const fmi2StatusKind k, fmi2String *v), (c, k, v))
