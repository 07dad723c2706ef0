/* This machine's floor for paced loops, for bench/realtime.py: no Python, no FMU, only the
 * pacer. N points every 20 ms (50 Hz) on CLOCK_MONOTONIC; each waits with an absolute
 * clock_nanosleep until SPIN_US before its deadline, then spins to it (what the master's
 * pacer does, in C). Prints {"p50": ..., "p99": ..., "max": ...}: how late the points
 * started, ms.
 *
 * usage: pacing_floor N SPIN_US
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static long long now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (long long)t.tv_sec * 1000000000LL + t.tv_nsec;
}

static int by_value(const void *a, const void *b) {
    long long x = *(const long long *)a, y = *(const long long *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    long n, k;
    long long spin, start, *late;
    if (argc != 3 || (n = atol(argv[1])) < 1 || (spin = atoll(argv[2]) * 1000) < 0) {
        fprintf(stderr, "usage: pacing_floor N SPIN_US (N >= 1 points, SPIN_US >= 0)\n");
        return 2;
    }
    if (!(late = malloc((size_t)n * sizeof *late))) return 1;
    start = now_ns();
    for (k = 0; k < n; ++k) {
        long long due = start + (k + 1) * 20000000LL, wake = due - spin, now;
        struct timespec ts;
        ts.tv_sec = (time_t)(wake / 1000000000LL);
        ts.tv_nsec = (long)(wake % 1000000000LL);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL)) continue;
        while ((now = now_ns()) < due) continue;
        late[k] = now - due;
    }
    qsort(late, (size_t)n, sizeof *late, by_value);
    printf("{\"p50\": %.4f, \"p99\": %.4f, \"max\": %.4f}\n", late[n / 2] / 1e6,
           late[n * 99 / 100] / 1e6, late[n - 1] / 1e6);
    free(late);
    return 0;
}
