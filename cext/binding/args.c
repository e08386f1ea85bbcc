/* The binding's shared argument reader: arrays checked for dtype, layout and size, the rays
 * of a batch, the timed GIL-free section and the status messages (args.h). */
#define HF_BINDING_ARGS_C
#include "binding/args.h"

/* An optional array argument: None, or a C-contiguous, aligned array of `type` with
 * exactly `size` elements (size < 0: at least one). */
int hf_arg_array(PyObject *object, const char *name, int type, npy_intp size, int writable,
                 int optional, void **data, npy_intp *length) {
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

void hf_timed_begin(hf_timed_section *section) {
    section->thread = PyEval_SaveThread();
    clock_gettime(CLOCK_MONOTONIC, &section->start);
}

long long hf_timed_end(hf_timed_section *section) {
    struct timespec stop;
    clock_gettime(CLOCK_MONOTONIC, &stop);
    PyEval_RestoreThread(section->thread);
    return (long long)(stop.tv_sec - section->start.tv_sec) * 1000000000LL +
           (long long)(stop.tv_nsec - section->start.tv_nsec);
}

int hf_arg_rays(PyObject *o_origins, PyObject *o_directions, PyObject *o_tmin, PyObject *o_tmax,
                int dim, hf_ray_arrays *rays) {
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

const char *hf_status_text(int status) {
    switch (status) {
    case HF_ERR_CAPACITY: return "an output buffer does not match the counting pass";
    case HF_ERR_INTERNAL: return "an exact walk missed its computed last cell";
    case HF_ERR_ARGUMENT: return "unknown kernel or mode";
    default: return "unknown error";
    }
}

/* A float32 C-contiguous array of exactly this shape (ndim given by the shape length). */
int hf_arg_f32(PyObject *object, const char *name, int ndim, const npy_intp *shape,
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
