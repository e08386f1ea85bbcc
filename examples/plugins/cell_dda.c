/* A minimal hftrace plugin: the plain cell DDA of Amanatides & Woo (1987) as a traversal.
 *
 *   cc -O2 -std=c99 -shared -fPIC -I cext examples/plugins/cell_dda.c -o cell_dda.so
 *   hftrace sweep examples/sweep-plugin.toml --plugin cell_dda.so
 *
 * The ray is clipped to the grid's box, the first cell taken by the half-open rule, and
 * the walk steps to whichever grid line comes first (both at a vertex crossing). */
#include <math.h>
#include <stddef.h>

#include "hftrace_plugin.h"

static const hftrace_plugin_info INFO = {
    HFTRACE_PLUGIN_ABI, "cell_dda_c", "traversal", 0, "", "plain cell DDA in C (examples/plugins)"};

const hftrace_plugin_info *hftrace_plugin(void) {
    return &INFO;
}

/* One ray's walk: folds each cell into *hash, counts it, and stores it at out[2 * k] when
 * out is not NULL (the caller sized out from a counting walk of the same ray). */
static void walk(int64_t nx, int64_t ny, const double o[2], const double d[2], double t0, double t1,
                 uint64_t *hash, int64_t *count, int32_t *out) {
    double t_max[2], t_delta[2];
    int64_t cell[2], step[2], size[2] = {nx, ny};
    for (int a = 0; a < 2; a++) { /* slab clipping to [0, size] */
        if (d[a] != 0) {
            const double ta = (0 - o[a]) / d[a], tb = ((double)size[a] - o[a]) / d[a];
            t0 = fmax(t0, fmin(ta, tb));
            t1 = fmin(t1, fmax(ta, tb));
        } else if (!(o[a] >= 0 && o[a] < (double)size[a])) {
            return;
        }
    }
    if (!(t0 < t1)) return;
    for (int a = 0; a < 2; a++) {
        double x = o[a] + t0 * d[a];
        x = d[a] < 0 ? ceil(x) - 1 : floor(x);
        cell[a] = (int64_t)fmin(fmax(x, 0), (double)size[a] - 1);
        step[a] = d[a] > 0 ? 1 : (d[a] < 0 ? -1 : 0);
        t_delta[a] = d[a] != 0 ? 1 / fabs(d[a]) : INFINITY;
        t_max[a] = d[a] > 0   ? ((double)(cell[a] + 1) - o[a]) / d[a]
                   : d[a] < 0 ? ((double)cell[a] - o[a]) / d[a]
                              : INFINITY;
    }
    for (;;) {
        double t;
        *hash = hftrace_fold_cell(*hash, (int32_t)cell[0], (int32_t)cell[1]);
        if (out) {
            out[2 * *count] = (int32_t)cell[0];
            out[2 * *count + 1] = (int32_t)cell[1];
        }
        *count += 1;
        if (t_max[0] < t_max[1]) {
            t = t_max[0];
            cell[0] += step[0];
            t_max[0] += t_delta[0];
        } else if (t_max[1] < t_max[0]) {
            t = t_max[1];
            cell[1] += step[1];
            t_max[1] += t_delta[1];
        } else { /* vertex crossing */
            t = t_max[0];
            cell[0] += step[0];
            cell[1] += step[1];
            t_max[0] += t_delta[0];
            t_max[1] += t_delta[1];
        }
        if (!(t < t1)) break;
        if (cell[0] < 0 || cell[0] >= nx || cell[1] < 0 || cell[1] >= ny) break;
    }
}

int hftrace_traverse(int64_t nx, int64_t ny, int64_t n, const double *origins,
                     const double *directions, const double *tmin, const double *tmax,
                     uint64_t *checksums, int64_t *cells) {
    if (nx < 1 || ny < 1 || n < 0) return 1;
    for (int64_t r = 0; r < n; r++) {
        uint64_t hash = 0;
        int64_t count = 0;
        walk(nx, ny, origins + 2 * r, directions + 2 * r, tmin ? tmin[r] : 0.0,
             tmax ? tmax[r] : INFINITY, &hash, &count, NULL);
        checksums[r] = hash;
        cells[r] = count;
    }
    return HFTRACE_PLUGIN_OK;
}

int hftrace_traverse_cells(int64_t nx, int64_t ny, int64_t n, const double *origins,
                           const double *directions, const double *tmin, const double *tmax,
                           const int64_t *offsets, int32_t *cells_out) {
    if (nx < 1 || ny < 1 || n < 0) return 1;
    for (int64_t r = 0; r < n; r++) {
        uint64_t hash = 0;
        int64_t count = 0;
        walk(nx, ny, origins + 2 * r, directions + 2 * r, tmin ? tmin[r] : 0.0,
             tmax ? tmax[r] : INFINITY, &hash, &count, cells_out + 2 * offsets[r]);
        if (count != offsets[r + 1] - offsets[r]) return 2; /* not the counted walk */
    }
    return HFTRACE_PLUGIN_OK;
}
