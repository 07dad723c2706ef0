/* Glider plant equations in C99: the twin of glider_plant.model / glider_plant.params.
 *
 * Every function mirrors its Python counterpart operation by operation (same evaluation
 * order, same libm calls), so on linux64 (glibc libm, which CPython's math calls) the
 * results are bit-identical to the Python model. Compile with -std=c99 -ffp-contract=off,
 * never -ffast-math. No heap, no global or static mutable state: everything lives in
 * caller-provided structs. Messages are written with snprintf into caller buffers and
 * equal the Python exceptions' texts byte for byte.
 */
#ifndef GLIDER_PLANT_MODEL_H
#define GLIDER_PLANT_MODEL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* GLIDER_SINCOS(x, &s, &c): s = sin(x), c = cos(x). On glibc one sincos() call, whose
 * code is sin's and cos's (the same bits: 0 differences in 20 million arguments, and the
 * Python model's math.sin/math.cos agree bit for bit in the tests), in 60 % of the two
 * calls' time; elsewhere (other C libraries) the two calls. */
#if defined(__GLIBC__)
void sincos(double x, double *s, double *c);
#define GLIDER_SINCOS(x, s, c) sincos((x), (s), (c))
#else
#define GLIDER_SINCOS(x, s, c) (*(s) = sin(x), *(c) = cos(x))
#endif

#define GP_V_STALL 1e-3
#define GP_SERVO_DEVIATION_REF 7e-3
/* math.pi (the literal parses to the same double) */
#define GP_PI 3.141592653589793

/* field order = MODEL_CONSTANTS order */
typedef struct {
    double m, J2, K_L0, K_L, K_D0, K_D, K_q, K_M0, K_M, K_Fdelta, K_udelta, m0, g;
} GliderParams;

typedef struct {
    double V, theta_g, alpha, omega2, K_De, K_Le;
} GliderEquilibrium;

/* The model constants from any struct with fields of the same names (a component's
 * generated variables), as GliderParams.from_mapping does in Python. */
#define GLIDER_PARAMS_FROM(p, v)                                                            \
    do {                                                                                    \
        (p)->m = (v)->m;                                                                    \
        (p)->J2 = (v)->J2;                                                                  \
        (p)->K_L0 = (v)->K_L0;                                                              \
        (p)->K_L = (v)->K_L;                                                                \
        (p)->K_D0 = (v)->K_D0;                                                              \
        (p)->K_D = (v)->K_D;                                                                \
        (p)->K_q = (v)->K_q;                                                                \
        (p)->K_M0 = (v)->K_M0;                                                              \
        (p)->K_M = (v)->K_M;                                                                \
        (p)->K_Fdelta = (v)->K_Fdelta;                                                      \
        (p)->K_udelta = (v)->K_udelta;                                                      \
        (p)->m0 = (v)->m0;                                                                  \
        (p)->g = (v)->g;                                                                    \
    } while (0)

/* GliderParams.__post_init__'s consistency check (K_L0 + K_L*alpha_e > 0): 0 ok, else 1 and
 * the ParameterError text. The per-constant range checks are done elsewhere. */
int glider_params_check(const GliderParams *p, char *msg, size_t n);

/* equilibrium(p) */
void glider_equilibrium(const GliderParams *p, GliderEquilibrium *eq);

/* rhs(V, th, al, w, u_delta, constants(p), F_x, F_z, M_y): Eqs. (6)-(9) */
void glider_rhs(double V, double th, double al, double w, double u_delta, const GliderParams *p,
                double F_x, double F_z, double M_y, double out[4]);

/* rhs_jacobian(V, th, al, w, u_delta, constants(p), F_x, F_z, M_y): the exact partial
 * derivatives of Eqs. (6)-(9), 4 rows (dV, dth, dal, dw) x 8 columns (V, th, al, w,
 * u_delta, F_x, F_z, M_y), row-major */
void glider_rhs_jacobian(double V, double th, double al, double w, double u_delta,
                         const GliderParams *p, double F_x, double F_z, double M_y,
                         double out[32]);

/* the plant's states (V, theta_g, alpha, omega2, x, z, delta) and inputs (delta_cmd, F_x,
 * F_z, M_y): GP_NSTATES + GP_NINPUTS columns of glider_plant_jacobian */
#define GP_NSTATES 7
#define GP_NINPUTS 4
#define GP_JAC_ROWS 8
#define GP_JAC_COLS (GP_NSTATES + GP_NINPUTS)

/* plant_jacobian(x, delta, delta_cmd, disturbance, p, tau_servo, delta_max): rows the
 * states' time derivatives and the pitch theta_g + alpha, row-major */
void glider_plant_jacobian(const double x[6], double delta, double delta_cmd,
                           const double disturbance[3], const GliderParams *p, double tau_servo,
                           double delta_max, double out[GP_JAC_ROWS * GP_JAC_COLS]);

/* plant_derivatives(...): the states' time derivatives */
void glider_plant_derivatives(const double x[6], double delta, double delta_cmd,
                              const double disturbance[3], const GliderParams *p,
                              double tau_servo, double delta_max, double out[GP_NSTATES]);

/* servo_response(delta0, command, tau, dt) */
double glider_servo_response(double delta0, double command, double tau, double dt);

/* saturate(value, limit) */
double glider_saturate(double value, double limit);

/* check_state(x): 0 ok; 1 stalled (V <= V_STALL or a non-finite entry), message = StallError's */
int glider_check_state(const double *x, int n, char *msg, size_t size);

/* plant_step: x = (V, theta_g, alpha, omega2, x, z) and *delta are updated in place on success
 * (return 0); on a stall they are left unchanged and 1 is returned with StallError's text. */
int glider_plant_step(double x[6], double *delta, double delta_cmd, double h,
                      const GliderParams *p, double tau_servo, const double disturbance[3],
                      double h_max, char *msg, size_t size);

/* math.hypot(x, y) as CPython >= 3.10 computes it (vector_norm, not libm's hypot) */
double py_hypot(double x, double y);

/* Python's repr(x) of a float: shortest round-trip digits, Python's layout */
void py_float_repr(double x, char *buf, size_t n);
/* Python's format(x, '.{prec}g') ('g' = '.6g'), with nan/inf spelled like Python */
void py_float_g(double x, int prec, char *buf, size_t n);

/* CPython's random.Random, bit for bit */
typedef struct {
    uint32_t mt[624];
    int index;
    int has_gauss_next;
    double gauss_next;
} PyRandom;

/* = random.Random(seed) for 0 <= seed < 2**32 */
void pyrandom_seed(PyRandom *r, uint32_t seed);
/* random.Random.random(): genrand_res53 */
double pyrandom_random(PyRandom *r);
/* random.Random.gauss(mu, sigma) with its cached pair */
double pyrandom_gauss(PyRandom *r, double mu, double sigma);

/* PitchSensor: theta + gauss(0, noise_std), or theta unchanged when noise_std == 0 */
typedef struct {
    double noise_std;
    PyRandom rng;
} PitchSensor;

/* PitchSensor(noise_std, seed): 0 ok; 1 and the ParameterError text if noise_std is invalid */
int pitch_sensor_init(PitchSensor *s, double noise_std, uint32_t seed, char *msg, size_t n);
double pitch_sensor_measure(PitchSensor *s, double theta);

#ifdef __cplusplus
}
#endif

#endif /* GLIDER_PLANT_MODEL_H */
