/* The CSV recorder's writer thread, in C (glider_cosim.runner.recorders.CsvRecorder):
 * the thread starts, and creates the file, when the recorder is made (glider_csv_open),
 * before the run knows its columns; the run gives it the header (glider_csv_start), then
 * hands blocks of rows over (copied into one of a few slots), and the thread writes the
 * header, formats the blocks (glider_format_rows, Python's repr of each value) and writes
 * them, in order. It never takes the GIL: handing a block over costs the run a copy and a
 * wake-up, not a hand-off of the interpreter between two threads (which, with a Python
 * writer thread, slowed the run's own blocks by half). Starting the thread (0.14-0.2 ms
 * here) and creating the file (0.25-0.45 ms on this machine's ext4 after a run's writes)
 * overlap the FMUs' initialisation, not the run.
 *
 * The first failure (the file cannot be created, a full disk) stops the writing; its
 * errno is returned by the next glider_csv_put and by glider_csv_close. Signals are blocked in the thread (they
 * are the main thread's to handle). POSIX threads only: on Windows glider_csv_open
 * returns NULL (ENOSYS) and the recorder keeps its Python thread.
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "shortest.h"

long glider_format_rows(const double *values, int nrows, int ncol, char *out, long size);

#ifndef _WIN32
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#ifndef O_CLOEXEC
#define O_CLOEXEC 0
#endif

/* A slot's state: filled by the caller, being formatted (by the thread or, helping,
 * by the caller), formatted (its text waits for its turn to be written). */
enum { FILLED, FORMATTING, FORMATTED };

typedef struct {
    double *values;
    long capacity; /* doubles */
    int nrows;
    int state;     /* under mu */
    char *text;    /* its text, once formatted */
    long text_size, text_len;
    int error;     /* of formatting it (ENOMEM), else 0 */
} Slot;

typedef struct {
    char *path, *header; /* copies; the header is written first (NULL until started) */
    long header_len;
    int fd, ncol, nslots; /* ncol: 0 until started */
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t freed, filled, formatted;
    Slot *slots;
    int head, count; /* the oldest filled slot, how many are filled (under mu) */
    int started;     /* the header is given (under mu) */
    int closing;     /* no more blocks (under mu) */
    int error;       /* errno of the first failed write or allocation, else 0 (under mu) */
} Writer;

/* Writes all n bytes of p to fd: 0, else errno. */
static int write_all(int fd, const char *p, long n) {
    while (n > 0) {
        ssize_t w = write(fd, p, (size_t)n);
        if (w < 0) {
            if (errno == EINTR) continue;
            return errno ? errno : EIO;
        }
        if (w == 0) return EIO;
        p += w;
        n -= (long)w;
    }
    return 0;
}

/* Formats slot s into its text (outside the lock: the slot is ours while FORMATTING). */
static void format_slot(const Writer *w, Slot *s) {
    long need = (long)s->nrows * w->ncol * (GLIDER_REPR_MAX + 1) + GLIDER_REPR_ROOM;
    s->error = 0;
    if (need > s->text_size) {
        char *grown = realloc(s->text, (size_t)need);
        if (grown == NULL) {
            s->error = ENOMEM;
            return;
        }
        s->text = grown;
        s->text_size = need;
    }
    s->text_len = glider_format_rows(s->values, s->nrows, w->ncol, s->text, s->text_size);
    if (s->text_len < 0) s->error = EOVERFLOW; /* cannot happen: sized for the longest */
}

/* The newest FILLED slot but the oldest (the thread's next), or NULL: what the caller
 * formats while it would otherwise wait (a full queue, close). Under mu. */
static Slot *newest_filled(Writer *w) {
    for (int k = w->count - 1; k >= 1; --k) {
        Slot *s = &w->slots[(w->head + k) % w->nslots];
        if (s->state == FILLED) return s;
    }
    return NULL;
}

/* The caller formats one slot for the thread, if one waits behind its next: 1 if it
 * did. Under mu (released while formatting). */
static int help(Writer *w) {
    Slot *s = w->error ? NULL : newest_filled(w);
    if (s == NULL) return 0;
    s->state = FORMATTING;
    pthread_mutex_unlock(&w->mu);
    format_slot(w, s);
    pthread_mutex_lock(&w->mu);
    s->state = FORMATTED;
    pthread_cond_signal(&w->formatted);
    return 1;
}

/* The thread: creates (or truncates) the file, waits for the header and writes it,
 * then the slots in order: formatted here (or by the caller, helping: then waited for)
 * and written. After a failure the slots are dropped. Closed before it was started, it
 * leaves the file empty. */
static void *writer_main(void *arg) {
    Writer *w = arg;
    w->fd = open(w->path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    int opened = w->fd < 0 ? (errno ? errno : EIO) : 0;
    pthread_mutex_lock(&w->mu);
    if (opened && !w->error) w->error = opened;
    while (!w->started && !w->closing) pthread_cond_wait(&w->filled, &w->mu);
    if (w->started && !w->error) {
        pthread_mutex_unlock(&w->mu);
        int err = write_all(w->fd, w->header, w->header_len);
        pthread_mutex_lock(&w->mu);
        if (err && !w->error) w->error = err;
    }
    for (;;) {
        while (w->count == 0 && !w->closing) pthread_cond_wait(&w->filled, &w->mu);
        if (w->count == 0) break; /* closing, all written */
        Slot *s = &w->slots[w->head];
        if (s->state == FILLED && !w->error) {
            s->state = FORMATTING;
            pthread_mutex_unlock(&w->mu);
            format_slot(w, s);
            pthread_mutex_lock(&w->mu);
            s->state = FORMATTED;
        }
        while (s->state == FORMATTING) pthread_cond_wait(&w->formatted, &w->mu);
        int err = w->error ? 0 : s->error;
        if (!w->error && !err) {
            pthread_mutex_unlock(&w->mu);
            err = write_all(w->fd, s->text, s->text_len);
            pthread_mutex_lock(&w->mu);
        }
        if (err && !w->error) w->error = err;
        w->head = (w->head + 1) % w->nslots;
        w->count--;
        pthread_cond_signal(&w->freed);
    }
    pthread_mutex_unlock(&w->mu);
    if (w->fd >= 0 && close(w->fd) != 0) {
        int err = errno ? errno : EIO;
        pthread_mutex_lock(&w->mu);
        if (!w->error) w->error = err;
        pthread_mutex_unlock(&w->mu);
    }
    return NULL;
}

static void destroy(Writer *w) {
    for (int i = 0; i < w->nslots; ++i) {
        free(w->slots[i].values);
        free(w->slots[i].text);
    }
    free(w->slots);
    free(w->path);
    free(w->header);
    pthread_cond_destroy(&w->freed);
    pthread_cond_destroy(&w->filled);
    pthread_cond_destroy(&w->formatted);
    pthread_mutex_destroy(&w->mu);
    free(w);
}

/* A writer of the file at path, created (or truncated) now by its thread, with at most
 * nslots blocks waiting; NULL (errno set) if it cannot start. A file that cannot be
 * created is a failure of the writer (below). */
void *glider_csv_open(const char *path, int nslots) {
    if (path == NULL || nslots < 1) {
        errno = EINVAL;
        return NULL;
    }
    Writer *w = calloc(1, sizeof *w);
    if (w == NULL) return NULL;
    w->fd = -1;
    w->nslots = nslots;
    w->slots = calloc((size_t)nslots, sizeof *w->slots);
    w->path = malloc(strlen(path) + 1);
    if (w->slots == NULL || w->path == NULL) {
        free(w->slots);
        free(w->path);
        free(w);
        errno = ENOMEM;
        return NULL;
    }
    strcpy(w->path, path);
    pthread_mutex_init(&w->mu, NULL);
    pthread_cond_init(&w->freed, NULL);
    pthread_cond_init(&w->filled, NULL);
    pthread_cond_init(&w->formatted, NULL);
    sigset_t all, old;
    sigfillset(&all);
    pthread_sigmask(SIG_SETMASK, &all, &old); /* the thread starts with every signal blocked */
    int err = pthread_create(&w->thread, NULL, writer_main, w);
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    if (err) {
        destroy(w);
        errno = err;
        return NULL;
    }
    return w;
}

/* The rows' header (header_len bytes, written first) and width (ncol doubles a row),
 * once: 0, else EINVAL (started before, or no column) or ENOMEM. */
int glider_csv_start(void *handle, const char *header, long header_len, int ncol) {
    Writer *w = handle;
    if (header == NULL || header_len < 0 || ncol < 1 || w->started) return EINVAL;
    char *copy = malloc((size_t)header_len + 1);
    if (copy == NULL) return ENOMEM;
    memcpy(copy, header, (size_t)header_len);
    pthread_mutex_lock(&w->mu);
    w->header = copy;
    w->header_len = header_len;
    w->ncol = ncol;
    w->started = 1;
    pthread_cond_signal(&w->filled);
    pthread_mutex_unlock(&w->mu);
    return 0;
}

/* Hands nrows rows of values (copied) to the writer, waiting for a free slot if none
 * is: 0, else the errno of the writer's first failure (the rows are not taken), or
 * EINVAL before glider_csv_start. */
int glider_csv_put(void *handle, const double *values, int nrows) {
    Writer *w = handle;
    if (nrows <= 0) return 0;
    if (!w->started) return EINVAL;
    pthread_mutex_lock(&w->mu);
    while (w->count == w->nslots && !w->error) /* full: format one for the thread, or wait */
        if (!help(w)) pthread_cond_wait(&w->freed, &w->mu);
    int err = w->error;
    Slot *s = &w->slots[(w->head + w->count) % w->nslots]; /* free: the thread skips it */
    pthread_mutex_unlock(&w->mu);
    if (err) return err;
    long need = (long)nrows * w->ncol;
    if (need > s->capacity) {
        double *grown = realloc(s->values, (size_t)need * sizeof *grown);
        if (grown == NULL) return ENOMEM;
        s->values = grown;
        s->capacity = need;
    }
    memcpy(s->values, values, (size_t)need * sizeof *values);
    s->nrows = nrows;
    pthread_mutex_lock(&w->mu);
    s->state = FILLED;
    w->count++;
    pthread_cond_signal(&w->filled);
    pthread_mutex_unlock(&w->mu);
    return 0;
}

/* Writes what was handed over, closes the file, ends the thread and frees the writer:
 * 0, else the errno of its first failure. */
int glider_csv_close(void *handle) {
    Writer *w = handle;
    pthread_mutex_lock(&w->mu);
    w->closing = 1;
    pthread_cond_signal(&w->filled);
    while (help(w)) { /* the blocks still waiting: formatted from the newest, with the thread */
    }
    pthread_mutex_unlock(&w->mu);
    pthread_join(w->thread, NULL);
    int err = w->error;
    destroy(w);
    return err;
}

#else /* _WIN32: no writer thread here (the recorder's Python thread writes) */

void *glider_csv_open(const char *path, int nslots) {
    (void)path, (void)nslots;
    errno = ENOSYS;
    return NULL;
}

int glider_csv_start(void *handle, const char *header, long header_len, int ncol) {
    (void)handle, (void)header, (void)header_len, (void)ncol;
    return ENOSYS;
}

int glider_csv_put(void *handle, const double *values, int nrows) {
    (void)handle, (void)values, (void)nrows;
    return ENOSYS;
}

int glider_csv_close(void *handle) {
    (void)handle;
    return ENOSYS;
}

#endif
