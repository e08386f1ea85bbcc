/* The optional C peer against the system Embree 3 (Debian's libembree-dev, 3.13).
 *
 * embreex reaches Embree's single-ray triangle queries only; this file reaches the rest
 * of Embree 3's API for the same height field: the grid geometry (RTC_GEOMETRY_TYPE_GRID)
 * next to the triangle geometry, single rays (rtcIntersect1) and packets of 4, 8 or 16
 * (rtcIntersect4/8/16, where the CPU runs them natively), the scene and build flags set
 * by the caller (algos/embree3_peer.py picks the fastest: no robust mode, high build
 * quality).
 *
 * Built by setup.py as algos._embree3 only where embree3/rtcore.h is found; the module
 * has no Python methods: algos/embree3_peer.py loads these plain C functions with ctypes
 * (which releases the GIL around each call).
 *
 * The surface. docs/CONVENTIONS.md splits cell (i, j) on its diagonal u = v: triangles
 * (i,j)(i+1,j)(i+1,j+1) and (i,j)(i+1,j+1)(i,j+1). Embree treats a grid's vertex quad
 * v0 v1 v2 v3 (v1 = v0 + one column, v3 = v0 + one row) as a quad mesh does: triangles
 * v0 v1 v3 and v2 v3 v1, split on the other diagonal v1-v3 (u + v = 1). So the grid is
 * laid out mirrored in x (grid column a is x = cols - 1 - a): then v1-v3 runs from
 * (x-1, y) to (x, y+1), which is the conventions' diagonal of cell (x-1, y).
 * HFE3_GRID_NATIVE keeps Embree's own column order (for the test that shows the
 * difference).
 */
#include <Python.h>
#include <embree3/rtcore.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <time.h>

enum hfe3_geometry {
    HFE3_TRIANGLES = 0,   /* two triangles per cell, vertex (i, j, H[j, i]) */
    HFE3_GRID = 1,        /* one grid, columns mirrored: the conventions' split */
    HFE3_GRID_NATIVE = 2, /* one grid in Embree's own column order: the other split */
};

/* Error codes returned below (negative): the Python wrapper turns them into messages. */
enum hfe3_status {
    HFE3_ERROR_EMBREE = -1,   /* rtcGetDeviceError reported an error */
    HFE3_ERROR_WIDTH = -2,    /* a packet width other than 1, 4, 8, 16 */
    HFE3_ERROR_NATIVE = -3,   /* a packet width the CPU does not run natively */
    HFE3_ERROR_ARGUMENT = -4, /* a size out of range */
};

typedef struct {
    RTCDevice device;
    RTCScene scene;
    int geometry;
    int rows, cols;
    int64_t bytes; /* Embree's own allocations, from the memory monitor */
} hfe3_scene;

/* Embree calls this for every allocation of the device, from any of its threads. */
static bool hfe3_count_bytes(void *user, ssize_t bytes, bool post) {
    (void)post;
    __atomic_add_fetch((int64_t *)user, (int64_t)bytes, __ATOMIC_RELAXED);
    return true;
}

static int64_t hfe3_now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

/* The vertex and index buffers of the triangle geometry. */
static void hfe3_fill_triangles(RTCGeometry geom, const double *heights, int rows, int cols) {
    float *v = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                       3 * sizeof(float), (size_t)rows * cols);
    unsigned *tri =
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(unsigned), 2 * (size_t)(rows - 1) * (cols - 1));
    if (v == NULL || tri == NULL) return; /* the device error is read by the caller */
    for (int j = 0; j < rows; j++)
        for (int i = 0; i < cols; i++) {
            size_t k = (size_t)j * cols + i;
            v[3 * k] = (float)i;
            v[3 * k + 1] = (float)j;
            v[3 * k + 2] = (float)heights[k];
        }
    /* primitive 2 (j nx + i) + k is triangle k of cell (i, j), as in algos/embree_peer.py */
    for (int j = 0; j < rows - 1; j++)
        for (int i = 0; i < cols - 1; i++) {
            unsigned v00 = (unsigned)(j * cols + i), v10 = v00 + 1, v01 = v00 + cols, v11 = v01 + 1;
            unsigned *t = tri + 6 * ((size_t)j * (cols - 1) + i);
            t[0] = v00, t[1] = v10, t[2] = v11;
            t[3] = v00, t[4] = v11, t[5] = v01;
        }
}

/* The vertex and grid buffers of the grid geometry (mirrored unless native). */
static void hfe3_fill_grid(RTCGeometry geom, const double *heights, int rows, int cols,
                           int mirrored) {
    float *v = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                       3 * sizeof(float), (size_t)rows * cols);
    struct RTCGrid *grid = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_GRID, 0, RTC_FORMAT_GRID,
                                                   sizeof(struct RTCGrid), 1);
    if (v == NULL || grid == NULL) return;
    for (int b = 0; b < rows; b++)
        for (int a = 0; a < cols; a++) {
            int i = mirrored ? cols - 1 - a : a;
            size_t k = (size_t)b * cols + a;
            v[3 * k] = (float)i;
            v[3 * k + 1] = (float)b;
            v[3 * k + 2] = (float)heights[(size_t)b * cols + i];
        }
    grid->startVertexID = 0;
    grid->stride = (unsigned)cols;
    grid->width = (unsigned short)cols;
    grid->height = (unsigned short)rows;
}

/* A committed scene of the height field heights (rows x cols, C order, cell units).
 * config: rtcNewDevice's configuration string (NULL: Embree's defaults); scene_flags,
 * quality: RTCSceneFlags and RTCBuildQuality. NULL on failure, with *status set. */
void *hfe3_new(const char *config, const double *heights, int rows, int cols, int geometry,
               int scene_flags, int quality, int *status) {
    *status = 0;
    if (rows < 2 || cols < 2 || geometry < HFE3_TRIANGLES || geometry > HFE3_GRID_NATIVE ||
        (geometry != HFE3_TRIANGLES && (rows > 32767 || cols > 32767))) {
        *status = HFE3_ERROR_ARGUMENT;
        return NULL;
    }
    hfe3_scene *s = calloc(1, sizeof(*s));
    if (s == NULL) {
        *status = HFE3_ERROR_ARGUMENT;
        return NULL;
    }
    s->geometry = geometry, s->rows = rows, s->cols = cols;
    s->device = rtcNewDevice(config);
    if (s->device == NULL) {
        free(s);
        *status = HFE3_ERROR_EMBREE;
        return NULL;
    }
    rtcSetDeviceMemoryMonitorFunction(s->device, hfe3_count_bytes, &s->bytes);
    s->scene = rtcNewScene(s->device);
    rtcSetSceneFlags(s->scene, (enum RTCSceneFlags)scene_flags);
    rtcSetSceneBuildQuality(s->scene, (enum RTCBuildQuality)quality);
    RTCGeometry geom =
        rtcNewGeometry(s->device, geometry == HFE3_TRIANGLES ? RTC_GEOMETRY_TYPE_TRIANGLE
                                                             : RTC_GEOMETRY_TYPE_GRID);
    rtcSetGeometryBuildQuality(geom, (enum RTCBuildQuality)quality);
    if (geometry == HFE3_TRIANGLES)
        hfe3_fill_triangles(geom, heights, rows, cols);
    else
        hfe3_fill_grid(geom, heights, rows, cols, geometry == HFE3_GRID);
    rtcCommitGeometry(geom);
    rtcAttachGeometry(s->scene, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(s->scene);
    int error = (int)rtcGetDeviceError(s->device);
    if (error != RTC_ERROR_NONE) {
        rtcReleaseScene(s->scene);
        rtcReleaseDevice(s->device);
        free(s);
        *status = HFE3_ERROR_EMBREE;
        return NULL;
    }
    return s;
}

void hfe3_free(void *handle) {
    hfe3_scene *s = handle;
    if (s == NULL) return;
    rtcReleaseScene(s->scene);
    rtcReleaseDevice(s->device);
    free(s);
}

/* Bytes Embree allocated for the device (scene, BVH, buffers), net of frees. */
int64_t hfe3_bytes(void *handle) {
    return ((hfe3_scene *)handle)->bytes;
}

/* 1 when the CPU runs packets of this width natively (1 always), else 0. */
int hfe3_native(void *handle, int width) {
    hfe3_scene *s = handle;
    switch (width) {
    case 1: return 1;
    case 4: return (int)rtcGetDeviceProperty(s->device, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED);
    case 8: return (int)rtcGetDeviceProperty(s->device, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED);
    case 16:
        return (int)rtcGetDeviceProperty(s->device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED);
    default: return 0;
    }
}

/* Where a batch writes: t (n), and when not NULL the cells (n x 2) and Embree's geometry
 * normals (n x 3, not normalised). */
typedef struct {
    float *t;
    int32_t *cell;
    float *normal;
} hfe3_outputs;

/* One hit's outputs: t (inf on a miss), the cell (i, j) ((-1, -1) on a miss) and Embree's
 * normal (0 on a miss). The grid's cell comes from its u/v (uniform over the whole grid,
 * rounded in float32: a hit on a cell edge may name the neighbour). */
static void hfe3_store(const hfe3_scene *s, float tfar, unsigned geom_id, unsigned prim_id, float u,
                       float v, const float normal[3], const hfe3_outputs *out, int64_t k) {
    int hit = geom_id != RTC_INVALID_GEOMETRY_ID;
    out->t[k] = hit ? tfar : INFINITY;
    if (out->normal != NULL)
        for (int c = 0; c < 3; c++) out->normal[3 * k + c] = hit ? normal[c] : 0.0f;
    if (out->cell == NULL) return;
    int32_t *cell_out = out->cell;
    if (!hit) {
        cell_out[2 * k] = cell_out[2 * k + 1] = -1;
        return;
    }
    int nx = s->cols - 1, ny = s->rows - 1, i, j;
    if (s->geometry == HFE3_TRIANGLES) {
        i = (int)(prim_id / 2 % (unsigned)nx), j = (int)(prim_id / 2 / (unsigned)nx);
    } else {
        int a = (int)(u * nx), b = (int)(v * ny);
        a = a < 0 ? 0 : a >= nx ? nx - 1 : a;
        j = b < 0 ? 0 : b >= ny ? ny - 1 : b;
        i = s->geometry == HFE3_GRID ? nx - 1 - a : a;
    }
    cell_out[2 * k] = i, cell_out[2 * k + 1] = j;
}

/* Packets of W rays: lanes past n are invalid (valid = 0), the rest run together. */
#define HFE3_DEFINE_PACKET(W)                                                               \
    static void hfe3_trace##W(const hfe3_scene *s, struct RTCIntersectContext *ctx,         \
                              const float *o, const float *d, const float *tfar, int64_t n, \
                              const hfe3_outputs *out) {                                    \
        struct RTCRayHit##W packet;                                                         \
        RTC_ALIGN(64) int valid[W];                                                         \
        for (int64_t k0 = 0; k0 < n; k0 += W) {                                             \
            for (int lane = 0; lane < W; lane++) {                                          \
                int64_t k = k0 + lane < n ? k0 + lane : n - 1;                              \
                valid[lane] = k0 + lane < n ? -1 : 0;                                       \
                packet.ray.org_x[lane] = o[3 * k], packet.ray.org_y[lane] = o[3 * k + 1];   \
                packet.ray.org_z[lane] = o[3 * k + 2], packet.ray.tnear[lane] = 0.0f;       \
                packet.ray.dir_x[lane] = d[3 * k], packet.ray.dir_y[lane] = d[3 * k + 1];   \
                packet.ray.dir_z[lane] = d[3 * k + 2], packet.ray.time[lane] = 0.0f;        \
                packet.ray.tfar[lane] = tfar[k], packet.ray.mask[lane] = 0xFFFFFFFFu;       \
                packet.ray.id[lane] = (unsigned)lane, packet.ray.flags[lane] = 0;           \
                packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;                          \
            }                                                                               \
            rtcIntersect##W(valid, s->scene, ctx, &packet);                                 \
            for (int lane = 0; lane < W && k0 + lane < n; lane++) {                         \
                float normal[3] = {packet.hit.Ng_x[lane], packet.hit.Ng_y[lane],            \
                                   packet.hit.Ng_z[lane]};                                  \
                hfe3_store(s, packet.ray.tfar[lane], packet.hit.geomID[lane],               \
                           packet.hit.primID[lane], packet.hit.u[lane], packet.hit.v[lane], \
                           normal, out, k0 + lane);                                         \
            }                                                                               \
        }                                                                                   \
    }

HFE3_DEFINE_PACKET(4)
HFE3_DEFINE_PACKET(8)
HFE3_DEFINE_PACKET(16)

/* Trace n rays (o, d: n x 3 float32; tfar: each ray's far bound, tnear 0) with packets of
 * width (1, 4, 8 or 16) and the coherent flag given; t_out (n) gets tfar at a hit, inf on
 * a miss; cell_out (n x 2) the cells and normal_out (n x 3) Embree's geometry normals,
 * when not NULL. Returns the elapsed ns of the loop (a monotonic clock around it), or a
 * negative hfe3_status. */
int64_t hfe3_trace(void *handle, const float *o, const float *d, const float *tfar, int64_t n,
                   int width, int coherent, float *t_out, int32_t *cell_out, float *normal_out) {
    hfe3_scene *s = handle;
    hfe3_outputs out = {t_out, cell_out, normal_out};
    if (n < 0) return HFE3_ERROR_ARGUMENT;
    if (width != 1 && width != 4 && width != 8 && width != 16) return HFE3_ERROR_WIDTH;
    if (!hfe3_native(s, width)) return HFE3_ERROR_NATIVE;
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags =
        coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    int64_t start = hfe3_now_ns();
    if (width == 1) {
        struct RTCRayHit rh;
        for (int64_t k = 0; k < n; k++) {
            rh.ray.org_x = o[3 * k], rh.ray.org_y = o[3 * k + 1], rh.ray.org_z = o[3 * k + 2];
            rh.ray.tnear = 0.0f;
            rh.ray.dir_x = d[3 * k], rh.ray.dir_y = d[3 * k + 1], rh.ray.dir_z = d[3 * k + 2];
            rh.ray.time = 0.0f, rh.ray.tfar = tfar[k];
            rh.ray.mask = 0xFFFFFFFFu, rh.ray.id = 0, rh.ray.flags = 0;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(s->scene, &ctx, &rh);
            float normal[3] = {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z};
            hfe3_store(s, rh.ray.tfar, rh.hit.geomID, rh.hit.primID, rh.hit.u, rh.hit.v, normal,
                       &out, k);
        }
    } else if (width == 4) {
        hfe3_trace4(s, &ctx, o, d, tfar, n, &out);
    } else if (width == 8) {
        hfe3_trace8(s, &ctx, o, d, tfar, n, &out);
    } else {
        hfe3_trace16(s, &ctx, o, d, tfar, n, &out);
    }
    int64_t elapsed = hfe3_now_ns() - start;
    return rtcGetDeviceError(s->device) == RTC_ERROR_NONE ? elapsed : HFE3_ERROR_EMBREE;
}

/* The module exists only to be built and found by pip; its functions are read by ctypes. */
static struct PyModuleDef hfe3_module = {PyModuleDef_HEAD_INIT, "_embree3",
                                         "The C Embree 3 peer (loaded with ctypes).", -1, NULL};

PyMODINIT_FUNC PyInit__embree3(void) {
    return PyModule_Create(&hfe3_module);
}
