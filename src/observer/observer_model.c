/* Observer equations in C99: the twin of glider_observer (see observer_model.h). */
#include "glider_fp.h" /* first: no fused multiply-add (see there) */
#include "observer_model.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* ---- Butterworth pre-filter, Eqs. (58)-(60) ----------------------------------------- */

int butterworth_coefficients(double f_sample, double f_cutoff, double c[5], char *msg, size_t n)
{
    char a[40], b[40];
    double f_r, wc, k, cc, a0;
    if (!(isfinite(f_sample) && f_sample > 0.0)) {
        py_float_repr(f_sample, a, sizeof a);
        snprintf(msg, n, "f_sample = %s is invalid: expected a finite value > 0 Hz", a);
        return 1;
    }
    if (!(isfinite(f_cutoff) && 0.0 < f_cutoff && f_cutoff < 0.5 * f_sample)) {
        py_float_repr(f_cutoff, a, sizeof a);
        py_float_g(0.5 * f_sample, 6, b, sizeof b);
        snprintf(msg, n,
                 "f_cutoff = %s is invalid: expected a value in (0, %s) Hz "
                 "(below the Nyquist frequency f_sample/2)",
                 a, b);
        return 1;
    }
    f_r = f_sample / f_cutoff;
    wc = tan(GP_PI / f_r);
    k = 2.0 * cos(GP_PI / 4.0) * wc;
    cc = 1.0 + k + wc * wc;
    a0 = wc * wc / cc;
    c[0] = a0;
    c[1] = 2.0 * a0;
    c[2] = a0;
    c[3] = 2.0 * (wc * wc - 1.0) / cc;
    c[4] = (1.0 - k + wc * wc) / cc;
    return 0;
}

int butterworth_init(Butterworth *f, double f_sample, double f_cutoff, char *msg, size_t n)
{
    int i;
    if (butterworth_coefficients(f_sample, f_cutoff, f->c, msg, n)) {
        return 1;
    }
    for (i = 0; i < 4; i++) {
        f->hist[i] = 0.0;
    }
    f->primed = 0;
    return 0;
}

double butterworth_filter(Butterworth *f, double x)
{
    double x1, x2, y1, y2, y;
    const double *c = f->c;
    if (!f->primed) {
        f->hist[0] = x;
        f->hist[1] = x;
        f->hist[2] = x;
        f->hist[3] = x;
        f->primed = 1;
    }
    x1 = f->hist[0];
    x2 = f->hist[1];
    y1 = f->hist[2];
    y2 = f->hist[3];
    y = c[0] * x + c[1] * x1 + c[2] * x2 - c[3] * y1 - c[4] * y2;
    f->hist[0] = x;
    f->hist[1] = x1;
    f->hist[2] = y;
    f->hist[3] = y1;
    return y;
}

/* ---- linearization ------------------------------------------------------------------ */

void observer_linearization(const GliderParams *p, const GliderEquilibrium *eq, double A[4][4])
{
    double V = eq->V, th = eq->theta_g, al = eq->alpha;
    double m = p->m, J2 = p->J2;
    double dD_dV = 2.0 * V * (p->K_D0 + p->K_D * al * al);
    double dD_da = 2.0 * p->K_D * V * V * al;
    double dL_dV = 2.0 * V * (p->K_L0 + p->K_L * al);
    double dL_da = p->K_L * V * V;
    double m0g = p->m0 * p->g;
    A[0][0] = -dD_dV / m;
    A[0][1] = -m0g * cos(th) / m;
    A[0][2] = -dD_da / m;
    A[0][3] = 0.0;
    A[1][0] = dL_dV / (m * V);
    A[1][1] = m0g * sin(th) / (m * V);
    A[1][2] = dL_da / (m * V);
    A[1][3] = 0.0;
    A[2][0] = -dL_dV / (m * V);
    A[2][1] = -m0g * sin(th) / (m * V);
    A[2][2] = -dL_da / (m * V);
    A[2][3] = 1.0;
    A[3][0] = 2.0 * V * (p->K_M0 + p->K_M * al) / J2;
    A[3][1] = 0.0;
    A[3][2] = p->K_M * V * V / J2;
    A[3][3] = p->K_q * V * V / J2;
}

/* ---- Riccati solver: glider_observer.riccati, same operations in the same order ------ */

#define RIC_SIGN_MAX_ITER 100
#define RIC_SIGN_SCALE_TOL 1e-2
#define RIC_SIGN_TOL 1e-10
#define RIC_NEWTON_MAX_ITER 30
#define RIC_NEWTON_TOL 1e-13
#define RIC_NMAX 16 /* largest dense system: the 16 x 16 Kronecker form of the Lyapunov solve */

/* out (n x m) = A (n x k) B (k x m); out must not alias A or B */
static void ric_matmul(const double *A, const double *B, int n, int k, int m, double *out)
{
    int i, j, l;
    for (i = 0; i < n; i++) {
        for (j = 0; j < m; j++) {
            double s = 0.0;
            for (l = 0; l < k; l++) {
                s += A[i * k + l] * B[l * m + j];
            }
            out[i * m + j] = s;
        }
    }
}

static void ric_transpose(const double *A, int n, int m, double *out)
{
    int i, j;
    for (i = 0; i < m; i++) {
        for (j = 0; j < n; j++) {
            out[i * n + j] = A[j * m + i];
        }
    }
}

static double ric_norm1(const double *A, int n, int m)
{
    double best = 0.0;
    int i, j;
    for (j = 0; j < m; j++) {
        double s = 0.0;
        for (i = 0; i < n; i++) {
            s += fabs(A[i * m + j]);
        }
        if (s > best) {
            best = s;
        }
    }
    return best;
}

static double ric_maxabs(const double *A, int n, int m)
{
    double best = 0.0;
    int i;
    for (i = 0; i < n * m; i++) {
        if (fabs(A[i]) > best) {
            best = fabs(A[i]);
        }
    }
    return best;
}

static void ric_swap_rows(double *M, int cols, int a, int b)
{
    int j;
    for (j = 0; j < cols; j++) {
        double t = M[a * cols + j];
        M[a * cols + j] = M[b * cols + j];
        M[b * cols + j] = t;
    }
}

/* M X = B by Gaussian elimination with partial pivoting (M n x n, B n x m, both
 * overwritten); 0 ok, 1 singular. *logdet (if not NULL) gets sum log|pivot|. */
static int ric_solve(double *M, double *B, int n, int m, double *X, double *logdet)
{
    int i, j, k, l;
    double ld = 0.0;
    for (k = 0; k < n; k++) {
        int p = k;
        double best = fabs(M[k * n + k]);
        double piv;
        for (i = k + 1; i < n; i++) {
            if (fabs(M[i * n + k]) > best) {
                best = fabs(M[i * n + k]);
                p = i;
            }
        }
        if (!(best > 0.0) || !isfinite(best)) {
            return 1;
        }
        if (logdet) {
            ld += log(best);
        }
        if (p != k) {
            ric_swap_rows(M, n, k, p);
            ric_swap_rows(B, m, k, p);
        }
        piv = M[k * n + k];
        for (i = k + 1; i < n; i++) {
            double f = M[i * n + k] / piv;
            if (f != 0.0) {
                for (j = k + 1; j < n; j++) {
                    M[i * n + j] -= f * M[k * n + j];
                }
                for (j = 0; j < m; j++) {
                    B[i * m + j] -= f * B[k * m + j];
                }
            }
        }
    }
    for (i = n - 1; i >= 0; i--) {
        for (j = 0; j < m; j++) {
            double s = B[i * m + j];
            for (l = i + 1; l < n; l++) {
                s -= M[i * n + l] * X[l * m + j];
            }
            X[i * m + j] = s / M[i * n + i];
        }
    }
    if (logdet) {
        *logdet = ld;
    }
    return 0;
}

/* A P + P A^T + Q - P G P (4 x 4) */
static void ric_residual(const double *A, const double *P, const double *Q, const double *G,
                         double *out)
{
    double AP[16], AT[16], PAT[16], PG[16], PGP[16];
    int i;
    ric_matmul(A, P, 4, 4, 4, AP);
    ric_transpose(A, 4, 4, AT);
    ric_matmul(P, AT, 4, 4, 4, PAT);
    ric_matmul(P, G, 4, 4, 4, PG);
    ric_matmul(PG, P, 4, 4, 4, PGP);
    for (i = 0; i < 16; i++) {
        out[i] = AP[i] + PAT[i] + Q[i] - PGP[i];
    }
}

/* X with F X + X F^T = M (4 x 4; Kronecker system, row-major unknowns); 0 ok, 1 singular */
static int ric_lyapunov(const double *F, const double *M, double *X)
{
    double K[256], b[16];
    int i, j, l;
    for (i = 0; i < 256; i++) {
        K[i] = 0.0;
    }
    for (i = 0; i < 4; i++) {
        for (j = 0; j < 4; j++) {
            int r = 4 * i + j;
            for (l = 0; l < 4; l++) {
                K[r * 16 + 4 * l + j] += F[i * 4 + l];
                K[r * 16 + 4 * i + l] += F[j * 4 + l];
            }
        }
    }
    for (i = 0; i < 16; i++) {
        b[i] = M[i];
    }
    return ric_solve(K, b, 16, 1, X, NULL);
}

static void ric_symmetrize(const double *P, double *out)
{
    int i, j;
    for (i = 0; i < 4; i++) {
        for (j = 0; j < 4; j++) {
            out[i * 4 + j] = 0.5 * (P[i * 4 + j] + P[j * 4 + i]);
        }
    }
}

static int ric_is_positive_definite(const double *P)
{
    double L[16];
    int i, j, k;
    for (i = 0; i < 16; i++) {
        L[i] = 0.0;
    }
    for (j = 0; j < 4; j++) {
        double s = P[j * 4 + j];
        double d;
        for (k = 0; k < j; k++) {
            s -= L[j * 4 + k] * L[j * 4 + k];
        }
        if (!(s > 0.0) || !isfinite(s)) {
            return 0;
        }
        d = sqrt(s);
        L[j * 4 + j] = d;
        for (i = j + 1; i < 4; i++) {
            double t = P[i * 4 + j];
            for (k = 0; k < j; k++) {
                t -= L[i * 4 + k] * L[j * 4 + k];
            }
            L[i * 4 + j] = t / d;
        }
    }
    return 1;
}

static int ric_sign_initial(const double *A, const double *Q, const double *G, double *P,
                            char *msg, size_t msize)
{
    enum { n = 4, n2 = 8 };
    double Z[64], Zn[64], Zi[64], M[64], B[64], D[64];
    double Mx[32], Nx[32], MT[32], MTM[16], MTN[16], X[16];
    double logdet, c, change, size;
    int scale = 1, converged = 0, it, i, j;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) {
            Z[i * n2 + j] = A[j * n + i];
            Z[i * n2 + n + j] = -G[i * n + j];
            Z[(n + i) * n2 + j] = -Q[i * n + j];
            Z[(n + i) * n2 + n + j] = -A[i * n + j];
        }
    }
    for (it = 0; it < RIC_SIGN_MAX_ITER; it++) {
        memcpy(M, Z, sizeof M);
        for (i = 0; i < n2; i++) {
            for (j = 0; j < n2; j++) {
                B[i * n2 + j] = i == j ? 1.0 : 0.0;
            }
        }
        if (ric_solve(M, B, n2, n2, Zi, &logdet)) {
            snprintf(msg, msize,
                     "the Hamiltonian matrix of the Riccati equation is singular "
                     "(an eigenvalue on the imaginary axis)");
            return 1;
        }
        c = scale ? exp(logdet / n2) : 1.0;
        for (i = 0; i < n2 * n2; i++) {
            Zn[i] = 0.5 * (Z[i] / c + c * Zi[i]);
        }
        for (i = 0; i < n2 * n2; i++) {
            D[i] = Zn[i] - Z[i];
        }
        change = ric_norm1(D, n2, n2);
        size = ric_norm1(Zn, n2, n2);
        memcpy(Z, Zn, sizeof Z);
        if (!isfinite(change) || !isfinite(size)) {
            break;
        }
        if (change <= RIC_SIGN_TOL * size) {
            converged = 1;
            break;
        }
        if (change <= RIC_SIGN_SCALE_TOL * size) {
            scale = 0;
        }
    }
    if (!converged) {
        snprintf(msg, msize,
                 "the sign iteration of the Riccati equation did not converge in "
                 "%d steps (no stabilizing solution?)",
                 RIC_SIGN_MAX_ITER);
        return 1;
    }
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) {
            Mx[i * n + j] = Z[i * n2 + n + j];
            Mx[(n + i) * n + j] = Z[(n + i) * n2 + n + j] + (i == j ? 1.0 : 0.0);
            Nx[i * n + j] = -(Z[i * n2 + j] + (i == j ? 1.0 : 0.0));
            Nx[(n + i) * n + j] = -Z[(n + i) * n2 + j];
        }
    }
    ric_transpose(Mx, n2, n, MT);
    ric_matmul(MT, Mx, n, n2, n, MTM);
    ric_matmul(MT, Nx, n, n2, n, MTN);
    if (ric_solve(MTM, MTN, n, n, X, NULL)) {
        snprintf(msg, msize,
                 "the stable invariant subspace of the Riccati equation is degenerate "
                 "(no stabilizing solution)");
        return 1;
    }
    ric_symmetrize(X, P);
    return 0;
}

int riccati_solve_filter_care(const double A[16], const double Q[16], const double G[16],
                              double P[16], char *msg, size_t n)
{
    const double *a = A, *q = Q, *g = G;
    double p[16], PG[16], F[16], Res[16], R[16], D[16], S[16];
    double size, change;
    int done = 0, final = 0, it, i;
    if (ric_sign_initial(a, q, g, p, msg, n)) {
        return 1;
    }
    for (it = 0; it < RIC_NEWTON_MAX_ITER; it++) {
        ric_matmul(p, g, 4, 4, 4, PG);
        for (i = 0; i < 16; i++) {
            F[i] = a[i] - PG[i];
        }
        ric_residual(a, p, q, g, Res);
        for (i = 0; i < 16; i++) {
            R[i] = -Res[i];
        }
        if (ric_lyapunov(F, R, D)) {
            break;
        }
        for (i = 0; i < 16; i++) {
            S[i] = p[i] + D[i];
        }
        ric_symmetrize(S, p);
        size = ric_maxabs(p, 4, 4);
        change = ric_maxabs(D, 4, 4);
        if (!isfinite(size) || !isfinite(change)) {
            break;
        }
        if (final) {
            done = 1;
            break;
        }
        if (change <= RIC_NEWTON_TOL * size) {
            final = 1;
        }
    }
    if (!done) {
        snprintf(msg, n,
                 "the Newton refinement of the Riccati equation did not converge in %d steps",
                 RIC_NEWTON_MAX_ITER);
        return 1;
    }
    if (!ric_is_positive_definite(p)) {
        snprintf(msg, n, "the Riccati solution is not positive definite (no stabilizing solution)");
        return 1;
    }
    memcpy(P, p, sizeof p);
    return 0;
}

/* ---- observer gain and step --------------------------------------------------------- */

static const double C_O[4] = {0.0, 1.0, 1.0, 0.0};

int observer_riccati_solution(const GliderParams *p, double R, const double Q[4], double P[4][4],
                              char *msg, size_t n)
{
    GliderEquilibrium eq;
    double A[4][4], Af[16], Qm[16], G[16], Pf[16];
    char err[256], r[40], q0[40], q1[40], q2[40], q3[40];
    int i, j;
    glider_equilibrium(p, &eq);
    observer_linearization(p, &eq, A);
    for (i = 0; i < 4; i++) {
        for (j = 0; j < 4; j++) {
            Af[i * 4 + j] = A[i][j];
            Qm[i * 4 + j] = i == j ? Q[i] : 0.0;
            G[i * 4 + j] = C_O[i] * C_O[j] / R;
        }
    }
    if (riccati_solve_filter_care(Af, Qm, G, Pf, err, sizeof err)) {
        py_float_repr(R, r, sizeof r);
        py_float_repr(Q[0], q0, sizeof q0);
        py_float_repr(Q[1], q1, sizeof q1);
        py_float_repr(Q[2], q2, sizeof q2);
        py_float_repr(Q[3], q3, sizeof q3);
        snprintf(msg, n, "observer gain for R = %s, Q = (%s, %s, %s, %s): %s", r, q0, q1, q2, q3,
                 err);
        return 1;
    }
    for (i = 0; i < 4; i++) {
        for (j = 0; j < 4; j++) {
            P[i][j] = Pf[i * 4 + j];
        }
    }
    return 0;
}

int observer_gain(const GliderParams *p, double R, const double Q[4], double H[4], char *msg,
                  size_t n)
{
    static const char *const names[4] = {"Q_V", "Q_theta_g", "Q_alpha", "Q_omega2"};
    double P[4][4];
    char r[40];
    int i, j;
    if (!(isfinite(R) && R > 0.0)) {
        py_float_repr(R, r, sizeof r);
        snprintf(msg, n, "R = %s is invalid: expected a finite value > 0", r);
        return 1;
    }
    for (i = 0; i < 4; i++) {
        if (!(isfinite(Q[i]) && Q[i] > 0.0)) {
            py_float_repr(Q[i], r, sizeof r);
            snprintf(msg, n, "%s = %s is invalid: expected a finite value > 0", names[i], r);
            return 1;
        }
    }
    if (observer_riccati_solution(p, R, Q, P, msg, n)) {
        return 1;
    }
    for (i = 0; i < 4; i++) {
        double s = 0.0;
        for (j = 0; j < 4; j++) {
            s += P[i][j] * C_O[j];
        }
        H[i] = s / R;
    }
    return 0;
}

/* f(x) of observer_step: rhs + H (theta - x[1] - x[2]) */
static void observer_f(const double x[4], double theta, double u_delta, const GliderParams *p,
                       const double H[4], double out[4])
{
    double d[4];
    double e;
    glider_rhs(x[0], x[1], x[2], x[3], u_delta, p, 0.0, 0.0, 0.0, d);
    e = theta - x[1] - x[2];
    out[0] = d[0] + H[0] * e;
    out[1] = d[1] + H[1] * e;
    out[2] = d[2] + H[2] * e;
    out[3] = d[3] + H[3] * e;
}

int observer_step(double xh[4], double theta, double u_delta, double h, const GliderParams *p,
                  const double H[4], double h_max, char *msg, size_t n)
{
    double nd, dt;
    double V, th, al, w, c;
    double k1[4], k2[4], k3[4], k4[4], xs[4];
    long i, steps;
    nd = ceil(h / h_max - 1e-9);
    if (!(nd > 1.0)) {
        nd = 1.0;
    }
    steps = (long)nd;
    dt = h / nd;
    V = xh[0];
    th = xh[1];
    al = xh[2];
    w = xh[3];
    for (i = 0; i < steps; i++) {
        xs[0] = V;
        xs[1] = th;
        xs[2] = al;
        xs[3] = w;
        observer_f(xs, theta, u_delta, p, H, k1);
        xs[0] = V + 0.5 * dt * k1[0];
        xs[1] = th + 0.5 * dt * k1[1];
        xs[2] = al + 0.5 * dt * k1[2];
        xs[3] = w + 0.5 * dt * k1[3];
        observer_f(xs, theta, u_delta, p, H, k2);
        xs[0] = V + 0.5 * dt * k2[0];
        xs[1] = th + 0.5 * dt * k2[1];
        xs[2] = al + 0.5 * dt * k2[2];
        xs[3] = w + 0.5 * dt * k2[3];
        observer_f(xs, theta, u_delta, p, H, k3);
        xs[0] = V + dt * k3[0];
        xs[1] = th + dt * k3[1];
        xs[2] = al + dt * k3[2];
        xs[3] = w + dt * k3[3];
        observer_f(xs, theta, u_delta, p, H, k4);
        c = dt / 6.0;
        V += c * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]);
        th += c * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]);
        al += c * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]);
        w += c * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]);
        xs[0] = V;
        xs[1] = th;
        xs[2] = al;
        xs[3] = w;
        if (glider_check_state(xs, 4, msg, n)) {
            return 1;
        }
    }
    xh[0] = V;
    xh[1] = th;
    xh[2] = al;
    xh[3] = w;
    return 0;
}
