/* Fast horizon kernels: the row-vectorised shared pattern (bounded radii) and the chain
 * walk (any direction, any distance). See horizon_fast.h for the contracts and
 * algos/terrain.py for the maths. */
#include <math.h>
#include <stdlib.h>
#include "terrain/horizon_fast.h"
#include "terrain/ray_walk.h"
#include "core/mipmap.h"
#include "surfaces/surfaces.h"

/* ---- row-vectorised shared pattern ------------------------------------------------------ */

/* One breakpoint for a contiguous run of vertices: the same expressions as
 * hf_horizon_pattern (hf_lerp, then the ratio), so the results are bit-identical. Where
 * GCC's function multiversioning is available, an AVX2 clone is picked at load time (4
 * doubles a step; without FMA, and C99 mode contracts nothing, so every clone rounds
 * alike). */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
__attribute__((target_clones("avx2", "default")))
#endif
static void
row_breakpoint(const double *restrict ha, const double *restrict hb, const double *restrict h,
               double w, double inv_t, int64_t n, double *restrict best) {
    for (int64_t i = 0; i < n; i++) {
        double r = hf_hz_ratio(hf_lerp(ha[i], hb[i], w), h[i], inv_t);
        best[i] = r > best[i] ? r : best[i];
    }
}

void hf_horizon_rows(const double *H, int64_t rows, int64_t cols, int64_t n, const double *inv_t,
                     const int64_t *off_a, const int64_t *off_b, const double *w, const int64_t *rx,
                     const int64_t *ry, int sx, int sy, int64_t n_main, int64_t end_k, double end_f,
                     double end_inv_t, int64_t row_start, int64_t row_stop, double *out) {
    for (int64_t j = row_start; j < row_stop; j++) {
        const double *row = H + j * cols;
        double *best = out + j * cols;
        for (int64_t i = 0; i < cols; i++) best[i] = -HF_HZ_INF;
        /* breakpoint e serves the vertices whose reach rx[e], ry[e] along the direction's
         * signs stays inside; the reaches never decrease, so the served vertices of a row
         * shrink from one end, and the first breakpoint that serves none ends the row */
        for (int64_t e = 0; e < n_main; e++) {
            int64_t lo = sx < 0 ? rx[e] : 0, hi = sx < 0 ? cols : cols - rx[e];
            if (hi <= lo || (sy < 0 ? j < ry[e] : j > rows - 1 - ry[e])) break;
            row_breakpoint(row + lo + off_a[e], row + lo + off_b[e], row + lo, w[e], inv_t[e],
                           hi - lo, best + lo);
        }
        /* max_distance between breakpoints end_k and end_k + 1, where the latter counts */
        if (end_k >= 0 && end_k + 1 < n &&
            (sy < 0 ? j >= ry[end_k + 1] : j <= rows - 1 - ry[end_k + 1])) {
            int64_t lo = sx < 0 ? rx[end_k + 1] : 0, hi = sx < 0 ? cols : cols - rx[end_k + 1];
            for (int64_t i = lo; i < hi; i++) {
                double r = hf_hz_ratio(hf_hz_pattern_end(row + i, off_a, off_b, w, end_k, end_f),
                                       row[i], end_inv_t);
                best[i] = r > best[i] ? r : best[i];
            }
        }
    }
}

/* ---- the chain walk --------------------------------------------------------------------- */

static int64_t clamp_index(int64_t v, int64_t lo, int64_t hi) {
    return v < lo ? lo : v > hi ? hi : v;
}

/* The surface at any point of the footprint, and the largest corner magnitude there (for
 * the rounding margin of a lower bound taken at that point). */
static double surface_point(const double *H, int64_t rows, int64_t cols, double x, double y,
                            double *corner_max) {
    int64_t i = clamp_index((int64_t)floor(x), 0, cols - 2);
    int64_t j = clamp_index((int64_t)floor(y), 0, rows - 2);
    const double *c = H + j * cols + i;
    double h00 = c[0], h10 = c[1], h01 = c[cols], h11 = c[cols + 1];
    double m = fabs(h00);
    m = fabs(h10) > m ? fabs(h10) : m;
    m = fabs(h01) > m ? fabs(h01) : m;
    m = fabs(h11) > m ? fabs(h11) : m;
    *corner_max = m;
    return hf_triangles_barycentric(h00, h10, h01, h11, x - (double)i, y - (double)j);
}

/* The ray from one vertex (terrain/ray_walk.h). */
typedef hf_hz_ray chain_ray;

/* The walk state of one vertex: its height, the best breakpoint ratio so far and where it
 * was, and the pruning bound (the best ratio or a borrowed lower bound, the larger). */
typedef struct {
    double h, best, t_best, prune;
} chain_best;

static inline void chain_visit(chain_best *b, double t, double s, double delta) {
    double rise = (s - b->h) + delta;
    if (rise > b->best * t) {
        b->best = rise / t;
        b->t_best = t;
        if (b->best > b->prune) b->prune = b->best;
    }
}

/* The first cell along one axis of a ray from a vertex (o an integer, s its sign: the
 * cell [o, o+1) moving forward or along the axis, (o-1, o] moving back), as terrain.c's
 * first_index for integer origins, without a libm call. */
static int64_t chain_first_index(double o, int s, int64_t n) {
    int64_t i = s < 0 ? (int64_t)o - 1 : (int64_t)o;
    if (s == 0 && i == n) i = n - 1; /* on the far edge of the footprint, moving along it */
    return i;
}

/* The horizon skip: every point of a tile with maximum m, crossed on [t_in, t_exit], has a
 * ratio at most (m - h) / t there, which is <= prune when this holds. */
static inline int chain_can_skip(const chain_best *b, double m, double t_in, double t_exit) {
    return m - b->h <= b->prune * (b->prune >= 0 ? t_in : t_exit);
}

/* Skip the largest tile around cell (ci, cj) that the bound allows (as terrain.c's
 * try_skip): 0 none, 1 moved past a tile, 2 the rest of the ray is covered. */
static int chain_try_skip(const double *H, int64_t rows, int64_t cols, const chain_ray *r,
                          const hf_hz_mip *mip, int *level_io, int64_t *ci, int64_t *cj,
                          double *t_in, double *s_in, double t_end, const chain_best *b,
                          int64_t *tests) {
    for (int level = hf_hz_skip_start(mip, *level_io); level >= 0; level--) {
        const hf_hz_tile e = hf_hz_tile_at(r, mip, level, *ci, *cj, t_end);
        (*tests)++;
        if (!chain_can_skip(b, e.max, *t_in, e.t_exit)) continue;
        *level_io = level;
        *t_in = e.t_exit;
        if (e.t_exit >= t_end) return 2;
        hf_hz_tile_leave(H, rows, cols, r, &e, level, ci, cj, s_in);
        return 1;
    }
    *level_io = 0;
    return 0;
}

/* One vertex's walk over the breakpoints in (0, t_end], the same points and expressions as
 * terrain.c's walk_ray_breakpoints with horizon_visit, skipping tiles below the bound. */
static void chain_walk(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip,
                       const chain_ray *r, double t_end, chain_best *b, hf_chain_stats *st) {
    int64_t ci = chain_first_index(r->ox, r->sx, r->nx),
            cj = chain_first_index(r->oy, r->sy, r->ny);
    double t_in = 0.0, s_in = b->h, ddiag = r->dx - r->dy, c0 = r->ox - r->oy;
    int level = 0;
    if (!(t_end > 0.0)) return;
    while (ci >= 0 && ci < r->nx && cj >= 0 && cj < r->ny) {
        hf_hz_cell c;
        if (b->prune > -HF_HZ_INF) {
            int moved = chain_try_skip(H, rows, cols, r, mip, &level, &ci, &cj, &t_in, &s_in, t_end,
                                       b, &st->tile_tests);
            if (moved) {
                st->skips++;
                if (moved == 2) break;
                continue;
            }
        }
        st->cells++;
        c = hf_hz_cell_breakpoints(H, cols, r, ci, cj, t_in, ddiag, c0);
        if (c.crossed && c.td < t_end) chain_visit(b, c.td, c.sd, 0.0);
        if (c.t_out >= t_end) {
            /* the end, interpolated on its piece from the nearer breakpoint (ray_walk.h) */
            const hf_hz_point end = hf_hz_end_point(H, rows, cols, r, &c, t_in, s_in, t_end);
            chain_visit(b, end.t, end.s, end.delta);
            break;
        }
        s_in = hf_hz_exit_value(H, rows, cols, r, c.X, c.Y, c.tX, c.tY);
        chain_visit(b, c.t_out, s_in, 0.0);
        if (c.tX <= c.tY) ci += r->sx;
        if (c.tY <= c.tX) cj += r->sy;
        t_in = c.t_out;
    }
}

void hf_horizon_chain(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip, double dx,
                      double dy, double max_distance, int64_t n_nb, const int64_t *nb_x,
                      const int64_t *nb_y, const double *nb_d, int64_t block_rows,
                      int64_t block_start, int64_t block_stop, double *out, double *occ,
                      hf_chain_stats *stats) {
    chain_ray r;
    hf_hz_ray_direction(&r, rows, cols, dx, dy);
    for (int64_t block = block_start; block < block_stop; block++) {
        int64_t rank_lo = block * block_rows;
        int64_t rank_hi = rank_lo + block_rows < rows ? rank_lo + block_rows : rows;
        for (int64_t rank = rank_lo; rank < rank_hi; rank++) {
            /* rank 0 is the row furthest along dy: a neighbour's row comes first */
            int64_t j = r.sy > 0 ? rows - 1 - rank : rank;
            for (int64_t step = 0; step < cols; step++) {
                int64_t i = r.sx > 0 ? cols - 1 - step : step, v = j * cols + i;
                double t_end;
                chain_best b;
                r.ox = (double)i;
                r.oy = (double)j;
                t_end = hf_hz_footprint_exit(&r);
                if (max_distance < t_end) t_end = max_distance;
                b.h = H[v];
                b.best = b.prune = -HF_HZ_INF;
                b.t_best = NAN;
                /* borrow: the neighbour's occluder, seen on v's own ray */
                for (int64_t k = 0; k < n_nb; k++) {
                    int64_t wi = i + nb_x[k], wj = j + nb_y[k], w_rank;
                    double t, x, y, s, corner_max, eps, bound;
                    if (wi < 0 || wi >= cols || wj < 0 || wj >= rows) continue;
                    w_rank = r.sy > 0 ? rows - 1 - wj : wj;
                    if (w_rank < rank_lo) continue; /* in another block: maybe not done */
                    if (isnan(occ[wj * cols + wi])) continue;
                    t = nb_d[k] + occ[wj * cols + wi];
                    if (!(t > 0.0) || t > t_end) continue;
                    x = r.ox + t * dx;
                    y = r.oy + t * dy;
                    if (x < 0.0 || y < 0.0 || x > (double)r.nx || y > (double)r.ny) continue;
                    s = surface_point(H, rows, cols, x, y, &corner_max);
                    /* rounding margin: a few ulps of the heights, and the surface's slope
                     * times the rounding of the point's position (both far below it) */
                    eps = 1e-14 * (corner_max + fabs(b.h) + 1.0) * (fabs(x) + fabs(y) + t + 16.0);
                    bound = (s - b.h - eps) / t;
                    if (bound > b.prune) b.prune = bound;
                }
                if (b.prune > -HF_HZ_INF) stats->bounded++;
                chain_walk(H, rows, cols, mip, &r, t_end, &b, stats);
                out[v] = b.best;
                occ[v] = b.t_best;
            }
        }
    }
}
