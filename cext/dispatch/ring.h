/* ring_maxmip (ring.c): dda_maxmip's walks of independent rays, interleaved a step at a
 * time with a software prefetch of each ray's next step. */
#ifndef HFTRACE_RING_H
#define HFTRACE_RING_H

#include "dispatch/plane.h"
#include "surfaces/hitbatch.h"

/* Rays in flight: the ring's slots (a compile-time constant; docs/ring.md gives the counts
 * it was chosen by). */
#ifndef HF_RING_SLOTS
#define HF_RING_SLOTS 8
#endif

/* A mipmap level whose tile maxima take at most this many bytes is taken as cached: a
 * walk's steps there follow one another without yielding its slot. */
#ifndef HF_RING_WARM_BYTES
#define HF_RING_WARM_BYTES (512 * 1024)
#endif

/* The batch with up to HF_RING_SLOTS max-mipmap walks in flight, each advanced one step in
 * turn; `steps` are dda_maxmip's own (intersect.c), which set up, solve (the rays without a
 * max-mipmap walk) and write out each ray. t, cell, normal and the statistics equal
 * dda_maxmip's bit for bit. HF_OK, or a step's error status (b->bad_ray names the ray). */
int hf_ring_batch(hf_hit_batch *b, const hf_ray_steps *steps);

#endif
