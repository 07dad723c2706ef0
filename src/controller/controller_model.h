/* Control laws in C99: the twin of glider_controller.laws, bit-identical to it on linux64
 * (see plant_model.h for the rules).
 */
#ifndef GLIDER_CONTROLLER_MODEL_H
#define GLIDER_CONTROLLER_MODEL_H

#include "plant_model.h"

#ifdef __cplusplus
extern "C" {
#endif

/* passivity_output(V, theta_g, p, eq): y_r of Eqs. (23)-(25) */
double passivity_output(double V, double theta_g, const GliderParams *p,
                        const GliderEquilibrium *eq);

/* passivity_law(V, theta_g, K_c, p, eq, delta_max): saturated tail command, rad */
double passivity_law(double V, double theta_g, double K_c, const GliderParams *p,
                     const GliderEquilibrium *eq, double delta_max);

/* PIController: integral in rad s, starts at 0 */
typedef struct {
    double K_P, K_I, delta_max, integral;
} PIController;

/* PIController(K_P, K_I, delta_max) */
void pi_init(PIController *c, double K_P, double K_I, double delta_max);
/* PIController.output(error) */
double pi_output(const PIController *c, double error);
/* PIController.update(error, h) */
void pi_update(PIController *c, double error, double h);

#ifdef __cplusplus
}
#endif

#endif /* GLIDER_CONTROLLER_MODEL_H */
