/* The first-hit batch: one field, its acceleration structures, N rays, the outputs. */
#ifndef HFTRACE_HITBATCH_H
#define HFTRACE_HITBATCH_H

#include <stdint.h>
#include "compact.h"
#include "hit.h"

/* Intersector ids: the traversal kernels (enum hf_kernel) and these. */
enum hf_hit_kernel {
    HF_HIT_DDA_MAXMIP = 6,
    HF_HIT_RUNS_MAXMIP = 7,
    HF_HIT_MARCH_LINEAR = 8,
    HF_HIT_MARCH_GROWING = 9,
    HF_HIT_MARCH_BINARY = 10,
    HF_HIT_CONE = 11,
    HF_HIT_CONE_RELAXED = 12,
    HF_HIT_PACKET_MAXMIP = 13,
    HF_HIT_DDA_COMPACT = 14,
    HF_HIT_PLANE_MAXMIP = 15,
    HF_N_HIT_KERNELS = 16
};

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
    int64_t bad_ray;
} hf_hit_batch;

int hf_intersect_batch(int kernel, hf_hit_batch *batch);

/* packet_maxmip: the dda_maxmip walks of the rays of hits[] whose bit is set in
 * `members` (clipped and prepared, each with a max-mipmap walk to do), together; each
 * hits[k] ends as dda_maxmip leaves it (packet.c). */
void hf_packet_maxmip(hf_hit *hits, unsigned members, const hf_hit_batch *b);

/* One ray of a batch as dda_maxmip treats it (hit.c): hf_hit_ray_begin clips ray `ray` and
 * fills h (0: it misses the box, nothing to walk); hf_hit_ray_solve walks it on
 * [t0, t1] (HF_OK or an error status); hf_hit_ray_end writes its outputs. */
int hf_hit_ray_begin(const hf_hit_batch *b, int64_t ray, hf_hit *h, double *t0, double *t1,
                     int *entry_axis);
int hf_hit_ray_solve(hf_hit_batch *b, int64_t ray, hf_hit *h, double t0, double t1, int entry_axis);
void hf_hit_ray_end(hf_hit_batch *b, int64_t ray, const hf_hit *h);

/* plane_maxmip: the batch with the rays of each vertical plane from one eye traced as a
 * chain of resumed dda_maxmip walks; outputs equal dda_maxmip's (plane.c). */
int hf_plane_batch(hf_hit_batch *b);

/* cone: the first hit of one clipped ray (1: found), cone.c. */
int hf_cone_hit(hf_hit *h, const float *cone);

/* cone_relaxed: the relaxed cone slope of every cell of an ny x nx grid of cell maxima,
 * from the destinations within `radius` rings (cone.c). */
void hf_cone_relaxed_build(const float *cellmax, int32_t ny, int32_t nx, int32_t radius,
                           float *slope);

#endif
