/* The one CPython/NumPy binding: algos._kernels.
 *
 * It checks only what memory safety needs (dtype, contiguity, sizes); algos/traverse.py
 * validates values and converts layouts before calling. The walk runs without the GIL
 * and is timed here, with a monotonic clock around the whole batch. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <time.h>
#include "hftrace.h"

/* An optional array argument: None, or a C-contiguous, aligned array of `type` with
 * exactly `size` elements (size < 0: at least one). */
static int get_array(PyObject *object, const char *name, int type, npy_intp size,
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
                     type == NPY_FLOAT64 ? "float64"
                     : type == NPY_INT64 ? "int64"
                     : type == NPY_INT32 ? "int32"
                                         : "uint64");
        return 0;
    }
    if (size >= 0 && PyArray_SIZE(array) != size) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd elements, got %zd", name,
                     (Py_ssize_t)size, (Py_ssize_t)PyArray_SIZE(array));
        return 0;
    }
    *data = PyArray_DATA(array);
    if (length) *length = PyArray_SIZE(array);
    return 1;
}

static const char *status_text(int status) {
    switch (status) {
    case HF_ERR_CAPACITY: return "an output buffer does not match the counting pass";
    case HF_ERR_INTERNAL: return "an exact walk missed its computed last cell";
    case HF_ERR_ARGUMENT: return "unknown kernel or mode";
    default: return "unknown error";
    }
}

PyDoc_STRVAR(walk_doc,
             "walk(kernel, mode, origins, directions, tmin, tmax, nx, ny, max_denominator,\n"
             "     pattern, n_cells, n_runs, offsets, out, checksums) -> int\n\n"
             "Run one kernel over a batch in one output mode and return the elapsed\n"
             "wall time of the C loop in nanoseconds (CLOCK_MONOTONIC). Private: use\n"
             "algos.traverse.");

static PyObject *walk(PyObject *self, PyObject *args) {
    int kernel, mode, status;
    long nx, ny;
    long long max_denominator;
    PyObject *o_origins, *o_directions, *o_tmin, *o_tmax, *o_pattern, *o_n_cells,
        *o_n_runs, *o_offsets, *o_out, *o_checksums;
    hf_batch batch;
    npy_intp n2, n, out_len, pattern_len;
    void *p;
    struct timespec start, stop;
    (void)self;
    if (!PyArg_ParseTuple(args, "iiOOOOllLOOOOOO", &kernel, &mode, &o_origins,
                          &o_directions, &o_tmin, &o_tmax, &nx, &ny, &max_denominator,
                          &o_pattern, &o_n_cells, &o_n_runs, &o_offsets, &o_out,
                          &o_checksums))
        return NULL;
    if (kernel < 0 || kernel >= HF_N_KERNELS || mode < 0 || mode >= HF_N_MODES) {
        PyErr_Format(PyExc_ValueError, "kernel %d or mode %d out of range", kernel, mode);
        return NULL;
    }
    if (nx < 1 || ny < 1 || nx > HF_MAX_GRID_SIDE || ny > HF_MAX_GRID_SIDE) {
        PyErr_Format(PyExc_ValueError, "grid %ld x %ld outside [1, %ld]", nx, ny,
                     (long)HF_MAX_GRID_SIDE);
        return NULL;
    }
    memset(&batch, 0, sizeof batch);
    if (!get_array(o_origins, "origins", NPY_FLOAT64, -1, 0, 0, &p, &n2)) return NULL;
    batch.origins = (const double *)p;
    if (n2 % 2 != 0) {
        PyErr_SetString(PyExc_ValueError, "origins: expected shape (N, 2)");
        return NULL;
    }
    n = n2 / 2;
    batch.n_rays = n;
    if (!get_array(o_directions, "directions", NPY_FLOAT64, 2 * n, 0, 0, &p, NULL))
        return NULL;
    batch.directions = (const double *)p;
    if (!get_array(o_tmin, "tmin", NPY_FLOAT64, n, 0, 1, &p, NULL)) return NULL;
    batch.tmin = (const double *)p;
    if (!get_array(o_tmax, "tmax", NPY_FLOAT64, n, 0, 1, &p, NULL)) return NULL;
    batch.tmax = (const double *)p;
    batch.nx = (int32_t)nx;
    batch.ny = (int32_t)ny;
    batch.max_denominator = max_denominator;
    if (!get_array(o_pattern, "pattern", NPY_INT32, -1, 1, 1, &p, &pattern_len))
        return NULL;
    batch.pattern = (int32_t *)p;
    if (kernel == HF_RUNS_PERIODIC &&
        (max_denominator < 1 || max_denominator > HF_MAX_DENOMINATOR ||
         batch.pattern == NULL || pattern_len < max_denominator + 1)) {
        PyErr_SetString(PyExc_ValueError,
                        "runs_periodic needs 1 <= max_denominator <= 2^24 and a pattern "
                        "workspace of max_denominator + 1 int32");
        return NULL;
    }
    if (mode == HF_MODE_COUNT) {
        if (!get_array(o_n_cells, "n_cells", NPY_INT64, n, 1, 0, &p, NULL)) return NULL;
        batch.n_cells = (int64_t *)p;
        if (!get_array(o_n_runs, "n_runs", NPY_INT64, n, 1, 0, &p, NULL)) return NULL;
        batch.n_runs = (int64_t *)p;
    } else if (mode == HF_MODE_CELLS || mode == HF_MODE_RUNS) {
        const npy_intp width = mode == HF_MODE_CELLS ? 2 : 3;
        if (!get_array(o_offsets, "offsets", NPY_INT64, n + 1, 0, 0, &p, NULL)) return NULL;
        batch.offsets = (const int64_t *)p;
        if (!get_array(o_out, "out", NPY_INT32, -1, 1, 0, &p, &out_len)) return NULL;
        if (out_len % width != 0) {
            PyErr_SetString(PyExc_ValueError, "out: size is not a whole number of rows");
            return NULL;
        }
        batch.out = (int32_t *)p;
        batch.out_rows = out_len / width;
    } else {
        if (!get_array(o_checksums, "checksums", NPY_UINT64, n, 1, 0, &p, NULL))
            return NULL;
        batch.checksums = (uint64_t *)p;
    }

    Py_BEGIN_ALLOW_THREADS
    clock_gettime(CLOCK_MONOTONIC, &start);
    status = hf_walk_batch(kernel, mode, &batch);
    clock_gettime(CLOCK_MONOTONIC, &stop);
    Py_END_ALLOW_THREADS

    if (status != HF_OK) {
        PyErr_Format(PyExc_RuntimeError, "kernel %d failed on ray %lld: %s", kernel,
                     (long long)batch.bad_ray, status_text(status));
        return NULL;
    }
    return PyLong_FromLongLong((long long)(stop.tv_sec - start.tv_sec) * 1000000000LL +
                               (long long)(stop.tv_nsec - start.tv_nsec));
}

PyDoc_STRVAR(quantize_doc,
             "quantize_ray(ox, oy, dx, dy) -> (ox, oy, dx, dy)\n\n"
             "The ray the exact kernels walk: the origin rounded to 2^-16 cell, the\n"
             "direction scaled by a power of two and rounded (see algos.lattice).");

static PyObject *quantize_ray(PyObject *self, PyObject *args) {
    double origin[2], direction[2], origin_out[2], direction_out[2];
    (void)self;
    if (!PyArg_ParseTuple(args, "dddd", &origin[0], &origin[1], &direction[0],
                          &direction[1]))
        return NULL;
    hf_quantize_ray(origin, direction, origin_out, direction_out);
    return Py_BuildValue("dddd", origin_out[0], origin_out[1], direction_out[0],
                         direction_out[1]);
}

PyDoc_STRVAR(best_rational_doc,
             "best_rational(num, den, max_den) -> (p, q)\n\n"
             "The C best rational approximation used by runs_periodic.");

static PyObject *best_rational(PyObject *self, PyObject *args) {
    long long num, den, max_den;
    int64_t p, q;
    (void)self;
    if (!PyArg_ParseTuple(args, "LLL", &num, &den, &max_den)) return NULL;
    if (den < 1 || num < 0 || num > den || max_den < 1) {
        PyErr_SetString(PyExc_ValueError, "need 0 <= num <= den, den >= 1, max_den >= 1");
        return NULL;
    }
    hf_best_rational(num, den, max_den, &p, &q);
    return Py_BuildValue("LL", (long long)p, (long long)q);
}

static PyMethodDef methods[] = {
    {"walk", walk, METH_VARARGS, walk_doc},
    {"quantize_ray", quantize_ray, METH_VARARGS, quantize_doc},
    {"best_rational", best_rational, METH_VARARGS, best_rational_doc},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "algos._kernels",
                                    "hftrace C kernels (private; see algos).", -1, methods,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__kernels(void) {
    PyObject *m;
    import_array();
    m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    PyModule_AddIntConstant(m, "FRAC_BITS", HF_FRAC_BITS);
    PyModule_AddIntConstant(m, "MAX_GRID_SIDE", HF_MAX_GRID_SIDE);
    PyModule_AddIntConstant(m, "DEFAULT_MAX_DENOMINATOR", HF_DEFAULT_MAX_DENOMINATOR);
    PyModule_AddIntConstant(m, "MAX_DENOMINATOR", HF_MAX_DENOMINATOR);
    return m;
}
