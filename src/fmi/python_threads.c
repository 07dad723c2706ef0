/* The GIL per FMI call, with one Python thread state kept per host thread.
 *
 * PyGILState_Ensure on a thread Python has never seen (a host's worker thread, as
 * libcosim and Ecos step from) creates a thread state, and the matching
 * PyGILState_Release destroys it again: on every call. Here the first call on such a
 * thread takes one more PyGILState_Ensure (the pin) and gives the GIL back with
 * PyEval_SaveThread: the thread state stays, with the GIL-state counter at 1, and later
 * Ensure/Release pairs only take and release the GIL. Dropping a pin: restore the state,
 * PyThreadState_Clear, PyEval_SaveThread, PyThreadState_Delete (all stable ABI).
 *
 * A thread state must be deleted by its own thread: deleting it from another one (the
 * thread calling fmi2FreeInstance) leaves that thread's GIL-state slot pointing at freed
 * memory. So the pin is dropped by the thread itself: when it frees the process's last
 * instance of this FMU (fmi2FreeInstance, glider_thread_unpin), or when it exits (a
 * pthread key destructor). Pins left when the library is unloaded stay valid thread
 * states of their threads, which the interpreter frees when it finalizes.
 *
 * Only stable-ABI functions, reached through the runtime's resolved pointers.
 */
#include "python_threads.h"

#include <pthread.h>

static GliderGilApi api;
static pthread_key_t pin_key;
static pthread_once_t pin_once = PTHREAD_ONCE_INIT;
static int pin_key_ok;
static __thread PyThreadState *t_pinned; /* this thread's pinned state, or NULL */

/* On the pinned thread, GIL not held. Through the thread state itself, not the
 * PyGILState functions: at thread exit the C library has already emptied Python's
 * thread-specific slot (so PyGILState_* no longer sees the state). */
static void drop_pin(PyThreadState *ts) {
    api.restore_thread(ts);
    api.clear(ts);
    api.save_thread();
    api.delete_(ts);
}

static void thread_exit(void *ts) {
    if (ts && ts == t_pinned && api.is_initialized && api.is_initialized()) drop_pin(ts);
    t_pinned = NULL;
}

static void make_key(void) { pin_key_ok = pthread_key_create(&pin_key, thread_exit) == 0; }

__attribute__((destructor)) static void unload(void) {
    /* no destructor may run in this library once it is unmapped */
    if (pin_key_ok) pthread_key_delete(pin_key);
    pin_key_ok = 0;
}

void glider_threads_init(const GliderGilApi *a) {
    api = *a;
    pthread_once(&pin_once, make_key);
}

PyGILState_STATE glider_gil_ensure(void) {
    if (!t_pinned && pin_key_ok && !api.this_thread()) {
        /* a thread Python has never seen: create its thread state once and keep it */
        PyGILState_STATE g = api.ensure();
        (void)g; /* PyGILState_UNLOCKED: the state was created here */
        PyThreadState *ts = api.this_thread();
        if (ts && pthread_setspecific(pin_key, ts) == 0) {
            t_pinned = ts;
            api.save_thread(); /* the GIL back; the state stays (counter 1) */
        } else {
            api.release(g); /* cannot pin: behave as before */
        }
    }
    return api.ensure();
}

void glider_gil_release(PyGILState_STATE state) { api.release(state); }

void glider_thread_unpin(void) {
    if (!t_pinned) return;
    if (pin_key_ok) pthread_setspecific(pin_key, NULL);
    PyThreadState *ts = t_pinned;
    t_pinned = NULL;
    if (api.is_initialized()) drop_pin(ts);
}
