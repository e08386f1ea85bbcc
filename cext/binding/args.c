/* The binding's shared argument reader: arrays checked for dtype, layout and size, the rays
 * of a batch, the outputs and grids every area reads, the timed GIL-free section and the
 * status messages (args.h). */
#define HF_BINDING_ARGS_C
#include "binding/args.h"

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

int hf_arg_out(PyObject *object, const char *name, int type, npy_intp size, int optional,
               void **data) {
    return hf_arg_array(object, name, type, size, 1, optional, data, NULL);
}

int hf_arg_f32_out(PyObject *object, const char *name, int ndim, const npy_intp *shape,
                   float **data) {
    const float *read;
    if (!hf_arg_f32(object, name, ndim, shape, &read)) return 0;
    if (!PyArray_ISWRITEABLE((PyArrayObject *)object)) {
        PyErr_Format(PyExc_ValueError, "%s: must be writable", name);
        return 0;
    }
    *data = (float *)read;
    return 1;
}

int hf_arg_grid_shape(PyObject *object, const char *name, enum hf_grid_kind kind,
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

const char *hf_status_text(int status) {
    switch (status) {
    case HF_ERR_CAPACITY: return "an output buffer does not match the counting pass";
    case HF_ERR_INTERNAL: return "an exact walk missed its computed last cell";
    case HF_ERR_ARGUMENT: return "unknown kernel or mode";
    case HF_ERR_MEMORY: return "out of memory for a kernel's or renderer's scratch";
    default: return "unknown error";
    }
}
