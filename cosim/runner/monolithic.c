/* The floor of the native flavor: the loop of plant, observer and controller with the
 * same C models as the native FMUs (src/<part>/<part>_model.c), called directly in one C
 * loop, no FMI. The exchange is the co-simulation's at every communication point
 * (Gauss-Seidel, simulate_monolithic's order): the sensor samples the pitch, the controller
 * acts on the estimate (or the state), the row is recorded, then the observer and the
 * plant advance over the step with those values held. Driven from
 * glider_cosim.runner.monolithic (NativeMonolithic, ctypes); its rows are bit for bit the
 * native co-simulation's (tested).
 */
#include "glider_fp.h" /* first: no fused multiply-add (see there) */

#include <stddef.h>
#include <string.h>

#include "controller_model.h"
#include "observer_model.h"
#include "plant_model.h"

/* Everything the loop starts from (the three FMUs' parameters and start values); the
 * Python side (monolithic._Setup) has the same fields in the same order. */
typedef struct {
    GliderParams plant, observer, controller;
    double V_0, theta_g_0, alpha_0, omega2_0, x_0, z_0, delta_0;
    double plant_delta_max, tau_servo, plant_h_max, noise_std, noise_seed;
    double R, Q[4], f_sample, f_cutoff, t_start, observer_h_max, theta_meas_start;
    double filter_enabled, start_at_equilibrium, V_hat_0, theta_g_hat_0, alpha_hat_0,
        omega2_hat_0;
    double law, K_c, K_P, K_I, controller_delta_max, delta_open, t_enable;
    double feedback_state;
} MonoSetup;

enum { LAW_OPEN_LOOP = 0, LAW_PASSIVITY = 1, LAW_P = 2, LAW_PI = 3 };

typedef struct {
    MonoSetup s;
    PitchSensor sensor;
    double x[6], delta; /* plant: V, theta_g, alpha, omega2, x, z; servo angle */
    double H[4], xh[4], theta_filt;
    Butterworth filter;
    GliderEquilibrium eq;
    PIController pi;
} MonoState;

size_t glider_mono_state_size(void) { return sizeof(MonoState); }

/* 0, or 1 with a message (the FMUs' own initialisation errors). */
int glider_mono_init(MonoState *m, const MonoSetup *s, char *msg, size_t size) {
    memset(m, 0, sizeof *m);
    m->s = *s;
    if (glider_params_check(&s->plant, msg, size) || glider_params_check(&s->observer, msg, size) ||
        glider_params_check(&s->controller, msg, size))
        return 1;
    if (pitch_sensor_init(&m->sensor, s->noise_std, (uint32_t)s->noise_seed, msg, size)) return 1;
    if (observer_gain(&s->observer, s->R, s->Q, m->H, msg, size)) return 1;
    if (butterworth_init(&m->filter, s->f_sample, s->f_cutoff, msg, size)) return 1;
    m->x[0] = s->V_0;
    m->x[1] = s->theta_g_0;
    m->x[2] = s->alpha_0;
    m->x[3] = s->omega2_0;
    m->x[4] = s->x_0;
    m->x[5] = s->z_0;
    m->delta = s->delta_0;
    if (s->start_at_equilibrium != 0.0) {
        GliderEquilibrium e;
        glider_equilibrium(&s->observer, &e);
        m->xh[0] = e.V;
        m->xh[1] = e.theta_g;
        m->xh[2] = e.alpha;
        m->xh[3] = 0.0;
    } else {
        m->xh[0] = s->V_hat_0;
        m->xh[1] = s->theta_g_hat_0;
        m->xh[2] = s->alpha_hat_0;
        m->xh[3] = s->omega2_hat_0;
    }
    m->theta_filt = s->theta_meas_start; /* until the first point's measurement */
    glider_equilibrium(&s->controller, &m->eq);
    pi_init(&m->pi, s->K_P, (int)s->law == LAW_PI ? s->K_I : 0.0, s->controller_delta_max);
    return 0;
}

/* Communication points k0 .. k0 + n - 1 (time k h): one row of 17 values each (the
 * columns of glider_cosim.runner.monolithic.COLUMNS), then the step to the next point,
 * except after the last. Returns the rows written (fewer when a model stops the run: the
 * plant stalls or the observer's estimate does, message in msg). */
long glider_mono_run(MonoState *m, double h, long k0, long n, int last, double *rows, char *msg,
                     size_t size) {
    const MonoSetup *s = &m->s;
    int law = (int)s->law;
    for (long j = 0; j < n; ++j) {
        long k = k0 + j;
        double t = (double)k * h;
        double *x = m->x, *xh = m->xh;
        double theta_meas = pitch_sensor_measure(&m->sensor, x[1] + x[2]);
        if (k == 0) m->theta_filt = theta_meas; /* set in Initialization Mode, passed on */
        double fb_V = s->feedback_state != 0.0 ? x[0] : xh[0];
        double fb_th = s->feedback_state != 0.0 ? x[1] : xh[1];
        int enabled = t >= s->t_enable - 1e-9;
        double cmd;
        if (!enabled || law == LAW_OPEN_LOOP)
            cmd = glider_saturate(s->delta_open, s->controller_delta_max);
        else if (law == LAW_PASSIVITY)
            cmd = passivity_law(fb_V, fb_th, s->K_c, &s->controller, &m->eq,
                                s->controller_delta_max);
        else
            cmd = pi_output(&m->pi, fb_th - m->eq.theta_g);
        double *r = rows + j * 17;
        r[0] = t;
        r[1] = theta_meas;
        r[2] = x[1] + x[2];
        r[3] = x[0];
        r[4] = x[1];
        r[5] = x[2];
        r[6] = x[3];
        r[7] = m->delta;
        r[8] = x[4];
        r[9] = x[5];
        r[10] = m->theta_filt;
        r[11] = xh[0];
        r[12] = xh[1];
        r[13] = xh[2];
        r[14] = xh[3];
        r[15] = xh[1] + xh[2];
        r[16] = cmd;
        if (last && j == n - 1) return n;
        if (t < s->t_start - 1e-9) {
            m->theta_filt = theta_meas;
        } else {
            m->theta_filt = s->filter_enabled != 0.0 ? butterworth_filter(&m->filter, theta_meas)
                                                     : theta_meas;
            if (observer_step(xh, m->theta_filt, s->observer.K_udelta * cmd, h, &s->observer,
                              m->H, s->observer_h_max, msg, size))
                return j + 1;
        }
        if (law == LAW_PI && enabled) pi_update(&m->pi, fb_th - m->eq.theta_g, h);
        double dist[3] = {0.0, 0.0, 0.0};
        if (glider_plant_step(x, &m->delta, glider_saturate(cmd, s->plant_delta_max), h, &s->plant,
                              s->tau_servo, dist, s->plant_h_max, msg, size))
            return j + 1;
    }
    return n;
}
