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
#include "hitbatch.h"

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
                     : type == NPY_FLOAT32 ? "float32"
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


/* A float32 C-contiguous array of exactly this shape (ndim given by the shape length). */
static int get_f32(PyObject *object, const char *name, int ndim, const npy_intp *shape,
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

/* (values, prefix, suffix, sparse, block_shift) for lines of `length` cells */
static int get_rmq(PyObject *object, const char *name, npy_intp lines, npy_intp length,
                   hf_rmq *q) {
    PyObject *values, *prefix, *suffix, *sparse;
    int block_shift;
    npy_intp shape[3];
    if (!PyArg_ParseTuple(object, "OOOOi", &values, &prefix, &suffix, &sparse, &block_shift)) {
        PyErr_Format(PyExc_TypeError, "%s: expected (values, prefix, suffix, sparse, block_shift)",
                     name);
        return 0;
    }
    if (block_shift < 0 || block_shift > 16) {
        PyErr_Format(PyExc_ValueError, "%s: block_shift out of range", name);
        return 0;
    }
    q->n_lines = (int32_t)lines;
    q->length = (int32_t)length;
    q->block_shift = block_shift;
    q->n_blocks = (int32_t)((length + (1 << block_shift) - 1) >> block_shift);
    q->n_levels = 1;
    while ((2 << (q->n_levels - 1)) <= q->n_blocks) q->n_levels += 1;
    shape[0] = lines;
    shape[1] = length;
    if (!get_f32(values, name, 2, shape, &q->values)) return 0;
    if (!get_f32(prefix, name, 2, shape, &q->prefix)) return 0;
    if (!get_f32(suffix, name, 2, shape, &q->suffix)) return 0;
    shape[1] = q->n_levels;
    shape[2] = q->n_blocks;
    return get_f32(sparse, name, 3, shape, &q->sparse);
}

PyDoc_STRVAR(intersect_doc,
             "intersect(kernel, surface, heights, cellmax, hmin, hmax, row_max, col_max, mip,\n"
             "          origins, directions, tmin, tmax, cull_cells, max_denominator, pattern,\n"
             "          march, fine_level, t, cell, normal, stats) -> int\n\n"
             "First hits of a batch; returns the elapsed nanoseconds of the C loop.\n"
             "Private: use algos.intersect.");

static PyObject *intersect(PyObject *self, PyObject *args) {
    int kernel, surface, cull_cells, fine_level, status, k;
    double hmin, hmax;
    long long max_denominator;
    PyObject *o_heights, *o_cellmax, *o_row, *o_col, *o_mip, *o_origins, *o_directions,
        *o_tmin, *o_tmax, *o_pattern, *o_march, *o_t, *o_cell, *o_normal, *o_stats;
    hf_hit_batch b;
    PyArrayObject *ha;
    npy_intp n3, n, shape[2], plen;
    void *p;
    struct timespec start, stop;
    (void)self;
    if (!PyArg_ParseTuple(args, "iiOOddOOOOOOOiLOOiOOOO", &kernel, &surface, &o_heights,
                          &o_cellmax, &hmin, &hmax, &o_row, &o_col, &o_mip, &o_origins,
                          &o_directions, &o_tmin, &o_tmax, &cull_cells, &max_denominator,
                          &o_pattern, &o_march, &fine_level, &o_t, &o_cell, &o_normal, &o_stats))
        return NULL;
    memset(&b, 0, sizeof b);
    if (kernel < 0 || kernel >= HF_N_HIT_KERNELS || surface < 0 || surface > HF_BILINEAR) {
        PyErr_SetString(PyExc_ValueError, "kernel or surface out of range");
        return NULL;
    }
    if (!PyArray_Check(o_heights) || PyArray_NDIM((PyArrayObject *)o_heights) != 2) {
        PyErr_SetString(PyExc_TypeError, "heights: expected a 2D numpy array");
        return NULL;
    }
    ha = (PyArrayObject *)o_heights;
    shape[0] = PyArray_DIM(ha, 0);
    shape[1] = PyArray_DIM(ha, 1);
    if (shape[0] < 2 || shape[1] < 2 || shape[0] > HF_MAX_GRID_SIDE || shape[1] > HF_MAX_GRID_SIDE) {
        PyErr_SetString(PyExc_ValueError, "heights: each side must be in [2, 2^24]");
        return NULL;
    }
    if (!get_f32(o_heights, "heights", 2, shape, &b.heights)) return NULL;
    b.rows = (int32_t)shape[0];
    b.cols = (int32_t)shape[1];
    shape[0] -= 1;
    shape[1] -= 1;
    if (!get_f32(o_cellmax, "cellmax", 2, shape, &b.cellmax)) return NULL;
    b.hmin = hmin;
    b.hmax = hmax;
    b.surface = surface;
    b.cull_cells = cull_cells;
    if (o_row != Py_None || o_col != Py_None) {
        if (o_row == Py_None || o_col == Py_None) {
            PyErr_SetString(PyExc_ValueError, "row_max and col_max come together");
            return NULL;
        }
        if (!get_rmq(o_row, "row_max", shape[0], shape[1], &b.row_max)) return NULL;
        if (!get_rmq(o_col, "col_max", shape[1], shape[0], &b.col_max)) return NULL;
        b.cull_runs = 1;
    }
    if (o_mip != Py_None) {
        npy_intp levels;
        if (!PyList_Check(o_mip)) {
            PyErr_SetString(PyExc_TypeError, "mip: expected a list of float32 arrays");
            return NULL;
        }
        levels = PyList_GET_SIZE(o_mip);
        if (levels < 1 || levels > HF_MAX_MIP_LEVELS) {
            PyErr_SetString(PyExc_ValueError, "mip: 1 to 32 levels");
            return NULL;
        }
        for (k = 0; k < levels; ++k) {
            npy_intp ms[2];
            /* level k covers 2^k x 2^k cells: ceil division of the cell grid */
            ms[0] = (shape[0] + ((npy_intp)1 << k) - 1) >> k;
            ms[1] = (shape[1] + ((npy_intp)1 << k) - 1) >> k;
            if (!get_f32(PyList_GET_ITEM(o_mip, k), "mip level", 2, ms, &b.mip[k])) return NULL;
            b.mip_cols[k] = (int32_t)ms[1];
        }
        b.mip_levels = (int)levels;
    }
    if (!get_array(o_origins, "origins", NPY_FLOAT64, -1, 0, 0, &p, &n3)) return NULL;
    if (n3 % 3 != 0) {
        PyErr_SetString(PyExc_ValueError, "origins: expected shape (N, 3)");
        return NULL;
    }
    n = n3 / 3;
    b.n_rays = n;
    b.origins = (const double *)p;
    if (!get_array(o_directions, "directions", NPY_FLOAT64, 3 * n, 0, 0, &p, NULL)) return NULL;
    b.directions = (const double *)p;
    if (!get_array(o_tmin, "tmin", NPY_FLOAT64, n, 0, 1, &p, NULL)) return NULL;
    b.tmin = (const double *)p;
    if (!get_array(o_tmax, "tmax", NPY_FLOAT64, n, 0, 1, &p, NULL)) return NULL;
    b.tmax = (const double *)p;
    b.max_denominator = max_denominator;
    if (!get_array(o_pattern, "pattern", NPY_INT32, -1, 1, 1, &p, &plen)) return NULL;
    b.pattern = (int32_t *)p;
    if (kernel == HF_RUNS_PERIODIC && (b.pattern == NULL || max_denominator < 1 ||
                                       max_denominator > HF_MAX_DENOMINATOR || plen < max_denominator + 1)) {
        PyErr_SetString(PyExc_ValueError, "runs_periodic needs a pattern of max_denominator + 1");
        return NULL;
    }
    if (!PyArg_ParseTuple(o_march, "iiddd", &b.march_steps, &b.march_refinements, &b.march_growth,
                          &b.march_first_fraction, &b.march_min_step))
        return NULL;
    if (b.march_steps < 1 || b.march_refinements < 0 || !(b.march_growth >= 1.0) ||
        !(b.march_first_fraction > 0) || !(b.march_min_step >= 0)) {
        PyErr_SetString(PyExc_ValueError, "march: invalid parameters");
        return NULL;
    }
    if ((kernel == HF_HIT_DDA_MAXMIP || kernel == HF_HIT_RUNS_MAXMIP) && b.mip_levels < 1) {
        PyErr_SetString(PyExc_ValueError, "the maxmip kernels need the mipmap");
        return NULL;
    }
    if (fine_level < 0 || fine_level >= (b.mip_levels > 0 ? b.mip_levels : 1)) {
        PyErr_SetString(PyExc_ValueError, "fine_level: outside the mipmap");
        return NULL;
    }
    b.fine_level = fine_level;
    if (!get_array(o_t, "t", NPY_FLOAT64, n, 1, 1, &p, NULL)) return NULL;
    b.t = (double *)p;
    if (!get_array(o_cell, "cell", NPY_INT32, 2 * n, 1, 1, &p, NULL)) return NULL;
    b.cell = (int32_t *)p;
    if (!get_array(o_normal, "normal", NPY_FLOAT64, 3 * n, 1, 1, &p, NULL)) return NULL;
    b.normal = (double *)p;
    if (!get_array(o_stats, "stats", NPY_INT64, 5 * n, 1, 1, &p, NULL)) return NULL;
    b.stats = (int64_t *)p;

    Py_BEGIN_ALLOW_THREADS
    clock_gettime(CLOCK_MONOTONIC, &start);
    status = hf_intersect_batch(kernel, &b);
    clock_gettime(CLOCK_MONOTONIC, &stop);
    Py_END_ALLOW_THREADS

    if (status != HF_OK) {
        PyErr_Format(PyExc_RuntimeError, "intersector %d failed on ray %lld: %s", kernel,
                     (long long)b.bad_ray, status_text(status));
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
    {"intersect", intersect, METH_VARARGS, intersect_doc},
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
