/* The binding of the rasterisers (raster/raster.c). */
#include "binding/args.h"
#include "raster/raster.h"

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
    hf_timed_section section;
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
    if (!hf_arg_f32(o_heights, "heights", 2, shape, &r.heights)) return NULL;
    r.rows = (int32_t)shape[0];
    r.cols = (int32_t)shape[1];
    if (!hf_arg_array(o_camera, "camera", NPY_FLOAT64, 14, 0, 0, &p, NULL)) return NULL;
    camera = (const double *)p;
    if (!hf_arg_array(o_sx, "sx", NPY_FLOAT64, -1, 0, 0, &p, &width)) return NULL;
    r.sx = (const double *)p;
    if (!hf_arg_array(o_sy, "sy", NPY_FLOAT64, -1, 0, 0, &p, &height)) return NULL;
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
    if (!hf_arg_array(o_t, "t", NPY_FLOAT64, pixels, 1, 0, &p, NULL)) return NULL;
    r.t = (double *)p;
    if (!hf_arg_array(o_cell, "cell", NPY_INT32, 2 * pixels, 1, 0, &p, NULL)) return NULL;
    r.cell = (int32_t *)p;
    if (!hf_arg_array(o_normal, "normal", NPY_FLOAT64, 3 * pixels, 1, 1, &p, NULL)) return NULL;
    r.normal = (double *)p;
    if (!hf_arg_array(o_coverage, "coverage", NPY_INT32, pixels, 1, 1, &p, NULL)) return NULL;
    r.coverage = (int32_t *)p;
    if (!hf_arg_array(o_primitive, "primitive", NPY_INT64, pixels, 1, 0, &p, NULL)) return NULL;
    r.primitive = (int64_t *)p;
    if (!hf_arg_array(o_mask, "mask", NPY_UINT8, pixels, 1,
                      algorithm != HF_RASTER_PAINTER && algorithm != HF_RASTER_HIDDEN_LINES, &p,
                      NULL))
        return NULL;
    r.mask = (uint8_t *)p;
    if (!hf_arg_array(o_counts, "counts", NPY_INT64, HF_N_COUNTS, 1, 0, &p, NULL)) return NULL;
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
    hf_timed_begin(&section);
    status = hf_raster_render(algorithm, &r);
    elapsed_ns = hf_timed_end(&section);
    free(r.vertex_rows);
    if (status == HF_ERR_MEMORY) return PyErr_NoMemory();
    if (status != HF_OK) {
        PyErr_Format(PyExc_RuntimeError, "rasteriser %d failed: %s", algorithm,
                     hf_status_text(status));
        return NULL;
    }
    memcpy(counts, r.counts, sizeof r.counts);
    return PyLong_FromLongLong(elapsed_ns);
}

static PyMethodDef raster_methods[] = {{"raster", raster, METH_VARARGS, raster_doc},
                                       {NULL, NULL, 0, NULL}};

int hf_bind_raster(PyObject *module) {
    return PyModule_AddFunctions(module, raster_methods);
}
