/* GliderController, native flavor: the C counterpart of glider_controller/slave.py.
 *
 * The variables are generated from the Python slave's table (GliderController_vars.h);
 * the laws are controller_model.c's. delta_cmd has direct feedthrough: it is computed
 * from the inputs when it is read (update()).
 */
#include "GliderController_vars.h"
#include "controller_model.h"

typedef struct {
    GliderControllerVars v; /* first: the variable table's offsets are into it */
    GliderParams p;
    GliderEquilibrium eq;
    PIController pi;
} ControllerData;

enum { LAW_OPEN_LOOP = 0, LAW_PASSIVITY = 1, LAW_P = 2, LAW_PI = 3 };

static void params_from(const GliderControllerVars *v, GliderParams *p) {
    p->m = v->m;
    p->J2 = v->J2;
    p->K_L0 = v->K_L0;
    p->K_L = v->K_L;
    p->K_D0 = v->K_D0;
    p->K_D = v->K_D;
    p->K_q = v->K_q;
    p->K_M0 = v->K_M0;
    p->K_M = v->K_M;
    p->K_Fdelta = v->K_Fdelta;
    p->K_udelta = v->K_udelta;
    p->m0 = v->m0;
    p->g = v->g;
}

static int initialize(void *data, char *msg, size_t size) {
    ControllerData *d = data;
    params_from(&d->v, &d->p);
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
};
