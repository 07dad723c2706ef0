/* Drives the CSV recorder's C writer thread (cosim/master/csvwriter.c) as the recorder
 * does, for tests/integration/test_csv_writer_thread.py, under ThreadSanitizer, ASan and
 * valgrind:
 *
 *   harness rows <csv> <bin> <ncol> <nslots> <blocks> <seed>
 *       blocks of 1..300 rows of random doubles (any bit pattern) handed over one by
 *       one; the doubles also written raw to <bin> (the test formats them with repr);
 *   harness fail <csv> <blocks>
 *       a file that cannot be written (/dev/full, a missing folder): prints the errno
 *       glider_csv_put and glider_csv_close return (the put's once the writer failed);
 *   harness idle <csv>
 *       a writer closed without being started (a run that failed before its first row):
 *       prints the errno of a put before the start and of glider_csv_close.
 *
 * Exit 0 when every call returned what it should.
 */
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void *glider_csv_open(const char *path, int nslots);
int glider_csv_start(void *handle, const char *header, long header_len, int ncol);
int glider_csv_put(void *handle, const double *values, int nrows);
int glider_csv_close(void *handle);

static uint64_t state;

static uint64_t next(void) { /* xorshift64* */
    state ^= state >> 12;
    state ^= state << 25;
    state ^= state >> 27;
    return state * UINT64_C(2685821657736338717);
}

static int rows(const char *csv, const char *bin, int ncol, int nslots, int blocks) {
    FILE *raw = fopen(bin, "wb");
    if (raw == NULL) return 2;
    char header[64];
    int hl = snprintf(header, sizeof header, "t,c1,c2\n");
    void *w = glider_csv_open(csv, nslots);
    if (w == NULL) {
        fclose(raw);
        return 3;
    }
    if (glider_csv_start(w, header, hl, ncol) != 0 || glider_csv_start(w, header, hl, ncol) !=
                                                          EINVAL) { /* once only */
        fclose(raw);
        glider_csv_close(w);
        return 7;
    }
    double *block = malloc(sizeof(double) * 300 * (size_t)ncol);
    for (int b = 0; b < blocks; ++b) {
        int n = 1 + (int)(next() % 300);
        for (int i = 0; i < n * ncol; ++i) {
            uint64_t bits = next();
            memcpy(&block[i], &bits, sizeof bits);
        }
        fwrite(block, sizeof(double), (size_t)n * ncol, raw);
        int err = glider_csv_put(w, block, n);
        memset(block, 0xff, sizeof(double) * (size_t)n * ncol); /* copied: reuse is safe */
        if (err) {
            fprintf(stderr, "put: %s\n", strerror(err));
            return 4;
        }
    }
    free(block);
    fclose(raw);
    int err = glider_csv_close(w);
    if (err) fprintf(stderr, "close: %s\n", strerror(err));
    return err ? 5 : 0;
}

static int fail(const char *csv, int blocks) {
    void *w = glider_csv_open(csv, 2);
    if (w == NULL) return 3;
    if (glider_csv_start(w, "a\n", 2, 1) != 0) {
        glider_csv_close(w);
        return 7;
    }
    double v = 1.0;
    int put = 0;
    for (int b = 0; b < blocks && !put; ++b) put = glider_csv_put(w, &v, 1);
    int closed = glider_csv_close(w);
    printf("put %d close %d\n", put, closed);
    return closed ? 0 : 6;
}

static int idle(const char *csv) {
    void *w = glider_csv_open(csv, 4);
    if (w == NULL) return 3;
    double v = 1.0;
    int put = glider_csv_put(w, &v, 1);
    int closed = glider_csv_close(w);
    printf("put %d close %d\n", put, closed);
    return 0;
}

int main(int argc, char **argv) {
    if (argc == 8 && strcmp(argv[1], "rows") == 0) {
        state = strtoull(argv[7], NULL, 10) | 1;
        return rows(argv[2], argv[3], atoi(argv[4]), atoi(argv[5]), atoi(argv[6]));
    }
    if (argc == 4 && strcmp(argv[1], "fail") == 0) return fail(argv[2], atoi(argv[3]));
    if (argc == 3 && strcmp(argv[1], "idle") == 0) return idle(argv[2]);
    fprintf(stderr, "usage: harness rows <csv> <bin> <ncol> <nslots> <blocks> <seed> | "
                    "harness fail <csv> <blocks> | harness idle <csv>\n");
    return 2;
}
