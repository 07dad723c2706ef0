/* The part of Python's stable ABI (limited API 3.11) the Python back end calls, declared
 * here so that the runtime builds without Python's headers (any Python, any platform,
 * or none: the FMUs are cross-compiled).
 *
 * Nothing here is linked: the back end takes each function's type with
 * __typeof__(&name) and resolves the function itself with dlsym (PY_FUNCTIONS in
 * backend_python.c), so only the exact prototypes matter. They are Python.h's: a test
 * compiles this file after Python.h (tests/integration/test_runtime.py), where a
 * prototype that differs from Python's is a "conflicting types" error. The types are
 * opaque (only pointers to them are used), as in the limited API.
 */
#ifndef GLIDER_PYTHON_H
#define GLIDER_PYTHON_H

#include <stddef.h>
#include <sys/types.h> /* ssize_t */

#ifndef Py_PYTHON_H /* Python.h included before (the test): its own types */
typedef ssize_t Py_ssize_t;
typedef struct _object PyObject;
typedef struct _typeobject PyTypeObject;
typedef struct _ts PyThreadState;
typedef enum { PyGILState_LOCKED, PyGILState_UNLOCKED } PyGILState_STATE;
#endif

/* interpreter, GIL and thread states */
int Py_IsInitialized(void);
void Py_InitializeEx(int);
PyThreadState *PyEval_SaveThread(void);
void PyEval_RestoreThread(PyThreadState *);
PyGILState_STATE PyGILState_Ensure(void);
void PyGILState_Release(PyGILState_STATE);
PyThreadState *PyGILState_GetThisThreadState(void);
void PyThreadState_Clear(PyThreadState *);
void PyThreadState_Delete(PyThreadState *);

/* references and errors */
void Py_IncRef(PyObject *);
void Py_DecRef(PyObject *);
PyObject *PyErr_Occurred(void);
void PyErr_Fetch(PyObject **, PyObject **, PyObject **);
void PyErr_Restore(PyObject *, PyObject *, PyObject *);
void PyErr_NormalizeException(PyObject **, PyObject **, PyObject **);
void PyErr_Clear(void);

/* objects, attributes, calls */
Py_ssize_t PyObject_Size(PyObject *);
PyObject *PyObject_Str(PyObject *);
PyObject *PyObject_GetAttr(PyObject *, PyObject *);
PyObject *PyObject_GetAttrString(PyObject *, const char *);
PyObject *PyObject_Call(PyObject *, PyObject *, PyObject *);
PyObject *PyObject_CallFunctionObjArgs(PyObject *, ...);
int PyObject_IsTrue(PyObject *);
PyObject *PyObject_GetIter(PyObject *);
PyObject *PyIter_Next(PyObject *);
PyObject *PyType_GetName(PyTypeObject *);
PyObject *PyImport_ImportModule(const char *);
PyObject *PySys_GetObject(const char *);
int PySys_SetObject(const char *, PyObject *);

/* str, int, float, bool, bytes */
const char *PyUnicode_AsUTF8AndSize(PyObject *, Py_ssize_t *);
PyObject *PyUnicode_FromString(const char *);
PyObject *PyUnicode_InternFromString(const char *);
PyObject *PyLong_FromLong(long);
long PyLong_AsLong(PyObject *);
PyObject *PyFloat_FromDouble(double);
double PyFloat_AsDouble(PyObject *);
PyObject *PyBool_FromLong(long);
PyObject *PyBytes_FromStringAndSize(const char *, Py_ssize_t);
int PyBytes_AsStringAndSize(PyObject *, char **, Py_ssize_t *);

/* list, tuple, dict, sequence */
PyObject *PyList_New(Py_ssize_t);
int PyList_SetItem(PyObject *, Py_ssize_t, PyObject *);
int PyList_SetSlice(PyObject *, Py_ssize_t, Py_ssize_t, PyObject *);
PyObject *PyTuple_New(Py_ssize_t);
int PyTuple_SetItem(PyObject *, Py_ssize_t, PyObject *);
PyObject *PyDict_New(void);
int PyDict_SetItemString(PyObject *, const char *, PyObject *);
Py_ssize_t PySequence_Size(PyObject *);
PyObject *PySequence_GetItem(PyObject *, Py_ssize_t);

#endif
