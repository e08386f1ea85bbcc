/* The one CPython/NumPy extension module, algos._kernels: it creates the module, adds each
 * area's entry points (traverse.c, intersect.c, terrain.c, raster.c) and the constants
 * Python reads from C rather than repeating: the documented limits and the kernel ids.
 *
 * Every entry point runs its kernel without the GIL and times it here, with a monotonic
 * clock around the whole batch (args.h). */
#define HF_BINDING_MODULE_C
#include "binding/args.h"

/* The name of every kernel id (enum hf_kernel and enum hf_hit_kernel, core/hftrace.h):
 * algos/registry.py looks its kernels up here, so the numbers are written once. */
static const struct {
    const char *name;
    int id;
} kernel_ids[] = {
    {"dda", HF_DDA},
    {"dda_f32", HF_DDA_F32},
    {"midpoint", HF_MIDPOINT},
    {"runs", HF_RUNS},
    {"runs_f64", HF_RUNS_F64},
    {"runs_periodic", HF_RUNS_PERIODIC},
    {"dda_maxmip", HF_HIT_DDA_MAXMIP},
    {"runs_maxmip", HF_HIT_RUNS_MAXMIP},
    {"march_linear", HF_HIT_MARCH_LINEAR},
    {"march_growing", HF_HIT_MARCH_GROWING},
    {"march_binary", HF_HIT_MARCH_BINARY},
    {"cone", HF_HIT_CONE},
    {"cone_relaxed", HF_HIT_CONE_RELAXED},
    {"packet_maxmip", HF_HIT_PACKET_MAXMIP},
    {"dda_compact", HF_HIT_DDA_COMPACT},
    {"plane_maxmip", HF_HIT_PLANE_MAXMIP},
    {"pitched_maxmip", HF_HIT_PITCHED_MAXMIP},
    {"ring_maxmip", HF_HIT_RING_MAXMIP},
};

/* KERNEL_IDS: {name: id} of every kernel above. */
static int add_kernel_ids(PyObject *module) {
    PyObject *ids = PyDict_New();
    size_t k;
    if (ids == NULL) return -1;
    for (k = 0; k < sizeof kernel_ids / sizeof kernel_ids[0]; ++k) {
        PyObject *id = PyLong_FromLong(kernel_ids[k].id);
        if (id == NULL || PyDict_SetItemString(ids, kernel_ids[k].name, id) < 0) {
            Py_XDECREF(id);
            Py_DECREF(ids);
            return -1;
        }
        Py_DECREF(id);
    }
    /* PyModule_AddObject steals the reference only on success */
    if (PyModule_AddObject(module, "KERNEL_IDS", ids) < 0) {
        Py_DECREF(ids);
        return -1;
    }
    return 0;
}

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT,
                                    "algos._kernels",
                                    "hftrace C kernels (private; see algos).",
                                    -1,
                                    NULL,
                                    NULL,
                                    NULL,
                                    NULL,
                                    NULL};

PyMODINIT_FUNC PyInit__kernels(void) {
    PyObject *m;
    import_array();
    m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    if (hf_bind_traverse(m) < 0 || hf_bind_intersect(m) < 0 || hf_bind_terrain(m) < 0 ||
        hf_bind_raster(m) < 0 || add_kernel_ids(m) < 0 ||
        PyModule_AddIntConstant(m, "FRAC_BITS", HF_FRAC_BITS) < 0 ||
        PyModule_AddIntConstant(m, "MAX_GRID_SIDE", HF_MAX_GRID_SIDE) < 0 ||
        PyModule_AddIntConstant(m, "DEFAULT_MAX_DENOMINATOR", HF_DEFAULT_MAX_DENOMINATOR) < 0 ||
        PyModule_AddIntConstant(m, "MAX_DENOMINATOR", HF_MAX_DENOMINATOR) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
