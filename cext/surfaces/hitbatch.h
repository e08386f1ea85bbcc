/* The first-hit batch: one field, its acceleration structures, N rays, the outputs. */
#ifndef HFTRACE_HITBATCH_H
#define HFTRACE_HITBATCH_H

#include <math.h>
#include <stdint.h>
#include "surfaces/cell_test.h"

#define HF_MAX_MIP_LEVELS 32

/* packet_maxmip: the most rays in one packet */
#define HF_PACKET_MAX 8

typedef struct {
    int64_t n_rays;
    const double *origins, *directions; /* (n, 3) */
    const double *tmin, *tmax;          /* (n,) or NULL for [0, inf) */
    /* the field */
    const float *heights, *cellmax;
    int32_t rows, cols;
    double hmin, hmax;
    double habs, grid_span; /* max(|hmin|, |hmax|); cols + rows + 2 (cell_test.h, hf_hit_window) */
    int surface;
    /* culling and skipping */
    int cull_cells, cull_runs;
    hf_rmq row_max, col_max;
    int mip_levels;
    const float *mip[HF_MAX_MIP_LEVELS];
    int32_t mip_cols[HF_MAX_MIP_LEVELS];
    int floor_level;  /* the maxmip kernels: the level whose tiles are walked cell by cell or
                         run by run (the public option fine_level) */
    int packet_width; /* packet_maxmip: rays per packet, 1 .. HF_PACKET_MAX */
    /* cone: (ny, nx, 2), each cell's cone top and slope side by side (one cache line holds
     * both); cone_relaxed: (ny, nx) slopes (its apex is the cell maximum); NULL for the
     * other kernels (cone.c) */
    const float *cone;
    /* dda_compact: the records of the compact maximum tree (compact.h), NULL for the others */
    const void *compact;
    /* runs_periodic */
    int64_t max_denominator;
    int32_t *pattern;
    /* ray marching */
    int32_t march_steps, march_refinements;
    double march_growth, march_first_fraction, march_min_step;
    /* outputs, NULL when not asked for */
    double *t;      /* (n,)    */
    int32_t *cell;  /* (n, 2)  */
    double *normal; /* (n, 3)  */
    int64_t *stats; /* (n, 5): cells visited, cells tested, runs visited, runs culled,
                       tiles skipped */
    /* pitched_maxmip: (n,) the parameter each ray's walk was allowed to start from (its
     * lower bound on the hit: t0 where none applies, inf where the ray meets no box or
     * misses the field's box), for the tests; NULL for every other call */
    double *bound;
    int64_t bad_ray;
} hf_hit_batch;

int hf_intersect_batch(int kernel, hf_hit_batch *batch);

/* The fields of a hit record that come from the batch alone: set once per record (the
 * dispatcher's `start`, dispatch/intersect.c; a plane's shared set-up, dispatch/plane.c),
 * as no walk changes them (dda_compact lends cull_cells and gives it back). */
static inline void hf_hit_fill_batch(hf_hit *h, const hf_hit_batch *b) {
    h->heights = b->heights;
    h->cellmax = b->cellmax;
    h->rows = b->rows;
    h->cols = b->cols;
    h->row_max = b->cull_runs ? &b->row_max : NULL;
    h->col_max = b->cull_runs ? &b->col_max : NULL;
    h->surface = b->surface;
    h->cull_cells = b->cull_cells;
    h->habs = b->habs;
    h->grid_span = b->grid_span;
}

/* The fields that come from the ray's 2D line (origin o, direction d, each (x, y, z), and
 * the inverse horizontal direction inv, hf_inverse): the one fill of dda_maxmip's per-ray
 * set-up (dispatch/intersect.c) and of a plane's shared set-up (dispatch/plane.c). The
 * caller sets oz, dz, the range and entry axis, then calls hf_hit_prepare. */
static inline void hf_hit_fill_line(hf_hit *h, const double *o, const double *d,
                                    const double inv[2]) {
    h->ox = o[0];
    h->oy = o[1];
    h->dx = d[0];
    h->dy = d[1];
    h->inv_dx = inv[0];
    h->inv_dy = inv[1];
}

#endif
