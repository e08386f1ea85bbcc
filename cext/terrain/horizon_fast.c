/* Fast horizon kernels: the row-vectorised shared pattern (bounded radii) and the chain
 * walk (any direction, any distance). See horizon_fast.h for the contracts and
 * algos/terrain.py for the maths. */
#include <math.h>
#include <stdio.h>
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
    const int64_t i = hf_hz_clamped_floor(x, 0, cols - 2), j = hf_hz_clamped_floor(y, 0, rows - 2);
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

/* ---- the strips ------------------------------------------------------------------------ */

/* c (across) and a (along) of the point (x, y) for the unit direction (dx, dy). */
static inline double strip_across(double dx, double dy, double x, double y) {
    return dx * y - dy * x;
}

static inline double strip_along(double dx, double dy, double x, double y) {
    return dx * x + dy * y;
}

int hf_horizon_strips_frame(int64_t rows, int64_t cols, double dx, double dy, double width,
                            double bin, double *c_min, double *a_min, int64_t *n_strips,
                            int64_t *n_bins0) {
    const double nx = (double)(cols - 1), ny = (double)(rows - 1);
    const double xs[4] = {0.0, nx, 0.0, nx}, ys[4] = {0.0, 0.0, ny, ny};
    double c_lo = HF_HZ_INF, c_hi = -HF_HZ_INF, a_lo = HF_HZ_INF, a_hi = -HF_HZ_INF, ns, nb;
    for (int k = 0; k < 4; k++) { /* the footprint's corners bound both coordinates */
        const double c = strip_across(dx, dy, xs[k], ys[k]), a = strip_along(dx, dy, xs[k], ys[k]);
        c_lo = c < c_lo ? c : c_lo;
        c_hi = c > c_hi ? c : c_hi;
        a_lo = a < a_lo ? a : a_lo;
        a_hi = a > a_hi ? a : a_hi;
    }
    /* two strips and bins of margin each side: cells reach past the corners by the slack */
    *c_min = c_lo - 2.0 * width;
    *a_min = a_lo - 2.0 * bin;
    ns = floor((c_hi - *c_min) / width) + 3.0;
    nb = floor((a_hi - *a_min) / bin) + 3.0;
    if (!(ns >= 1.0 && nb >= 1.0 && ns * nb < 4.0e18)) return -1;
    *n_strips = (int64_t)ns;
    *n_bins0 = (int64_t)nb;
    return 0;
}

/* The index of coordinate v in slots of `size` from `lo`, clamped to [0, n - 1]: floor of
 * the quotient, by truncation (no libm call): the two differ only below 1, clamped to 0. */
static inline int64_t strip_slot(double v, double lo, double size, int64_t n) {
    const double q = (v - lo) / size;
    return q < 1.0 ? 0 : q >= (double)(n - 1) ? n - 1 : (int64_t)q;
}

void hf_horizon_strips_build(const double *H, int64_t rows, int64_t cols, double dx, double dy,
                             const hf_hz_strips *s, float *data) {
    /* a cell's c and a ranges, relative to its corner (i, j): the extremes over its four
     * corners, widened by the slack */
    const double c_lo = (dx < 0 ? dx : 0.0) + (-dy < 0 ? -dy : 0.0) - HF_STRIP_SLACK;
    const double c_hi = (dx > 0 ? dx : 0.0) + (-dy > 0 ? -dy : 0.0) + HF_STRIP_SLACK;
    const double a_lo = (dx < 0 ? dx : 0.0) + (dy < 0 ? dy : 0.0) - HF_STRIP_SLACK;
    const double a_hi = (dx > 0 ? dx : 0.0) + (dy > 0 ? dy : 0.0) + HF_STRIP_SLACK;
    const int64_t nb0 = s->n_bins[0];
    for (int64_t k = 0; k < s->offset[s->n_levels - 1] + s->n_strips * s->n_bins[s->n_levels - 1];
         k++)
        data[k] = -HUGE_VALF;
    /* level 0: every cell into each strip and bin it reaches */
    for (int64_t j = 0; j + 1 < rows; j++) {
        const double *row = H + j * cols;
        for (int64_t i = 0; i + 1 < cols; i++) {
            double m = row[i];
            float top;
            const double c = strip_across(dx, dy, (double)i, (double)j);
            const double a = strip_along(dx, dy, (double)i, (double)j);
            const int64_t k0 = strip_slot(c + c_lo, s->c_min, s->width, s->n_strips);
            const int64_t k1 = strip_slot(c + c_hi, s->c_min, s->width, s->n_strips);
            const int64_t b0 = strip_slot(a + a_lo, s->a_min, s->bin, nb0);
            const int64_t b1 = strip_slot(a + a_hi, s->a_min, s->bin, nb0);
            m = row[i + 1] > m ? row[i + 1] : m;
            m = row[i + cols] > m ? row[i + cols] : m;
            m = row[i + cols + 1] > m ? row[i + cols + 1] : m;
            /* in single precision, rounded up: still a bound, in half the memory */
            top = (float)m;
            if ((double)top < m) top = nextafterf(top, HUGE_VALF);
            for (int64_t b = b0; b <= b1; b++) {
                float *bin = data + b * s->n_strips;
                for (int64_t k = k0; k <= k1; k++) bin[k] = top > bin[k] ? top : bin[k];
            }
        }
    }
    /* each level above: the maximum of two bins below (a missing second one is -inf) */
    for (int32_t l = 1; l < s->n_levels; l++) {
        const int64_t nb = s->n_bins[l], below = s->n_bins[l - 1], ns = s->n_strips;
        for (int64_t b = 0; b < nb; b++) {
            const float *first = data + s->offset[l - 1] + 2 * b * ns;
            float *dst = data + s->offset[l] + b * ns;
            if (2 * b + 1 < below) {
                const float *second = first + ns;
                for (int64_t k = 0; k < ns; k++)
                    dst[k] = second[k] > first[k] ? second[k] : first[k];
            } else {
                for (int64_t k = 0; k < ns; k++) dst[k] = first[k];
            }
        }
    }
}

/* ---- the chain walk --------------------------------------------------------------------- */

/* The horizon skip: every point with surface at most m, crossed on [t_in, t_exit], has a
 * ratio at most (m - h) / t there, which is <= prune when this holds. */
static inline int chain_can_skip(const chain_best *b, double m, double t_in, double t_exit) {
    const double rise = m - b->h;
    if (b->prune >= 0) return rise <= b->prune * t_in;
    return rise <= b->prune * t_exit;
}

/* One vertex's place in the strips: its along coordinate relative to a_min and its
 * strip's first level-0 bin; bin b of that strip at level l is base[off[l] + b stride]. */
typedef struct {
    double along;
    const float *base; /* the strip's first bin at level 0 (then every n_strips) */
    int64_t off[62];   /* each level's start relative to level 0's, set once per direction */
    /* the strips' shape, copied once per direction: a walk's stores cannot alias them */
    int top;              /* the top level */
    int64_t last, stride; /* the last level-0 bin; n_strips */
    double bin, inv_bin;  /* a level-0 bin's length and its inverse */
} chain_strip;

/* floor(x) (forward) or ceil(x), by truncation (no libm call; |x| far below 2^63 here: a
 * point of the footprint, give or take a rounding). A zero comes out as +0, where
 * floor(-0.0) is -0: the walk uses the line only through t_line > t_in >= 0 and the
 * integer index, alike for both. */
static inline double chain_line(double x, int forward) {
    const int64_t k = (int64_t)x;
    return forward ? (double)(k - ((double)k > x)) : (double)(k + ((double)k < x));
}

/* Skip the longest stretch of the ray from t_in that bins of its strip prove below the
 * bound: from each certified point, the bin that holds it at one level above the last
 * passed (down to level 0 on a failure), until level 0 fails or the end is covered; pure
 * arithmetic on t. Then move the cell walk to the last grid line of the walk's major axis
 * inside the stretch: there the cell entered is known on that axis exactly and on the
 * other by the forward rule, as after a tile of the max mipmap (ray_walk.h). Returns 0
 * (nothing skipped; *wait is where to try again), 1 (moved to (ci, cj) at *t_in with the
 * surface *s_in there) or 2 (the rest of the ray is covered). */
static int chain_strip_skip(const double *H, int64_t rows, int64_t cols, const chain_ray *r,
                            int major_x, const chain_strip *v, int64_t *ci, int64_t *cj,
                            double *t_in, double *s_in, double t_end, const chain_best *b,
                            double *wait, int64_t *wait_bin, int64_t *tests) {
    const int top = v->top;
    const int64_t last = v->last, stride = v->stride;
    const double along = v->along, bin = v->bin;
    double t = *t_in, t_line;
    int level = 0, passed = 0;
    int64_t ni, nj, bin0;
    /* the level-0 bin holding t: the one after the last failed, when t lies before its
     * end, or else the quotient (bin is a power of two, so it rounds once; a slot off by
     * one at a bin's edge lies within the slack the bins were widened by); after a pass,
     * the next bin follows by integer arithmetic: the point reached is that bin's first
     * edge, up to a rounding far inside the slack */
    if (*wait_bin >= 0 && t < *wait + bin) {
        bin0 = *wait_bin;
    } else {
        const double q = (along + t) * v->inv_bin;
        bin0 = q < 0.0 ? 0 : q >= (double)last ? last : (int64_t)q;
    }
    for (;;) {
        /* its ancestor at this level */
        const int64_t slot = bin0 >> level;
        const double m = v->base[v->off[level] + slot * stride];
        const int64_t next = (slot + 1) << level;
        const double t_stop = (double)next * bin - along;
        (*tests)++;
        if (chain_can_skip(b, m, t, t_stop < t_end ? t_stop : t_end)) {
            if (t_stop >= t_end) return 2;
            /* never step backwards */
            if (t_stop > t) {
                t = t_stop;
                bin0 = next < last ? next : last;
                passed = 1;
            }
            if (level < top) level++;
            continue;
        }
        if (level > 0) {
            level--;
            continue;
        }
        if (!passed) {
            *wait = t_stop;
            *wait_bin = next <= last ? next : -1;
            return 0;
        }
        break;
    }
    /* the last grid line of the major axis at or before t (rounding may put it a hair
     * past: inside the slack the bins were widened by) */
    if (major_x) {
        const double x = r->ox + t * r->dx;
        const double line = chain_line(x, r->sx > 0);
        t_line = (line - r->ox) * r->inv_dx;
        ni = r->sx > 0 ? (int64_t)line : (int64_t)line - 1;
        nj = hf_index_of(r->oy + t_line * r->dy, r->sy >= 0);
        if (nj == r->ny && r->sy == 0) nj = r->ny - 1; /* along the far edge */
    } else {
        const double y = r->oy + t * r->dy;
        const double line = chain_line(y, r->sy > 0);
        t_line = (line - r->oy) * r->inv_dy;
        nj = r->sy > 0 ? (int64_t)line : (int64_t)line - 1;
        ni = hf_index_of(r->ox + t_line * r->dx, r->sx >= 0);
        if (ni == r->nx && r->sx == 0) ni = r->nx - 1;
    }
    /* no progress (the line lies behind the walk), or a cell the walk cannot be in: walk
     * the cells up to t instead */
    if (!(t_line > *t_in) || ni < 0 || ni >= r->nx || nj < 0 || nj >= r->ny ||
        (r->sx > 0   ? ni < *ci
         : r->sx < 0 ? ni > *ci
                     : ni != *ci) ||
        (r->sy > 0   ? nj < *cj
         : r->sy < 0 ? nj > *cj
                     : nj != *cj)) {
        *wait = t;
        *wait_bin = -1;
        return 0;
    }
    *s_in = major_x
                ? hf_hz_exit_value(H, rows, cols, r, r->sx > 0 ? ni : ni + 1, 0, t_line, HF_HZ_INF)
                : hf_hz_exit_value(H, rows, cols, r, 0, r->sy > 0 ? nj : nj + 1, HF_HZ_INF, t_line);
    *ci = ni;
    *cj = nj;
    *t_in = t_line;
    return 1;
}

/* One vertex's walk over the breakpoints in (0, t_end], the same points and expressions as
 * terrain.c's walk_ray_breakpoints with horizon_visit, skipping stretches of its strip
 * below the bound. */
static void chain_walk(const double *H, int64_t rows, int64_t cols, const chain_ray *r,
                       const chain_strip *v, double t_end, chain_best *b, hf_chain_stats *st) {
    int64_t ci = chain_first_index(r->ox, r->sx, r->nx),
            cj = chain_first_index(r->oy, r->sy, r->ny);
    double t_in = 0.0, s_in = b->h, ddiag = r->dx - r->dy, c0 = r->ox - r->oy, wait = 0.0;
    const int major_x = fabs(r->dx) >= fabs(r->dy);
    int s_in_known = 1;
    int64_t wait_bin = -1; /* the level-0 bin that starts at wait, after a failed test */
    int64_t n_cells = 0, n_skips = 0, n_tests = 0, n_cell_skips = 0;
    /* the faces of the current cell, stepped along incrementally (hf_hz_cell_step), and
     * of the last cell stepped past unseen */
    hf_hz_cell c = hf_hz_cell_faces(r, ci, cj), entry = c;
    if (!(t_end > 0.0)) return;
    /* No footprint test per cell: the walk stays inside. Its first cell is (t_end > 0);
     * a strip skip moves only to a cell it checks; and a step leaves the footprint only
     * through a border face, whose parameter is the footprint exit's (the same expression,
     * so the same bits), at least t_end: the walk ends there before stepping. */
    for (;;) {
#ifdef HF_DEBUG
        if (ci < 0 || ci >= r->nx || cj < 0 || cj >= r->ny) {
            fprintf(stderr, "hftrace: chain walk left the footprint at cell (%lld, %lld)\n",
                    (long long)ci, (long long)cj);
            abort();
        }
#endif
        if (b->prune > -HF_HZ_INF) {
            const double *corner;
            double m;
            if (t_in >= wait) {
                int moved;
                if (wait_bin >= 0 && t_in < wait + v->bin) {
                    /* the level-0 bin after the last failed one, tested first here: it
                     * fails most often, near the vertex and the occluder */
                    const double m0 = v->base[wait_bin * v->stride];
                    const double t_stop = (double)(wait_bin + 1) * v->bin - v->along;
                    if (!chain_can_skip(b, m0, t_in, t_stop < t_end ? t_stop : t_end)) {
                        n_tests++;
                        wait = t_stop;
                        wait_bin = wait_bin + 1 <= v->last ? wait_bin + 1 : -1;
                        goto cell;
                    }
                }
                moved = chain_strip_skip(H, rows, cols, r, major_x, v, &ci, &cj, &t_in, &s_in,
                                         t_end, b, &wait, &wait_bin, &n_tests);
                if (moved) {
                    n_skips++;
                    s_in_known = 1;
                    if (moved == 2) break;
                    c = hf_hz_cell_faces(r, ci, cj);
                    continue;
                }
            }
        cell:
            /* the cell alone: every point of it lies at most at its highest corner */
            corner = H + cj * cols + ci;
            m = corner[0];
            m = corner[1] > m ? corner[1] : m;
            m = corner[cols] > m ? corner[cols] : m;
            m = corner[cols + 1] > m ? corner[cols + 1] : m;
            if (chain_can_skip(b, m, t_in, c.t_out < t_end ? c.t_out : t_end)) {
                n_cell_skips++;
                if (c.t_out >= t_end) break;
                entry = c;
                s_in_known = 0;
                t_in = c.t_out;
                hf_hz_cell_step(r, &c, &ci, &cj);
                continue;
            }
        }
        n_cells++;
        hf_hz_cell_diagonal(H, cols, r, &c, ci, cj, t_in, ddiag, c0);
        if (c.crossed && c.td < t_end) chain_visit(b, c.td, c.sd, 0.0);
        if (c.t_out >= t_end) {
            /* the end, interpolated on its piece from the nearer breakpoint (ray_walk.h); the
             * surface where the cell was entered, unless already known */
            hf_hz_point end;
            if (!s_in_known)
                s_in = hf_hz_exit_value(H, rows, cols, r, entry.X, entry.Y, entry.tX, entry.tY);
            end = hf_hz_end_point(H, rows, cols, r, &c, t_in, s_in, t_end);
            chain_visit(b, end.t, end.s, end.delta);
            break;
        }
        s_in = hf_hz_exit_value(H, rows, cols, r, c.X, c.Y, c.tX, c.tY);
        s_in_known = 1;
        chain_visit(b, c.t_out, s_in, 0.0);
        t_in = c.t_out;
        hf_hz_cell_step(r, &c, &ci, &cj);
    }
    st->cells += n_cells;
    st->skips += n_skips;
    st->tile_tests += n_tests;
    st->cell_skips += n_cell_skips;
}

void hf_horizon_chain(const double *H, int64_t rows, int64_t cols, const hf_hz_strips *strips,
                      double dx, double dy, double max_distance, int64_t n_nb, const int64_t *nb_x,
                      const int64_t *nb_y, const double *nb_d, int64_t block_rows,
                      int64_t block_start, int64_t block_stop, double *out, double *occ,
                      hf_chain_stats *stats) {
    chain_ray r;
    chain_strip place;
    hf_hz_ray_direction(&r, rows, cols, dx, dy);
    place.top = strips->n_levels - 1;
    place.last = strips->n_bins[0] - 1;
    place.stride = strips->n_strips;
    place.bin = strips->bin;
    place.inv_bin = strips->inv_bin;
    for (int32_t l = 0; l < strips->n_levels; l++)
        place.off[l] = strips->offset[l] - strips->offset[0];
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
                    double t, x, y, s, corner_max, eps, rise;
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
                    rise = s - b.h - eps;
                    /* divide only for a better bound (a rounding the compare misses only
                     * leaves the bound lower: still a bound) */
                    if (rise > b.prune * t) {
                        const double bound = rise / t;
                        if (bound > b.prune) b.prune = bound;
                    }
                }
                if (b.prune > -HF_HZ_INF) stats->bounded++;
                {
                    const int64_t k = strip_slot(strip_across(dx, dy, r.ox, r.oy), strips->c_min,
                                                 strips->width, strips->n_strips);
                    place.base = strips->data + strips->offset[0] + k;
                }
                place.along = strip_along(dx, dy, r.ox, r.oy) - strips->a_min;
                chain_walk(H, rows, cols, &r, &place, t_end, &b, stats);
                out[v] = b.best;
                occ[v] = b.t_best;
            }
        }
    }
}
