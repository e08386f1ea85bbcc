/* midpoint: the 4-connected walk driven by an exact integer decision variable.
 *
 * In the reduced frame (travel along +major, minor non-decreasing) the walk stands in
 * cell (a, b) and asks on which side of the corner (a+1, b+1) the line passes:
 *   E = A * (minor of the line at major = a+1) - A * (b+1)   [lattice units, scaled by A]
 * E < 0: the line leaves through the right edge (a += 1);
 * E > 0: it leaves through the top edge (b += 1);
 * E = 0: it passes exactly through the vertex, so both indices change at once and the
 *        two cells that touch the line only at that vertex are not visited.
 * |E| <= 2 A 2^16 < 2^48, so the loop runs in int64. */
#include "internal.h"

HF_INLINE int walk_midpoint(hf_batch *b, int64_t ray, hf_sink *s, const int mode,
                            void *ctx) {
    hf_line L;
    hf_frame f;
    int32_t a, m;
    int64_t E, step_major, step_minor;
    const int nonempty = hf_line_exact(b->origins + 2 * ray, b->directions + 2 * ray,
                                       hf_tmin(b, ray), hf_tmax(b, ray), b->nx, b->ny, 0,
                                       &L);
    const int status = hf_ray_begin(b, ray, s, mode, !L.swap);
    (void)ctx;
    if (status != HF_OK || !nonempty) return status;
    f = hf_frame_of(&L);

    /* parallel to the major axis: one straight run */
    if (L.slope_minor == 0) {
        for (a = L.a0; a <= L.a1; ++a)
            if (hf_emit_reduced_cell(s, mode, &f, a, L.b0)) return HF_OK;
        return HF_OK;
    }

    /* decision variable at the first cell, computed in 128 bits once */
    a = L.a0;
    m = L.b0;
    {
        const hf_i128 A = L.slope_major, B = L.slope_minor;
        E = (int64_t)(A * (hf_i128)L.o_minor + B * ((hf_i128)(a + 1) * HF_ONE - L.o_major) -
                      A * (hf_i128)(m + 1) * HF_ONE);
    }
    step_major = L.slope_minor * HF_ONE;
    step_minor = L.slope_major * HF_ONE;
    for (;;) {
        if (hf_emit_reduced_cell(s, mode, &f, a, m)) return HF_OK;
        if (a == L.a1 && m == L.b1) break;
        if (E < 0) { a += 1; E += step_major; }
        else if (E > 0) { m += 1; E -= step_minor; }
        else { a += 1; m += 1; E += step_major - step_minor; }
        /* exact arithmetic ends on (a1, b1); anything else is a bug, never a wild write */
        if (a > L.a1 || m > L.b1) return HF_ERR_INTERNAL;
    }
    return HF_OK;
}

HF_DEFINE_BATCH(hf_batch_midpoint, walk_midpoint)
