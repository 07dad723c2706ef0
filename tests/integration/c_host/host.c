/* A minimal FMI 2.0 co-simulation host in C, for tests/integration/test_c_host.py; with
 * -DGLIDER_HOST_FMI3 the same host for FMI 3.0 (tests/integration/test_fmi3.py).
 *
 * Reads a plan (one directive per line), loads the binaries of unzipped FMUs with
 * dlopen, instantiates them with a logger callback, sets parameters, initialises them
 * and steps them as a closed loop with Jacobi coupling (at every communication point all
 * connected outputs are read, then all inputs set, then every instance steps), printing
 * the recorded outputs at every point as CSV with 17 significant digits. It then
 * terminates and frees the instances and returns from main (a normal exit).
 *
 *   fmu NAME DIR MODEL_IDENTIFIER GUID     an instance of the FMU unzipped in DIR
 *   real NAME VR VALUE                     a Real set before initialisation
 *   integer NAME VR VALUE                  an Integer set before initialisation
 *   connect SRC VR DST VR                  SRC's output to DST's input (Real)
 *   record NAME VR                         a Real printed at every point
 *   run STEP STOP                          communication step and stop time (s)
 *   threads                                step the instances each in a thread of its own
 *                                          at every point (as libcosim's thread pool does)
 *
 * usage: host PLAN.  Compiled against the FMI 2.0 headers fmpy ships, with gcc for linux64
 * (dlopen, pthreads) or with mingw-w64 for win64 (LoadLibrary, Win32 threads: no
 * libwinpthread, which wine lacks), where DIR is a Windows path such as Z:/tmp/x; built
 * for aarch64 Linux (zig cc -target aarch64-linux-gnu.2.17, run under qemu-aarch64) it
 * loads binaries/aarch64-linux/ in both FMI versions.
 * Exit codes: 0 ok, 2 usage or plan, 3 dlopen/dlsym, 4 instantiate, 5 initialisation,
 * 6 step, 7 get/set.
 *
 * FMI 3.0 (-DGLIDER_HOST_FMI3, against fmpy's FMI 3.0 headers): GUID is the
 * instantiation token, binaries come from x86_64-linux or x86_64-windows, the resource
 * location is the native path of resources/ with a trailing '/', the start time goes to
 * fmi3EnterInitializationMode (stopTimeDefined false), Real and Integer are Float64 and
 * Int32, and a doStep returning terminateSimulation ends the run (exit 6) as a Discard.
 * Logging is off (loggingOn false): the messages printed are those an FMU must send
 * anyway (errors).
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef GLIDER_HOST_FMI3
#include "fmi3Functions.h"
typedef fmi3Status fmi2Status;
typedef fmi3ValueReference fmi2ValueReference;
typedef fmi3Int32 fmi2Integer;
#define fmi2OK fmi3OK
#define fmi2Warning fmi3Warning
#define fmi2True fmi3True
#define fmi2False fmi3False
#else
#include "fmi2Functions.h"
#endif

#ifdef _WIN32
#include <windows.h>
#ifdef GLIDER_HOST_FMI3
#define PLATFORM "x86_64-windows"
#define URI_FORMAT "%s/resources/"
#else
#define PLATFORM "win64"
#define URI_FORMAT "file:///%s/resources"
#endif
#define SUFFIX ".dll"
typedef HANDLE thread_t;
static void *open_library(const char *path) { return (void *)LoadLibraryA(path); }
static void *library_symbol(void *lib, const char *name) {
    FARPROC f = GetProcAddress((HMODULE)lib, name);
    void *p;
    memcpy(&p, &f, sizeof p);
    return p;
}
static const char *library_error(void) {
    static char text[64];
    snprintf(text, sizeof text, "Windows error %lu", (unsigned long)GetLastError());
    return text;
}
#else
#include <dlfcn.h>
#include <pthread.h>
#ifdef GLIDER_HOST_FMI3
#define PLATFORM "x86_64-linux"
#define URI_FORMAT "%s/resources/"
#else
#define PLATFORM "linux64"
#define URI_FORMAT "file://%s/resources"
#endif
#ifdef __aarch64__ /* FMI 3's tuple, and our FMI 2 FMUs' folder for aarch64 Linux */
#undef PLATFORM
#define PLATFORM "aarch64-linux"
#endif
#define SUFFIX ".so"
typedef pthread_t thread_t;
static void *open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *library_symbol(void *lib, const char *name) { return dlsym(lib, name); }
static const char *library_error(void) { return dlerror(); }
#endif

#define MAX 32

#ifdef GLIDER_HOST_FMI3
typedef struct {
    char name[4096];
    void *lib;
    fmi3Instance c;
    fmi3InstantiateCoSimulationTYPE *instantiate;
    fmi3EnterInitializationModeTYPE *enter3;
    fmi3ExitInitializationModeTYPE *exit_init;
    fmi3SetFloat64TYPE *set_float64;
    fmi3SetInt32TYPE *set_int32;
    fmi3GetFloat64TYPE *get_float64;
    fmi3DoStepTYPE *do_step3;
    fmi3TerminateTYPE *terminate;
    fmi3FreeInstanceTYPE *free_instance;
} Fmu;

/* the FMI 2.0 calls main() makes, in FMI 3.0 */
static fmi2Status setup(Fmu *f, double stop) {
    (void)f, (void)stop; /* the experiment goes to fmi3EnterInitializationMode */
    return fmi3OK;
}
static fmi2Status enter(Fmu *f, double stop) {
    (void)stop;
    return f->enter3(f->c, fmi3False, 0.0, 0.0, fmi3False, 0.0);
}
static fmi2Status set_real(Fmu *f, const fmi2ValueReference *vr, double *v) {
    return f->set_float64(f->c, vr, 1, v, 1);
}
static fmi2Status set_integer(Fmu *f, const fmi2ValueReference *vr, fmi2Integer *v) {
    return f->set_int32(f->c, vr, 1, v, 1);
}
static fmi2Status get_real(Fmu *f, const fmi2ValueReference *vr, double *v) {
    return f->get_float64(f->c, vr, 1, v, 1);
}
static fmi2Status do_step(Fmu *f, double t, double h) {
    fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
    fmi3Float64 last = t;
    fmi3Status st = f->do_step3(f->c, t, h, fmi3True, &event, &terminate, &early, &last);
    return st <= fmi3Warning && terminate ? fmi3Discard : st;
}
#else
typedef struct {
    char name[4096];
    void *lib;
    fmi2Component c;
    fmi2InstantiateTYPE *instantiate;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2GetRealTYPE *get_real;
    fmi2DoStepTYPE *do_step;
    fmi2TerminateTYPE *terminate;
    fmi2FreeInstanceTYPE *free_instance;
} Fmu;

static fmi2Status setup(Fmu *f, double stop) {
    return f->setup(f->c, fmi2False, 0.0, 0.0, fmi2True, stop);
}
static fmi2Status enter(Fmu *f, double stop) {
    (void)stop;
    return f->enter(f->c);
}
static fmi2Status set_real(Fmu *f, const fmi2ValueReference *vr, double *v) {
    return f->set_real(f->c, vr, 1, v);
}
static fmi2Status set_integer(Fmu *f, const fmi2ValueReference *vr, fmi2Integer *v) {
    return f->set_integer(f->c, vr, 1, v);
}
static fmi2Status get_real(Fmu *f, const fmi2ValueReference *vr, double *v) {
    return f->get_real(f->c, vr, 1, v);
}
static fmi2Status do_step(Fmu *f, double t, double h) { return f->do_step(f->c, t, h, fmi2True); }
#endif

typedef struct {
    int fmu;
    fmi2ValueReference vr;
    double value;
    int integer;
} Ref;

static Fmu fmus[MAX];
static int n_fmus;
static Ref params[MAX * 4], records[MAX];
static int n_params, n_records;
static Ref conn_src[MAX], conn_dst[MAX];
static int n_conns, use_threads;

typedef struct {
    Fmu *f;
    double t, h;
    fmi2Status status;
} StepJob;

static void *step_job(void *arg) {
    StepJob *j = arg;
    j->status = do_step(j->f, j->t, j->h);
    return NULL;
}

#ifdef _WIN32
static DWORD WINAPI win_step_job(LPVOID arg) {
    step_job(arg);
    return 0;
}
static int start_thread(thread_t *t, StepJob *j) {
    *t = CreateThread(NULL, 0, win_step_job, j, 0, NULL);
    return *t == NULL;
}
static void join_thread(thread_t t) {
    WaitForSingleObject(t, INFINITE);
    CloseHandle(t);
}
#else
static int start_thread(thread_t *t, StepJob *j) { return pthread_create(t, NULL, step_job, j); }
static void join_thread(thread_t t) { pthread_join(t, NULL); }
#endif

#ifdef GLIDER_HOST_FMI3
static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                    fmi3String message) {
    (void)env;
    fprintf(stderr, "[fmi3] status %d %s: %s\n", (int)status, category ? category : "",
            message ? message : "");
}
#else
static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    char text[4096];
    va_list args;
    (void)env;
    va_start(args, message);
    vsnprintf(text, sizeof text, message ? message : "", args);
    va_end(args);
    fprintf(stderr, "[%s] status %d %s: %s\n", instance ? instance : "?", (int)status,
            category ? category : "", text);
}
#endif

static int find(const char *name) {
    for (int i = 0; i < n_fmus; ++i)
        if (!strcmp(fmus[i].name, name)) return i;
    fprintf(stderr, "plan: no fmu %s\n", name);
    exit(2);
}

static void *sym(void *lib, const char *name) {
    void *f = library_symbol(lib, name);
    if (!f) {
        fprintf(stderr, "symbol %s not found: %s\n", name, library_error());
        exit(3);
    }
    return f;
}

static int load(Fmu *f, const char *dir, const char *model, const char *guid) {
    char path[12288], uri[12288];
    snprintf(path, sizeof path, "%s/binaries/" PLATFORM "/%s" SUFFIX, dir, model);
    f->lib = open_library(path);
    if (!f->lib) {
        fprintf(stderr, "loading %s failed: %s\n", path, library_error());
        return 3;
    }
    snprintf(uri, sizeof uri, URI_FORMAT, dir);
#ifdef GLIDER_HOST_FMI3
    f->instantiate = (fmi3InstantiateCoSimulationTYPE *)sym(f->lib, "fmi3InstantiateCoSimulation");
    f->enter3 = (fmi3EnterInitializationModeTYPE *)sym(f->lib, "fmi3EnterInitializationMode");
    f->exit_init = (fmi3ExitInitializationModeTYPE *)sym(f->lib, "fmi3ExitInitializationMode");
    f->set_float64 = (fmi3SetFloat64TYPE *)sym(f->lib, "fmi3SetFloat64");
    f->set_int32 = (fmi3SetInt32TYPE *)sym(f->lib, "fmi3SetInt32");
    f->get_float64 = (fmi3GetFloat64TYPE *)sym(f->lib, "fmi3GetFloat64");
    f->do_step3 = (fmi3DoStepTYPE *)sym(f->lib, "fmi3DoStep");
    f->terminate = (fmi3TerminateTYPE *)sym(f->lib, "fmi3Terminate");
    f->free_instance = (fmi3FreeInstanceTYPE *)sym(f->lib, "fmi3FreeInstance");
    f->c = f->instantiate(f->name, guid, uri, fmi3False, fmi3False, fmi3False, fmi3False, NULL,
                          0, NULL, logger3, NULL);
    if (!f->c) {
        fprintf(stderr, "fmi3InstantiateCoSimulation of %s failed\n", f->name);
        return 4;
    }
    return 0;
#else
    f->instantiate = (fmi2InstantiateTYPE *)sym(f->lib, "fmi2Instantiate");
    f->setup = (fmi2SetupExperimentTYPE *)sym(f->lib, "fmi2SetupExperiment");
    f->enter = (fmi2EnterInitializationModeTYPE *)sym(f->lib, "fmi2EnterInitializationMode");
    f->exit_init = (fmi2ExitInitializationModeTYPE *)sym(f->lib, "fmi2ExitInitializationMode");
    f->set_real = (fmi2SetRealTYPE *)sym(f->lib, "fmi2SetReal");
    f->set_integer = (fmi2SetIntegerTYPE *)sym(f->lib, "fmi2SetInteger");
    f->get_real = (fmi2GetRealTYPE *)sym(f->lib, "fmi2GetReal");
    f->do_step = (fmi2DoStepTYPE *)sym(f->lib, "fmi2DoStep");
    f->terminate = (fmi2TerminateTYPE *)sym(f->lib, "fmi2Terminate");
    f->free_instance = (fmi2FreeInstanceTYPE *)sym(f->lib, "fmi2FreeInstance");
    static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    f->c = f->instantiate(f->name, fmi2CoSimulation, guid, uri, &callbacks, fmi2False,
                          fmi2False);
    if (!f->c) {
        fprintf(stderr, "fmi2Instantiate of %s failed\n", f->name);
        return 4;
    }
    return 0;
#endif
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: host PLAN\n");
        return 2;
    }
    FILE *plan = fopen(argv[1], "r");
    if (!plan) {
        fprintf(stderr, "cannot read %s\n", argv[1]);
        return 2;
    }
    char line[8192], a[4096], b[4096], c[4096], d[4096], e[4096];
    double h = 0.0, stop = 0.0;
    while (fgets(line, sizeof line, plan)) {
        int n = sscanf(line, "%4095s %4095s %4095s %4095s %4095s", a, b, c, d, e);
        if (n <= 0) continue;
        if (!strcmp(a, "fmu") && n == 5 && n_fmus < MAX) {
            Fmu *f = &fmus[n_fmus++];
            snprintf(f->name, sizeof f->name, "%s", b);
            int rc = load(f, c, d, e);
            if (rc) return rc;
        } else if ((!strcmp(a, "real") || !strcmp(a, "integer")) && n == 4 &&
                   n_params < MAX * 4) {
            params[n_params++] = (Ref){find(b), (fmi2ValueReference)strtoul(c, NULL, 10),
                                       strtod(d, NULL), a[0] == 'i'};
        } else if (!strcmp(a, "connect") && n == 5 && n_conns < MAX) {
            conn_src[n_conns] = (Ref){find(b), (fmi2ValueReference)strtoul(c, NULL, 10), 0, 0};
            conn_dst[n_conns++] = (Ref){find(d), (fmi2ValueReference)strtoul(e, NULL, 10), 0, 0};
        } else if (!strcmp(a, "record") && n == 3 && n_records < MAX) {
            records[n_records++] = (Ref){find(b), (fmi2ValueReference)strtoul(c, NULL, 10), 0, 0};
        } else if (!strcmp(a, "threads") && n == 1) {
            use_threads = 1;
        } else if (!strcmp(a, "run") && n == 3) {
            h = strtod(b, NULL);
            stop = strtod(c, NULL);
        } else {
            fprintf(stderr, "plan: bad line %s", line);
            return 2;
        }
    }
    fclose(plan);
    if (!(h > 0.0) || !(stop > 0.0)) {
        fprintf(stderr, "plan: no run line\n");
        return 2;
    }
    for (int i = 0; i < n_fmus; ++i)
        if (setup(&fmus[i], stop) > fmi2Warning) return 5;
    for (int i = 0; i < n_params; ++i) {
        Fmu *f = &fmus[params[i].fmu];
        fmi2Integer iv = (fmi2Integer)params[i].value;
        fmi2Status st = params[i].integer ? set_integer(f, &params[i].vr, &iv)
                                          : set_real(f, &params[i].vr, &params[i].value);
        if (st > fmi2Warning) return 5;
    }
    for (int i = 0; i < n_fmus; ++i)
        if (enter(&fmus[i], stop) > fmi2Warning || fmus[i].exit_init(fmus[i].c) > fmi2Warning)
            return 5;
    const long steps = lround(stop / h);
    for (long k = 0;; ++k) {
        double t = (double)k * h;
        double v[MAX];
        for (int i = 0; i < n_conns; ++i) {
            Fmu *f = &fmus[conn_src[i].fmu];
            if (get_real(f, &conn_src[i].vr, &v[i]) > fmi2Warning) return 7;
        }
        printf("%.17g", t);
        for (int i = 0; i < n_records; ++i) {
            Fmu *f = &fmus[records[i].fmu];
            double r;
            if (get_real(f, &records[i].vr, &r) > fmi2Warning) return 7;
            printf(",%.17g", r);
        }
        printf("\n");
        if (k == steps) break;
        for (int i = 0; i < n_conns; ++i) {
            Fmu *f = &fmus[conn_dst[i].fmu];
            if (set_real(f, &conn_dst[i].vr, &v[i]) > fmi2Warning) return 7;
        }
        StepJob jobs[MAX];
        thread_t tids[MAX];
        for (int i = 0; i < n_fmus; ++i) {
            jobs[i] = (StepJob){&fmus[i], t, h, fmi2OK};
            if (!use_threads) step_job(&jobs[i]);
            else if (start_thread(&tids[i], &jobs[i])) return 6;
        }
        for (int i = 0; use_threads && i < n_fmus; ++i) join_thread(tids[i]);
        for (int i = 0; i < n_fmus; ++i) {
            if (jobs[i].status > fmi2Warning) {
                fprintf(stderr, "%s: step %ld at t = %g failed\n", fmus[i].name, k, t);
                return 6;
            }
        }
    }
    for (int i = 0; i < n_fmus; ++i) {
        fmus[i].terminate(fmus[i].c);
        fmus[i].free_instance(fmus[i].c);
    }
    return 0;
}
