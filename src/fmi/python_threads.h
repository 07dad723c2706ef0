/* The GIL per FMI call, with one Python thread state kept per host thread (python_threads.c). */
#ifndef GLIDER_PYTHON_THREADS_H
#define GLIDER_PYTHON_THREADS_H

#include "glider_python.h"

/* The stable-ABI functions used here, resolved by the runtime (its PY_FUNCTIONS). */
typedef struct {
    PyGILState_STATE (*ensure)(void);
    void (*release)(PyGILState_STATE);
    PyThreadState *(*this_thread)(void);
    PyThreadState *(*save_thread)(void);
    void (*restore_thread)(PyThreadState *);
    void (*clear)(PyThreadState *);
    void (*delete_)(PyThreadState *);
    int (*is_initialized)(void);
} GliderGilApi;

/* Once Python is usable (the functions resolved). */
void glider_threads_init(const GliderGilApi *api);
/* Take the GIL for one call (PyGILState_Ensure). On a host thread Python has never
 * seen, the thread state created there is kept (pinned) for the thread's life, so that
 * later calls neither create nor destroy one. */
PyGILState_STATE glider_gil_ensure(void);
/* Give the GIL back after a call (PyGILState_Release). */
void glider_gil_release(PyGILState_STATE state);
/* Drop this thread's pinned thread state, if it has one (the last instance was freed
 * here). Without the GIL. */
void glider_thread_unpin(void);

#endif
