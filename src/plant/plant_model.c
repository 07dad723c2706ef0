/* Glider plant equations in C99: the twin of glider_plant.model (see plant_model.h). */
#include "glider_fp.h" /* first: no fused multiply-add (see there) */
#include "plant_model.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- Python number formatting ------------------------------------------------------- */

/* At a power of two the round-trip interval is asymmetric: the correctly rounded p-digit
 * string may miss it while its neighbour one unit in the last digit (on the wider side)
 * round-trips, and that neighbour is what Python's shortest repr gives. If so, rewrite tmp
 * (a "%.*e" string) to that neighbour and return 1. */
static int py_repr_neighbor(char *tmp, double x)
{
    char cand[48];
    char *e = strchr(tmp, 'e');
    int step, last, i;
    if (e == NULL || e == tmp) {
        return 0;
    }
    last = (int)(e - tmp) - 1;
    for (step = -1; step <= 1; step += 2) {
        int carry = step;
        memcpy(cand, tmp, strlen(tmp) + 1);
        for (i = last; i >= 0 && carry != 0; i--) {
            int d;
            if (cand[i] < '0' || cand[i] > '9') {
                continue;
            }
            d = cand[i] - '0' + carry;
            carry = 0;
            if (d < 0) {
                d = 9;
                carry = -1;
            } else if (d > 9) {
                d = 0;
                carry = 1;
            }
            cand[i] = (char)('0' + d);
        }
        /* skip candidates whose leading digit over- or underflowed (fewer or more digits) */
        if (carry != 0 || cand[cand[0] == '-' ? 1 : 0] == '0') {
            continue;
        }
        if (strtod(cand, NULL) == x) {
            memcpy(tmp, cand, strlen(cand) + 1);
            return 1;
        }
    }
    return 0;
}

void py_float_repr(double x, char *buf, size_t n)
{
    char tmp[48];
    char digits[24];
    char out[64];
    int p, nd = 0, exp10, neg, decpt, k = 0, i;
    const char *s;
    char *end;

    if (n == 0) {
        return;
    }
    if (isnan(x)) {
        snprintf(buf, n, "nan");
        return;
    }
    if (isinf(x)) {
        snprintf(buf, n, "%s", x > 0 ? "inf" : "-inf");
        return;
    }
    for (p = 0; p < 17; p++) {
        snprintf(tmp, sizeof tmp, "%.*e", p, x);
        if (strtod(tmp, NULL) == x || py_repr_neighbor(tmp, x)) {
            break;
        }
    }
    s = tmp;
    neg = (*s == '-');
    if (neg) {
        s++;
    }
    while (*s && *s != 'e') {
        if (*s >= '0' && *s <= '9' && nd < (int)sizeof digits - 1) {
            digits[nd++] = *s;
        }
        s++;
    }
    exp10 = (*s == 'e') ? (int)strtol(s + 1, &end, 10) : 0;
    while (nd > 1 && digits[nd - 1] == '0') {
        nd--;
    }
    digits[nd] = '\0';
    if (neg) {
        out[k++] = '-';
    }
    if (exp10 >= -4 && exp10 < 16) {
        decpt = exp10 + 1;
        if (decpt <= 0) {
            out[k++] = '0';
            out[k++] = '.';
            for (i = 0; i < -decpt; i++) {
                out[k++] = '0';
            }
            for (i = 0; i < nd; i++) {
                out[k++] = digits[i];
            }
        } else if (decpt >= nd) {
            for (i = 0; i < nd; i++) {
                out[k++] = digits[i];
            }
            for (i = nd; i < decpt; i++) {
                out[k++] = '0';
            }
            out[k++] = '.';
            out[k++] = '0';
        } else {
            for (i = 0; i < nd; i++) {
                if (i == decpt) {
                    out[k++] = '.';
                }
                out[k++] = digits[i];
            }
        }
        out[k] = '\0';
    } else {
        out[k++] = digits[0];
        if (nd > 1) {
            out[k++] = '.';
            for (i = 1; i < nd; i++) {
                out[k++] = digits[i];
            }
        }
        snprintf(out + k, sizeof out - (size_t)k, "e%c%02d", exp10 < 0 ? '-' : '+',
                 exp10 < 0 ? -exp10 : exp10);
    }
    snprintf(buf, n, "%s", out);
}

void py_float_g(double x, int prec, char *buf, size_t n)
{
    if (isnan(x)) {
        snprintf(buf, n, "nan");
    } else if (isinf(x)) {
        snprintf(buf, n, "%s", x > 0 ? "inf" : "-inf");
    } else {
        snprintf(buf, n, "%.*g", prec, x);
    }
}

/* ---- math.hypot: CPython's vector_norm for two coordinates -------------------------- */

typedef struct {
    double hi, lo;
} PyDoubleLength;

static PyDoubleLength dl_fast_sum(double a, double b)
{
    PyDoubleLength r;
    double x = a + b;
    double z = x - a;
    double y = b - z;
    r.hi = x;
    r.lo = y;
    return r;
}

static PyDoubleLength dl_split(double x)
{
    PyDoubleLength r;
    double t = x * 134217729.0; /* Veltkamp constant 2**27 + 1 */
    double hi = t - (t - x);
    r.hi = hi;
    r.lo = x - hi;
    return r;
}

/* exact product (Dekker); equal to CPython's fma variant for the scaled, normal operands */
static PyDoubleLength dl_mul(double x, double y)
{
    PyDoubleLength xx = dl_split(x);
    PyDoubleLength yy = dl_split(y);
    PyDoubleLength r;
    double p = xx.hi * yy.hi;
    double q = xx.hi * yy.lo + xx.lo * yy.hi;
    double z = p + q;
    r.hi = z;
    r.lo = p - z + q + xx.lo * yy.lo;
    return r;
}

static double vector_norm(int n, double *vec, double max, int found_nan)
{
    double x, h, scale, csum = 1.0, frac1 = 0.0, frac2 = 0.0;
    PyDoubleLength pr, sm;
    int max_e, i;

    if (isinf(max)) {
        return max;
    }
    if (found_nan) {
        return NAN;
    }
    if (max == 0.0 || n <= 1) {
        return max;
    }
    frexp(max, &max_e);
    if (max_e < -1023) {
        for (i = 0; i < n; i++) {
            vec[i] /= DBL_MIN;
        }
        return DBL_MIN * vector_norm(n, vec, max / DBL_MIN, found_nan);
    }
    scale = ldexp(1.0, -max_e);
    for (i = 0; i < n; i++) {
        x = vec[i];
        x *= scale;
        pr = dl_mul(x, x);
        sm = dl_fast_sum(csum, pr.hi);
        csum = sm.hi;
        frac1 += pr.lo;
        frac2 += sm.lo;
    }
    h = sqrt(csum - 1.0 + (frac1 + frac2));
    pr = dl_mul(-h, h);
    sm = dl_fast_sum(csum, pr.hi);
    csum = sm.hi;
    frac1 += pr.lo;
    frac2 += sm.lo;
    x = csum - 1.0 + (frac1 + frac2);
    h += x / (2.0 * h);
    return h / scale;
}

double py_hypot(double x, double y)
{
    double vec[2];
    double max = 0.0;
    int found_nan;
    vec[0] = fabs(x);
    vec[1] = fabs(y);
    found_nan = isnan(vec[0]) || isnan(vec[1]);
    if (vec[0] > max) {
        max = vec[0];
    }
    if (vec[1] > max) {
        max = vec[1];
    }
    return vector_norm(2, vec, max, found_nan);
}

/* ---- parameters and equilibrium ----------------------------------------------------- */

int glider_params_check(const GliderParams *p, char *msg, size_t n)
{
    double alpha_e = -p->K_M0 / p->K_M;
    double k_le = p->K_L0 + p->K_L * alpha_e;
    char r[40];
    if (!(k_le > 0.0)) {
        py_float_repr(k_le, r, sizeof r);
        snprintf(msg, n,
                 "K_L0 + K_L*alpha_e = %s is invalid: expected > 0 "
                 "(no descending steady glide otherwise)",
                 r);
        return 1;
    }
    return 0;
}

void glider_equilibrium(const GliderParams *p, GliderEquilibrium *eq)
{
    double alpha_e = -p->K_M0 / p->K_M;
    double k_de = p->K_D0 + p->K_D * pow(alpha_e, 2.0);
    double k_le = p->K_L0 + p->K_L * alpha_e;
    double theta_ge = atan(-k_de / k_le);
    double v_e = sqrt(fabs(p->m0) * p->g / py_hypot(k_de, k_le));
    eq->V = v_e;
    eq->theta_g = theta_ge;
    eq->alpha = alpha_e;
    eq->omega2 = 0.0;
    eq->K_De = k_de;
    eq->K_Le = k_le;
}

/* ---- right-hand side ---------------------------------------------------------------- */

/* rhs() with m0g = m0 * g computed once by the caller, as constants(p) does; sc_th gets
 * sin(th) and cos(th) (the position's integration needs them too) */
static void rhs_c(double V, double th, double al, double w, double u_delta, const GliderParams *p,
                  double m0g, double F_x, double F_z, double M_y, double out[4], double sc_th[2])
{
    double V2 = V * V;
    double s_th, c_th, s_al, c_al;
    GLIDER_SINCOS(th, &s_th, &c_th);
    GLIDER_SINCOS(al, &s_al, &c_al);
    double lift = (p->K_L0 + p->K_L * al) * V2;
    double drag = (p->K_D0 + p->K_D * al * al) * V2;
    double f_delta = p->K_Fdelta * V2 * u_delta;
    double f_v = F_x * c_th - F_z * s_th;
    double f_n = -F_x * s_th - F_z * c_th;
    double dV = (-m0g * s_th - drag + f_delta * s_al + f_v) / p->m;
    double dth = (-m0g * c_th + lift + f_delta * c_al + f_n) / (p->m * V);
    double dw = ((p->K_M0 + p->K_M * al + p->K_q * w - p->K_M * u_delta) * V2 + M_y) / p->J2;
    out[0] = dV;
    out[1] = dth;
    out[2] = w - dth;
    out[3] = dw;
    sc_th[0] = s_th;
    sc_th[1] = c_th;
}

void glider_rhs(double V, double th, double al, double w, double u_delta, const GliderParams *p,
                double F_x, double F_z, double M_y, double out[4])
{
    double m0g = p->m0 * p->g;
    double sc_th[2];
    rhs_c(V, th, al, w, u_delta, p, m0g, F_x, F_z, M_y, out, sc_th);
}

void glider_rhs_jacobian(double V, double th, double al, double w, double u_delta,
                         const GliderParams *p, double F_x, double F_z, double M_y,
                         double out[32])
{
    double m = p->m, J2 = p->J2, K_Fdelta = p->K_Fdelta, m0g = p->m0 * p->g;
    double V2 = V * V;
    double s_th, c_th, s_al, c_al;
    GLIDER_SINCOS(th, &s_th, &c_th);
    GLIDER_SINCOS(al, &s_al, &c_al);
    double k_lift = p->K_L0 + p->K_L * al;
    double f_delta = K_Fdelta * V2 * u_delta;
    double f_v = F_x * c_th - F_z * s_th;
    double f_n = -F_x * s_th - F_z * c_th;
    double mV = m * V;
    double dth = (-m0g * c_th + k_lift * V2 + f_delta * c_al + f_n) / mV;
    double V_V = (-2.0 * V * (p->K_D0 + p->K_D * al * al) + 2.0 * K_Fdelta * V * u_delta * s_al) / m;
    double V_th = (-m0g * c_th + f_n) / m;
    double V_al = (-2.0 * p->K_D * al * V2 + f_delta * c_al) / m;
    double V_u = K_Fdelta * V2 * s_al / m;
    double th_V = (2.0 * V * k_lift + 2.0 * K_Fdelta * V * u_delta * c_al) / mV - dth / V;
    double th_th = (m0g * s_th - f_v) / mV;
    double th_al = (p->K_L * V2 - f_delta * s_al) / mV;
    double th_u = K_Fdelta * V2 * c_al / mV;
    double w_V = 2.0 * V * (p->K_M0 + p->K_M * al + p->K_q * w - p->K_M * u_delta) / J2;
    const double J[32] = {
        V_V,   V_th,   V_al,   0.0, V_u,   c_th / m,   -s_th / m,  0.0,
        th_V,  th_th,  th_al,  0.0, th_u,  -s_th / mV, -c_th / mV, 0.0,
        -th_V, -th_th, -th_al, 1.0, -th_u, s_th / mV,  c_th / mV,  0.0,
        w_V, 0.0, p->K_M * V2 / J2, p->K_q * V2 / J2, -p->K_M * V2 / J2, 0.0, 0.0, 1.0 / J2,
    };
    (void)M_y; /* enters linearly: its column is constant */
    memcpy(out, J, sizeof J);
}

void glider_plant_jacobian(const double x[6], double delta, double delta_cmd,
                           const double disturbance[3], const GliderParams *p, double tau_servo,
                           double delta_max, double out[GP_JAC_ROWS * GP_JAC_COLS])
{
    double body[32], s_th, c_th, ku = p->K_udelta, V = x[0];
    int i, j;
    glider_rhs_jacobian(x[0], x[1], x[2], x[3], ku * delta, p, disturbance[0], disturbance[1],
                        disturbance[2], body);
    for (i = 0; i < GP_JAC_ROWS * GP_JAC_COLS; i++) out[i] = 0.0;
    for (i = 0; i < 4; i++) { /* (V, th, al, w), then x, z, delta: u_delta = K_udelta delta */
        double *r = out + i * GP_JAC_COLS;
        const double *b = body + i * 8;
        for (j = 0; j < 4; j++) r[j] = b[j];
        r[6] = b[4] * ku;
        for (j = 0; j < 3; j++) r[8 + j] = b[5 + j];
    }
    GLIDER_SINCOS(x[1], &s_th, &c_th);
    out[4 * GP_JAC_COLS + 0] = c_th;
    out[4 * GP_JAC_COLS + 1] = -V * s_th;
    out[5 * GP_JAC_COLS + 0] = -s_th;
    out[5 * GP_JAC_COLS + 1] = -V * c_th;
    out[6 * GP_JAC_COLS + 6] = -1.0 / tau_servo;
    out[6 * GP_JAC_COLS + 7] = -delta_max <= delta_cmd && delta_cmd <= delta_max ? 1.0 / tau_servo
                                                                                 : 0.0;
    out[7 * GP_JAC_COLS + 1] = 1.0;
    out[7 * GP_JAC_COLS + 2] = 1.0;
}

void glider_plant_derivatives(const double x[6], double delta, double delta_cmd,
                              const double disturbance[3], const GliderParams *p,
                              double tau_servo, double delta_max, double out[GP_NSTATES])
{
    double sc_th[2];
    rhs_c(x[0], x[1], x[2], x[3], p->K_udelta * delta, p, p->m0 * p->g, disturbance[0],
          disturbance[1], disturbance[2], out, sc_th);
    out[4] = x[0] * sc_th[1];
    out[5] = -x[0] * sc_th[0];
    out[6] = (glider_saturate(delta_cmd, delta_max) - delta) / tau_servo;
}

double glider_servo_response(double delta0, double command, double tau, double dt)
{
    return command + (delta0 - command) * exp(-dt / tau);
}

double glider_saturate(double value, double limit)
{
    return value > limit ? limit : (value < -limit ? -limit : value);
}

int glider_check_state(const double *x, int n, char *msg, size_t size)
{
    double V = x[0];
    int finite = 1, i;
    char v[40], vs[40];
    for (i = 0; i < n; i++) {
        if (!isfinite(x[i])) {
            finite = 0;
            break;
        }
    }
    if (!(V > GP_V_STALL) || !finite) {
        py_float_g(V, 6, v, sizeof v);
        py_float_g(GP_V_STALL, 6, vs, sizeof vs);
        snprintf(msg, size,
                 "glider stalled: V = %s m/s (model valid for V > %s m/s, "
                 "Eq. (7) divides by V)",
                 v, vs);
        return 1;
    }
    return 0;
}

/* ---- plant step --------------------------------------------------------------------- */

int glider_plant_step(double x[6], double *delta, double delta_cmd, double h,
                      const GliderParams *p, double tau_servo, const double disturbance[3],
                      double h_max, char *msg, size_t size)
{
    double d0 = *delta - delta_cmd;
    double dt_max = h_max;
    double nd, dt, F_x, F_z, M_y, ku, m0g;
    double V, th, al, w, px, pz;
    double k1[4], k2[4], k3[4], k4[4], x2[4], x3[4], x4[4], st[6];
    double sc1[2], sc2[2], sc3[2], sc4[2]; /* sin, cos of each stage's th */
    long i, n;

    if (fabs(d0) > GP_SERVO_DEVIATION_REF) {
        double b = tau_servo * pow(GP_SERVO_DEVIATION_REF / fabs(d0), 0.25);
        dt_max = b < h_max ? b : h_max; /* min(h_max, b) */
    }
    nd = ceil(h / dt_max - 1e-9);
    if (!(nd > 1.0)) { /* max(1, ceil(...)) */
        nd = 1.0;
    }
    n = (long)nd;
    dt = h / nd;
    F_x = disturbance[0];
    F_z = disturbance[1];
    M_y = disturbance[2];
    ku = p->K_udelta;
    m0g = p->m0 * p->g;
    V = x[0];
    th = x[1];
    al = x[2];
    w = x[3];
    px = x[4];
    pz = x[5];
    for (i = 0; i < n; i++) {
        double s0 = (double)i * dt;
        double e0 = exp(-s0 / tau_servo);
        double e1 = exp(-(s0 + dt) / tau_servo);
        double eh = (6.0 * tau_servo / dt * (e0 - e1) - e0 - e1) / 4.0;
        double u0 = ku * (delta_cmd + d0 * e0);
        double uh = ku * (delta_cmd + d0 * eh);
        double u1 = ku * (delta_cmd + d0 * e1);
        double kx, kz, c;
        rhs_c(V, th, al, w, u0, p, m0g, F_x, F_z, M_y, k1, sc1);
        x2[0] = V + 0.5 * dt * k1[0];
        x2[1] = th + 0.5 * dt * k1[1];
        x2[2] = al + 0.5 * dt * k1[2];
        x2[3] = w + 0.5 * dt * k1[3];
        rhs_c(x2[0], x2[1], x2[2], x2[3], uh, p, m0g, F_x, F_z, M_y, k2, sc2);
        x3[0] = V + 0.5 * dt * k2[0];
        x3[1] = th + 0.5 * dt * k2[1];
        x3[2] = al + 0.5 * dt * k2[2];
        x3[3] = w + 0.5 * dt * k2[3];
        rhs_c(x3[0], x3[1], x3[2], x3[3], uh, p, m0g, F_x, F_z, M_y, k3, sc3);
        x4[0] = V + dt * k3[0];
        x4[1] = th + dt * k3[1];
        x4[2] = al + dt * k3[2];
        x4[3] = w + dt * k3[3];
        rhs_c(x4[0], x4[1], x4[2], x4[3], u1, p, m0g, F_x, F_z, M_y, k4, sc4);
        /* cos(th), cos(x2[1]), ... as the stages' right-hand sides computed them */
        kx = V * sc1[1] + 2.0 * x2[0] * sc2[1] + 2.0 * x3[0] * sc3[1] + x4[0] * sc4[1];
        kz = V * sc1[0] + 2.0 * x2[0] * sc2[0] + 2.0 * x3[0] * sc3[0] + x4[0] * sc4[0];
        c = dt / 6.0;
        V += c * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]);
        th += c * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]);
        al += c * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]);
        w += c * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]);
        px += c * kx;
        pz -= c * kz;
        st[0] = V;
        st[1] = th;
        st[2] = al;
        st[3] = w;
        st[4] = px;
        st[5] = pz;
        if (glider_check_state(st, 6, msg, size)) {
            return 1;
        }
    }
    x[0] = V;
    x[1] = th;
    x[2] = al;
    x[3] = w;
    x[4] = px;
    x[5] = pz;
    *delta = delta_cmd + d0 * exp(-h / tau_servo);
    return 0;
}

/* ---- CPython's random.Random (MT19937) ---------------------------------------------- */

#define PYR_N 624
#define PYR_M 397
#define PYR_MATRIX_A 0x9908b0dfU
#define PYR_UPPER_MASK 0x80000000U
#define PYR_LOWER_MASK 0x7fffffffU

static void pyrandom_init_genrand(PyRandom *r, uint32_t s)
{
    int mti;
    uint32_t *mt = r->mt;
    mt[0] = s;
    for (mti = 1; mti < PYR_N; mti++) {
        mt[mti] = (uint32_t)(1812433253U * (mt[mti - 1] ^ (mt[mti - 1] >> 30)) + (uint32_t)mti);
    }
    r->index = mti;
}

static void pyrandom_init_by_array(PyRandom *r, const uint32_t *init_key, size_t key_length)
{
    size_t i, j, k;
    uint32_t *mt = r->mt;
    pyrandom_init_genrand(r, 19650218U);
    i = 1;
    j = 0;
    k = (PYR_N > key_length ? PYR_N : key_length);
    for (; k; k--) {
        mt[i] = (uint32_t)((mt[i] ^ ((mt[i - 1] ^ (mt[i - 1] >> 30)) * 1664525U)) + init_key[j] +
                           (uint32_t)j);
        i++;
        j++;
        if (i >= PYR_N) {
            mt[0] = mt[PYR_N - 1];
            i = 1;
        }
        if (j >= key_length) {
            j = 0;
        }
    }
    for (k = PYR_N - 1; k; k--) {
        mt[i] = (uint32_t)((mt[i] ^ ((mt[i - 1] ^ (mt[i - 1] >> 30)) * 1566083941U)) -
                           (uint32_t)i);
        i++;
        if (i >= PYR_N) {
            mt[0] = mt[PYR_N - 1];
            i = 1;
        }
    }
    mt[0] = 0x80000000U;
}

void pyrandom_seed(PyRandom *r, uint32_t seed)
{
    uint32_t key[1];
    key[0] = seed; /* abs(seed) in 32-bit words: one word for 0 <= seed < 2**32 */
    pyrandom_init_by_array(r, key, 1);
    r->has_gauss_next = 0;
    r->gauss_next = 0.0;
}

static uint32_t pyrandom_genrand_uint32(PyRandom *r)
{
    uint32_t y;
    uint32_t *mt = r->mt;
    if (r->index >= PYR_N) {
        int kk;
        for (kk = 0; kk < PYR_N - PYR_M; kk++) {
            y = (mt[kk] & PYR_UPPER_MASK) | (mt[kk + 1] & PYR_LOWER_MASK);
            mt[kk] = mt[kk + PYR_M] ^ (y >> 1) ^ ((y & 0x1U) ? PYR_MATRIX_A : 0x0U);
        }
        for (; kk < PYR_N - 1; kk++) {
            y = (mt[kk] & PYR_UPPER_MASK) | (mt[kk + 1] & PYR_LOWER_MASK);
            mt[kk] = mt[kk + (PYR_M - PYR_N)] ^ (y >> 1) ^ ((y & 0x1U) ? PYR_MATRIX_A : 0x0U);
        }
        y = (mt[PYR_N - 1] & PYR_UPPER_MASK) | (mt[0] & PYR_LOWER_MASK);
        mt[PYR_N - 1] = mt[PYR_M - 1] ^ (y >> 1) ^ ((y & 0x1U) ? PYR_MATRIX_A : 0x0U);
        r->index = 0;
    }
    y = mt[r->index++];
    y ^= (y >> 11);
    y ^= (y << 7) & 0x9d2c5680U;
    y ^= (y << 15) & 0xefc60000U;
    y ^= (y >> 18);
    return y;
}

double pyrandom_random(PyRandom *r)
{
    uint32_t a = pyrandom_genrand_uint32(r) >> 5;
    uint32_t b = pyrandom_genrand_uint32(r) >> 6;
    return (a * 67108864.0 + b) * (1.0 / 9007199254740992.0);
}

double pyrandom_gauss(PyRandom *r, double mu, double sigma)
{
    double z;
    if (r->has_gauss_next) {
        z = r->gauss_next;
        r->has_gauss_next = 0;
    } else {
        double x2pi = pyrandom_random(r) * (2.0 * GP_PI);
        double g2rad = sqrt(-2.0 * log(1.0 - pyrandom_random(r)));
        z = cos(x2pi) * g2rad;
        r->gauss_next = sin(x2pi) * g2rad;
        r->has_gauss_next = 1;
    }
    return mu + z * sigma;
}

/* ---- pitch sensor ------------------------------------------------------------------- */

int pitch_sensor_init(PitchSensor *s, double noise_std, uint32_t seed, char *msg, size_t n)
{
    char r[40];
    if (!(isfinite(noise_std) && noise_std >= 0.0)) {
        py_float_repr(noise_std, r, sizeof r);
        snprintf(msg, n, "noise_std = %s is invalid: expected a finite value >= 0", r);
        return 1;
    }
    s->noise_std = noise_std;
    pyrandom_seed(&s->rng, seed);
    return 0;
}

double pitch_sensor_measure(PitchSensor *s, double theta)
{
    if (s->noise_std == 0.0) {
        return theta;
    }
    return theta + pyrandom_gauss(&s->rng, 0.0, s->noise_std);
}
