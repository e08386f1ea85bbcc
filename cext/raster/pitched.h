/* pitched_maxmip: dda_maxmip for the rays of one eye (a pinhole camera at any pitch),
 * each started at a conservative lower bound on its first hit (pitched.c). */
#ifndef HFTRACE_RASTER_PITCHED_H
#define HFTRACE_RASTER_PITCHED_H

#include "dispatch/plane.h"
#include "surfaces/hitbatch.h"

/* The batch's first hits, equal to dda_maxmip's (t, cell, normal) bit for bit. When every
 * ray shares one origin (bit for bit) and the rays' directions fit in a cone of half angle
 * below about 87 degrees, each ray's walk starts at the bound read from a coarse image of
 * the field's tile boxes; otherwise every ray takes dda_maxmip's walk (`steps`, the
 * dispatcher's). HF_OK, HF_ERR_ARGUMENT (no mipmap), HF_ERR_MEMORY, or a step's error
 * status (b->bad_ray names the ray). */
int hf_pitched_batch(hf_hit_batch *b, const hf_ray_steps *steps);

#endif
