/* Times FMI calls into one FMU from C (no Python in the host), for bench/fmu_step.py.
 *
 * usage: fmi_call_timer FMU_DIR MODEL_IDENTIFIER N GET_VRS SET_VR=VALUE,...
 * GET_VRS: comma-separated value references read by fmi2GetReal; SET_VR=VALUE pairs: the
 * inputs written by fmi2SetReal (and held). After initialisation and 200 warm-up steps,
 * N calls of each of fmi2DoStep, fmi2GetReal and fmi2SetReal are timed; prints
 * {"doStep_ns": ..., "getReal_ns": ..., "setReal_ns": ...} (mean per call).
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
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

int main(int argc, char **argv) {
    if (argc != 6) {
        fprintf(stderr, "usage: fmi_call_timer FMU_DIR MODEL N GET_VRS SET_VR=VALUE,...\n");
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
    const double h = 0.02;
    long k = 0;
    for (; k < 200; ++k)
        if (DoStep(c, (double)k * h, h, fmi2True)) return 6;
    double t0 = now();
    for (long i = 0; i < n; ++i, ++k)
        if (DoStep(c, (double)k * h, h, fmi2True)) return 6;
    double t1 = now();
    for (long i = 0; i < n; ++i)
        if (GetReal(c, get_vr, n_get, get_val)) return 7;
    double t2 = now();
    for (long i = 0; i < n; ++i)
        if (SetReal(c, set_vr, n_set, set_val)) return 7;
    double t3 = now();
    printf("{\"doStep_ns\": %.1f, \"getReal_ns\": %.1f, \"setReal_ns\": %.1f}\n",
           (t1 - t0) / (double)n * 1e9, (t2 - t1) / (double)n * 1e9, (t3 - t2) / (double)n * 1e9);
    FreeInstance(c);
    return 0;
}
