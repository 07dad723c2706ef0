/* A minimal FMI 2.0 co-simulation host in C, for tests/integration/test_c_host.py.
 *
 * Loads the binary of an unzipped FMU with dlopen, instantiates it with a logger
 * callback, sets it up and initialises it, then steps it from t = 0 with step h,
 * holding a list of Real inputs at given values, and prints one Real output at the end
 * with 17 significant digits.
 *
 * usage: host FMU_DIR MODEL_IDENTIFIER GUID STOP_TIME STEP OUT_VR [IN_VR=VALUE ...]
 *
 * Compiled against the FMI 2.0 headers fmpy ships (fmpy/c-code/fmi2Functions.h).
 * Exit codes: 0 ok, 2 usage, 3 dlopen/dlsym, 4 instantiate, 5 initialisation, 6 step,
 * 7 get.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fmi2Functions.h"

#define MAX_INPUTS 16

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    char text[2048];
    va_list args;
    (void)env;
    va_start(args, message);
    vsnprintf(text, sizeof text, message ? message : "", args);
    va_end(args);
    fprintf(stderr, "[%s] status %d %s: %s\n", instance ? instance : "?", (int)status,
            category ? category : "", text);
}

static void *load(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "dlsym %s failed: %s\n", name, dlerror());
    }
    return f;
}

int main(int argc, char **argv) {
    if (argc < 7) {
        fprintf(stderr, "usage: host FMU_DIR MODEL_IDENTIFIER GUID STOP_TIME STEP OUT_VR "
                        "[IN_VR=VALUE ...]\n");
        return 2;
    }
    const char *dir = argv[1], *model = argv[2], *guid = argv[3];
    const double stop = atof(argv[4]), h = atof(argv[5]);
    const fmi2ValueReference out_vr = (fmi2ValueReference)strtoul(argv[6], NULL, 10);
    fmi2ValueReference in_vr[MAX_INPUTS];
    fmi2Real in_value[MAX_INPUTS];
    size_t n_in = 0;
    for (int i = 7; i < argc && n_in < MAX_INPUTS; ++i, ++n_in) {
        char *eq = strchr(argv[i], '=');
        if (!eq) {
            fprintf(stderr, "bad input %s: expected VR=VALUE\n", argv[i]);
            return 2;
        }
        in_vr[n_in] = (fmi2ValueReference)strtoul(argv[i], NULL, 10);
        in_value[n_in] = atof(eq + 1);
    }

    char path[4096], uri[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, model);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen failed: %s\n", dlerror());
        return 3;
    }
    fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)load(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)load(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter =
        (fmi2EnterInitializationModeTYPE *)load(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init =
        (fmi2ExitInitializationModeTYPE *)load(lib, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *set_real = (fmi2SetRealTYPE *)load(lib, "fmi2SetReal");
    fmi2GetRealTYPE *get_real = (fmi2GetRealTYPE *)load(lib, "fmi2GetReal");
    fmi2DoStepTYPE *do_step = (fmi2DoStepTYPE *)load(lib, "fmi2DoStep");
    fmi2TerminateTYPE *terminate = (fmi2TerminateTYPE *)load(lib, "fmi2Terminate");
    fmi2FreeInstanceTYPE *free_instance = (fmi2FreeInstanceTYPE *)load(lib, "fmi2FreeInstance");
    if (!instantiate || !setup || !enter || !exit_init || !set_real || !get_real || !do_step ||
        !terminate || !free_instance) {
        return 3;
    }

    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("plant", fmi2CoSimulation, guid, uri, &callbacks, fmi2False,
                                  fmi2True);
    if (!c) {
        fprintf(stderr, "fmi2Instantiate failed\n");
        return 4;
    }
    if (setup(c, fmi2False, 0.0, 0.0, fmi2True, stop) > fmi2Warning ||
        set_real(c, in_vr, n_in, in_value) > fmi2Warning || enter(c) > fmi2Warning ||
        exit_init(c) > fmi2Warning) {
        fprintf(stderr, "initialisation failed\n");
        return 5;
    }
    const long n = lround(stop / h);
    for (long k = 0; k < n; ++k) {
        if (set_real(c, in_vr, n_in, in_value) > fmi2Warning ||
            do_step(c, (double)k * h, h, fmi2True) > fmi2Warning) {
            fprintf(stderr, "step %ld at t = %g failed\n", k, (double)k * h);
            return 6;
        }
    }
    fmi2Real value = 0.0;
    if (get_real(c, &out_vr, 1, &value) > fmi2Warning) {
        fprintf(stderr, "fmi2GetReal failed\n");
        return 7;
    }
    printf("%.17g\n", value);
    terminate(c);
    free_instance(c);
    fflush(stdout);
    fflush(stderr);
    /* Leave without exit-time finalisers: pythonfmu's binary can abort in them (see the
     * README's "Reliability"); the library is never unloaded either. */
    _exit(0);
}
