/* GliderPlant, native flavor: the C counterpart of glider_plant/slave.py.
 *
 * The variables are generated from the Python slave's table (GliderPlant_vars.h); the
 * equations are plant_model.c's (the twins of glider_plant/model.py). The native back end
 * (backend_native.c) checks the parameters' ranges and the inputs before this is called.
 */
#include "glider_fp.h" /* first: no fused multiply-add (see there) */
#include <math.h>
#include <stdio.h>

#include "GliderPlant_vars.h"
#include "plant_model.h"

typedef struct {
    GliderPlantVars v; /* first: the variable table's offsets are into it */
    GliderParams p;
    PitchSensor sensor;
    double x[6]; /* V, theta_g, alpha, omega2, x, z */
} PlantData;

static void publish(PlantData *d) {
    GliderPlantVars *v = &d->v;
    v->V = d->x[0];
    v->theta_g = d->x[1];
    v->alpha = d->x[2];
    v->omega2 = d->x[3];
    v->x = d->x[4];
    v->z = d->x[5];
    v->theta = v->theta_g + v->alpha;
    v->theta_meas = pitch_sensor_measure(&d->sensor, v->theta);
}

static int initialize(void *data, char *msg, size_t size) {
    PlantData *d = data;
    GliderPlantVars *v = &d->v;
    GLIDER_PARAMS_FROM(&d->p, v);
    if (glider_params_check(&d->p, msg, size)) return NATIVE_REFUSED;
    if (pitch_sensor_init(&d->sensor, v->noise_std, (uint32_t)v->noise_seed, msg, size))
        return NATIVE_REFUSED;
    if (fabs(v->delta_0) > v->delta_max) {
        char r[64];
        py_float_repr(v->delta_0, r, sizeof r);
        snprintf(msg, size, "delta_0 = %s is invalid: expected |delta_0| <= delta_max", r);
        return NATIVE_REFUSED;
    }
    d->x[0] = v->V_0;
    d->x[1] = v->theta_g_0;
    d->x[2] = v->alpha_0;
    d->x[3] = v->omega2_0;
    d->x[4] = v->x_0;
    d->x[5] = v->z_0;
    v->delta = v->delta_0;
    publish(d);
    return NATIVE_OK;
}

static int step(void *data, double t, double time, double h, char *msg, size_t size, char *warning,
                size_t wsize) {
    PlantData *d = data;
    GliderPlantVars *v = &d->v;
    double cmd = glider_saturate(v->delta_cmd, v->delta_max);
    double dist[3];
    char stall[512], tg[64];
    (void)time, (void)warning, (void)wsize;
    dist[0] = v->F_x;
    dist[1] = v->F_z;
    dist[2] = v->M_y;
    if (glider_plant_step(d->x, &v->delta, cmd, h, &d->p, v->tau_servo, dist, v->h_max, stall,
                          sizeof stall)) {
        py_float_g(t, 6, tg, sizeof tg);
        snprintf(msg, size, "%s at t = %s s", stall, tg);
        return NATIVE_DISCARD;
    }
    publish(d);
    return NATIVE_OK;
}

/* The arguments of glider_plant_derivatives and glider_plant_jacobian now: the state
 * (before initialisation the one the parameters give, as the Python slave's _point) */
typedef struct {
    const double *x;
    double delta;
    double dist[3];
    GliderParams p;
} PlantPoint;

static void point(PlantData *d, int initialized, double x0[6], PlantPoint *pt) {
    GliderPlantVars *v = &d->v;
    if (initialized) {
        pt->x = d->x;
        pt->delta = v->delta;
        pt->p = d->p;
    } else {
        x0[0] = v->V_0;
        x0[1] = v->theta_g_0;
        x0[2] = v->alpha_0;
        x0[3] = v->omega2_0;
        x0[4] = v->x_0;
        x0[5] = v->z_0;
        pt->x = x0;
        pt->delta = v->delta_0;
        GLIDER_PARAMS_FROM(&pt->p, v);
    }
    pt->dist[0] = v->F_x;
    pt->dist[1] = v->F_z;
    pt->dist[2] = v->M_y;
}

/* the state derivatives (computed variables), brought up to date before they are read */
static void update(void *data, double time, int initialized) {
    PlantData *d = data;
    GliderPlantVars *v = &d->v;
    double x0[6], der[GP_NSTATES];
    PlantPoint pt;
    (void)time;
    point(d, initialized, x0, &pt);
    glider_plant_derivatives(pt.x, pt.delta, v->delta_cmd, pt.dist, &pt.p, v->tau_servo,
                             v->delta_max, der);
    v->der_V = der[0];
    v->der_theta_g = der[1];
    v->der_alpha = der[2];
    v->der_omega2 = der[3];
    v->der_x = der[4];
    v->der_z = der[5];
    v->der_delta = der[6];
}

/* the generated table's Jacobian is the model's */
typedef char jacobian_shape_check[GLIDERPLANT_JAC_NROWS == GP_JAC_ROWS &&
                                          GLIDERPLANT_JAC_NCOLS == GP_JAC_COLS
                                      ? 1
                                      : -1];

static void jacobian(void *data, int initialized, double *J) {
    PlantData *d = data;
    double x0[6];
    PlantPoint pt;
    point(d, initialized, x0, &pt);
    glider_plant_jacobian(pt.x, pt.delta, d->v.delta_cmd, pt.dist, &pt.p, d->v.tau_servo,
                          d->v.delta_max, J);
}

static int valid(const void *data) {
    const PlantData *d = data;
    return d->sensor.rng.index >= 0 && d->sensor.rng.index <= 624;
}

const NativeModel GLIDER_NATIVE_MODEL = {
    MODEL_IDENTIFIER, GLIDERPLANT_VARS, GLIDERPLANT_NVARS, GLIDERPLANT_TYPES, GLIDERPLANT_NAMES,
    sizeof(PlantData), initialize, step, update, valid,
    GLIDERPLANT_REAL_INPUTS, GLIDERPLANT_NREAL_INPUTS, GLIDERPLANT_JAC_ROW, GLIDERPLANT_JAC_COL,
    GLIDERPLANT_JAC_NROWS, GLIDERPLANT_JAC_NCOLS, jacobian,
};
