/* Minimal FMI 2.0 co-simulation host in C: loads GliderPlant's binary, instantiates it,
 * steps 60 s at 0.02 s with the tail at zero and prints the glide angle at the end.
 * Usage: host <unzipped FMU folder> <guid> */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    (void)category;
    fprintf(stderr, "[%s %d] %s\n", instance, status, message);
}

#define LOAD(name) \
    name##TYPE *name = (name##TYPE *)dlsym(lib, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 3; }

int main(int argc, char **argv) {
    if (argc < 3) { fprintf(stderr, "usage: host FMU_DIR GUID\n"); return 2; }
    char path[4096], uri[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/GliderPlant.so", argv[1]);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "dlopen failed: %s\n", dlerror()); return 3; }
    LOAD(fmi2Instantiate) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode) LOAD(fmi2DoStep) LOAD(fmi2GetReal) LOAD(fmi2Terminate)
    LOAD(fmi2FreeInstance)
    snprintf(uri, sizeof uri, "file://%s/resources", argv[1]);
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate("plant", fmi2CoSimulation, argv[2], uri, &cb, fmi2False,
                                      fmi2True);
    if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 4; }
    if (fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) > fmi2Warning ||
        fmi2EnterInitializationMode(c) > fmi2Warning ||
        fmi2ExitInitializationMode(c) > fmi2Warning) { fprintf(stderr, "init failed\n"); return 5; }
    const fmi2ValueReference vr_theta_g = (fmi2ValueReference)atoi(argc > 3 ? argv[3] : "7");
    const double h = 0.02;
    for (int k = 0; k < 3000; ++k) {
        if (fmi2DoStep(c, k * h, h, fmi2True) > fmi2Warning) { fprintf(stderr, "step\n"); return 6; }
    }
    fmi2Real theta_g = 0.0;
    fmi2GetReal(c, &vr_theta_g, 1, &theta_g);
    printf("%.17g\n", theta_g);
    fmi2Terminate(c);
    fmi2FreeInstance(c);
    return 0;
}
