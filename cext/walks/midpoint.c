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
#include "walks/walk.h"

/* The cell loop from (a, m), decision variable E. `swap` is a compile-time constant at
 * both call sites, so the hit mode's carried bound steps along a fixed axis. The loop
 * ends on (a1, b1); `left` is negative only if exact arithmetic went wrong, which is
 * reported rather than walked. */
HF_INLINE int midpoint_loop(hf_sink *s, const int mode, hf_cull *cull, const hf_line *L,
                            const hf_frame *f, int32_t a, int32_t m, int64_t E, const int swap) {
    const int64_t step_major = L->slope_minor * HF_ONE, step_minor = L->slope_major * HF_ONE;
    const int32_t a1 = L->a1, b1 = L->b1;
    int32_t left = (a1 - a) | (b1 - m);
    for (;;) {
        if (hf_visit_reduced_cell(s, mode, cull, f, a, m)) break;
        if (left == 0) break;
        if (E < 0) {
            a += 1;
            E += step_major;
            hf_cull_walk(cull, mode, swap);
        } else if (E > 0) {
            m += 1;
            E -= step_minor;
            hf_cull_walk(cull, mode, !swap);
        } else {
            a += 1;
            m += 1;
            E += step_major - step_minor;
            hf_cull_walk(cull, mode, 0);
            hf_cull_walk(cull, mode, 1);
        }
        left = (a1 - a) | (b1 - m);
        if (left < 0) return HF_ERR_INTERNAL;
    }
    return HF_OK;
}

HF_INLINE int walk_midpoint(hf_batch *b, int64_t ray, hf_sink *s, const int mode, void *ctx) {
    hf_line L;
    hf_frame f;
    int32_t a, m;
    int64_t E;
    hf_cull cull;
    int status;
    (void)ctx;
    if (!hf_exact_begin(b, ray, s, mode, 0, 0, &L, &f, &cull, &status)) return status;

    /* parallel to the major axis: one straight run */
    if (L.slope_minor == 0) {
        for (a = L.a0; a <= L.a1; ++a) {
            if (hf_visit_reduced_cell(s, mode, &cull, &f, a, L.b0)) break;
            hf_cull_walk(&cull, mode, L.swap);
        }
        hf_cull_end(&cull, s, mode);
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
    status = L.swap ? midpoint_loop(s, mode, &cull, &L, &f, a, m, E, 1)
                    : midpoint_loop(s, mode, &cull, &L, &f, a, m, E, 0);
    hf_cull_end(&cull, s, mode);
    return status;
}

HF_DEFINE_BATCH(hf_batch_midpoint, walk_midpoint)
