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

/* The decision variable at the line's first cell, computed in 128 bits once. */
HF_INLINE int64_t midpoint_start(const hf_line *L) {
    const hf_i128 A = L->slope_major, B = L->slope_minor;
    return (int64_t)(A * (hf_i128)L->o_minor + B * ((hf_i128)(L->a0 + 1) * HF_ONE - L->o_major) -
                     A * (hf_i128)(L->b0 + 1) * HF_ONE);
}

/* ---- first hits: the same loop with the band of a ray off the lattice ----------------
 * (walk.h, "first hits of rays off the lattice"). HF_MODE_HIT only; the other modes keep
 * the loop above, untouched. */

/* The walk is about to step from row m to m + 1 at column a with decision variable E in
 * [0, W) (E == 0: through the vertex (a + 1, m + 1)). The line crosses y = m + 1 at
 * N = (a + 1) W - E in the crossing units of the band: row m's band beyond a, then row
 * m + 1's band before its first cell. Returns 1 on a hit. */
HF_COLD int midpoint_band_step(hf_sink *s, const hf_frame *f, const hf_band *bd, int32_t a,
                               int32_t m, int64_t E) {
    const int64_t c = E == 0 ? (int64_t)a + 1 : a, R = E == 0 ? 0 : bd->W - E;
    if (hf_band_right(s, f, bd, m, a, c, R)) return 1;
    return hf_band_left(s, f, bd, m + 1, E == 0 ? a + 1 : a, c, R);
}

/* midpoint_loop in HF_MODE_HIT; `band` (a constant): the band's cells too. Each step to
 * the next row whose crossing lies within the band's reach of a column line first tests
 * the band there (E <= thr: row m beyond a; E > W - thr: row m + 1 before a): two
 * compares per row. */
HF_INLINE int midpoint_hit_loop(hf_sink *s, hf_cull *cull, const hf_line *L, const hf_frame *f,
                                int32_t a, int32_t m, int64_t E, const int swap, const hf_band *bd,
                                const int band) {
    const int64_t step_major = L->slope_minor * HF_ONE, step_minor = L->slope_major * HF_ONE;
    const int32_t a1 = L->a1, b1 = L->b1;
    int32_t left = (a1 - a) | (b1 - m);
    if (band && hf_band_start(s, f, L, bd)) return HF_OK;
    for (;;) {
        if (hf_visit_reduced_cell(s, HF_MODE_HIT, cull, f, a, m)) return HF_OK;
        if (left == 0) break;
        if (E < 0) {
            a += 1;
            E += step_major;
            hf_cull_walk(cull, HF_MODE_HIT, swap);
        } else if (E > 0) {
            if (band && (E <= bd->thr || E > bd->right_cut) &&
                midpoint_band_step(s, f, bd, a, m, E))
                return HF_OK;
            m += 1;
            E -= step_minor;
            hf_cull_walk(cull, HF_MODE_HIT, !swap);
        } else {
            if (band && midpoint_band_step(s, f, bd, a, m, E)) return HF_OK;
            a += 1;
            m += 1;
            E += step_major - step_minor;
            hf_cull_walk(cull, HF_MODE_HIT, 0);
            hf_cull_walk(cull, HF_MODE_HIT, 1);
        }
        left = (a1 - a) | (b1 - m);
        if (left < 0) return HF_ERR_INTERNAL;
    }
    if (band) hf_band_end(s, f, L, bd);
    return HF_OK;
}

/* walk_midpoint in HF_MODE_HIT, with the band for a ray off the lattice. */
HF_INLINE int walk_midpoint_hit(hf_batch *b, hf_sink *s) {
    hf_line L;
    hf_frame f;
    int32_t a;
    int64_t E;
    hf_cull cull;
    hf_band bd;
    int status;
    if (!hf_exact_begin(b, 0, s, HF_MODE_HIT, 0, 0, &L, &f, &cull, &status)) return status;
    hf_band_init(&bd, s->hit, &L);
    if (L.slope_minor == 0) {
        if (bd.on) {
            hf_band_straight(s, &f, &bd);
        } else {
            for (a = L.a0; a <= L.a1; ++a) {
                if (hf_visit_reduced_cell(s, HF_MODE_HIT, &cull, &f, a, L.b0)) break;
                hf_cull_walk(&cull, HF_MODE_HIT, L.swap);
            }
        }
        hf_cull_end(&cull, s, HF_MODE_HIT);
        return HF_OK;
    }
    E = midpoint_start(&L);
    if (bd.on)
        status = L.swap ? midpoint_hit_loop(s, &cull, &L, &f, L.a0, L.b0, E, 1, &bd, 1)
                        : midpoint_hit_loop(s, &cull, &L, &f, L.a0, L.b0, E, 0, &bd, 1);
    else
        status = L.swap ? midpoint_hit_loop(s, &cull, &L, &f, L.a0, L.b0, E, 1, NULL, 0)
                        : midpoint_hit_loop(s, &cull, &L, &f, L.a0, L.b0, E, 0, NULL, 0);
    hf_cull_end(&cull, s, HF_MODE_HIT);
    return status;
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

HF_DEFINE_BATCH_MODES(hf_batch_midpoint, walk_midpoint)

/* The first-hit walk (HF_MODE_HIT), apart from walk_midpoint so that the other modes'
 * loops stay exactly as they were. */
int hf_batch_midpoint_hit(hf_batch *b, hf_sink *sink, void *ctx) {
    (void)ctx;
    return walk_midpoint_hit(b, sink);
}
