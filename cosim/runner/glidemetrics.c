/* The glide metrics of a run's table in C: glider_cosim.runner.metrics.glide_metrics and
 * glider_cosim.runner.outcome.classify, bit for bit, without numpy.
 *
 * The table is the run's rows of doubles, row-major (time first); the columns are read
 * strided. The same operations as numpy's, in the same order (compiled with
 * -ffp-contract=off): numpy's pairwise summation (np.sum, np.mean), npy_remainder
 * (np.mod, the angle wrap), searchsorted's left side, argmax's first maximum, the zero
 * crossings of outcome._crossings sample by sample. Where the outcome needs a fit
 * (np.polyfit: an error that neither settled nor tumbled) the kernel hands the points to
 * fit back (GM_FIT_PEAKS, GM_FIT_WINDOW) and the caller fits them with numpy and decides;
 * where an input is not finite or the time not strictly increasing (numpy raises or
 * propagates NaN there) it returns GM_NUMPY and the caller runs the numpy code instead.
 * Tested against it bit for bit (tests/test_glide_kernel.py). */

#include <math.h>
#include <stddef.h>
#include <stdlib.h>

#define GM_PI 3.141592653589793 /* math.pi */

#define GM_NUMPY (-1) /* the caller computes these metrics with numpy */
#define GM_NONE 0     /* the controller never took over: no outcome */
#define GM_STOPPED 1
#define GM_SETTLED 2
#define GM_TUMBLING 3
#define GM_FIT_PEAKS 4  /* fit log(peak) of the half-cycle peaks (fit x, y) over time */
#define GM_FIT_WINDOW 5 /* fit log|e| over the examined window (fit x, y) */

/* the slots of out[]; a slot that stays None has its bit set in *none */
enum {
    S_EFFORT, S_MAXABS, S_RISE, S_OVER, S_OVER_PCT, S_BAND, S_FINAL, S_SETTLING, S_PERIOD,
    S_RATE, S_WIN0, S_WIN1, S_HOLD, S_IN_BAND, S_I0, S_AMP, S_MINABS, S_E0, S_NFIT, S_TW0,
    S_TW1, S_COUNT
};

#define MIN_HOLD_S 10.0
#define HOLD_PERIODS 3.0
#define MIN_WINDOW_S 10.0
#define BAND_FRACTION 0.02

#define NONE(slot) (n_none |= 1L << (slot)) /* slot stays None */
#define AT(col, i) (data[(size_t)(i) * (size_t)ncol + (size_t)(col)])

/* numpy's pairwise sum of f(k) for k in [lo, lo + n) (DOUBLE_pairwise_sum: blocks of 128,
 * 8 accumulators, halves split on a multiple of 8) */
typedef double (*term_fn)(const void *ctx, long k);

static double pairwise(term_fn f, const void *ctx, long lo, long n)
{
    if (n < 8) {
        double res = -0.0;
        for (long i = 0; i < n; i++)
            res += f(ctx, lo + i);
        return res;
    }
    if (n <= 128) {
        double r[8];
        long i;
        for (int k = 0; k < 8; k++)
            r[k] = f(ctx, lo + k);
        for (i = 8; i < n - (n % 8); i += 8)
            for (int k = 0; k < 8; k++)
                r[k] += f(ctx, lo + i + k);
        double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++)
            res += f(ctx, lo + i);
        return res;
    }
    long n2 = n / 2;
    n2 -= n2 % 8;
    return pairwise(f, ctx, lo, n2) + pairwise(f, ctx, lo + n2, n - n2);
}

/* np.sum of n terms: the add's identity 0.0 plus the pairwise sum */
static double np_sum(term_fn f, const void *ctx, long n) { return 0.0 + pairwise(f, ctx, 0, n); }

/* np.mod (npy_remainder through npy_divmod) for a finite, non-zero b */
static double np_mod(double a, double b)
{
    double mod = fmod(a, b);
    if (mod != 0.0) {
        if ((b < 0) != (mod < 0))
            mod += b;
    } else {
        mod = copysign(0.0, b);
    }
    return mod;
}

/* outcome.wrap_angle: to [-period/2, period/2) */
static double wrap(double x, double period)
{
    double half = 0.5 * period;
    return np_mod(x + half, period) - half;
}

typedef struct {
    const double *data;
    long ncol, col;
} column_t;

static double abs_term(const void *ctx, long k)
{
    const column_t *c = ctx;
    const double *data = c->data;
    long ncol = c->ncol;
    return fabs(AT(c->col, k));
}

static double array_term(const void *ctx, long k) { return ((const double *)ctx)[k]; }

static double abs_array_term(const void *ctx, long k) { return fabs(((const double *)ctx)[k]); }

static double diff_term(const void *ctx, long k)
{
    const double *c = ctx;
    return c[k + 1] - c[k];
}

/* the error and its time from the takeover: e(k) and tt(k) of glide_metrics */
typedef struct {
    const double *data;
    long ncol, ct, cth, i0, n; /* n samples from row i0 */
    double theta_ge, period;
    double *ew;   /* the wrapped error, computed once */
    double *cbuf; /* room for n crossing times */
} error_t;

static double e_turns(const error_t *x, long k)
{
    const double *data = x->data;
    long ncol = x->ncol;
    return AT(x->cth, x->i0 + k) - x->theta_ge;
}

static double e_wrapped(const error_t *x, long k) { return x->ew[k]; }

static double tt(const error_t *x, long k)
{
    const double *data = x->data;
    long ncol = x->ncol;
    return AT(x->ct, x->i0 + k) - AT(x->ct, x->i0);
}

/* outcome._crossings of the wrapped error over the samples [lo, n) (times tt): the times
 * into c[], their count. The vectorised rule, sample by sample: a sign change from a
 * non-zero value is the last change (one by a step above jump instead forgets the side
 * the signal was on, and its sample is skipped); a sample beyond +-hyst on the other
 * side than the last one beyond it is a crossing, at the last change (interpolated). */
static long crossings(const error_t *x, long lo, double hyst, double jump, double *c)
{
    long last = -1;  /* the last sign change (-1: none yet) */
    int before = 0;  /* the side of the last sample beyond +-hyst; 0 after a jump */
    long count = 0;
    double e_prev = 0.0;
    for (long i = lo; i < x->n; i++) {
        double e = x->ew[i];
        int jumped = 0;
        if (i > lo) {
            int s = (e > 0) - (e < 0), sp = (e_prev > 0) - (e_prev < 0);
            if (s != sp && e_prev != 0.0) {
                if (fabs(e - e_prev) > jump)
                    jumped = 1;
                else
                    last = i;
            }
        }
        int side = jumped ? 0 : (e > hyst ? 1 : (e < -hyst ? -1 : 0));
        if (side != 0 && before != 0 && side != before && last >= 0) {
            double a = x->ew[last - 1], b = x->ew[last];
            double t0 = tt(x, last - 1), t1 = tt(x, last);
            c[count++] = a != b ? t0 + (t1 - t0) * a / (a - b) : t1;
        }
        if (side != 0 || jumped)
            before = side;
        e_prev = e;
    }
    return count;
}

/* outcome.oscillation_period: twice the longest interval between consecutive crossings
 * (hysteresis hyst), the first ignored when there are more than three; *found 0 for
 * fewer than three crossings */
static double oscillation_period(const error_t *x, double hyst, double jump, int *found)
{
    long m = crossings(x, 0, hyst, jump, x->cbuf);
    *found = m >= 3;
    if (m < 3)
        return 0.0;
    /* np.max(np.diff(c)[1:] if len(c) > 3 else np.diff(c)) */
    long first = m > 3 ? 1 : 0;
    double best = 0.0;
    for (long k = first; k < m - 1; k++) {
        double gap = x->cbuf[k + 1] - x->cbuf[k];
        if (k == first || gap > best)
            best = gap;
    }
    return 2.0 * best;
}

/* np.searchsorted(column, v) (side left) over rows [lo, hi) of a sorted column */
static long searchsorted(const double *data, long ncol, long col, long lo, long hi, double v)
{
    while (lo < hi) {
        long mid = lo + (hi - lo) / 2;
        if (AT(col, mid) < v)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* the rest of glider_glide_metrics, from the takeover on (x->n >= 1 samples) */
static long classify(const error_t *x_, int completed, double floor_, double *out, long *none,
                     double *fx, double *fy)
{
    const double period = x_->period;
    const error_t x = *x_;
    long n = x.n, n_none = *none;
    const double *data = x.data;
    long ncol = x.ncol, i0 = x.i0, ct = x.ct;
    double e0 = e_wrapped(&x, 0), ae0 = fabs(e0);
    double band = BAND_FRACTION * ae0;
    if (floor_ > band)
        band = floor_;
    out[S_BAND] = band;
    out[S_FINAL] = e_wrapped(&x, n - 1);
    if (ae0 < 1e-12) {
        out[S_RISE] = out[S_OVER] = out[S_OVER_PCT] = 0.0;
    } else {
        double lim = 0.1 * ae0;
        long k = 0;
        while (k < n && !(fabs(e_wrapped(&x, k)) <= lim))
            k++;
        if (k < n)
            out[S_RISE] = tt(&x, k);
        else
            NONE(S_RISE);
        double sgn = -(double)((e0 > 0) - (e0 < 0));
        double m = sgn * e_wrapped(&x, 0);
        for (k = 1; k < n; k++) {
            double p = sgn * e_wrapped(&x, k);
            if (p > m)
                m = p;
        }
        double over = m > 0.0 ? m : 0.0;
        out[S_OVER] = over;
        if (ae0 >= floor_)
            out[S_OVER_PCT] = 100.0 * over / ae0;
        else
            NONE(S_OVER_PCT);
    }
    if (!completed) {
        *none = n_none;
        return GM_STOPPED;
    }
    if (n < 2) {
        *none = n_none;
        return GM_NONE;
    }
    /* outcome.classify(tt, e_turns, band, period) */
    double t_end = tt(&x, n - 1);
    double width = t_end / 3.0; /* (t[-1] - t[0]) / 3.0, t[0] = 0.0 */
    if (!(width > MIN_WINDOW_S))
        width = MIN_WINDOW_S;
    double key = t_end - width;
    long lo = 0, hi = n; /* searchsorted(tt, key) */
    while (lo < hi) {
        long mid = lo + (hi - lo) / 2;
        if (tt(&x, mid) < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    long iw = lo;
    double emin = e_turns(&x, iw), emax = emin;
    for (long k = iw + 1; k < n; k++) {
        double v = e_turns(&x, k);
        if (v < emin)
            emin = v;
        if (v > emax)
            emax = v;
    }
    double t_on0 = AT(ct, i0);
    if (emax - emin > period) {
        double rate = (e_turns(&x, n - 1) - e_turns(&x, iw)) / (t_end - tt(&x, iw)) / period;
        if (rate != 0.0)
            out[S_PERIOD] = 1.0 / fabs(rate), n_none &= ~(1L << S_PERIOD);
        out[S_RATE] = rate;
        out[S_WIN0] = tt(&x, iw) + t_on0;
        out[S_WIN1] = t_end + t_on0;
        out[S_HOLD] = MIN_HOLD_S;
        n_none &= ~((1L << S_WIN0) | (1L << S_WIN1) | (1L << S_HOLD));
        *none = n_none;
        return GM_TUMBLING;
    }
    int found;
    double p_osc = oscillation_period(&x, band, 0.5 * period, &found);
    double hold = HOLD_PERIODS * (found ? p_osc : 0.0);
    if (!(hold > MIN_HOLD_S))
        hold = MIN_HOLD_S;
    long last_out = -1;
    for (long k = n - 1; k >= 0; k--)
        if (fabs(e_wrapped(&x, k)) > band) {
            last_out = k;
            break;
        }
    int has_in_band = last_out != n - 1; /* in the band at the last sample */
    double t_in = last_out < 0 ? 0.0 : (has_in_band ? tt(&x, last_out + 1) : 0.0);
    double in_band = t_end - t_in;
    if (found)
        out[S_PERIOD] = p_osc, n_none &= ~(1L << S_PERIOD);
    out[S_HOLD] = hold;
    n_none &= ~(1L << S_HOLD);
    if (has_in_band)
        out[S_IN_BAND] = in_band, n_none &= ~(1L << S_IN_BAND);
    if (has_in_band && in_band >= hold) {
        out[S_SETTLING] = t_in - 0.0;
        n_none &= ~(1L << S_SETTLING);
        *none = n_none;
        return GM_SETTLED;
    }
    /* the end of the run: its last third, at least MIN_WINDOW_S (or all of it) */
    long nw = n - iw;
    out[S_TW0] = tt(&x, iw);
    out[S_TW1] = t_end;
    out[S_WIN0] = tt(&x, iw) + t_on0;
    out[S_WIN1] = t_end + t_on0;
    n_none &= ~((1L << S_WIN0) | (1L << S_WIN1));
    double peak = fabs(x.ew[iw]);
    for (long k = iw + 1; k < n; k++)
        if (fabs(x.ew[k]) > peak)
            peak = fabs(x.ew[k]);
    long m = peak > 0 ? crossings(&x, iw, 0.1 * peak, 0.5 * period, x.cbuf) : 0;
    *none = n_none;
    if (m >= 4) { /* the half-cycle peaks of |e| between consecutive crossings */
        long a = iw + 0, b;
        for (long k = 0; k < m; k++) {
            /* np.searchsorted(tw, c[k]) */
            long lo = iw, hi = n;
            while (lo < hi) {
                long mid = lo + (hi - lo) / 2;
                if (tt(&x, mid) < x.cbuf[k])
                    lo = mid + 1;
                else
                    hi = mid;
            }
            b = lo;
            if (k > 0) {
                if (b <= a)
                    return GM_NUMPY; /* an empty stretch: numpy's argmax raises */
                long best = a; /* np.argmax: the first largest */
                for (long j = a + 1; j < b; j++)
                    if (fabs(x.ew[j]) > fabs(x.ew[best]))
                        best = j;
                fx[k - 1] = tt(&x, best);
                fy[k - 1] = fabs(x.ew[best]);
            }
            a = b;
        }
        long npk = m - 1;
        out[S_NFIT] = (double)npk;
        out[S_PERIOD] = 2.0 * (np_sum(diff_term, x.cbuf, npk) / (double)npk);
        n_none &= ~(1L << S_PERIOD);
        out[S_AMP] = np_sum(array_term, fy, npk) / (double)npk;
        *none = n_none;
        return GM_FIT_PEAKS;
    }
    for (long k = 0; k < nw; k++) {
        fx[k] = tt(&x, iw + k);
        fy[k] = x.ew[iw + k];
    }
    double mn = fabs(fy[0]);
    for (long k = 1; k < nw; k++)
        if (fabs(fy[k]) < mn)
            mn = fabs(fy[k]);
    out[S_NFIT] = (double)nw;
    out[S_MINABS] = mn;
    out[S_E0] = x.ew[0];
    out[S_AMP] = np_sum(abs_array_term, fy, nw) / (double)nw;
    return GM_FIT_WINDOW;
}

/* glide_metrics(t, theta_g, delta_cmd, theta_ge, t_on, completed) of the table's columns
 * ct, cth, cd (nrows rows of ncol doubles); t_on given as its searchsorted key
 * t_on - 1e-9 (has_t_on 0: None). Returns GM_NUMPY, GM_NONE, GM_STOPPED, GM_SETTLED,
 * GM_TUMBLING, GM_FIT_PEAKS or GM_FIT_WINDOW; the values in out[S_COUNT], the bits of
 * the None ones in *none; floor_ the band's floor BAND_FLOOR [rad]; fit (2 nrows doubles)
 * the points to fit, out[S_NFIT] of them: their x from fit[0], their y from fit[nrows]. */
long glider_glide_metrics(const double *data, long nrows, long ncol, long ct, long cth, long cd,
                          double theta_ge, int has_t_on, double t_on_key, int completed,
                          double floor_, double *out, long *none, double *fit)
{
    const double period = 2.0 * GM_PI;
    long n_none = 0;
    for (int k = 0; k < S_COUNT; k++)
        out[k] = 0.0;
    if (nrows < 1 || ncol < 1 || !isfinite(theta_ge))
        return GM_NUMPY;
    for (long i = 0; i < nrows; i++) {
        if (!isfinite(AT(ct, i)) || !isfinite(AT(cth, i)) || !isfinite(AT(cd, i)))
            return GM_NUMPY;
        if (i > 0 && !(AT(ct, i) > AT(ct, i - 1)))
            return GM_NUMPY;
    }
    double h = nrows > 1 ? AT(ct, 1) - AT(ct, 0) : 0.0;
    column_t dc = {data, ncol, cd};
    out[S_EFFORT] = nrows > 1 ? np_sum(abs_term, &dc, nrows - 1) * h : 0.0;
    double mx = fabs(AT(cd, 0));
    for (long i = 1; i < nrows; i++)
        if (fabs(AT(cd, i)) > mx)
            mx = fabs(AT(cd, i));
    out[S_MAXABS] = mx;
    long i0 = has_t_on ? searchsorted(data, ncol, ct, 0, nrows, t_on_key) : nrows;
    out[S_I0] = (double)i0;
    NONE(S_PERIOD);
    NONE(S_WIN0);
    NONE(S_WIN1);
    NONE(S_HOLD);
    NONE(S_IN_BAND);
    NONE(S_SETTLING);
    if (i0 >= nrows) {
        NONE(S_RISE), NONE(S_OVER), NONE(S_OVER_PCT), NONE(S_BAND), NONE(S_FINAL);
        *none = n_none;
        return completed ? GM_NONE : GM_STOPPED;
    }
    error_t x = {data, ncol, ct, cth, i0, nrows - i0, theta_ge, period, NULL, NULL};
    long n = x.n;
    x.ew = malloc(2 * (size_t)n * sizeof(double));
    if (x.ew == NULL)
        return GM_NUMPY;
    x.cbuf = x.ew + n;
    for (long k = 0; k < n; k++)
        x.ew[k] = wrap(e_turns(&x, k), period);
    long code = classify(&x, completed, floor_, out, &n_none, fit, fit + nrows);
    free(x.ew);
    *none = n_none;
    return code;
}

/* worker.py's estimation_rms_rad: sqrt(mean(wrap(a - b)^2)) of two columns */
typedef struct {
    const double *data;
    long ncol, ca, cb;
} diff_t;

static double wrapped_square(const void *ctx, long k)
{
    const diff_t *d = ctx;
    const double *data = d->data;
    long ncol = d->ncol;
    double e = wrap(AT(d->ca, k) - AT(d->cb, k), 2.0 * GM_PI);
    return e * e;
}

/* 0 and *rms set, or -1 (a value not finite: the caller computes it with numpy) */
int glider_wrapped_rms(const double *data, long nrows, long ncol, long ca, long cb, double *rms)
{
    if (nrows < 1)
        return -1;
    for (long i = 0; i < nrows; i++)
        if (!isfinite(AT(ca, i)) || !isfinite(AT(cb, i)))
            return -1;
    diff_t d = {data, ncol, ca, cb};
    *rms = sqrt(np_sum(wrapped_square, &d, nrows) / (double)nrows);
    return 0;
}
