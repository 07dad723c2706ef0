/* Finding a Python 3.11+ for an FMU loaded by a host without one.
 *
 * No Python function is called here: candidates are libpython files, checked by
 * dlopen, by their Py_Version (3.11 or later: the runtime uses the 3.11 stable ABI) and
 * by their standard library's presence; an interpreter found on PATH or beside a
 * system libpython is asked, in a subprocess started with posix_spawn (no shell), for
 * its libpython, prefix, executable and site folders and whether it can import the
 * FMU's slave module. The runtime then starts the chosen one (backend_python.c,
 * ensure_python). Once a libpython is started it cannot be swapped for another, which is
 * why every check is made before.
 */
#define _GNU_SOURCE
#include "python_find.h"

#include "bundle_loader.h"

#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

extern char **environ;

#define PY_MINOR_MIN 11
#define PY_MINOR_MAX 30
#define PROBE_TIMEOUT_MS 60000

static void trim_line(char *s) {
    size_t n = strlen(s);
    while (n && (s[n - 1] == '\n' || s[n - 1] == '\r' || s[n - 1] == ' ')) s[--n] = '\0';
}

int glider_read_python_config(const char *path, FoundPython *out, char *err, size_t errsize) {
    FILE *f = fopen(path, "r");
    memset(out, 0, sizeof *out);
    if (!f) {
        snprintf(err, errsize, "cannot read the Python configuration %s", path);
        return 0;
    }
    char line[1200];
    while (fgets(line, sizeof line, f)) {
        trim_line(line);
        char *eq = strchr(line, '=');
        if (line[0] == '#' || !eq) continue;
        *eq = '\0';
        const char *v = eq + 1;
        if (!strcmp(line, "libpython")) snprintf(out->libpython, sizeof out->libpython, "%s", v);
        else if (!strcmp(line, "home")) snprintf(out->home, sizeof out->home, "%s", v);
        else if (!strcmp(line, "executable"))
            snprintf(out->executable, sizeof out->executable, "%s", v);
        else if (!strcmp(line, "site") && out->nsite < GLIDER_MAX_SITES)
            snprintf(out->site[out->nsite++], sizeof out->site[0], "%s", v);
    }
    fclose(f);
    if (!out->libpython[0]) {
        snprintf(err, errsize, "%s names no libpython", path);
        return 0;
    }
    return 1;
}

static int exists(const char *path, int mode) { return path[0] && access(path, mode) == 0; }

/* dlopen the candidate's libpython and check it before anything starts it. */
static int load_candidate(FoundPython *c, char *why, size_t ws) {
    dlerror();
    void *h = dlopen(c->libpython, RTLD_NOW | RTLD_GLOBAL);
    if (!h) {
        const char *e = dlerror();
        snprintf(why, ws, "cannot load %.500s (%.400s)", c->libpython, e ? e : "dlopen failed");
        return 0;
    }
    const unsigned long *version = (const unsigned long *)dlsym(h, "Py_Version");
    if (!version || *version < 0x030B0000UL) {
        snprintf(why, ws, "%.500s is not Python 3.11 or later", c->libpython);
        dlclose(h);
        return 0;
    }
    int major = (int)(*version >> 24), minor = (int)((*version >> 16) & 0xff);
    if (c->home[0]) {
        char os_py[1200], zip[1200];
        snprintf(os_py, sizeof os_py, "%s/lib/python%d.%d/os.py", c->home, major, minor);
        snprintf(zip, sizeof zip, "%s/lib/python%d%d.zip", c->home, major, minor);
        if (!exists(os_py, R_OK) && !exists(zip, R_OK)) {
            snprintf(why, ws, "%.400s: no standard library in %.400s/lib/python%d.%d", c->libpython,
                     c->home, major, minor);
            dlclose(h);
            return 0;
        }
    }
    if (c->executable[0] && !exists(c->executable, X_OK)) c->executable[0] = '\0';
    c->handle = h;
    return 1;
}

/* What the probe runs: argv[1] = resources folder, argv[2] = module to import ("" none),
 * as the back end imports it (bundle_loader.h). */
static const char PROBE[] =
    "import os, sys, sysconfig\n"
    "sys.dont_write_bytecode = True\n"
    "v = sysconfig.get_config_var\n"
    "print('GLIDER_VER %d %d' % sys.version_info[:2])\n"
    "print('GLIDER_LIB ' + os.path.join(v('LIBDIR') or '', v('INSTSONAME') or ''))\n"
    "print('GLIDER_HOME ' + sys.base_prefix)\n"
    "print('GLIDER_EXE ' + (sys.executable or ''))\n"
    "for p in sys.path:\n"
    "    if p.endswith(('site-packages', 'dist-packages')) and os.path.isdir(p):\n"
    "        print('GLIDER_SITE ' + p)\n"
    "sys.stdout.flush()\n"
    GLIDER_BUNDLE_LOADER
    "try:\n"
    "    if sys.argv[2]:\n"
    "        glider_load(sys.argv[1], sys.argv[2], '')\n"
    "except BaseException as e:\n"
    "    t = (str(e).splitlines() or [''])[0]\n"
    "    print('GLIDER_FAIL %s: %s' % (type(e).__name__, t))\n"
    "else:\n"
    "    print('GLIDER_OK')\n";

static long ms_since(const struct timespec *t0) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (t.tv_sec - t0->tv_sec) * 1000L + (t.tv_nsec - t0->tv_nsec) / 1000000L;
}

/* Run `exe` with the probe; fill c (libpython, home, executable, sites) on success. */
static int probe(const char *exe, const char *resources, const char *module, FoundPython *c,
                 char *why, size_t ws) {
    int fd[2];
    if (pipe2(fd, O_CLOEXEC)) {
        snprintf(why, ws, "cannot ask %s (pipe: %s)", exe, strerror(errno));
        return 0;
    }
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, fd[1], 1);
    posix_spawn_file_actions_adddup2(&fa, fd[1], 2);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    char *argv[] = {(char *)exe, "-c", (char *)PROBE, (char *)resources, (char *)module, NULL};
    pid_t pid;
    int rc = posix_spawn(&pid, exe, &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    close(fd[1]);
    if (rc) {
        close(fd[0]);
        snprintf(why, ws, "cannot run %s (%s)", exe, strerror(rc));
        return 0;
    }
    char buf[65536];
    size_t n = 0;
    struct timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int timed_out = 0;
    for (;;) {
        long left = PROBE_TIMEOUT_MS - ms_since(&t0);
        if (left <= 0) {
            timed_out = 1;
            kill(pid, SIGKILL);
            break;
        }
        struct pollfd p = {fd[0], POLLIN, 0};
        int r = poll(&p, 1, (int)left);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) continue;
        ssize_t got = read(fd[0], buf + n, sizeof buf - 1 - n);
        if (got < 0 && errno == EINTR) continue;
        if (got <= 0) break;
        n += (size_t)got;
        if (n == sizeof buf - 1) break;
    }
    buf[n] = '\0';
    close(fd[0]);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (timed_out) {
        snprintf(why, ws, "%s did not answer within %d s", exe, PROBE_TIMEOUT_MS / 1000);
        return 0;
    }
    FoundPython found;
    memset(&found, 0, sizeof found);
    int ok = 0, major = 0, minor = 0;
    char fail[600] = "", other[300] = "";
    for (char *line = strtok(buf, "\n"); line; line = strtok(NULL, "\n")) {
        trim_line(line);
        if (!strncmp(line, "GLIDER_VER ", 11)) sscanf(line + 11, "%d %d", &major, &minor);
        else if (!strncmp(line, "GLIDER_LIB ", 11))
            snprintf(found.libpython, sizeof found.libpython, "%s", line + 11);
        else if (!strncmp(line, "GLIDER_HOME ", 12))
            snprintf(found.home, sizeof found.home, "%s", line + 12);
        else if (!strncmp(line, "GLIDER_EXE ", 11))
            snprintf(found.executable, sizeof found.executable, "%s", line + 11);
        else if (!strncmp(line, "GLIDER_SITE ", 12) && found.nsite < GLIDER_MAX_SITES)
            snprintf(found.site[found.nsite++], sizeof found.site[0], "%s", line + 12);
        else if (!strcmp(line, "GLIDER_OK")) ok = 1;
        else if (!strncmp(line, "GLIDER_FAIL ", 12)) snprintf(fail, sizeof fail, "%s", line + 12);
        else if (line[0]) snprintf(other, sizeof other, "%s", line);
    }
    if (major && (major != 3 || minor < PY_MINOR_MIN)) {
        snprintf(why, ws, "%s is Python %d.%d: 3.11 or later is needed", exe, major, minor);
        return 0;
    }
    if (fail[0]) {
        snprintf(why, ws, "%s cannot import %s: %s", exe, module, fail);
        return 0;
    }
    if (!ok) {
        int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        snprintf(why, ws, "%s failed (exit %d)%s%s", exe, code, other[0] ? ": " : "", other);
        return 0;
    }
    snprintf(found.origin, sizeof found.origin, "%s", c->origin);
    *c = found;
    return 1;
}

typedef struct {
    char *err;
    size_t errsize;
    int nnotes;
    char seen[32][PATH_MAX];
    int nseen;
} Search;

static void note(Search *s, const char *fmt, ...) {
    size_t used = strlen(s->err);
    if (used + 8 >= s->errsize) return;
    if (s->nnotes++) used += (size_t)snprintf(s->err + used, s->errsize - used, "; ");
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(s->err + used, s->errsize - used, fmt, ap);
    va_end(ap);
}

/* 1 if this libpython (by real path) was tried already, else remember it. */
static int seen_before(Search *s, const char *libpython) {
    char real[PATH_MAX];
    if (!realpath(libpython, real)) snprintf(real, sizeof real, "%s", libpython);
    for (int i = 0; i < s->nseen; ++i)
        if (!strcmp(s->seen[i], real)) return 1;
    if (s->nseen < 32) snprintf(s->seen[s->nseen++], sizeof s->seen[0], "%s", real);
    return 0;
}

/* Probe an interpreter and load the libpython it names. */
static int try_interpreter(Search *s, const char *label, const char *exe, const char *resources,
                           const char *module, FoundPython *out) {
    FoundPython c;
    char why[1200];
    memset(&c, 0, sizeof c);
    snprintf(c.origin, sizeof c.origin, "%s", label);
    if (!probe(exe, resources, module, &c, why, sizeof why)) {
        note(s, "%s: %s", label, why);
        return 0;
    }
    if (seen_before(s, c.libpython)) return 0;
    if (!load_candidate(&c, why, sizeof why)) {
        note(s, "%s (%s): %s", label, exe, why);
        return 0;
    }
    *out = c;
    return 1;
}

static int find_on_path(const char *name, char *out, size_t size) {
    const char *path = getenv("PATH");
    if (!path) return 0;
    const char *p = path;
    while (*p) {
        const char *colon = strchr(p, ':');
        size_t len = colon ? (size_t)(colon - p) : strlen(p);
        if (len) {
            snprintf(out, size, "%.*s/%s", (int)len, p, name);
            struct stat st;
            if (!stat(out, &st) && S_ISREG(st.st_mode) && !access(out, X_OK)) return 1;
        }
        p += len + (colon != NULL);
    }
    return 0;
}

static void slave_module(const char *resources, char *module, size_t size) {
    char path[1200];
    snprintf(path, sizeof path, "%s/slavemodule.txt", resources);
    module[0] = '\0';
    FILE *f = fopen(path, "r");
    if (!f) return;
    if (!fgets(module, (int)size, f)) module[0] = '\0';
    fclose(f);
    trim_line(module);
}

static const char *const LIB_DIRS[] = {"/usr/local/lib", "/usr/lib/x86_64-linux-gnu",
                                       "/usr/lib/aarch64-linux-gnu", "/usr/lib64", "/usr/lib"};
#define N_LIB_DIRS (sizeof LIB_DIRS / sizeof LIB_DIRS[0])

int glider_find_python(const char *resources, const char *recorded_cfg_path, FoundPython *out,
                       char *err, size_t errsize) {
    char why[1200], module[256];
    memset(out, 0, sizeof *out);
    err[0] = '\0';
    const char *override = getenv("GLIDER_FMI_PYTHON_CONFIG");
    if (override && override[0]) {
        /* named by the user: the only one tried, so that a mistake is not hidden */
        if (!glider_read_python_config(override, out, why, sizeof why) ||
            !load_candidate(out, why, sizeof why)) {
            snprintf(err, errsize, "%s; fix or unset GLIDER_FMI_PYTHON_CONFIG=%s (while it is "
                                   "set, no other Python is tried)", why, override);
            return 0;
        }
        snprintf(out->origin, sizeof out->origin, "GLIDER_FMI_PYTHON_CONFIG");
        return 1;
    }
    static Search search; /* large; callers hold the runtime's lock */
    Search *s = &search;
    memset(s, 0, sizeof *s);
    s->err = err;
    s->errsize = errsize;
    snprintf(err, errsize, "no usable Python 3.11 or later; tried: ");
    slave_module(resources, module, sizeof module);
    /* 1. the interpreter recorded at build time */
    FoundPython c;
    if (!glider_read_python_config(recorded_cfg_path, &c, why, sizeof why)) {
        note(s, "recorded: %s", why);
    } else if (!exists(c.libpython, R_OK)) {
        note(s, "recorded %s: not found", c.libpython);
        seen_before(s, c.libpython);
    } else if (c.home[0] && !exists(c.home, X_OK)) {
        note(s, "recorded %s: its home %s is not found", c.libpython, c.home);
        seen_before(s, c.libpython);
    } else {
        seen_before(s, c.libpython);
        if (load_candidate(&c, why, sizeof why)) {
            snprintf(c.origin, sizeof c.origin, "recorded");
            *out = c;
            return 1;
        }
        note(s, "recorded: %s", why);
    }
    /* 2. python3 on PATH */
    char exe[PATH_MAX];
    if (find_on_path("python3", exe, sizeof exe)) {
        if (try_interpreter(s, "python3 on PATH", exe, resources, module, out)) return 1;
    } else {
        note(s, "python3: not on PATH");
    }
    /* 3. system locations, newest first */
    int any = 0;
    for (int minor = PY_MINOR_MAX; minor >= PY_MINOR_MIN; --minor) {
        for (size_t d = 0; d < N_LIB_DIRS; ++d) {
            memset(&c, 0, sizeof c);
            snprintf(c.libpython, sizeof c.libpython, "%s/libpython3.%d.so.1.0", LIB_DIRS[d],
                     minor);
            if (!exists(c.libpython, R_OK)) continue;
            any = 1;
            /* prefix: the folder above lib/ */
            snprintf(c.home, sizeof c.home, "%s", LIB_DIRS[d]);
            char *lib = strstr(c.home, "/lib");
            if (lib) *lib = '\0';
            snprintf(exe, sizeof exe, "%s/bin/python3.%d", c.home, minor);
            if (exists(exe, X_OK)) {
                if (seen_before(s, c.libpython)) continue;
                s->nseen--; /* the probe names the library; let it be compared again */
                if (try_interpreter(s, c.libpython, exe, resources, module, out)) return 1;
                continue;
            }
            if (seen_before(s, c.libpython)) continue;
            snprintf(c.origin, sizeof c.origin, "system");
            if (load_candidate(&c, why, sizeof why)) {
                *out = c;
                return 1;
            }
            note(s, "%s", why);
        }
    }
    if (!any)
        note(s, "no libpython3.X.so.1.0 (X >= %d) in /usr/local/lib, /usr/lib/<multiarch>, "
                "/usr/lib64 or /usr/lib", PY_MINOR_MIN);
    size_t n = strlen(err);
    snprintf(err + n, errsize - n, "; install a Python 3.11+ with its shared library (Debian: "
                                   "apt-get install python3 libpython3.11) or set "
                                   "GLIDER_FMI_PYTHON_CONFIG");
    return 0;
}
