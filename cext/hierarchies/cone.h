/* Cone step mapping (cone.c): the exact cone walk and the relaxed cones' build. */
#ifndef HFTRACE_CONE_H
#define HFTRACE_CONE_H

#include <stdint.h>
#include "surfaces/cell_test.h"

/* cone: the first hit of one clipped ray (1: found), cone.c. */
int hf_cone_hit(hf_hit *h, const float *cone);

/* cone_relaxed: the relaxed cone slope of every cell of an ny x nx grid of cell maxima,
 * from the destinations within `radius` rings (cone.c). */
void hf_cone_relaxed_build(const float *cellmax, int32_t ny, int32_t nx, int32_t radius,
                           float *slope);

#endif
