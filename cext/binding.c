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
#include "terrain.h"
#include "horizon_fast.h"
#include "raster.h"

/* An optional array argument: None, or a C-contiguous, aligned array of `type` with
 * exactly `size` elements (size < 0: at least one). */
static int get_array(PyObject *object, const char *name, int type, npy_intp size, int writable,
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

/* ---- shared pieces of every entry point ------------------------------------------- */

/* A kernel call without the GIL, timed with the monotonic clock: timed_begin releases
 * the GIL and starts the clock, timed_end stops it, takes the GIL back and returns the
 * elapsed nanoseconds. Nothing between the two may touch a Python object. */
typedef struct {
    PyThreadState *thread;
    struct timespec start;
} timed_section;

static void timed_begin(timed_section *section) {
    section->thread = PyEval_SaveThread();
    clock_gettime(CLOCK_MONOTONIC, &section->start);
}

static long long timed_end(timed_section *section) {
    struct timespec stop;
    clock_gettime(CLOCK_MONOTONIC, &stop);
    PyEval_RestoreThread(section->thread);
    return (long long)(stop.tv_sec - section->start.tv_sec) * 1000000000LL +
           (long long)(stop.tv_nsec - section->start.tv_nsec);
}

/* The rays of a batch: origins and directions of shape (N, dim), float64, and the
 * optional ranges tmin, tmax (None, or N float64). */
typedef struct {
    npy_intp n;
    const double *origins, *directions, *tmin, *tmax;
} ray_arrays;

static int get_rays(PyObject *o_origins, PyObject *o_directions, PyObject *o_tmin, PyObject *o_tmax,
                    int dim, ray_arrays *rays) {
    npy_intp size;
    void *p;
    if (!get_array(o_origins, "origins", NPY_FLOAT64, -1, 0, 0, &p, &size)) return 0;
    if (size % dim != 0) {
        PyErr_Format(PyExc_ValueError, "origins: expected shape (N, %d)", dim);
        return 0;
    }
    rays->n = size / dim;
    rays->origins = (const double *)p;
    if (!get_array(o_directions, "directions", NPY_FLOAT64, dim * rays->n, 0, 0, &p, NULL))
        return 0;
    rays->directions = (const double *)p;
    if (!get_array(o_tmin, "tmin", NPY_FLOAT64, rays->n, 0, 1, &p, NULL)) return 0;
    rays->tmin = (const double *)p;
    if (!get_array(o_tmax, "tmax", NPY_FLOAT64, rays->n, 0, 1, &p, NULL)) return 0;
    rays->tmax = (const double *)p;
    return 1;
}

static const char *status_text(int status) {
    switch (status) {
    case HF_ERR_CAPACITY: return "an output buffer does not match the counting pass";
    case HF_ERR_INTERNAL: return "an exact walk missed its computed last cell";
    case HF_ERR_ARGUMENT: return "unknown kernel or mode";
    case HF_ERR_MEMORY: return "out of memory for the renderer's table";
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
    PyObject *o_origins, *o_directions, *o_tmin, *o_tmax, *o_pattern, *o_n_cells, *o_n_runs,
        *o_offsets, *o_out, *o_checksums;
    hf_batch batch;
    ray_arrays rays;
    npy_intp n, out_len, pattern_len;
    void *p;
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "iiOOOOllLOOOOOO", &kernel, &mode, &o_origins, &o_directions,
                          &o_tmin, &o_tmax, &nx, &ny, &max_denominator, &o_pattern, &o_n_cells,
                          &o_n_runs, &o_offsets, &o_out, &o_checksums))
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
    if (!get_rays(o_origins, o_directions, o_tmin, o_tmax, 2, &rays)) return NULL;
    n = rays.n;
    batch.n_rays = n;
    batch.origins = rays.origins;
    batch.directions = rays.directions;
    batch.tmin = rays.tmin;
    batch.tmax = rays.tmax;
    batch.nx = (int32_t)nx;
    batch.ny = (int32_t)ny;
    batch.max_denominator = max_denominator;
    if (!get_array(o_pattern, "pattern", NPY_INT32, -1, 1, 1, &p, &pattern_len)) return NULL;
    batch.pattern = (int32_t *)p;
    if (kernel == HF_RUNS_PERIODIC &&
        (max_denominator < 1 || max_denominator > HF_MAX_DENOMINATOR || batch.pattern == NULL ||
         pattern_len < max_denominator + 1)) {
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
        if (!get_array(o_checksums, "checksums", NPY_UINT64, n, 1, 0, &p, NULL)) return NULL;
        batch.checksums = (uint64_t *)p;
    }

    timed_begin(&section);
    status = hf_walk_batch(kernel, mode, &batch);
    elapsed_ns = timed_end(&section);

    if (status != HF_OK) {
        PyErr_Format(PyExc_RuntimeError, "kernel %d failed on ray %lld: %s", kernel,
                     (long long)batch.bad_ray, status_text(status));
        return NULL;
    }
    return PyLong_FromLongLong(elapsed_ns);
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
static int get_rmq(PyObject *object, const char *name, npy_intp lines, npy_intp length, hf_rmq *q) {
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
             "          march, fine_level, t, cell, normal, stats[, packet_width]) -> int\n\n"
             "First hits of a batch; returns the elapsed nanoseconds of the C loop.\n"
             "Private: use algos.intersect.");

/* The compact maximum tree of an ny x nx cell grid (compact.h): a C-contiguous uint8
 * array of exactly its node count times 64 bytes, aligned to 64 (one node per line). */
static int get_compact(PyObject *object, int32_t nx, int32_t ny, int writable, void **records) {
    PyArrayObject *a;
    hf_compact layout;
    const npy_intp bytes = (npy_intp)hf_compact_layout(nx, ny, &layout) * HF_COMPACT_NODE_BYTES;
    if (!PyArray_Check(object)) {
        PyErr_Format(PyExc_TypeError, "compact: expected a numpy array, got %s",
                     Py_TYPE(object)->tp_name);
        return 0;
    }
    a = (PyArrayObject *)object;
    if (PyArray_TYPE(a) != NPY_UINT8 || PyArray_NDIM(a) != 1 || !PyArray_ISCARRAY_RO(a) ||
        (writable && !PyArray_ISWRITEABLE(a))) {
        PyErr_SetString(PyExc_TypeError, "compact: expected a C-contiguous 1D uint8 array");
        return 0;
    }
    if (PyArray_SIZE(a) != bytes) {
        PyErr_Format(PyExc_ValueError, "compact: expected %zd bytes for %d x %d cells, got %zd",
                     (Py_ssize_t)bytes, (int)nx, (int)ny, (Py_ssize_t)PyArray_SIZE(a));
        return 0;
    }
    if (((uintptr_t)PyArray_DATA(a)) % HF_COMPACT_NODE_BYTES != 0) {
        PyErr_SetString(PyExc_ValueError, "compact: the buffer must be aligned to 64 bytes");
        return 0;
    }
    *records = PyArray_DATA(a);
    return 1;
}

/* intersect, intersect_cone and intersect_compact: the batch from `args`, with the cone
 * structure (NULL but for intersect_cone): float32 of shape (rows - 1, cols - 1, 2) for
 * cone, (rows - 1, cols - 1) for cone_relaxed; and the compact tree (NULL but for
 * intersect_compact). */
static PyObject *intersect_with(PyObject *args, PyObject *o_cone, PyObject *o_compact) {
    int kernel, surface, cull_cells, fine_level, status, k, packet_width = 4;
    double hmin, hmax;
    long long max_denominator;
    PyObject *o_heights, *o_cellmax, *o_row, *o_col, *o_mip, *o_origins, *o_directions, *o_tmin,
        *o_tmax, *o_pattern, *o_march, *o_t, *o_cell, *o_normal, *o_stats;
    hf_hit_batch b;
    PyArrayObject *ha;
    ray_arrays rays;
    npy_intp n, shape[2], plen;
    void *p;
    timed_section section;
    long long elapsed_ns;
    if (!PyArg_ParseTuple(args, "iiOOddOOOOOOOiLOOiOOOO|i", &kernel, &surface, &o_heights,
                          &o_cellmax, &hmin, &hmax, &o_row, &o_col, &o_mip, &o_origins,
                          &o_directions, &o_tmin, &o_tmax, &cull_cells, &max_denominator,
                          &o_pattern, &o_march, &fine_level, &o_t, &o_cell, &o_normal, &o_stats,
                          &packet_width))
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
    if (shape[0] < 2 || shape[1] < 2 || shape[0] > HF_MAX_GRID_SIDE ||
        shape[1] > HF_MAX_GRID_SIDE) {
        PyErr_SetString(PyExc_ValueError, "heights: each side must be in [2, 2^24]");
        return NULL;
    }
    if (!get_f32(o_heights, "heights", 2, shape, &b.heights)) return NULL;
    b.rows = (int32_t)shape[0];
    b.cols = (int32_t)shape[1];
    shape[0] -= 1;
    shape[1] -= 1;
    if (o_cellmax == Py_None) {
        /* the lean layout (algos.Field(lean=True)): runs_maxmip without cell culling is
         * the one kernel that never reads the cell maxima */
        if (kernel != HF_HIT_RUNS_MAXMIP || cull_cells || o_row != Py_None) {
            PyErr_SetString(
                PyExc_ValueError,
                "cellmax: only runs_maxmip without cell or run culling runs without it");
            return NULL;
        }
        b.cellmax = NULL;
    } else if (!get_f32(o_cellmax, "cellmax", 2, shape, &b.cellmax)) {
        return NULL;
    }
    if ((o_cone != NULL) != (kernel == HF_HIT_CONE || kernel == HF_HIT_CONE_RELAXED)) {
        PyErr_SetString(
            PyExc_ValueError,
            "cone: only intersect_cone runs the cone kernels, and it runs nothing else");
        return NULL;
    }
    if (o_cone != NULL) {
        /* cone: top and slope side by side; cone_relaxed: slopes (its apex: the cell max) */
        npy_intp cone_shape[3];
        cone_shape[0] = shape[0];
        cone_shape[1] = shape[1];
        cone_shape[2] = 2;
        if (!get_f32(o_cone, "cone", kernel == HF_HIT_CONE ? 3 : 2, cone_shape, &b.cone))
            return NULL;
    }
    if ((o_compact != NULL) != (kernel == HF_HIT_DDA_COMPACT)) {
        PyErr_SetString(
            PyExc_ValueError,
            "compact: only intersect_compact runs dda_compact, and it runs nothing else");
        return NULL;
    }
    if (o_compact != NULL) {
        void *records;
        if (!get_compact(o_compact, (int32_t)shape[1], (int32_t)shape[0], 0, &records)) return NULL;
        b.compact = records;
    }
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
            if (PyList_GET_ITEM(o_mip, k) == Py_None && k < fine_level) {
                /* levels below the floor level are never read (the lean layout) */
                b.mip[k] = NULL;
            } else if (!get_f32(PyList_GET_ITEM(o_mip, k), "mip level", 2, ms, &b.mip[k])) {
                return NULL;
            }
            b.mip_cols[k] = (int32_t)ms[1];
        }
        b.mip_levels = (int)levels;
    }
    if (!get_rays(o_origins, o_directions, o_tmin, o_tmax, 3, &rays)) return NULL;
    n = rays.n;
    b.n_rays = n;
    b.origins = rays.origins;
    b.directions = rays.directions;
    b.tmin = rays.tmin;
    b.tmax = rays.tmax;
    b.max_denominator = max_denominator;
    if (!get_array(o_pattern, "pattern", NPY_INT32, -1, 1, 1, &p, &plen)) return NULL;
    b.pattern = (int32_t *)p;
    if (kernel == HF_RUNS_PERIODIC &&
        (b.pattern == NULL || max_denominator < 1 || max_denominator > HF_MAX_DENOMINATOR ||
         plen < max_denominator + 1)) {
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
    if ((kernel == HF_HIT_DDA_MAXMIP || kernel == HF_HIT_RUNS_MAXMIP ||
         kernel == HF_HIT_PACKET_MAXMIP) &&
        b.mip_levels < 1) {
        PyErr_SetString(PyExc_ValueError, "the maxmip kernels need the mipmap");
        return NULL;
    }
    if (fine_level < 0 || fine_level >= (b.mip_levels > 0 ? b.mip_levels : 1)) {
        PyErr_SetString(PyExc_ValueError, "fine_level: outside the mipmap");
        return NULL;
    }
    b.floor_level = fine_level;
    if (packet_width < 1 || packet_width > HF_PACKET_MAX) {
        PyErr_Format(PyExc_ValueError, "packet_width: expected 1 .. %d, got %d", HF_PACKET_MAX,
                     packet_width);
        return NULL;
    }
    b.packet_width = packet_width;
    if (!get_array(o_t, "t", NPY_FLOAT64, n, 1, 1, &p, NULL)) return NULL;
    b.t = (double *)p;
    if (!get_array(o_cell, "cell", NPY_INT32, 2 * n, 1, 1, &p, NULL)) return NULL;
    b.cell = (int32_t *)p;
    if (!get_array(o_normal, "normal", NPY_FLOAT64, 3 * n, 1, 1, &p, NULL)) return NULL;
    b.normal = (double *)p;
    if (!get_array(o_stats, "stats", NPY_INT64, 5 * n, 1, 1, &p, NULL)) return NULL;
    b.stats = (int64_t *)p;

    timed_begin(&section);
    status = hf_intersect_batch(kernel, &b);
    elapsed_ns = timed_end(&section);

    if (status != HF_OK) {
        PyErr_Format(PyExc_RuntimeError, "intersector %d failed on ray %lld: %s", kernel,
                     (long long)b.bad_ray, status_text(status));
        return NULL;
    }
    return PyLong_FromLongLong(elapsed_ns);
}

static PyObject *intersect(PyObject *self, PyObject *args) {
    (void)self;
    return intersect_with(args, NULL, NULL);
}

PyDoc_STRVAR(quantize_doc, "quantize_ray(ox, oy, dx, dy) -> (ox, oy, dx, dy)\n\n"
                           "The ray the exact kernels walk: the origin rounded to 2^-16 cell, the\n"
                           "direction scaled by a power of two and rounded (see algos.lattice).");

static PyObject *quantize_ray(PyObject *self, PyObject *args) {
    double origin[2], direction[2], origin_out[2], direction_out[2];
    (void)self;
    if (!PyArg_ParseTuple(args, "dddd", &origin[0], &origin[1], &direction[0], &direction[1]))
        return NULL;
    hf_quantize_ray(origin, direction, origin_out, direction_out);
    return Py_BuildValue("dddd", origin_out[0], origin_out[1], direction_out[0], direction_out[1]);
}

PyDoc_STRVAR(best_rational_doc, "best_rational(num, den, max_den) -> (p, q)\n\n"
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

/* ---- terrain products ------------------------------------------------------------- */

/* heights: a C-contiguous float64 (rows, cols) array with both sides in [2, 2^24]. */
static int get_heights(PyObject *object, const double **data, int64_t *rows, int64_t *cols) {
    PyArrayObject *a;
    void *p;
    if (!PyArray_Check(object) || PyArray_NDIM((PyArrayObject *)object) != 2) {
        PyErr_SetString(PyExc_TypeError, "heights: expected a 2D numpy array");
        return 0;
    }
    a = (PyArrayObject *)object;
    *rows = PyArray_DIM(a, 0);
    *cols = PyArray_DIM(a, 1);
    if (*rows < 2 || *cols < 2 || *rows > HF_MAX_GRID_SIDE || *cols > HF_MAX_GRID_SIDE) {
        PyErr_SetString(PyExc_ValueError, "heights: each side must be in [2, 2^24]");
        return 0;
    }
    if (!get_array(object, "heights", NPY_FLOAT64, -1, 0, 0, &p, NULL)) return 0;
    *data = (const double *)p;
    return 1;
}

static int vertex_range(long long start, long long stop, int64_t rows, int64_t cols) {
    if (start < 0 || stop < start || stop > (long long)(rows * cols)) {
        PyErr_Format(PyExc_ValueError, "vertex range [%lld, %lld) outside [0, %lld]", start, stop,
                     (long long)(rows * cols));
        return 0;
    }
    return 1;
}

/* Optional mipmap (None or data, offset, rows, cols), checked against the cell grid. */
static int get_mip(PyObject *o_mip, int64_t rows, int64_t cols, hf_hz_mip *mip, int *has) {
    PyObject *o_data, *o_off, *o_r, *o_c;
    npy_intp n_data, n_levels;
    void *p;
    *has = 0;
    if (o_mip == Py_None) return 1;
    if (!PyArg_ParseTuple(o_mip, "OOOO", &o_data, &o_off, &o_r, &o_c)) return 0;
    if (!get_array(o_data, "mip data", NPY_FLOAT64, -1, 0, 0, &p, &n_data)) return 0;
    mip->data = (const double *)p;
    if (!get_array(o_off, "mip offset", NPY_INT64, -1, 0, 0, &p, &n_levels)) return 0;
    mip->offset = (const int64_t *)p;
    if (!get_array(o_r, "mip rows", NPY_INT64, n_levels, 0, 0, &p, NULL)) return 0;
    mip->rows = (const int64_t *)p;
    if (!get_array(o_c, "mip cols", NPY_INT64, n_levels, 0, 0, &p, NULL)) return 0;
    mip->cols = (const int64_t *)p;
    if (n_levels < 1 || n_levels > 62) {
        PyErr_SetString(PyExc_ValueError, "mip: 1 to 62 levels");
        return 0;
    }
    for (npy_intp L = 0; L < n_levels; L++) {
        int64_t need_r = ((rows - 1) + ((int64_t)1 << L) - 1) >> L;
        int64_t need_c = ((cols - 1) + ((int64_t)1 << L) - 1) >> L;
        if (mip->rows[L] < need_r || mip->cols[L] < need_c || mip->offset[L] < 0 ||
            mip->offset[L] + mip->rows[L] * mip->cols[L] > n_data) {
            PyErr_Format(PyExc_ValueError, "mip: level %ld does not cover the grid", (long)L);
            return 0;
        }
    }
    if (mip->rows[n_levels - 1] != 1 || mip->cols[n_levels - 1] != 1) {
        PyErr_SetString(PyExc_ValueError, "mip: the top level must be one tile");
        return 0;
    }
    mip->n_levels = (int32_t)n_levels;
    *has = 1;
    return 1;
}

static PyObject *stats_tuple(const hf_hz_stats *s, long long elapsed_ns) {
    return Py_BuildValue("LLL", elapsed_ns, (long long)s->cells, (long long)s->skips);
}

/* A pattern's interpolation arrays: dx_a, dy_a, dx_b, dy_b (int64) and w (float64), n
 * elements each. */
static int get_lerp_arrays(PyObject *const objects[5], npy_intp n, const int64_t *ints[4],
                           const double **w) {
    static const char *const names[4] = {"dx_a", "dy_a", "dx_b", "dy_b"};
    void *p;
    for (int k = 0; k < 4; k++) {
        if (!get_array(objects[k], names[k], NPY_INT64, n, 0, 0, &p, NULL)) return 0;
        ints[k] = (const int64_t *)p;
    }
    if (!get_array(objects[4], "w", NPY_FLOAT64, n, 0, 0, &p, NULL)) return 0;
    *w = (const double *)p;
    return 1;
}

PyDoc_STRVAR(horizon_pattern_doc,
             "horizon_pattern(heights, inv_t, dx_a, dy_a, dx_b, dy_b, w, limit_x, limit_y,\n"
             "                end_k, end_f, end_inv_t, zmax, stop_every, start, stop, out,\n"
             "                kappa=0.0) -> (ns, 0, 0)\n\nHorizon tangents by one shared pattern\n"
             "(octant frame); kappa: curvature. Private: use algos.horizon.");

static PyObject *horizon_pattern(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_inv, *o_dxa, *o_dya, *o_dxb, *o_dyb, *o_w, *o_lx, *o_ly, *o_out;
    long long end_k, stop_every, start, stop;
    double end_f, end_inv_t, zmax, kappa = 0.0;
    const double *H;
    int64_t rows, cols, *off_a = NULL, *off_b = NULL;
    const int64_t *dxa, *dya, *dxb, *dyb, *lx, *ly;
    npy_intp n;
    void *p;
    hf_hz_pattern pat;
    hf_hz_stats st = {0, 0};
    timed_section section;
    long long elapsed_ns;
    int64_t reach = 0;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOLdddLLLO|d", &o_h, &o_inv, &o_dxa, &o_dya, &o_dxb, &o_dyb,
                          &o_w, &o_lx, &o_ly, &end_k, &end_f, &end_inv_t, &zmax, &stop_every,
                          &start, &stop, &o_out, &kappa))
        return NULL;
    if (!isfinite(kappa)) {
        PyErr_SetString(PyExc_ValueError, "kappa: expected a finite curvature");
        return NULL;
    }
    if (!get_heights(o_h, &H, &rows, &cols) || !vertex_range(start, stop, rows, cols)) return NULL;
    if (!get_array(o_inv, "inv_t", NPY_FLOAT64, -1, 0, 0, &p, &n)) return NULL;
    pat.inv_t = (const double *)p;
    {
        PyObject *const lerp[5] = {o_dxa, o_dya, o_dxb, o_dyb, o_w};
        const int64_t *ints[4];
        if (!get_lerp_arrays(lerp, n, ints, &pat.w)) return NULL;
        dxa = ints[0];
        dya = ints[1];
        dxb = ints[2];
        dyb = ints[3];
    }
    if (!get_array(o_lx, "limit_x", NPY_INT64, cols, 0, 0, &p, NULL)) return NULL;
    lx = (const int64_t *)p;
    if (!get_array(o_ly, "limit_y", NPY_INT64, rows, 0, 0, &p, NULL)) return NULL;
    ly = (const int64_t *)p;
    if (!get_array(o_out, "out", NPY_FLOAT64, rows * cols, 1, 0, &p, NULL)) return NULL;
    if (end_k < -1 || end_k + 1 >= (long long)n + (end_k < 0)) {
        PyErr_SetString(PyExc_ValueError, "end_k: outside the pattern");
        return NULL;
    }
    /* memory safety: every breakpoint a limit admits reads inside the field */
    for (int64_t k = 0; k < cols; k++)
        if (lx[k] < 0 || lx[k] > n || (k && lx[k] < lx[k - 1])) reach = -1;
    for (int64_t k = 0; k < rows; k++)
        if (ly[k] < 0 || ly[k] > n || (k && ly[k] < ly[k - 1])) reach = -1;
    if (reach == 0) {
        int64_t e = 0, mxx = 0, myy = 0;
        for (int64_t k = 0; k < cols && reach == 0; k++) {
            for (; e < lx[k]; e++) {
                int64_t ax = dxa[e] > dxb[e] ? dxa[e] : dxb[e];
                if (dxa[e] < 0 || dxb[e] < 0 || dya[e] < 0 || dyb[e] < 0) reach = -1;
                if (ax > mxx) mxx = ax;
            }
            if (mxx > k) reach = -1;
        }
        e = 0;
        for (int64_t k = 0; k < rows && reach == 0; k++) {
            for (; e < ly[k]; e++) {
                int64_t ay = dya[e] > dyb[e] ? dya[e] : dyb[e];
                if (ay > myy) myy = ay;
            }
            if (myy > k) reach = -1;
        }
    }
    if (reach < 0) {
        PyErr_SetString(PyExc_ValueError, "pattern: a limit admits a breakpoint outside the field");
        return NULL;
    }
    off_a = malloc((size_t)(n ? n : 1) * sizeof *off_a);
    off_b = malloc((size_t)(n ? n : 1) * sizeof *off_b);
    if (!off_a || !off_b) {
        free(off_a);
        free(off_b);
        return PyErr_NoMemory();
    }
    for (npy_intp e = 0; e < n; e++) {
        off_a[e] = dya[e] * cols + dxa[e];
        off_b[e] = dyb[e] * cols + dxb[e];
    }
    pat.n = n;
    pat.off_a = off_a;
    pat.off_b = off_b;
    pat.limit_x = lx;
    pat.limit_y = ly;
    pat.end_k = end_k;
    pat.end_f = end_f;
    pat.end_inv_t = end_inv_t;
    timed_begin(&section);
    hf_horizon_pattern(H, rows, cols, &pat, zmax, stop_every, kappa, start, stop, (double *)p);
    elapsed_ns = timed_end(&section);
    free(off_a);
    free(off_b);
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(horizon_sweep_doc,
             "horizon_sweep(heights, q, p, tfrac, dx_a, dy_a, dx_b, dy_b, w, mx, my, norm,\n"
             "              k_lo, k_hi, out) -> (ns, 0, 0)\n\nHorizon tangents of the vertices on\n"
             "lines [k_lo, k_hi) by the rational sweep (octant frame). Private: use\n"
             "algos.horizon.");

static PyObject *horizon_sweep(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_tf, *o_dxa, *o_dya, *o_dxb, *o_dyb, *o_w, *o_mx, *o_my, *o_out;
    long long q, pp, k_lo, k_hi;
    double norm;
    const double *H, *tf, *w;
    const int64_t *dxa, *dya, *dxb, *dyb, *mx, *my;
    int64_t rows, cols;
    npy_intp n;
    void *p, *out;
    int status;
    hf_hz_stats st = {0, 0};
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OLLOOOOOOOOdLLO", &o_h, &q, &pp, &o_tf, &o_dxa, &o_dya, &o_dxb,
                          &o_dyb, &o_w, &o_mx, &o_my, &norm, &k_lo, &k_hi, &o_out))
        return NULL;
    if (!get_heights(o_h, &H, &rows, &cols)) return NULL;
    if (q < 1 || pp < 0 || pp > q || q > HF_MAX_GRID_SIDE) {
        PyErr_SetString(PyExc_ValueError, "direction: need q >= p >= 0 and 1 <= q <= 2^24");
        return NULL;
    }
    if (k_lo < 0 || k_hi < k_lo || k_hi > q * (rows - 1) + pp * (cols - 1) + 1) {
        PyErr_SetString(PyExc_ValueError, "k_lo, k_hi: the line range is outside the field");
        return NULL;
    }
    if (!get_array(o_tf, "tfrac", NPY_FLOAT64, -1, 0, 0, &p, &n)) return NULL;
    tf = (const double *)p;
    {
        PyObject *const lerp[5] = {o_dxa, o_dya, o_dxb, o_dyb, o_w};
        const int64_t *ints[4];
        if (!get_lerp_arrays(lerp, n, ints, &w)) return NULL;
        dxa = ints[0];
        dya = ints[1];
        dxb = ints[2];
        dyb = ints[3];
    }
    if (!get_array(o_mx, "mx", NPY_INT64, n, 0, 0, &p, NULL)) return NULL;
    mx = (const int64_t *)p;
    if (!get_array(o_my, "my", NPY_INT64, n, 0, 0, &p, NULL)) return NULL;
    my = (const int64_t *)p;
    if (!get_array(o_out, "out", NPY_FLOAT64, rows * cols, 1, 0, &out, NULL)) return NULL;
    if (n < 1 || mx[n - 1] != q || my[n - 1] != pp || dxa[n - 1] != q || dya[n - 1] != pp ||
        dxb[n - 1] != q || dyb[n - 1] != pp) {
        PyErr_SetString(PyExc_ValueError, "pattern: the last breakpoint must be the next vertex");
        return NULL;
    }
    for (npy_intp e = 0; e < n; e++) {
        if (dxa[e] < 0 || dya[e] < 0 || dxb[e] < 0 || dyb[e] < 0 || dxa[e] > mx[e] ||
            dxb[e] > mx[e] || dya[e] > my[e] || dyb[e] > my[e] || mx[e] > q || my[e] > pp ||
            !(tf[e] > 0.0 && tf[e] <= 1.0) || (e && !(tf[e] > tf[e - 1]))) {
            PyErr_Format(PyExc_ValueError, "pattern: breakpoint %ld is inconsistent", (long)e);
            return NULL;
        }
    }
    timed_begin(&section);
    status = hf_horizon_sweep(H, rows, cols, q, pp, n, tf, dxa, dya, dxb, dyb, w, mx, my, norm,
                              k_lo, k_hi, (double *)out);
    elapsed_ns = timed_end(&section);
    if (status) return PyErr_NoMemory();
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(horizon_walk_doc,
             "horizon_walk(heights, mip, dx, dy, max_distance, start, stop, out, kappa=0.0)\n"
             "-> (ns, cells, skips)\n\nPer-vertex horizon walks (mip None: every cell);\n"
             "kappa: curvature. Private: use algos.horizon.");

static PyObject *horizon_walk(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_mip, *o_out;
    double dx, dy, max_distance, kappa = 0.0;
    long long start, stop;
    const double *H;
    int64_t rows, cols;
    hf_hz_mip mip;
    int has_mip;
    void *out;
    hf_hz_stats st = {0, 0};
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOdddLLO|d", &o_h, &o_mip, &dx, &dy, &max_distance, &start, &stop,
                          &o_out, &kappa))
        return NULL;
    if (!isfinite(kappa)) {
        PyErr_SetString(PyExc_ValueError, "kappa: expected a finite curvature");
        return NULL;
    }
    if (!get_heights(o_h, &H, &rows, &cols) || !vertex_range(start, stop, rows, cols) ||
        !get_mip(o_mip, rows, cols, &mip, &has_mip))
        return NULL;
    if (!isfinite(dx) || !isfinite(dy) || (dx == 0 && dy == 0) || isnan(max_distance)) {
        PyErr_SetString(PyExc_ValueError, "direction: finite and nonzero; max_distance not NaN");
        return NULL;
    }
    if (!get_array(o_out, "out", NPY_FLOAT64, rows * cols, 1, 0, &out, NULL)) return NULL;
    timed_begin(&section);
    hf_horizon_walk(H, rows, cols, has_mip ? &mip : NULL, dx, dy, max_distance, kappa, start, stop,
                    (double *)out, &st);
    elapsed_ns = timed_end(&section);
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(horizon_rows_doc,
             "horizon_rows(heights, inv_t, dx_a, dy_a, dx_b, dy_b, w, rx, ry, sx, sy, n_main,\n"
             "             end_k, end_f, end_inv_t, row_start, row_stop, out) -> (ns, 0, 0)\n\n"
             "Horizon tangents of rows [row_start, row_stop) by one shared pattern in the\n"
             "grid's own frame, row by row. Private: use algos.horizon.");

static PyObject *horizon_rows(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_inv, *o_dxa, *o_dya, *o_dxb, *o_dyb, *o_w, *o_rx, *o_ry, *o_out;
    long long n_main, end_k, row_start, row_stop;
    int sx, sy;
    double end_f, end_inv_t;
    const double *H, *inv_t, *w;
    const int64_t *dxa, *dya, *dxb, *dyb, *rx, *ry;
    int64_t rows, cols, *off_a = NULL, *off_b = NULL;
    npy_intp n;
    void *p, *out;
    hf_hz_stats st = {0, 0};
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOiiLLddLLO", &o_h, &o_inv, &o_dxa, &o_dya, &o_dxb, &o_dyb,
                          &o_w, &o_rx, &o_ry, &sx, &sy, &n_main, &end_k, &end_f, &end_inv_t,
                          &row_start, &row_stop, &o_out))
        return NULL;
    if (!get_heights(o_h, &H, &rows, &cols)) return NULL;
    if (row_start < 0 || row_stop < row_start || row_stop > (long long)rows) {
        PyErr_Format(PyExc_ValueError, "row range [%lld, %lld) outside [0, %lld]", row_start,
                     row_stop, (long long)rows);
        return NULL;
    }
    if ((sx != 1 && sx != -1) || (sy != 1 && sy != -1)) {
        PyErr_SetString(PyExc_ValueError, "sx, sy: expected +1 or -1");
        return NULL;
    }
    if (!get_array(o_inv, "inv_t", NPY_FLOAT64, -1, 0, 0, &p, &n)) return NULL;
    inv_t = (const double *)p;
    {
        PyObject *const lerp[5] = {o_dxa, o_dya, o_dxb, o_dyb, o_w};
        const int64_t *ints[4];
        if (!get_lerp_arrays(lerp, n, ints, &w)) return NULL;
        dxa = ints[0];
        dya = ints[1];
        dxb = ints[2];
        dyb = ints[3];
    }
    if (!get_array(o_rx, "rx", NPY_INT64, n, 0, 0, &p, NULL)) return NULL;
    rx = (const int64_t *)p;
    if (!get_array(o_ry, "ry", NPY_INT64, n, 0, 0, &p, NULL)) return NULL;
    ry = (const int64_t *)p;
    if (!get_array(o_out, "out", NPY_FLOAT64, rows * cols, 1, 0, &out, NULL)) return NULL;
    if (n_main < 0 || n_main > (long long)n || end_k < -1 ||
        (end_k >= 0 && (n_main != end_k + 1 || end_k + 1 >= (long long)n))) {
        PyErr_SetString(PyExc_ValueError, "n_main, end_k: outside the pattern");
        return NULL;
    }
    /* memory safety: each breakpoint reads within the reaches it is limited by, on the
     * direction's side */
    for (npy_intp e = 0; e < n; e++) {
        if (sx * dxa[e] < 0 || sx * dxb[e] < 0 || sy * dya[e] < 0 || sy * dyb[e] < 0 ||
            sx * dxa[e] > rx[e] || sx * dxb[e] > rx[e] || sy * dya[e] > ry[e] ||
            sy * dyb[e] > ry[e] || (e && (rx[e] < rx[e - 1] || ry[e] < ry[e - 1]))) {
            PyErr_Format(PyExc_ValueError, "pattern: breakpoint %ld reads outside its reach",
                         (long)e);
            return NULL;
        }
    }
    off_a = malloc((size_t)(n ? n : 1) * sizeof *off_a);
    off_b = malloc((size_t)(n ? n : 1) * sizeof *off_b);
    if (!off_a || !off_b) {
        free(off_a);
        free(off_b);
        return PyErr_NoMemory();
    }
    for (npy_intp e = 0; e < n; e++) {
        off_a[e] = dya[e] * cols + dxa[e];
        off_b[e] = dyb[e] * cols + dxb[e];
    }
    timed_begin(&section);
    hf_horizon_rows(H, rows, cols, n, inv_t, off_a, off_b, w, rx, ry, sx, sy, n_main, end_k, end_f,
                    end_inv_t, row_start, row_stop, (double *)out);
    elapsed_ns = timed_end(&section);
    free(off_a);
    free(off_b);
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(horizon_chain_doc,
             "horizon_chain(heights, mip, dx, dy, max_distance, nb_x, nb_y, nb_d, block_rows,\n"
             "              block_start, block_stop, out, occ)\n"
             "-> (ns, cells, skips, tile_tests, bounded)\n\n"
             "Per-vertex mipmap walks started from lower bounds borrowed along almost the\n"
             "same line. Private: use algos.horizon.");

static PyObject *horizon_chain(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_mip, *o_nx, *o_ny, *o_nd, *o_out, *o_occ;
    double dx, dy, max_distance;
    long long block_rows, block_start, block_stop;
    const double *H, *nb_d;
    const int64_t *nb_x, *nb_y;
    int64_t rows, cols, n_blocks;
    hf_hz_mip mip;
    int has_mip;
    npy_intp n_nb;
    void *p, *out, *occ;
    hf_chain_stats st = {0, 0, 0, 0};
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOdddOOOLLLOO", &o_h, &o_mip, &dx, &dy, &max_distance, &o_nx,
                          &o_ny, &o_nd, &block_rows, &block_start, &block_stop, &o_out, &o_occ))
        return NULL;
    if (!get_heights(o_h, &H, &rows, &cols) || !get_mip(o_mip, rows, cols, &mip, &has_mip))
        return NULL;
    if (!has_mip) {
        PyErr_SetString(PyExc_ValueError, "mip: the chain walk needs a mipmap");
        return NULL;
    }
    if (!isfinite(dx) || !isfinite(dy) || (dx == 0 && dy == 0) || isnan(max_distance)) {
        PyErr_SetString(PyExc_ValueError, "direction: finite and nonzero; max_distance not NaN");
        return NULL;
    }
    if (block_rows < 1) {
        PyErr_SetString(PyExc_ValueError, "block_rows: expected >= 1");
        return NULL;
    }
    n_blocks = (rows + block_rows - 1) / block_rows;
    if (block_start < 0 || block_stop < block_start || block_stop > n_blocks) {
        PyErr_Format(PyExc_ValueError, "block range [%lld, %lld) outside [0, %lld]", block_start,
                     block_stop, (long long)n_blocks);
        return NULL;
    }
    if (!get_array(o_nx, "nb_x", NPY_INT64, -1, 0, 0, &p, &n_nb)) return NULL;
    nb_x = (const int64_t *)p;
    if (!get_array(o_ny, "nb_y", NPY_INT64, n_nb, 0, 0, &p, NULL)) return NULL;
    nb_y = (const int64_t *)p;
    if (!get_array(o_nd, "nb_d", NPY_FLOAT64, n_nb, 0, 0, &p, NULL)) return NULL;
    nb_d = (const double *)p;
    for (npy_intp k = 0; k < n_nb; k++) {
        /* any vertex serves (the bound is a point of v's own ray); ahead is merely useful */
        if (!(nb_d[k] > 0.0) || !isfinite(nb_d[k]) || (nb_x[k] == 0 && nb_y[k] == 0)) {
            PyErr_Format(PyExc_ValueError, "neighbour %ld: expected an offset ahead (nb_d > 0)",
                         (long)k);
            return NULL;
        }
    }
    if (!get_array(o_out, "out", NPY_FLOAT64, rows * cols, 1, 0, &out, NULL)) return NULL;
    if (!get_array(o_occ, "occ", NPY_FLOAT64, rows * cols, 1, 0, &occ, NULL)) return NULL;
    timed_begin(&section);
    hf_horizon_chain(H, rows, cols, &mip, dx, dy, max_distance, n_nb, nb_x, nb_y, nb_d, block_rows,
                     block_start, block_stop, (double *)out, (double *)occ, &st);
    elapsed_ns = timed_end(&section);
    return Py_BuildValue("LLLLL", elapsed_ns, (long long)st.cells, (long long)st.skips,
                         (long long)st.tile_tests, (long long)st.bounded);
}

PyDoc_STRVAR(viewshed_doc,
             "viewshed(heights, mip, ox, oy, z0, target_height, drop, eps, start, stop, out)\n"
             "-> (ns, cells, skips)\n\nLine of sight to every target vertex: out 0 visible,\n"
             "1 blocked, 2 uncertain. Private: use algos.viewshed.");

static PyObject *viewshed(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_mip, *o_out;
    double ox, oy, z0, th, drop, eps;
    long long start, stop;
    const double *H;
    int64_t rows, cols;
    hf_hz_mip mip;
    int has_mip;
    void *out;
    hf_hz_stats st = {0, 0};
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOddddddLLO", &o_h, &o_mip, &ox, &oy, &z0, &th, &drop, &eps,
                          &start, &stop, &o_out))
        return NULL;
    if (!get_heights(o_h, &H, &rows, &cols) || !vertex_range(start, stop, rows, cols) ||
        !get_mip(o_mip, rows, cols, &mip, &has_mip))
        return NULL;
    if (!(ox >= 0 && ox <= (double)(cols - 1) && oy >= 0 && oy <= (double)(rows - 1)) ||
        !isfinite(z0) || !isfinite(th) || !isfinite(drop) || !(eps >= 0) || !isfinite(eps)) {
        PyErr_SetString(PyExc_ValueError, "observer: outside the footprint, or a non-finite value");
        return NULL;
    }
    if (!get_array(o_out, "out", NPY_UINT8, rows * cols, 1, 0, &out, NULL)) return NULL;
    timed_begin(&section);
    hf_viewshed(H, rows, cols, has_mip ? &mip : NULL, ox, oy, z0, th, drop, eps, start, stop,
                (uint8_t *)out, &st);
    elapsed_ns = timed_end(&section);
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(
    viewshed_threshold_doc,
    "viewshed_threshold(heights, mip, ox, oy, z0, target_height, drop, kind, start, stop,\n"
    "out) -> (ns, cells, skips)\n\nThe bound on the target top (kind 0) or the eye "
    "(kind 1)\nthat a line of sight to every target vertex needs: float64 out, -inf "
    "where\nnothing lies between. Private: use algos.viewshed(mode=...).");

static PyObject *viewshed_threshold(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_mip, *o_out;
    double ox, oy, z0, th, drop;
    int kind;
    long long start, stop;
    const double *H;
    int64_t rows, cols;
    hf_hz_mip mip;
    int has_mip;
    void *out;
    hf_hz_stats st = {0, 0};
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOdddddiLLO", &o_h, &o_mip, &ox, &oy, &z0, &th, &drop, &kind,
                          &start, &stop, &o_out))
        return NULL;
    if (!get_heights(o_h, &H, &rows, &cols) || !vertex_range(start, stop, rows, cols) ||
        !get_mip(o_mip, rows, cols, &mip, &has_mip))
        return NULL;
    if (!(ox >= 0 && ox <= (double)(cols - 1) && oy >= 0 && oy <= (double)(rows - 1)) ||
        !isfinite(z0) || !isfinite(th) || !isfinite(drop)) {
        PyErr_SetString(PyExc_ValueError, "observer: outside the footprint, or a non-finite value");
        return NULL;
    }
    if (kind != HF_VS_TARGET && kind != HF_VS_OBSERVER) {
        PyErr_Format(PyExc_ValueError, "kind: expected 0 (target) or 1 (observer), got %d", kind);
        return NULL;
    }
    if (!get_array(o_out, "out", NPY_FLOAT64, rows * cols, 1, 0, &out, NULL)) return NULL;
    timed_begin(&section);
    hf_viewshed_threshold(H, rows, cols, has_mip ? &mip : NULL, ox, oy, z0, th, drop, kind, start,
                          stop, (double *)out, &st);
    elapsed_ns = timed_end(&section);
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(horizon_march_doc,
             "horizon_march(heights, dx, dy, step, max_distance, zmax, start, stop, out,\n"
             "              kappa=0.0) -> (ns, samples, 0)\n\nThe r.horizon-style fixed-step\n"
             "marcher; kappa: curvature. Private: use algos.horizon(algorithm='march').");

static PyObject *horizon_march(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_out;
    double dx, dy, step, max_distance, zmax, kappa = 0.0;
    long long start, stop;
    const double *H;
    int64_t rows, cols;
    void *out;
    hf_hz_stats st = {0, 0};
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OdddddLLO|d", &o_h, &dx, &dy, &step, &max_distance, &zmax, &start,
                          &stop, &o_out, &kappa))
        return NULL;
    if (!isfinite(kappa)) {
        PyErr_SetString(PyExc_ValueError, "kappa: expected a finite curvature");
        return NULL;
    }
    if (!get_heights(o_h, &H, &rows, &cols) || !vertex_range(start, stop, rows, cols)) return NULL;
    if (!isfinite(dx) || !isfinite(dy) || (dx == 0 && dy == 0) || !(step > 0) || !isfinite(step) ||
        isnan(max_distance) || isnan(zmax)) {
        PyErr_SetString(PyExc_ValueError, "direction, step or max_distance invalid");
        return NULL;
    }
    if (!get_array(o_out, "out", NPY_FLOAT64, rows * cols, 1, 0, &out, NULL)) return NULL;
    timed_begin(&section);
    hf_horizon_march(H, rows, cols, dx, dy, step, max_distance, zmax, kappa, start, stop,
                     (double *)out, &st);
    elapsed_ns = timed_end(&section);
    return stats_tuple(&st, elapsed_ns);
}

/* ---- rasterisers -------------------------------------------------------------------- */

PyDoc_STRVAR(raster_doc,
             "raster(algorithm, heights, hmin, hmax, camera, sx, sy, near, z_bottom, step,\n"
             "       region, t, cell, normal, coverage, primitive, mask, counts) -> int\n\n"
             "Draw one region (row_begin, row_end, column_begin, column_end) of an image with\n"
             "a rasteriser (0 zbuffer, 1 painter, 2 floating_horizon, 3 hidden lines,\n"
             "4 watkins, 5 warnock);\n"
             "camera is float64\n"
             "(position, forward, right, up, half_w, half_h); primitive (int64) and mask\n"
             "(uint8, painter) are whole-image workspaces. Returns the elapsed nanoseconds\n"
             "of the C loop. Private: use algos.raster.");

static PyObject *raster(PyObject *self, PyObject *args) {
    int algorithm, status;
    double hmin, hmax, near, z_bottom, step;
    PyObject *o_heights, *o_camera, *o_sx, *o_sy, *o_t, *o_cell, *o_normal, *o_coverage,
        *o_primitive, *o_mask, *o_counts;
    hf_raster r;
    npy_intp shape[2], width, height, pixels;
    long long region[4];
    const double *camera;
    int64_t *counts;
    void *p;
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "iOddOOOddd(LLLL)OOOOOOO", &algorithm, &o_heights, &hmin, &hmax,
                          &o_camera, &o_sx, &o_sy, &near, &z_bottom, &step, &region[0], &region[1],
                          &region[2], &region[3], &o_t, &o_cell, &o_normal, &o_coverage,
                          &o_primitive, &o_mask, &o_counts))
        return NULL;
    memset(&r, 0, sizeof r);
    if (algorithm < 0 || algorithm >= HF_N_RASTER) {
        PyErr_Format(PyExc_ValueError, "algorithm: %d is not a rasteriser id", algorithm);
        return NULL;
    }
    if (!PyArray_Check(o_heights) || PyArray_NDIM((PyArrayObject *)o_heights) != 2) {
        PyErr_SetString(PyExc_TypeError, "heights: expected a 2D numpy array");
        return NULL;
    }
    shape[0] = PyArray_DIM((PyArrayObject *)o_heights, 0);
    shape[1] = PyArray_DIM((PyArrayObject *)o_heights, 1);
    if (shape[0] < 2 || shape[1] < 2 || shape[0] > HF_MAX_GRID_SIDE ||
        shape[1] > HF_MAX_GRID_SIDE) {
        PyErr_SetString(PyExc_ValueError, "heights: each side must be in [2, 2^24]");
        return NULL;
    }
    if (!get_f32(o_heights, "heights", 2, shape, &r.heights)) return NULL;
    r.rows = (int32_t)shape[0];
    r.cols = (int32_t)shape[1];
    if (!get_array(o_camera, "camera", NPY_FLOAT64, 14, 0, 0, &p, NULL)) return NULL;
    camera = (const double *)p;
    if (!get_array(o_sx, "sx", NPY_FLOAT64, -1, 0, 0, &p, &width)) return NULL;
    r.sx = (const double *)p;
    if (!get_array(o_sy, "sy", NPY_FLOAT64, -1, 0, 0, &p, &height)) return NULL;
    r.sy = (const double *)p;
    /* sizes: each side fits int32, so every pixel index (int64) and workspace size fits */
    if (width < 1 || height < 1 || width > HF_MAX_GRID_SIDE || height > HF_MAX_GRID_SIDE) {
        PyErr_Format(PyExc_ValueError, "image: %zd x %zd pixels, each side must be in [1, 2^24]",
                     (Py_ssize_t)width, (Py_ssize_t)height);
        return NULL;
    }
    pixels = width * height;
    if (region[0] < 0 || region[1] > height || region[0] >= region[1] || region[2] < 0 ||
        region[3] > width || region[2] >= region[3]) {
        PyErr_Format(PyExc_ValueError,
                     "region: rows [%lld, %lld) x columns [%lld, %lld) is empty or outside "
                     "the %zd x %zd image",
                     region[0], region[1], region[2], region[3], (Py_ssize_t)width,
                     (Py_ssize_t)height);
        return NULL;
    }
    if (algorithm == HF_RASTER_FLOATING_HORIZON ? (region[0] != 0 || region[1] != height)
                                                : (region[2] != 0 || region[3] != width)) {
        PyErr_SetString(PyExc_ValueError, "region: zbuffer, painter, watkins and warnock draw "
                                          "whole rows, "
                                          "floating_horizon whole columns");
        return NULL;
    }
    if (algorithm == HF_RASTER_HIDDEN_LINES && (region[0] != 0 || region[1] != height)) {
        PyErr_SetString(PyExc_ValueError, "region: hidden lines draw the whole image");
        return NULL;
    }
    for (int k = 0; k < 14; ++k) {
        if (!isfinite(camera[k])) {
            PyErr_Format(PyExc_ValueError, "camera: element %d is not finite", k);
            return NULL;
        }
    }
    if (!(camera[12] > 0) || !(camera[13] > 0) || !(near > 0) || !isfinite(near) ||
        !isfinite(z_bottom) || !(step > 0) || !isfinite(step) || !isfinite(hmin) ||
        !isfinite(hmax)) {
        PyErr_SetString(PyExc_ValueError,
                        "camera: half_w, half_h, near and step must be positive and finite");
        return NULL;
    }
    memcpy(r.position, camera, sizeof r.position);
    memcpy(r.forward, camera + 3, sizeof r.forward);
    memcpy(r.right, camera + 6, sizeof r.right);
    memcpy(r.up, camera + 9, sizeof r.up);
    r.half_w = camera[12];
    r.half_h = camera[13];
    r.width = (int32_t)width;
    r.height = (int32_t)height;
    r.row_begin = (int32_t)region[0];
    r.row_end = (int32_t)region[1];
    r.column_begin = (int32_t)region[2];
    r.column_end = (int32_t)region[3];
    r.hmin = hmin;
    r.hmax = hmax;
    r.near = near;
    r.z_bottom = z_bottom;
    r.step = step;
    if (!get_array(o_t, "t", NPY_FLOAT64, pixels, 1, 0, &p, NULL)) return NULL;
    r.t = (double *)p;
    if (!get_array(o_cell, "cell", NPY_INT32, 2 * pixels, 1, 0, &p, NULL)) return NULL;
    r.cell = (int32_t *)p;
    if (!get_array(o_normal, "normal", NPY_FLOAT64, 3 * pixels, 1, 1, &p, NULL)) return NULL;
    r.normal = (double *)p;
    if (!get_array(o_coverage, "coverage", NPY_INT32, pixels, 1, 1, &p, NULL)) return NULL;
    r.coverage = (int32_t *)p;
    if (!get_array(o_primitive, "primitive", NPY_INT64, pixels, 1, 0, &p, NULL)) return NULL;
    r.primitive = (int64_t *)p;
    if (!get_array(o_mask, "mask", NPY_UINT8, pixels, 1,
                   algorithm != HF_RASTER_PAINTER && algorithm != HF_RASTER_HIDDEN_LINES, &p, NULL))
        return NULL;
    r.mask = (uint8_t *)p;
    if (!get_array(o_counts, "counts", NPY_INT64, HF_N_COUNTS, 1, 0, &p, NULL)) return NULL;
    counts = (int64_t *)p;
    /* allocated once per call: the zbuffer's two rows of projected corners, the hidden
     * lines' horizons */
    {
        const size_t doubles = hf_raster_workspace_doubles(algorithm, r.cols, r.width);
        if (doubles) {
            r.vertex_rows = malloc(doubles * sizeof(double));
            if (!r.vertex_rows) return PyErr_NoMemory();
        }
    }
    timed_begin(&section);
    status = hf_raster_render(algorithm, &r);
    elapsed_ns = timed_end(&section);
    free(r.vertex_rows);
    if (status == HF_ERR_MEMORY) return PyErr_NoMemory();
    if (status != HF_OK) {
        PyErr_Format(PyExc_RuntimeError, "rasteriser %d failed: %s", algorithm,
                     status_text(status));
        return NULL;
    }
    memcpy(counts, r.counts, sizeof r.counts);
    return PyLong_FromLongLong(elapsed_ns);
}

/* ---- cone step mapping (issue 22) ----------------------------------------------------- */

PyDoc_STRVAR(intersect_cone_doc,
             "intersect_cone(cone, kernel, surface, heights, ...) -> int\n\n"
             "intersect() for the cone kernels: the cone structure (algos/cone.py; float32\n"
             "of shape (rows - 1, cols - 1, 2) for cone, (rows - 1, cols - 1) for\n"
             "cone_relaxed) before intersect()'s arguments.\n"
             "Private: use algos.intersect.");

static PyObject *intersect_cone(PyObject *self, PyObject *args) {
    PyObject *rest, *result;
    (void)self;
    if (!PyTuple_Check(args) || PyTuple_GET_SIZE(args) < 1) {
        PyErr_SetString(PyExc_TypeError,
                        "intersect_cone: expected cone, then intersect()'s arguments");
        return NULL;
    }
    rest = PyTuple_GetSlice(args, 1, PyTuple_GET_SIZE(args));
    if (rest == NULL) return NULL;
    result = intersect_with(rest, PyTuple_GET_ITEM(args, 0), NULL);
    Py_DECREF(rest);
    return result;
}

PyDoc_STRVAR(cone_relaxed_slopes_doc,
             "cone_relaxed_slopes(cellmax, radius, slope) -> int\n\n"
             "Fill slope (float32, the shape of cellmax) with the relaxed cone slope of every\n"
             "cell (Policarpo & Oliveira 2007, cext/cone.c) from the destinations within\n"
             "radius rings (1 to 64); returns the elapsed nanoseconds. Private: use\n"
             "algos.cone.");

static PyObject *cone_relaxed_slopes(PyObject *self, PyObject *args) {
    PyObject *o_cellmax, *o_slope;
    int radius;
    const float *cellmax;
    float *slope;
    npy_intp shape[2];
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OiO", &o_cellmax, &radius, &o_slope)) return NULL;
    if (!PyArray_Check(o_cellmax) || PyArray_NDIM((PyArrayObject *)o_cellmax) != 2) {
        PyErr_SetString(PyExc_TypeError, "cellmax: expected a 2D numpy array");
        return NULL;
    }
    shape[0] = PyArray_DIM((PyArrayObject *)o_cellmax, 0);
    shape[1] = PyArray_DIM((PyArrayObject *)o_cellmax, 1);
    if (shape[0] < 1 || shape[1] < 1 || shape[0] >= HF_MAX_GRID_SIDE ||
        shape[1] >= HF_MAX_GRID_SIDE) {
        PyErr_SetString(PyExc_ValueError, "cellmax: each side must be in [1, 2^24 - 1]");
        return NULL;
    }
    if (radius < 1 || radius > 64) {
        PyErr_Format(PyExc_ValueError, "radius: expected 1 to 64, got %d", radius);
        return NULL;
    }
    if (!get_f32(o_cellmax, "cellmax", 2, shape, &cellmax)) return NULL;
    if (!get_f32(o_slope, "slope", 2, shape, (const float **)&slope)) return NULL;
    if (!PyArray_ISWRITEABLE((PyArrayObject *)o_slope)) {
        PyErr_SetString(PyExc_ValueError, "slope: must be writable");
        return NULL;
    }
    timed_begin(&section);
    hf_cone_relaxed_build(cellmax, (int32_t)shape[0], (int32_t)shape[1], radius, slope);
    elapsed_ns = timed_end(&section);
    return PyLong_FromLongLong(elapsed_ns);
}

/* ---- the compact maximum tree (issue 22) ---------------------------------------------- */

PyDoc_STRVAR(intersect_compact_doc,
             "intersect_compact(compact, kernel, surface, heights, ...) -> int\n\n"
             "intersect() for dda_compact: the compact tree (algos/compact.py; uint8, 64\n"
             "bytes per node, aligned to 64) before intersect()'s arguments.\n"
             "Private: use algos.intersect.");

static PyObject *intersect_compact(PyObject *self, PyObject *args) {
    PyObject *rest, *result;
    (void)self;
    if (!PyTuple_Check(args) || PyTuple_GET_SIZE(args) < 1) {
        PyErr_SetString(PyExc_TypeError,
                        "intersect_compact: expected compact, then intersect()'s arguments");
        return NULL;
    }
    rest = PyTuple_GetSlice(args, 1, PyTuple_GET_SIZE(args));
    if (rest == NULL) return NULL;
    result = intersect_with(rest, NULL, PyTuple_GET_ITEM(args, 0));
    Py_DECREF(rest);
    return result;
}

PyDoc_STRVAR(compact_build_doc,
             "compact_build(cellmax, compact) -> int\n\n"
             "Fill compact (uint8, writable, 64 bytes per node, aligned to 64) with the compact\n"
             "maximum tree of cellmax (float32, (ny, nx); cext/compact.c); returns the elapsed\n"
             "nanoseconds. Private: use algos.compact.");

static PyObject *compact_build(PyObject *self, PyObject *args) {
    PyObject *o_cellmax, *o_compact;
    const float *cellmax;
    void *records;
    npy_intp shape[2];
    timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OO", &o_cellmax, &o_compact)) return NULL;
    if (!PyArray_Check(o_cellmax) || PyArray_NDIM((PyArrayObject *)o_cellmax) != 2) {
        PyErr_SetString(PyExc_TypeError, "cellmax: expected a 2D numpy array");
        return NULL;
    }
    shape[0] = PyArray_DIM((PyArrayObject *)o_cellmax, 0);
    shape[1] = PyArray_DIM((PyArrayObject *)o_cellmax, 1);
    if (shape[0] < 1 || shape[1] < 1 || shape[0] >= HF_MAX_GRID_SIDE ||
        shape[1] >= HF_MAX_GRID_SIDE) {
        PyErr_SetString(PyExc_ValueError, "cellmax: each side must be in [1, 2^24 - 1]");
        return NULL;
    }
    if (!get_f32(o_cellmax, "cellmax", 2, shape, &cellmax)) return NULL;
    if (!get_compact(o_compact, (int32_t)shape[1], (int32_t)shape[0], 1, &records)) return NULL;
    timed_begin(&section);
    hf_compact_build(cellmax, (int32_t)shape[0], (int32_t)shape[1], records);
    elapsed_ns = timed_end(&section);
    return PyLong_FromLongLong(elapsed_ns);
}

static PyMethodDef methods[] = {
    {"walk", walk, METH_VARARGS, walk_doc},
    {"intersect", intersect, METH_VARARGS, intersect_doc},
    {"quantize_ray", quantize_ray, METH_VARARGS, quantize_doc},
    {"best_rational", best_rational, METH_VARARGS, best_rational_doc},
    {"horizon_pattern", horizon_pattern, METH_VARARGS, horizon_pattern_doc},
    {"horizon_sweep", horizon_sweep, METH_VARARGS, horizon_sweep_doc},
    {"horizon_walk", horizon_walk, METH_VARARGS, horizon_walk_doc},
    {"horizon_rows", horizon_rows, METH_VARARGS, horizon_rows_doc},
    {"horizon_chain", horizon_chain, METH_VARARGS, horizon_chain_doc},
    {"viewshed", viewshed, METH_VARARGS, viewshed_doc},
    {"viewshed_threshold", viewshed_threshold, METH_VARARGS, viewshed_threshold_doc},
    {"horizon_march", horizon_march, METH_VARARGS, horizon_march_doc},
    {"raster", raster, METH_VARARGS, raster_doc},
    {"intersect_cone", intersect_cone, METH_VARARGS, intersect_cone_doc},
    {"cone_relaxed_slopes", cone_relaxed_slopes, METH_VARARGS, cone_relaxed_slopes_doc},
    {"intersect_compact", intersect_compact, METH_VARARGS, intersect_compact_doc},
    {"compact_build", compact_build, METH_VARARGS, compact_build_doc},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT,
                                    "algos._kernels",
                                    "hftrace C kernels (private; see algos).",
                                    -1,
                                    methods,
                                    NULL,
                                    NULL,
                                    NULL,
                                    NULL};

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
