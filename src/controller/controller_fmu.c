/* GliderController, native flavor: the C counterpart of glider_controller/slave.py.
 *
 * The variables are generated from the Python slave's table (GliderController_vars.h);
 * the laws are controller_model.c's. delta_cmd has direct feedthrough: it is computed
 * from the inputs when it is read (update()).
 */
#include "glider_fp.h" /* first: no fused multiply-add (see there) */
#include "GliderController_vars.h"
#include "controller_model.h"

typedef struct {
    GliderControllerVars v; /* first: the variable table's offsets are into it */
    GliderParams p;
    GliderEquilibrium eq;
    PIController pi;
} ControllerData;

enum { LAW_OPEN_LOOP = 0, LAW_PASSIVITY = 1, LAW_P = 2, LAW_PI = 3 };

static int initialize(void *data, char *msg, size_t size) {
    ControllerData *d = data;
    GLIDER_PARAMS_FROM(&d->p, &d->v);
    if (glider_params_check(&d->p, msg, size)) return NATIVE_REFUSED;
    glider_equilibrium(&d->p, &d->eq);
    pi_init(&d->pi, d->v.K_P, d->v.K_I, d->v.delta_max);
    return NATIVE_OK;
}

/* The tail command (rad) for the current inputs and time (the slave's command()). */
static void update(void *data, double time, int initialized) {
    ControllerData *d = data;
    GliderControllerVars *v = &d->v;
    if (v->law == LAW_OPEN_LOOP || !initialized || time < v->t_enable - 1e-9) {
        v->delta_cmd = glider_saturate(v->delta_open, v->delta_max);
    } else if (v->law == LAW_PASSIVITY) {
        v->delta_cmd = passivity_law(v->V_hat, v->theta_g_hat, v->K_c, &d->p, &d->eq,
                                     v->delta_max);
    } else {
        d->pi.K_P = v->K_P;
        d->pi.K_I = v->law == LAW_PI ? v->K_I : 0.0;
        v->delta_cmd = pi_output(&d->pi, v->theta_g_hat - d->eq.theta_g);
    }
}

static int step(void *data, double t, double time, double h, char *msg, size_t size, char *warning,
                size_t wsize) {
    ControllerData *d = data;
    GliderControllerVars *v = &d->v;
    (void)t, (void)msg, (void)size, (void)warning, (void)wsize;
    if (v->law == LAW_PI && time >= v->t_enable - 1e-9) {
        d->pi.K_P = v->K_P;
        d->pi.K_I = v->K_I;
        pi_update(&d->pi, v->theta_g_hat - d->eq.theta_g, h);
    }
    return NATIVE_OK;
}

const NativeModel GLIDER_NATIVE_MODEL = {
    MODEL_IDENTIFIER,     GLIDERCONTROLLER_VARS, GLIDERCONTROLLER_NVARS, GLIDERCONTROLLER_TYPES,
    GLIDERCONTROLLER_NAMES, sizeof(ControllerData), initialize, step, update, NULL,
    GLIDERCONTROLLER_REAL_INPUTS, GLIDERCONTROLLER_NREAL_INPUTS, GLIDERCONTROLLER_JAC_ROW, GLIDERCONTROLLER_JAC_COL,
    GLIDERCONTROLLER_JAC_NROWS, GLIDERCONTROLLER_JAC_NCOLS, NULL,
};
