/* Observer equations in C99: the twin of glider_observer.filter, glider_observer.model and
 * glider_observer.riccati, bit-identical to them on linux64 (see plant_model.h for the rules).
 */
#ifndef GLIDER_OBSERVER_MODEL_H
#define GLIDER_OBSERVER_MODEL_H

#include <stddef.h>

#include "plant_model.h"

#ifdef __cplusplus
extern "C" {
#endif

/* butterworth_coefficients(f_sample, f_cutoff) -> c = (a0, a1, a2, b1, b2): 0 ok, else 1 and
 * the ParameterError text */
int butterworth_coefficients(double f_sample, double f_cutoff, double c[5], char *msg, size_t n);

/* ButterworthFilter: hist = (x(n-1), x(n-2), y(n-1), y(n-2)), primed at the first sample */
typedef struct {
    double c[5];
    double hist[4];
    int primed;
} Butterworth;

int butterworth_init(Butterworth *f, double f_sample, double f_cutoff, char *msg, size_t n);
double butterworth_filter(Butterworth *f, double x);

/* linearization(p, eq): A_o */
void observer_linearization(const GliderParams *p, const GliderEquilibrium *eq, double A[4][4]);

/* Stabilizing P of A P + P A^T + Q - P G P = 0 (glider_observer.riccati.solve_filter_care,
 * n = 4, row-major 4 x 4 arrays): 0 ok, else 1 and the RiccatiError text of the failed stage */
int riccati_solve_filter_care(const double A[16], const double Q[16], const double G[16],
                              double P[16], char *msg, size_t n);

/* riccati_solution(p, R, Q) (R, Q already checked): 0 ok, else 1 and the RiccatiError text */
int observer_riccati_solution(const GliderParams *p, double R, const double Q[4], double P[4][4],
                              char *msg, size_t n);

/* observer_gain(p, R, Q) -> H: 0 ok, else 1 and the ParameterError text */
int observer_gain(const GliderParams *p, double R, const double Q[4], double H[4], char *msg,
                  size_t n);

/* observer_step: xh updated in place on success (0); on a stall (1, StallError's text) it is
 * left unchanged */
int observer_step(double xh[4], double theta, double u_delta, double h, const GliderParams *p,
                  const double H[4], double h_max, char *msg, size_t n);

#ifdef __cplusplus
}
#endif

#endif /* GLIDER_OBSERVER_MODEL_H */
