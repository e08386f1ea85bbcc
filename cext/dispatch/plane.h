/* plane_maxmip: dda_maxmip for batches of vertical planes (plane.c). */
#ifndef HFTRACE_PLANE_H
#define HFTRACE_PLANE_H

#include <stdint.h>
#include "surfaces/hitbatch.h"

/* The steps of one ray as dda_maxmip takes them, given by the dispatcher (intersect.c),
 * so that this file calls nothing above it: `start` sets up a hit record for the batch's
 * rays, once (a record may then serve any number of rays in turn); `begin` clips ray `ray`
 * and fills h, a started record (0: it misses the box, nothing to walk); `solve` walks it
 * on [t0, t1] with dda_maxmip (HF_OK or an error status); `end` writes its outputs. */
typedef struct {
    void (*start)(const hf_hit_batch *b, hf_hit *h);
    int (*begin)(const hf_hit_batch *b, int64_t ray, hf_hit *h, double *t0, double *t1,
                 int *entry_axis);
    int (*solve)(hf_hit_batch *b, int64_t ray, hf_hit *h, double t0, double t1, int entry_axis);
    void (*end)(hf_hit_batch *b, int64_t ray, const hf_hit *h);
} hf_ray_steps;

/* dda_maxmip's three steps (intersect.c): what plane_maxmip here and the kernels above
 * the dispatcher (pitched_maxmip, raster/pitched.c) walk a ray with. */
const hf_ray_steps *hf_maxmip_steps(void);

/* The batch with the rays of each vertical plane traced bottom up as a chain of resumed
 * dda_maxmip walks; t, cell and normal equal dda_maxmip's. HF_OK, HF_ERR_MEMORY, or a
 * step's error status (b->bad_ray names the ray). */
int hf_plane_batch(hf_hit_batch *b, const hf_ray_steps *steps);

#endif
