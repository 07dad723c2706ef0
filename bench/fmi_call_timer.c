/* Times FMI calls into one FMU from C (no Python in the host), for bench/fmu_step.py.
 *
 * usage: fmi_call_timer FMU_DIR MODEL_IDENTIFIER N GET_VRS SET_VR=VALUE,... [thread]
 * GET_VRS: comma-separated value references read by fmi2GetReal; SET_VR=VALUE pairs: the
 * inputs written by fmi2SetReal (and held). After initialisation and 200 warm-up steps,
 * N calls of each of fmi2DoStep, fmi2GetReal and fmi2SetReal are timed; prints
 * {"doStep_ns": ..., "getReal_ns": ..., "setReal_ns": ...} (mean per call). With
 * "thread", the timed calls are made from a new pthread, one Python has never seen (as
 * libcosim's and Ecos's worker threads are); instantiation stays on the main thread.
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment e, fmi2String i, fmi2Status s, fmi2String c,
                   fmi2String m, ...) {
    (void)e, (void)c;
    fprintf(stderr, "[%s] %d %s\n", i, (int)s, m);
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static size_t parse_vrs(char *text, fmi2ValueReference *vr, fmi2Real *val, size_t max) {
    size_t n = 0;
    for (char *tok = strtok(text, ","); tok && n < max; tok = strtok(NULL, ","), ++n) {
        vr[n] = (fmi2ValueReference)strtoul(tok, NULL, 10);
        char *eq = strchr(tok, '=');
        if (val) val[n] = eq ? strtod(eq + 1, NULL) : 0.0;
    }
    return n;
}

typedef struct {
    fmi2DoStepTYPE *DoStep;
    fmi2GetRealTYPE *GetReal;
    fmi2SetRealTYPE *SetReal;
    fmi2Component c;
    long n;
    const fmi2ValueReference *get_vr, *set_vr;
    fmi2Real *get_val;
    const fmi2Real *set_val;
    size_t n_get, n_set;
    double t[4];
    int rc;
} Job;

static void *timed(void *arg) {
    Job *j = arg;
    const double h = 0.02;
    long k = 0;
    for (; k < 200; ++k)
        if (j->DoStep(j->c, (double)k * h, h, fmi2True)) return j->rc = 6, NULL;
    j->t[0] = now();
    for (long i = 0; i < j->n; ++i, ++k)
        if (j->DoStep(j->c, (double)k * h, h, fmi2True)) return j->rc = 6, NULL;
    j->t[1] = now();
    for (long i = 0; i < j->n; ++i)
        if (j->GetReal(j->c, j->get_vr, j->n_get, j->get_val)) return j->rc = 7, NULL;
    j->t[2] = now();
    for (long i = 0; i < j->n; ++i)
        if (j->SetReal(j->c, j->set_vr, j->n_set, j->set_val)) return j->rc = 7, NULL;
    j->t[3] = now();
    return NULL;
}

int main(int argc, char **argv) {
    if (argc != 6 && !(argc == 7 && !strcmp(argv[6], "thread"))) {
        fprintf(stderr, "usage: fmi_call_timer FMU_DIR MODEL N GET_VRS SET_VR=VALUE,... [thread]\n");
        return 2;
    }
    char path[8192], uri[8192];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", argv[1], argv[2]);
    snprintf(uri, sizeof uri, "file://%s/resources", argv[1]);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "%s\n", dlerror());
        return 3;
    }
#define F(name) fmi2##name##TYPE *name = (fmi2##name##TYPE *)dlsym(lib, "fmi2" #name)
    F(Instantiate);
    F(SetupExperiment);
    F(EnterInitializationMode);
    F(ExitInitializationMode);
    F(DoStep);
    F(GetReal);
    F(SetReal);
    F(FreeInstance);
#undef F
    const long n = atol(argv[3]);
    fmi2ValueReference get_vr[64], set_vr[64];
    fmi2Real get_val[64], set_val[64];
    size_t n_get = parse_vrs(argv[4], get_vr, NULL, 64);
    size_t n_set = parse_vrs(argv[5], set_vr, set_val, 64);
    const fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = Instantiate("timer", fmi2CoSimulation, "", uri, &cb, fmi2False, fmi2False);
    if (!c || SetupExperiment(c, fmi2False, 0, 0, fmi2False, 0) || SetReal(c, set_vr, n_set, set_val) ||
        EnterInitializationMode(c) || ExitInitializationMode(c))
        return 5;
    Job j = {DoStep, GetReal, SetReal, c, n, get_vr, set_vr, get_val, set_val, n_get, n_set,
             {0, 0, 0, 0}, 0};
    if (argc == 7) {
        pthread_t tid;
        if (pthread_create(&tid, NULL, timed, &j) || pthread_join(tid, NULL)) return 8;
    } else {
        timed(&j);
    }
    if (j.rc) return j.rc;
    printf("{\"doStep_ns\": %.1f, \"getReal_ns\": %.1f, \"setReal_ns\": %.1f}\n",
           (j.t[1] - j.t[0]) / (double)n * 1e9, (j.t[2] - j.t[1]) / (double)n * 1e9,
           (j.t[3] - j.t[2]) / (double)n * 1e9);
    FreeInstance(c);
    return 0;
}
