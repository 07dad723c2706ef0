/* Finding a Python 3.11+ for an FMU loaded by a host without one (see python_find.c). */
#ifndef GLIDER_PYTHON_FIND_H
#define GLIDER_PYTHON_FIND_H

#include <stddef.h>

#define GLIDER_MAX_SITES 16

/* A Python installation: the libpython to load, the PYTHONHOME to start it with, the
 * sys.executable to set and the site folders to add (site.addsitedir) once it runs. */
typedef struct {
    void *handle; /* dlopen handle of libpython (RTLD_GLOBAL), set by glider_find_python */
    char libpython[1024], home[1024], executable[1024];
    char site[GLIDER_MAX_SITES][1024];
    int nsite;
    char origin[96]; /* what found it: "GLIDER_FMI_PYTHON_CONFIG", "recorded", ... */
} FoundPython;

/* Key=value lines (libpython, home, executable, site repeated; '#' comments) into *out
 * (handle NULL). 0 with a message in err if the file cannot be read or names no
 * libpython. */
int glider_read_python_config(const char *path, FoundPython *out, char *err, size_t errsize);

/* Find and dlopen a Python for an FMU whose resources folder is `resources`. Tries, in
 * order: the configuration named by $GLIDER_FMI_PYTHON_CONFIG (if set, the only one
 * tried); the recorded configuration `recorded_cfg_path`, if its libpython and home
 * still exist; the python3 on PATH, asked in a subprocess for its libpython, prefix and
 * site folders, and whether it can import the FMU's slave module from `resources`; the
 * usual system locations of libpython3.X.so.1.0 for X >= 11 (probed the same way through
 * the python3.X beside them, when there is one). Takes the first that dlopens, is Python
 * 3.11 or later, has its standard library and (when probed) imports the slave module.
 * 1 on success (out->handle set); 0 with one line in err naming what was tried and why
 * each failed. */
int glider_find_python(const char *resources, const char *recorded_cfg_path, FoundPython *out,
                       char *err, size_t errsize);

#endif
