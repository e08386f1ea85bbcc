/* The binding's shared pieces (args.c), included first by every binding file: Python and
 * NumPy with one C-API table for the whole module, the argument reader, the timed section.
 *
 * It checks only what memory safety needs (dtype, contiguity, sizes); the Python wrappers
 * in algos/ validate values and convert layouts before calling. Each area of the binding
 * (traverse.c, intersect.c, terrain.c, raster.c) adds its entry points to the module with
 * its hf_bind_* function; module.c creates the module. */
#ifndef HFTRACE_BINDING_ARGS_H
#define HFTRACE_BINDING_ARGS_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API  NPY_1_7_API_VERSION
/* one NumPy C-API table for the module: module.c imports it, the other files share it */
#define PY_ARRAY_UNIQUE_SYMBOL hf_numpy_api
#ifndef HF_BINDING_MODULE_C
#define NO_IMPORT_ARRAY
#endif
#include <numpy/arrayobject.h>
#include <time.h>
#include "core/hftrace.h"

/* An optional array argument: None, or a C-contiguous, aligned array of `type` with
 * exactly `size` elements (size < 0: at least one). */
int hf_arg_array(PyObject *object, const char *name, int type, npy_intp size, int writable,
                 int optional, void **data, npy_intp *length);

/* A float32 C-contiguous array of exactly this shape (ndim given by the shape length). */
int hf_arg_f32(PyObject *object, const char *name, int ndim, const npy_intp *shape,
               const float **data);

/* A kernel call without the GIL, timed with the monotonic clock: timed_begin releases
 * the GIL and starts the clock, timed_end stops it, takes the GIL back and returns the
 * elapsed nanoseconds. Nothing between the two may touch a Python object. */
typedef struct {
    PyThreadState *thread;
    struct timespec start;
} hf_timed_section;

void hf_timed_begin(hf_timed_section *section);
long long hf_timed_end(hf_timed_section *section);

/* The rays of a batch: origins and directions of shape (N, dim), float64, and the
 * optional ranges tmin, tmax (None, or N float64). */
typedef struct {
    npy_intp n;
    const double *origins, *directions, *tmin, *tmax;
} hf_ray_arrays;

int hf_arg_rays(PyObject *o_origins, PyObject *o_directions, PyObject *o_tmin, PyObject *o_tmax,
                int dim, hf_ray_arrays *rays);

/* The message of a kernel's error status (enum hf_status). */
const char *hf_status_text(int status);

/* Each area's entry points, added to the module (0 on success, -1 with an exception). */
int hf_bind_traverse(PyObject *module);
int hf_bind_intersect(PyObject *module);
int hf_bind_terrain(PyObject *module);
int hf_bind_raster(PyObject *module);

#endif
