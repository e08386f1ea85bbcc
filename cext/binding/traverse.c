/* The binding of the 2D traversals (walks/, dispatch/traverse.c): walk, and the exact
 * lattice's helpers for tests. */
#include "binding/args.h"

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
    hf_ray_arrays rays;
    npy_intp n, out_len, pattern_len;
    void *p;
    hf_timed_section section;
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
    if (!hf_arg_rays(o_origins, o_directions, o_tmin, o_tmax, 2, &rays)) return NULL;
    n = rays.n;
    batch.n_rays = n;
    batch.origins = rays.origins;
    batch.directions = rays.directions;
    batch.tmin = rays.tmin;
    batch.tmax = rays.tmax;
    batch.nx = (int32_t)nx;
    batch.ny = (int32_t)ny;
    batch.max_denominator = max_denominator;
    if (!hf_arg_array(o_pattern, "pattern", NPY_INT32, -1, 1, 1, &p, &pattern_len)) return NULL;
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
        if (!hf_arg_array(o_n_cells, "n_cells", NPY_INT64, n, 1, 0, &p, NULL)) return NULL;
        batch.n_cells = (int64_t *)p;
        if (!hf_arg_array(o_n_runs, "n_runs", NPY_INT64, n, 1, 0, &p, NULL)) return NULL;
        batch.n_runs = (int64_t *)p;
    } else if (mode == HF_MODE_CELLS || mode == HF_MODE_RUNS) {
        const npy_intp width = mode == HF_MODE_CELLS ? 2 : 3;
        if (!hf_arg_array(o_offsets, "offsets", NPY_INT64, n + 1, 0, 0, &p, NULL)) return NULL;
        batch.offsets = (const int64_t *)p;
        if (!hf_arg_array(o_out, "out", NPY_INT32, -1, 1, 0, &p, &out_len)) return NULL;
        if (out_len % width != 0) {
            PyErr_SetString(PyExc_ValueError, "out: size is not a whole number of rows");
            return NULL;
        }
        batch.out = (int32_t *)p;
        batch.out_rows = out_len / width;
    } else {
        if (!hf_arg_array(o_checksums, "checksums", NPY_UINT64, n, 1, 0, &p, NULL)) return NULL;
        batch.checksums = (uint64_t *)p;
    }

    hf_timed_begin(&section);
    status = hf_walk_batch(kernel, mode, &batch);
    elapsed_ns = hf_timed_end(&section);

    if (status != HF_OK) {
        PyErr_Format(PyExc_RuntimeError, "kernel %d failed on ray %lld: %s", kernel,
                     (long long)batch.bad_ray, hf_status_text(status));
        return NULL;
    }
    return PyLong_FromLongLong(elapsed_ns);
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

static PyMethodDef traverse_methods[] = {
    {"walk", walk, METH_VARARGS, walk_doc},
    {"quantize_ray", quantize_ray, METH_VARARGS, quantize_doc},
    {"best_rational", best_rational, METH_VARARGS, best_rational_doc},
    {NULL, NULL, 0, NULL}};

int hf_bind_traverse(PyObject *module) {
    return PyModule_AddFunctions(module, traverse_methods);
}
