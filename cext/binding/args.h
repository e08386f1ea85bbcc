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

/* The binding's own functions are shared by its files only: hidden from the dynamic
 * symbol table, so a call between two binding files is a direct call, not a jump through
 * the procedure linkage table (the entry points reach Python through the method tables). */
#if defined(__GNUC__) || defined(__clang__)
#define HF_BINDING __attribute__((visibility("hidden")))
#else
#define HF_BINDING
#endif

/* An optional array argument: None, or a C-contiguous, aligned array of `type` with
 * exactly `size` elements (size < 0: at least one). */
static inline int hf_arg_array(PyObject *object, const char *name, int type, npy_intp size,
                               int writable, int optional, void **data, npy_intp *length) {
    PyArrayObject *array;
    *data = NULL;
    if (length) *length = 0;
    if (object == Py_None) {
        if (optional) return 1;
        PyErr_Format(PyExc_TypeError, "%s: an array is required, not None", name);
        return 0;
    }
    if (!PyArray_Check(object)) {
        PyErr_Format(PyExc_TypeError, "%s: expected a numpy array, got %s", name,
                     Py_TYPE(object)->tp_name);
        return 0;
    }
    array = (PyArrayObject *)object;
    if (PyArray_TYPE(array) != type || !PyArray_ISCARRAY_RO(array) ||
        !PyArray_ISNOTSWAPPED(array) || (writable && !PyArray_ISWRITEABLE(array))) {
        PyErr_Format(PyExc_TypeError,
                     "%s: expected a C-contiguous, aligned, native-order%s array of dtype "
                     "%s",
                     name, writable ? ", writable" : "",
                     type == NPY_FLOAT64   ? "float64"
                     : type == NPY_FLOAT32 ? "float32"
                     : type == NPY_INT64   ? "int64"
                     : type == NPY_INT32   ? "int32"
                                           : "uint64");
        return 0;
    }
    if (size >= 0 && PyArray_SIZE(array) != size) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd elements, got %zd", name, (Py_ssize_t)size,
                     (Py_ssize_t)PyArray_SIZE(array));
        return 0;
    }
    *data = PyArray_DATA(array);
    if (length) *length = PyArray_SIZE(array);
    return 1;
}

/* A float32 C-contiguous array of exactly this shape (ndim given by the shape length). */
static inline int hf_arg_f32(PyObject *object, const char *name, int ndim, const npy_intp *shape,
                             const float **data) {
    PyArrayObject *a;
    int k;
    if (!PyArray_Check(object)) {
        PyErr_Format(PyExc_TypeError, "%s: expected a numpy array", name);
        return 0;
    }
    a = (PyArrayObject *)object;
    if (PyArray_TYPE(a) != NPY_FLOAT32 || !PyArray_ISCARRAY_RO(a) || !PyArray_ISNOTSWAPPED(a) ||
        PyArray_NDIM(a) != ndim) {
        PyErr_Format(PyExc_TypeError, "%s: expected a C-contiguous native float32 array of %d dims",
                     name, ndim);
        return 0;
    }
    for (k = 0; k < ndim; ++k) {
        if (PyArray_DIM(a, k) != shape[k]) {
            PyErr_Format(PyExc_ValueError, "%s: dimension %d is %zd, expected %zd", name, k,
                         (Py_ssize_t)PyArray_DIM(a, k), (Py_ssize_t)shape[k]);
            return 0;
        }
    }
    *data = (const float *)PyArray_DATA(a);
    return 1;
}

/* An output array: a writable, C-contiguous, aligned, native-order array of `type` with
 * exactly `size` elements (with optional, None too: *data is then NULL). The messages are
 * hf_arg_array's. */
static inline int hf_arg_out(PyObject *object, const char *name, int type, npy_intp size,
                             int optional, void **data) {
    return hf_arg_array(object, name, type, size, 1, optional, data, NULL);
}

/* A float32 output of exactly this shape (hf_arg_f32), writable: "<name>: must be
 * writable" (ValueError) otherwise. */
static inline int hf_arg_f32_out(PyObject *object, const char *name, int ndim,
                                 const npy_intp *shape, float **data) {
    const float *read;
    if (!hf_arg_f32(object, name, ndim, shape, &read)) return 0;
    if (!PyArray_ISWRITEABLE((PyArrayObject *)object)) {
        PyErr_Format(PyExc_ValueError, "%s: must be writable", name);
        return 0;
    }
    *data = (float *)read;
    return 1;
}

/* The shape (rows, cols) of a 2D array, its dtype and layout left to the caller's reader:
 * a grid of vertices (HF_GRID_VERTICES, each side in [2, 2^24]) or of the cells between
 * them (HF_GRID_CELLS, each side in [1, 2^24 - 1]). */
enum hf_grid_kind { HF_GRID_VERTICES, HF_GRID_CELLS };

static inline int hf_arg_grid_shape(PyObject *object, const char *name, enum hf_grid_kind kind,
                                    npy_intp shape[2]) {
    /* a cell grid has one cell fewer per side than the vertices around it */
    const npy_intp fewer = kind == HF_GRID_CELLS ? 1 : 0;
    if (!PyArray_Check(object) || PyArray_NDIM((PyArrayObject *)object) != 2) {
        PyErr_Format(PyExc_TypeError, "%s: expected a 2D numpy array", name);
        return 0;
    }
    shape[0] = PyArray_DIM((PyArrayObject *)object, 0);
    shape[1] = PyArray_DIM((PyArrayObject *)object, 1);
    if (shape[0] < 2 - fewer || shape[1] < 2 - fewer || shape[0] > HF_MAX_GRID_SIDE - fewer ||
        shape[1] > HF_MAX_GRID_SIDE - fewer) {
        PyErr_Format(PyExc_ValueError, "%s: each side must be in %s", name,
                     fewer ? "[1, 2^24 - 1]" : "[2, 2^24]");
        return 0;
    }
    return 1;
}

/* A kernel call without the GIL, timed with the monotonic clock: timed_begin releases
 * the GIL and starts the clock, timed_end stops it, takes the GIL back and returns the
 * elapsed nanoseconds. Nothing between the two may touch a Python object. */
typedef struct {
    PyThreadState *thread;
    struct timespec start;
} hf_timed_section;

HF_BINDING void hf_timed_begin(hf_timed_section *section);
HF_BINDING long long hf_timed_end(hf_timed_section *section);

/* The rays of a batch: origins and directions of shape (N, dim), float64, and the
 * optional ranges tmin, tmax (None, or N float64). */
typedef struct {
    npy_intp n;
    const double *origins, *directions, *tmin, *tmax;
} hf_ray_arrays;

static inline int hf_arg_rays(PyObject *o_origins, PyObject *o_directions, PyObject *o_tmin,
                              PyObject *o_tmax, int dim, hf_ray_arrays *rays) {
    npy_intp size;
    void *p;
    if (!hf_arg_array(o_origins, "origins", NPY_FLOAT64, -1, 0, 0, &p, &size)) return 0;
    if (size % dim != 0) {
        PyErr_Format(PyExc_ValueError, "origins: expected shape (N, %d)", dim);
        return 0;
    }
    rays->n = size / dim;
    rays->origins = (const double *)p;
    if (!hf_arg_array(o_directions, "directions", NPY_FLOAT64, dim * rays->n, 0, 0, &p, NULL))
        return 0;
    rays->directions = (const double *)p;
    if (!hf_arg_array(o_tmin, "tmin", NPY_FLOAT64, rays->n, 0, 1, &p, NULL)) return 0;
    rays->tmin = (const double *)p;
    if (!hf_arg_array(o_tmax, "tmax", NPY_FLOAT64, rays->n, 0, 1, &p, NULL)) return 0;
    rays->tmax = (const double *)p;
    return 1;
}

/* The message of a kernel's error status (enum hf_status). */
HF_BINDING const char *hf_status_text(int status);

/* Each area's entry points, added to the module (0 on success, -1 with an exception). */
HF_BINDING int hf_bind_traverse(PyObject *module);
HF_BINDING int hf_bind_intersect(PyObject *module);
HF_BINDING int hf_bind_terrain(PyObject *module);
HF_BINDING int hf_bind_raster(PyObject *module);

#endif
