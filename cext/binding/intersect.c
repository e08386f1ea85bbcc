/* The binding of the first-hit intersectors (dispatch/intersect.c) and of the structures
 * built in C for them: the cone slopes and the compact tree. */
#include <stdarg.h>
#include "binding/args.h"
#include "hierarchies/compact.h"
#include "hierarchies/cone.h"
#include "raster/pitched.h"
#include "surfaces/hitbatch.h"

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
    if (!hf_arg_f32(values, name, 2, shape, &q->values)) return 0;
    if (!hf_arg_f32(prefix, name, 2, shape, &q->prefix)) return 0;
    if (!hf_arg_f32(suffix, name, 2, shape, &q->suffix)) return 0;
    shape[1] = q->n_levels;
    shape[2] = q->n_blocks;
    return hf_arg_f32(sparse, name, 3, shape, &q->sparse);
}

PyDoc_STRVAR(intersect_doc,
             "intersect(kernel, surface, field, rays, options, outputs) -> int\n\n"
             "First hits of a batch; returns the elapsed nanoseconds of the C loop.\n"
             "field: (heights, cellmax, hmin, hmax, row_max, col_max, mip);\n"
             "rays: (origins, directions, tmin, tmax);\n"
             "options: (cull_cells, max_denominator, pattern, march, fine_level, packet_width);\n"
             "outputs: (t, cell, normal, stats), each None when not wanted.\n"
             "Private: use algos.intersect.");

/* The arguments of intersect(kernel, surface, field, rays, options, outputs): the kernel
 * ids, then four small tuples (intersect_doc) rather than 23 positional arguments. */
typedef struct {
    int kernel, surface;
    PyObject *heights, *cellmax, *row_max, *col_max, *mip; /* field */
    double hmin, hmax;
    PyObject *origins, *directions, *tmin, *tmax; /* rays */
    int cull_cells, fine_level, packet_width;     /* options */
    long long max_denominator;
    PyObject *pattern, *march;
    PyObject *t, *cell, *normal, *stats; /* outputs */
} intersect_args;

/* One group of arguments: a tuple of exactly `size` items, read by `format`. */
static int read_group(PyObject *group, const char *name, Py_ssize_t size, const char *format, ...) {
    va_list items;
    int ok;
    if (!PyTuple_Check(group) || PyTuple_GET_SIZE(group) != size) {
        PyErr_Format(PyExc_TypeError, "%s: expected a tuple of %zd items, got %s", name, size,
                     Py_TYPE(group)->tp_name);
        return 0;
    }
    va_start(items, format);
    ok = PyArg_VaParse(group, format, items);
    va_end(items);
    return ok;
}

static int read_intersect_args(PyObject *args, intersect_args *a) {
    PyObject *field, *rays, *options, *outputs;
    if (!PyArg_ParseTuple(args, "iiOOOO", &a->kernel, &a->surface, &field, &rays, &options,
                          &outputs))
        return 0;
    return read_group(field, "field", 7, "OOddOOO", &a->heights, &a->cellmax, &a->hmin, &a->hmax,
                      &a->row_max, &a->col_max, &a->mip) &&
           read_group(rays, "rays", 4, "OOOO", &a->origins, &a->directions, &a->tmin, &a->tmax) &&
           read_group(options, "options", 6, "iLOOii", &a->cull_cells, &a->max_denominator,
                      &a->pattern, &a->march, &a->fine_level, &a->packet_width) &&
           read_group(outputs, "outputs", 4, "OOOO", &a->t, &a->cell, &a->normal, &a->stats);
}

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

/* The kernel and surface ids in range. */
static int check_ids(const intersect_args *a) {
    if (a->kernel < 0 || a->kernel >= HF_N_HIT_KERNELS || a->surface < 0 ||
        a->surface > HF_BILINEAR) {
        PyErr_SetString(PyExc_ValueError, "kernel or surface out of range");
        return 0;
    }
    return 1;
}

/* The heights (float32, a vertex grid) and the cell maxima (float32, one per cell; None
 * only in the lean layout); `cells` receives the cell grid's shape (rows - 1, cols - 1). */
static int read_grids(const intersect_args *a, hf_hit_batch *b, npy_intp cells[2]) {
    if (!hf_arg_grid_shape(a->heights, "heights", HF_GRID_VERTICES, cells)) return 0;
    if (!hf_arg_f32(a->heights, "heights", 2, cells, &b->heights)) return 0;
    b->rows = (int32_t)cells[0];
    b->cols = (int32_t)cells[1];
    cells[0] -= 1;
    cells[1] -= 1;
    if (a->cellmax == Py_None) {
        /* the lean layout (algos.Field(lean=True)): runs_maxmip without cell culling is
         * the one kernel that never reads the cell maxima */
        if (a->kernel != HF_HIT_RUNS_MAXMIP || a->cull_cells || a->row_max != Py_None) {
            PyErr_SetString(
                PyExc_ValueError,
                "cellmax: only runs_maxmip without cell or run culling runs without it");
            return 0;
        }
        b->cellmax = NULL;
        return 1;
    }
    return hf_arg_f32(a->cellmax, "cellmax", 2, cells, &b->cellmax);
}

/* The structure of the one entry point that runs the kernel it belongs to: the cone
 * (intersect_cone) or the compact tree (intersect_compact); NULL from every other entry. */
static int read_structures(const intersect_args *a, PyObject *o_cone, PyObject *o_compact,
                           const npy_intp cells[2], hf_hit_batch *b) {
    if ((o_cone != NULL) != (a->kernel == HF_HIT_CONE || a->kernel == HF_HIT_CONE_RELAXED)) {
        PyErr_SetString(
            PyExc_ValueError,
            "cone: only intersect_cone runs the cone kernels, and it runs nothing else");
        return 0;
    }
    if (o_cone != NULL) {
        /* cone: top and slope side by side; cone_relaxed: slopes (its apex: the cell max) */
        npy_intp cone_shape[3];
        cone_shape[0] = cells[0];
        cone_shape[1] = cells[1];
        cone_shape[2] = 2;
        if (!hf_arg_f32(o_cone, "cone", a->kernel == HF_HIT_CONE ? 3 : 2, cone_shape, &b->cone))
            return 0;
    }
    if ((o_compact != NULL) != (a->kernel == HF_HIT_DDA_COMPACT)) {
        PyErr_SetString(
            PyExc_ValueError,
            "compact: only intersect_compact runs dda_compact, and it runs nothing else");
        return 0;
    }
    if (o_compact != NULL) {
        void *records;
        if (!get_compact(o_compact, (int32_t)cells[1], (int32_t)cells[0], 0, &records)) return 0;
        b->compact = records;
    }
    return 1;
}

/* The run maxima (row_max and col_max together, or neither) and the mipmap: a list of
 * float32 levels, level k of ceil(cells / 2^k) per side (None below fine_level). */
static int read_hierarchies(const intersect_args *a, const npy_intp cells[2], hf_hit_batch *b) {
    if (a->row_max != Py_None || a->col_max != Py_None) {
        if (a->row_max == Py_None || a->col_max == Py_None) {
            PyErr_SetString(PyExc_ValueError, "row_max and col_max come together");
            return 0;
        }
        if (!get_rmq(a->row_max, "row_max", cells[0], cells[1], &b->row_max)) return 0;
        if (!get_rmq(a->col_max, "col_max", cells[1], cells[0], &b->col_max)) return 0;
        b->cull_runs = 1;
    }
    if (a->mip != Py_None) {
        npy_intp levels;
        if (!PyList_Check(a->mip)) {
            PyErr_SetString(PyExc_TypeError, "mip: expected a list of float32 arrays");
            return 0;
        }
        levels = PyList_GET_SIZE(a->mip);
        if (levels < 1 || levels > HF_MAX_MIP_LEVELS) {
            PyErr_SetString(PyExc_ValueError, "mip: 1 to 32 levels");
            return 0;
        }
        for (int k = 0; k < levels; ++k) {
            npy_intp ms[2];
            /* level k covers 2^k x 2^k cells: ceil division of the cell grid */
            ms[0] = (cells[0] + ((npy_intp)1 << k) - 1) >> k;
            ms[1] = (cells[1] + ((npy_intp)1 << k) - 1) >> k;
            if (PyList_GET_ITEM(a->mip, k) == Py_None && k < a->fine_level) {
                /* levels below the floor level are never read (the lean layout) */
                b->mip[k] = NULL;
            } else if (!hf_arg_f32(PyList_GET_ITEM(a->mip, k), "mip level", 2, ms, &b->mip[k])) {
                return 0;
            }
            b->mip_cols[k] = (int32_t)ms[1];
        }
        b->mip_levels = (int)levels;
    }
    return 1;
}

/* The rays (hf_arg_rays) and the options: the periodic pattern, the marchers' steps, the
 * mipmap's floor level and the packet width, each checked against the kernel. */
static int read_rays_and_options(const intersect_args *a, hf_hit_batch *b) {
    hf_ray_arrays rays;
    npy_intp plen;
    void *p;
    if (!hf_arg_rays(a->origins, a->directions, a->tmin, a->tmax, 3, &rays)) return 0;
    b->n_rays = rays.n;
    b->origins = rays.origins;
    b->directions = rays.directions;
    b->tmin = rays.tmin;
    b->tmax = rays.tmax;
    b->max_denominator = a->max_denominator;
    if (!hf_arg_array(a->pattern, "pattern", NPY_INT32, -1, 1, 1, &p, &plen)) return 0;
    b->pattern = (int32_t *)p;
    if (a->kernel == HF_RUNS_PERIODIC &&
        (b->pattern == NULL || a->max_denominator < 1 || a->max_denominator > HF_MAX_DENOMINATOR ||
         plen < a->max_denominator + 1)) {
        PyErr_SetString(PyExc_ValueError, "runs_periodic needs a pattern of max_denominator + 1");
        return 0;
    }
    if (!PyArg_ParseTuple(a->march, "iiddd", &b->march_steps, &b->march_refinements,
                          &b->march_growth, &b->march_first_fraction, &b->march_min_step))
        return 0;
    if (b->march_steps < 1 || b->march_refinements < 0 || !(b->march_growth >= 1.0) ||
        !(b->march_first_fraction > 0) || !(b->march_min_step >= 0)) {
        PyErr_SetString(PyExc_ValueError, "march: invalid parameters");
        return 0;
    }
    if ((a->kernel == HF_HIT_DDA_MAXMIP || a->kernel == HF_HIT_RUNS_MAXMIP ||
         a->kernel == HF_HIT_PACKET_MAXMIP || a->kernel == HF_HIT_PLANE_MAXMIP ||
         a->kernel == HF_HIT_PITCHED_MAXMIP || a->kernel == HF_HIT_RING_MAXMIP) &&
        b->mip_levels < 1) {
        PyErr_SetString(PyExc_ValueError, "the maxmip kernels need the mipmap");
        return 0;
    }
    if (a->fine_level < 0 || a->fine_level >= (b->mip_levels > 0 ? b->mip_levels : 1)) {
        PyErr_SetString(PyExc_ValueError, "fine_level: outside the mipmap");
        return 0;
    }
    b->floor_level = a->fine_level;
    if (a->packet_width < 1 || a->packet_width > HF_PACKET_MAX) {
        PyErr_Format(PyExc_ValueError, "packet_width: expected 1 .. %d, got %d", HF_PACKET_MAX,
                     a->packet_width);
        return 0;
    }
    b->packet_width = a->packet_width;
    return 1;
}

/* The hit record's fields (each None when not wanted, hf_arg_out): t, cell (i, j),
 * normal (x, y, z) and the five statistics, per ray. */
static int read_outputs(const intersect_args *a, hf_hit_batch *b) {
    const npy_intp n = b->n_rays;
    void *p;
    if (!hf_arg_out(a->t, "t", NPY_FLOAT64, n, 1, &p)) return 0;
    b->t = (double *)p;
    if (!hf_arg_out(a->cell, "cell", NPY_INT32, 2 * n, 1, &p)) return 0;
    b->cell = (int32_t *)p;
    if (!hf_arg_out(a->normal, "normal", NPY_FLOAT64, 3 * n, 1, &p)) return 0;
    b->normal = (double *)p;
    if (!hf_arg_out(a->stats, "stats", NPY_INT64, 5 * n, 1, &p)) return 0;
    b->stats = (int64_t *)p;
    return 1;
}

/* intersect, intersect_cone and intersect_compact: the batch from `args`, with the cone
 * structure (NULL but for intersect_cone): float32 of shape (rows - 1, cols - 1, 2) for
 * cone, (rows - 1, cols - 1) for cone_relaxed; and the compact tree (NULL but for
 * intersect_compact); and the bounds' output (NULL but for intersect_pitched_bounds).
 * Validation, then the kernel without the GIL; returns its elapsed nanoseconds. */
static PyObject *intersect_with(PyObject *args, PyObject *o_cone, PyObject *o_compact,
                                PyObject *o_bound) {
    int status;
    intersect_args a;
    hf_hit_batch b;
    npy_intp cells[2];
    hf_timed_section section;
    long long elapsed_ns;
    if (!read_intersect_args(args, &a)) return NULL;
    memset(&b, 0, sizeof b);
    if (!check_ids(&a) || !read_grids(&a, &b, cells) ||
        !read_structures(&a, o_cone, o_compact, cells, &b))
        return NULL;
    b.hmin = a.hmin;
    b.hmax = a.hmax;
    b.habs = fabs(a.hmin) > fabs(a.hmax) ? fabs(a.hmin) : fabs(a.hmax);
    b.grid_span = (double)b.cols + (double)b.rows + 2;
    b.surface = a.surface;
    b.cull_cells = a.cull_cells;
    if (!read_hierarchies(&a, cells, &b) || !read_rays_and_options(&a, &b) || !read_outputs(&a, &b))
        return NULL;
    if (o_bound != NULL) {
        void *p;
        if (a.kernel != HF_HIT_PITCHED_MAXMIP) {
            PyErr_SetString(PyExc_ValueError, "bound: only pitched_maxmip writes its bounds");
            return NULL;
        }
        if (!hf_arg_array(o_bound, "bound", NPY_FLOAT64, b.n_rays, 1, 1, &p, NULL)) return NULL;
        b.bound = (double *)p;
    }

    hf_timed_begin(&section);
    /* pitched_maxmip sits above the dispatcher (it draws with the rasteriser's geometry) */
    status = a.kernel == HF_HIT_PITCHED_MAXMIP ? hf_pitched_batch(&b, hf_maxmip_steps())
                                               : hf_intersect_batch(a.kernel, &b);
    elapsed_ns = hf_timed_end(&section);

    if (status != HF_OK) {
        PyErr_Format(PyExc_RuntimeError, "intersector %d failed on ray %lld: %s", a.kernel,
                     (long long)b.bad_ray, hf_status_text(status));
        return NULL;
    }
    return PyLong_FromLongLong(elapsed_ns);
}

static PyObject *intersect(PyObject *self, PyObject *args) {
    (void)self;
    return intersect_with(args, NULL, NULL, NULL);
}

PyDoc_STRVAR(intersect_pitched_bounds_doc,
             "intersect_pitched_bounds(bound, kernel, surface, field, ...) -> int\n\n"
             "intersect() for pitched_maxmip, also writing into bound (float64, (n,)) the\n"
             "parameter each ray's walk was allowed to start from: its lower bound on the\n"
             "first hit (t0 where none applies, inf where the ray meets no tile box).\n"
             "Private: for the tests of the bound.");

static PyObject *intersect_pitched_bounds(PyObject *self, PyObject *args) {
    PyObject *rest, *result;
    (void)self;
    if (!PyTuple_Check(args) || PyTuple_GET_SIZE(args) < 1) {
        PyErr_SetString(PyExc_TypeError,
                        "intersect_pitched_bounds: expected bound, then intersect()'s arguments");
        return NULL;
    }
    rest = PyTuple_GetSlice(args, 1, PyTuple_GET_SIZE(args));
    if (rest == NULL) return NULL;
    result = intersect_with(rest, NULL, NULL, PyTuple_GET_ITEM(args, 0));
    Py_DECREF(rest);
    return result;
}

/* intersect_cone and intersect_compact: their structure first, then intersect()'s
 * arguments; `cone` says which of the two it is. */
static PyObject *intersect_after_structure(PyObject *args, const char *entry, const char *structure,
                                           int cone) {
    PyObject *rest, *first, *result;
    if (!PyTuple_Check(args) || PyTuple_GET_SIZE(args) < 1) {
        PyErr_Format(PyExc_TypeError, "%s: expected %s, then intersect()'s arguments", entry,
                     structure);
        return NULL;
    }
    rest = PyTuple_GetSlice(args, 1, PyTuple_GET_SIZE(args));
    if (rest == NULL) return NULL;
    first = PyTuple_GET_ITEM(args, 0);
    result = intersect_with(rest, cone ? first : NULL, cone ? NULL : first, NULL);
    Py_DECREF(rest);
    return result;
}

/* ---- cone step mapping ----------------------------------------------------------------- */

PyDoc_STRVAR(intersect_cone_doc,
             "intersect_cone(cone, kernel, surface, heights, ...) -> int\n\n"
             "intersect() for the cone kernels: the cone structure (algos/cone.py; float32\n"
             "of shape (rows - 1, cols - 1, 2) for cone, (rows - 1, cols - 1) for\n"
             "cone_relaxed) before intersect()'s arguments.\n"
             "Private: use algos.intersect.");

static PyObject *intersect_cone(PyObject *self, PyObject *args) {
    (void)self;
    return intersect_after_structure(args, "intersect_cone", "cone", 1);
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
    hf_timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OiO", &o_cellmax, &radius, &o_slope)) return NULL;
    if (!hf_arg_grid_shape(o_cellmax, "cellmax", HF_GRID_CELLS, shape)) return NULL;
    if (radius < 1 || radius > 64) {
        PyErr_Format(PyExc_ValueError, "radius: expected 1 to 64, got %d", radius);
        return NULL;
    }
    if (!hf_arg_f32(o_cellmax, "cellmax", 2, shape, &cellmax)) return NULL;
    if (!hf_arg_f32_out(o_slope, "slope", 2, shape, &slope)) return NULL;
    hf_timed_begin(&section);
    hf_cone_relaxed_build(cellmax, (int32_t)shape[0], (int32_t)shape[1], radius, slope);
    elapsed_ns = hf_timed_end(&section);
    return PyLong_FromLongLong(elapsed_ns);
}

/* ---- the compact maximum tree ----------------------------------------------------------- */

PyDoc_STRVAR(intersect_compact_doc,
             "intersect_compact(compact, kernel, surface, heights, ...) -> int\n\n"
             "intersect() for dda_compact: the compact tree (algos/compact.py; uint8, 64\n"
             "bytes per node, aligned to 64) before intersect()'s arguments.\n"
             "Private: use algos.intersect.");

static PyObject *intersect_compact(PyObject *self, PyObject *args) {
    (void)self;
    return intersect_after_structure(args, "intersect_compact", "compact", 0);
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
    hf_timed_section section;
    long long elapsed_ns;
    (void)self;
    if (!PyArg_ParseTuple(args, "OO", &o_cellmax, &o_compact)) return NULL;
    if (!hf_arg_grid_shape(o_cellmax, "cellmax", HF_GRID_CELLS, shape)) return NULL;
    if (!hf_arg_f32(o_cellmax, "cellmax", 2, shape, &cellmax)) return NULL;
    if (!get_compact(o_compact, (int32_t)shape[1], (int32_t)shape[0], 1, &records)) return NULL;
    hf_timed_begin(&section);
    hf_compact_build(cellmax, (int32_t)shape[0], (int32_t)shape[1], records);
    elapsed_ns = hf_timed_end(&section);
    return PyLong_FromLongLong(elapsed_ns);
}

static PyMethodDef intersect_methods[] = {
    {"intersect", intersect, METH_VARARGS, intersect_doc},
    {"intersect_cone", intersect_cone, METH_VARARGS, intersect_cone_doc},
    {"intersect_pitched_bounds", intersect_pitched_bounds, METH_VARARGS,
     intersect_pitched_bounds_doc},
    {"cone_relaxed_slopes", cone_relaxed_slopes, METH_VARARGS, cone_relaxed_slopes_doc},
    {"intersect_compact", intersect_compact, METH_VARARGS, intersect_compact_doc},
    {"compact_build", compact_build, METH_VARARGS, compact_build_doc},
    {NULL, NULL, 0, NULL}};

int hf_bind_intersect(PyObject *module) {
    return PyModule_AddFunctions(module, intersect_methods);
}
