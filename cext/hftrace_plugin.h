/* hftrace_plugin.h: the interface of a kernel that hftrace benchmarks next to its own.
 *
 * A plugin is a shared library (cc -O2 -std=c99 -shared -fPIC -I cext mine.c -o mine.so)
 * that exports hftrace_plugin() and one kernel: hftrace_traverse (a 2D traversal, the
 * "visit" workload) or hftrace_first_hit (a first-hit intersector on a cell surface).
 * Load it with algos.plugins.load_c_plugin("mine.so"), `hftrace sweep --plugin mine.so`,
 * or `plugins = ["mine.so"]` in a sweep config (docs/plugins.md).
 *
 * Conventions (docs/CONVENTIONS.md): cell (i, j) is [i, i+1] x [j, j+1]; shape = (nx, ny)
 * cells; heights are H[j, i] with rows = ny + 1 and cols = nx + 1 samples, row-major,
 * float32, in cell units; a ray is origin + t * direction, t in [tmin, tmax]; a cell is
 * half-open toward the direction of travel; at an exact vertex crossing both indices
 * change at once. Arrays are C-contiguous; tmin/tmax may be NULL (then 0 and +infinity).
 *
 * Timing: the harness reads CLOCK_MONOTONIC (time.monotonic_ns) immediately before and
 * after the call, as the built-in kernels' C loops do, flushes the caches before every
 * call and interleaves the call with the built-in kernels on the same rays. Do all set-up
 * that should not be timed in the first call or in static state: one untimed warm-up call
 * precedes the timed ones. Use one thread (the harness pins itself to one CPU).
 *
 * Return HFTRACE_PLUGIN_OK (0) on success; any other value is an error the harness
 * reports in the kernel's row (the other kernels' rows are kept). */
#ifndef HFTRACE_PLUGIN_H
#define HFTRACE_PLUGIN_H

#include <stdint.h>

#define HFTRACE_PLUGIN_ABI 1
#define HFTRACE_PLUGIN_OK  0

/* What the library holds. Strings are static and NUL-terminated. */
typedef struct {
    int abi;              /* HFTRACE_PLUGIN_ABI                                           */
    const char *name;     /* the name in every table: an identifier, not a built-in name  */
    const char *kind;     /* "traversal" or "first_hit"                                   */
    int exact;            /* 1: claims to equal the exact reference on every ray (checked) */
    const char *surfaces; /* first_hit: comma-separated, of flat,plane3,triangles,bilinear */
    const char *summary;  /* one line for `hftrace list`                                  */
} hftrace_plugin_info;

/* Surfaces, in algos.SURFACES order (the `surface` argument of hftrace_first_hit). */
enum { HFTRACE_FLAT = 0, HFTRACE_PLANE3 = 1, HFTRACE_TRIANGLES = 2, HFTRACE_BILINEAR = 3 };

const hftrace_plugin_info *hftrace_plugin(void);

/* A traversal over the grid of nx x ny cells, n rays: origins and directions (n, 2)
 * float64. For every ray, fold each visited cell into checksums[ray] with
 * hftrace_fold_cell (from 0, in visiting order) and store the number of visited cells in
 * cells[ray]. The harness compares the checksums with the exact reference's. */
int hftrace_traverse(int64_t nx, int64_t ny, int64_t n, const double *origins,
                     const double *directions, const double *tmin, const double *tmax,
                     uint64_t *checksums, int64_t *cells);

/* Optional, for algos.traverse: the visited cells themselves. The harness first calls
 * hftrace_traverse for the counts, then this with offsets (n + 1 int64, offsets[0] = 0,
 * offsets[ray + 1] - offsets[ray] = cells[ray] of that call): store ray r's cells in
 * visiting order as int32 pairs (i, j) at cells_out[2 * offsets[r]] onwards, exactly as
 * many as counted. A traversal library without it serves sweeps (the checksum) only. */
int hftrace_traverse_cells(int64_t nx, int64_t ny, int64_t n, const double *origins,
                           const double *directions, const double *tmin, const double *tmax,
                           const int64_t *offsets, int32_t *cells_out);

/* The first hit of n rays, origins and directions (n, 3) float64, on the surface
 * `surface` (enum above) of the height field heights (rows, cols) float32. Store the ray
 * parameter of the first hit in t[ray] (+infinity on a miss) and the hit cell (i, j) in
 * hit_cells[2 * ray], hit_cells[2 * ray + 1] (-1 on a miss). */
int hftrace_first_hit(const float *heights, int64_t rows, int64_t cols, int surface, int64_t n,
                      const double *origins, const double *directions, const double *tmin,
                      const double *tmax, double *t, int32_t *hit_cells);

/* The visit checksum's fold: a rotate-xor chain over the cell keys (i << 32) | j, the
 * same as the built-in kernels', so a plugin that visits the same cells in the same order
 * gives the same checksum. */
static inline uint64_t hftrace_fold_cell(uint64_t hash, int32_t i, int32_t j) {
    const uint64_t key = ((uint64_t)(uint32_t)i << 32) | (uint64_t)(uint32_t)j;
    return ((hash << 7) | (hash >> 57)) ^ key;
}

#endif
