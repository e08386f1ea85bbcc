/* dda: the cell walk of Amanatides & Woo (1987), "A fast voxel traversal algorithm for
 * ray tracing", in float64 (dda) and float32 (dda_f32).
 *
 * t_max_x / t_max_y hold the parameter of the next x / y grid line and advance by
 * t_delta = 1/|d| per step (the incremental form the paper gives). Equal t_max values
 * are a vertex crossing: both indices change at once, as the conventions require.
 * Float kernels are measured, not trusted: rounding in the increments drifts on long
 * rays, and ties are decided by whatever the rounded values say. Every loop is bounded by
 * the grid, so drift can change the cells but never the memory touched. */
#include "walks/walk.h"

#define HF_DEFINE_DDA(NAME, REAL, FLOOR, CEIL, FMAX, FMIN)                                   \
    HF_INLINE int NAME(hf_batch *b, int64_t ray, hf_sink *s, const int mode, void *ctx) {    \
        const REAL ox = (REAL)b->origins[2 * ray], oy = (REAL)b->origins[2 * ray + 1];       \
        const REAL dx = (REAL)b->directions[2 * ray];                                        \
        const REAL dy = (REAL)b->directions[2 * ray + 1];                                    \
        const REAL nx = (REAL)b->nx, ny = (REAL)b->ny;                                       \
        const REAL inf = (REAL)INFINITY;                                                     \
        REAL t0 = (REAL)hf_tmin(b, ray), t1 = (REAL)hf_tmax(b, ray), t;                      \
        REAL t_max_x, t_max_y, t_delta_x, t_delta_y, x, y;                                   \
        int32_t i, j, step_x, step_y;                                                        \
        hf_cull cull;                                                                        \
        const int status = hf_ray_begin(b, ray, s, mode, (REAL)fabs(dx) >= (REAL)fabs(dy));  \
        (void)ctx;                                                                           \
        if (status != HF_OK) return status;                                                  \
        /* slab clipping to the box [0, nx] x [0, ny] */                                     \
        if (dx != 0) {                                                                       \
            const REAL ta = (0 - ox) / dx, tb = (nx - ox) / dx;                              \
            t0 = FMAX(t0, ta < tb ? ta : tb);                                                \
            t1 = FMIN(t1, ta < tb ? tb : ta);                                                \
        } else if (!(ox >= 0 && ox < nx)) {                                                  \
            return HF_OK;                                                                    \
        }                                                                                    \
        if (dy != 0) {                                                                       \
            const REAL ta = (0 - oy) / dy, tb = (ny - oy) / dy;                              \
            t0 = FMAX(t0, ta < tb ? ta : tb);                                                \
            t1 = FMIN(t1, ta < tb ? tb : ta);                                                \
        } else if (!(oy >= 0 && oy < ny)) {                                                  \
            return HF_OK;                                                                    \
        }                                                                                    \
        if (!(t0 < t1)) return HF_OK;                                                        \
        /* first cell, by the half-open rule; rounding may land outside: clamp. A zero       \
         * component keeps the origin: t0 may be -inf (vertical rays), -inf * 0 is NaN */    \
        x = dx != 0 ? ox + t0 * dx : ox;                                                     \
        y = dy != 0 ? oy + t0 * dy : oy;                                                     \
        /* the side by the float64 sign: a tiny negative component that rounds to -0         \
         * in float32 still reads the cell on its - side, as the cell tests do */            \
        x = b->directions[2 * ray] < 0 ? CEIL(x) - 1 : FLOOR(x);                             \
        y = b->directions[2 * ray + 1] < 0 ? CEIL(y) - 1 : FLOOR(y);                         \
        i = (int32_t)FMIN(FMAX(x, (REAL)0), nx - 1);                                         \
        j = (int32_t)FMIN(FMAX(y, (REAL)0), ny - 1);                                         \
        step_x = dx > 0 ? 1 : (dx < 0 ? -1 : 0);                                             \
        step_y = dy > 0 ? 1 : (dy < 0 ? -1 : 0);                                             \
        t_delta_x = dx != 0 ? 1 / (REAL)fabs(dx) : inf;                                      \
        t_delta_y = dy != 0 ? 1 / (REAL)fabs(dy) : inf;                                      \
        t_max_x = dx > 0 ? ((REAL)(i + 1) - ox) / dx : (dx < 0 ? ((REAL)i - ox) / dx : inf); \
        t_max_y = dy > 0 ? ((REAL)(j + 1) - oy) / dy : (dy < 0 ? ((REAL)j - oy) / dy : inf); \
        hf_cull_begin(&cull, s, mode, i, j, 0);                                              \
        for (;;) {                                                                           \
            if (hf_visit_cell(s, mode, &cull, i, j)) break;                                  \
            if (t_max_x < t_max_y) {                                                         \
                t = t_max_x;                                                                 \
                i += step_x;                                                                 \
                t_max_x += t_delta_x;                                                        \
                hf_cull_walk(&cull, mode, 0);                                                \
            } else if (t_max_y < t_max_x) {                                                  \
                t = t_max_y;                                                                 \
                j += step_y;                                                                 \
                t_max_y += t_delta_y;                                                        \
                hf_cull_walk(&cull, mode, 1);                                                \
            } else { /* vertex crossing (or a vertical ray: both infinite) */                \
                t = t_max_x;                                                                 \
                i += step_x;                                                                 \
                j += step_y;                                                                 \
                t_max_x += t_delta_x;                                                        \
                t_max_y += t_delta_y;                                                        \
                hf_cull_walk(&cull, mode, 0);                                                \
                hf_cull_walk(&cull, mode, 1);                                                \
            }                                                                                \
            if (!(t < t1)) break;                                                            \
            if ((uint32_t)i >= (uint32_t)b->nx || (uint32_t)j >= (uint32_t)b->ny) break;     \
        }                                                                                    \
        hf_cull_end(&cull, s, mode);                                                         \
        return HF_OK;                                                                        \
    }

HF_DEFINE_DDA(walk_dda, double, floor, ceil, fmax, fmin)
HF_DEFINE_DDA(walk_dda_f32, float, floorf, ceilf, fmaxf, fminf)

HF_DEFINE_BATCH(hf_batch_dda, walk_dda)
HF_DEFINE_BATCH(hf_batch_dda_f32, walk_dda_f32)
