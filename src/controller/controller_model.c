/* Control laws in C99: the twin of glider_controller.laws (see controller_model.h). */
#include "glider_fp.h" /* first: no fused multiply-add (see there) */
#include "controller_model.h"

#include <math.h>

double passivity_output(double V, double theta_g, const GliderParams *p,
                        const GliderEquilibrium *eq)
{
    double v = (V - eq->V) / eq->V;
    double th = theta_g - eq->theta_g;
    double k = p->K_Fdelta / eq->K_De;
    double one_v = 1.0 + v;
    double s_al, c_al, s_th, c_th;
    GLIDER_SINCOS(eq->alpha, &s_al, &c_al);
    GLIDER_SINCOS(th, &s_th, &c_th);
    double g1 = k * one_v * one_v * s_al;
    double g2 = k * one_v * c_al;
    return (one_v * one_v - c_th) * g1 + one_v * s_th * g2;
}

double passivity_law(double V, double theta_g, double K_c, const GliderParams *p,
                     const GliderEquilibrium *eq, double delta_max)
{
    double u = -atan(passivity_output(V, theta_g, p, eq)) / K_c;
    return glider_saturate(u / p->K_udelta, delta_max);
}

void pi_init(PIController *c, double K_P, double K_I, double delta_max)
{
    c->K_P = K_P;
    c->K_I = K_I;
    c->delta_max = delta_max;
    c->integral = 0.0;
}

double pi_output(const PIController *c, double error)
{
    return glider_saturate(-(c->K_P * error + c->K_I * c->integral), c->delta_max);
}

void pi_update(PIController *c, double error, double h)
{
    double raw;
    int winding_up;
    if (c->K_I == 0.0) {
        return;
    }
    raw = -(c->K_P * error + c->K_I * c->integral);
    winding_up = (raw > c->delta_max && -error > 0.0) || (raw < -c->delta_max && -error < 0.0);
    if (!winding_up) {
        c->integral += error * h;
    }
}
