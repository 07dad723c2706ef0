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

static int valid(const void *data) {
    const PlantData *d = data;
    return d->sensor.rng.index >= 0 && d->sensor.rng.index <= 624;
}

const NativeModel GLIDER_NATIVE_MODEL = {
    MODEL_IDENTIFIER, GLIDERPLANT_VARS, GLIDERPLANT_NVARS, GLIDERPLANT_TYPES, GLIDERPLANT_NAMES,
    sizeof(PlantData), initialize, step, NULL, valid,
    GLIDERPLANT_REAL_INPUTS, GLIDERPLANT_NREAL_INPUTS,
};
