/* GliderObserver, native flavor: the C counterpart of glider_observer/slave.py.
 *
 * The variables are generated from the Python slave's table (GliderObserver_vars.h); the
 * equations are observer_model.c's (Butterworth pre-filter, observer, Riccati gain) and
 * plant_model.c's (the glider model the observer runs).
 */
#include "glider_fp.h" /* first: no fused multiply-add (see there) */
#include <math.h>
#include <stdio.h>

#include "GliderObserver_vars.h"
#include "observer_model.h"

typedef struct {
    GliderObserverVars v; /* first: the variable table's offsets are into it */
    GliderParams p;
    double H[4];
    Butterworth filter;
    double xh[4]; /* estimate V, theta_g, alpha, omega2 */
    int step_warned; /* the step's mismatch with f_sample was reported */
} ObserverData;

static void publish(ObserverData *d) {
    GliderObserverVars *v = &d->v;
    v->V_hat = d->xh[0];
    v->theta_g_hat = d->xh[1];
    v->alpha_hat = d->xh[2];
    v->omega2_hat = d->xh[3];
    v->theta_hat = v->theta_g_hat + v->alpha_hat;
}

static int initialize(void *data, char *msg, size_t size) {
    ObserverData *d = data;
    GliderObserverVars *v = &d->v;
    double Q[4];
    GLIDER_PARAMS_FROM(&d->p, v);
    if (glider_params_check(&d->p, msg, size)) return NATIVE_REFUSED;
    Q[0] = v->Q_V;
    Q[1] = v->Q_theta_g;
    Q[2] = v->Q_alpha;
    Q[3] = v->Q_omega2;
    if (observer_gain(&d->p, v->R, Q, d->H, msg, size)) return NATIVE_REFUSED;
    if (butterworth_init(&d->filter, v->f_sample, v->f_cutoff, msg, size)) return NATIVE_REFUSED;
    if (v->start_at_equilibrium) {
        GliderEquilibrium e;
        glider_equilibrium(&d->p, &e);
        d->xh[0] = e.V;
        d->xh[1] = e.theta_g;
        d->xh[2] = e.alpha;
        d->xh[3] = 0.0;
    } else {
        d->xh[0] = v->V_hat_0;
        d->xh[1] = v->theta_g_hat_0;
        d->xh[2] = v->alpha_hat_0;
        d->xh[3] = v->omega2_hat_0;
    }
    v->theta_filt = v->theta_meas;
    d->step_warned = 0;
    publish(d);
    return NATIVE_OK;
}

static int step(void *data, double t, double time, double h, char *msg, size_t size, char *warning,
                size_t wsize) {
    ObserverData *d = data;
    GliderObserverVars *v = &d->v;
    char stall[512], tg[64];
    (void)time;
    if (v->filter_enabled && !d->step_warned && fabs(h * v->f_sample - 1.0) > 1e-9) {
        /* the pre-filter runs once per step: its coefficients assume 1/step = f_sample */
        char hs[64], fs[64], rs[64];
        d->step_warned = 1;
        py_float_g(h, 6, hs, sizeof hs);
        py_float_g(v->f_sample, 6, fs, sizeof fs);
        py_float_g(1.0 / h, 6, rs, sizeof rs);
        snprintf(warning, wsize,
                 "communication step %s s does not match f_sample = %s Hz (1/step = %s Hz): "
                 "the pre-filter runs once per step, its coefficients assume f_sample",
                 hs, fs, rs);
    }
    if (t < v->t_start - 1e-9) { /* not initialised yet (Sec. 5.2: 2 s after release) */
        v->theta_filt = v->theta_meas;
        return NATIVE_OK;
    }
    v->theta_filt = v->filter_enabled ? butterworth_filter(&d->filter, v->theta_meas)
                                      : v->theta_meas;
    if (observer_step(d->xh, v->theta_filt, d->p.K_udelta * v->delta_cmd, h, &d->p, d->H,
                      v->h_max, stall, sizeof stall)) {
        py_float_g(t, 6, tg, sizeof tg);
        snprintf(msg, size, "observer estimate %s at t = %s s", stall, tg);
        return NATIVE_DISCARD;
    }
    publish(d);
    return NATIVE_OK;
}

static int valid(const void *data) {
    const ObserverData *d = data;
    return (d->filter.primed == 0 || d->filter.primed == 1) &&
           (d->step_warned == 0 || d->step_warned == 1);
}

const NativeModel GLIDER_NATIVE_MODEL = {
    MODEL_IDENTIFIER,   GLIDEROBSERVER_VARS, GLIDEROBSERVER_NVARS, GLIDEROBSERVER_TYPES,
    GLIDEROBSERVER_NAMES, sizeof(ObserverData), initialize, step, NULL, valid,
    GLIDEROBSERVER_REAL_INPUTS, GLIDEROBSERVER_NREAL_INPUTS, GLIDEROBSERVER_JAC_ROW, GLIDEROBSERVER_JAC_COL,
    GLIDEROBSERVER_JAC_NROWS, GLIDEROBSERVER_JAC_NCOLS, NULL,
};
