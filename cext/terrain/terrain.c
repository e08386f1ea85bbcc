/* Terrain products: horizon angles by shared patterns, by the rational sweep, by
 * per-vertex walks (plain or max-mipmap) and by a fixed-step marcher, and line of sight
 * for viewsheds. See terrain.h for the contracts and algos/terrain.py for the maths. */
#include <math.h>
#include <stdlib.h>
#include "core/mipmap.h"
#include "surfaces/surfaces.h"
#include "terrain/terrain.h"
#include "terrain/ray_walk.h"

static int64_t clamp64(int64_t v, int64_t lo, int64_t hi) {
    return v < lo ? lo : v > hi ? hi : v;
}

/* The two-triangle surface (split u = v) at any point of the footprint. */
static double surface_at(const double *H, int64_t rows, int64_t cols, double x, double y) {
    int64_t i = clamp64((int64_t)floor(x), 0, cols - 2);
    int64_t j = clamp64((int64_t)floor(y), 0, rows - 2);
    double u = x - (double)i, v = y - (double)j;
    const double *c = H + j * cols + i;
    double h00 = c[0], h10 = c[1], h01 = c[cols], h11 = c[cols + 1];
    /* barycentric: exact on the edges, where a clamped cell puts the footprint's border */
    return hf_triangles_barycentric(h00, h10, h01, h11, u, v);
}

/* ---- shared pattern ----------------------------------------------------------------- */

/* ---- curvature: the candidates of one linear piece -------------------------------- */

/* With curvature a point at distance t is lowered by kappa t^2, and on a linear piece of
 * the rise r(t) = a + b t (relative to the start vertex) the ratio g(t) = a / t + b -
 * kappa t is no longer monotone: for kappa > 0 and a < 0 it peaks at t* = sqrt(-a / kappa),
 * where g = b - 2 sqrt(-a kappa). This returns the larger of `best` and that peak when t*
 * lies strictly inside the piece from (t0, r0) to (t1, r1). On the first piece (t0 = 0,
 * r0 = 0) the supremum is the slope limit b at t -> 0+ instead (a = 0). */
static double piece_peak(double best, double kappa, double t0, double r0, double t1, double r1) {
    double b, minus_a, t_star2, g;
    if (t0 == 0.0) {
        b = r1 / t1;
        return b > best ? b : best;
    }
    if (!(kappa > 0.0) || !(t1 > t0)) return best;
    b = (r1 - r0) / (t1 - t0);
    /* -a = b t0 - r0: its rounding moves g(t*) by about (1 - t0 / t*) times the error of b,
     * which the short piece keeps small (t* lies in the piece) */
    minus_a = b * t0 - r0;
    if (!(minus_a > 0.0)) return best;
    t_star2 = minus_a / kappa;
    if (!(t_star2 > t0 * t0 && t_star2 < t1 * t1)) return best;
    g = b - 2.0 * sqrt(minus_a * kappa);
    return g > best ? g : best;
}

/* The shared-pattern walk with curvature (kappa != 0): every breakpoint's lowered ratio,
 * each piece's interior peak and the first piece's slope limit. The early stop holds for
 * kappa > 0 only (the lowered surface stays below zmax); kappa < 0 (a raised surface, the
 * negative openness's mirror) walks every breakpoint. */
static void pattern_curved(const double *H, int64_t rows, int64_t cols, const hf_hz_pattern *p,
                           double zmax, int64_t stop_every, double kappa, int64_t start,
                           int64_t stop, double *out) {
    const double *inv_t = p->inv_t, *w = p->w;
    const int64_t *off_a = p->off_a, *off_b = p->off_b;
    int64_t chunk;
    if (kappa < 0.0) stop_every = 0;
    chunk = stop_every > 0 ? stop_every : p->n + 1;
    for (int64_t v = start; v < stop; v++) {
        int64_t j = v / cols, i = v - j * cols;
        int64_t n = p->limit_x[cols - 1 - i];
        int64_t ny = p->limit_y[rows - 1 - j];
        int64_t n_valid;
        const double *base = H + v;
        double h = base[0], best = -HF_HZ_INF, t_prev = 0.0, r_prev = 0.0;
        if (ny < n) n = ny;
        n_valid = n;
        if (p->end_k >= 0 && n > p->end_k + 1) n = p->end_k + 1;
        for (int64_t e0 = 0; e0 < n; e0 += chunk) {
            int64_t e1 = e0 + chunk < n ? e0 + chunk : n;
            for (int64_t e = e0; e < e1; e++) {
                double t = 1.0 / inv_t[e];
                double rise = hf_hz_breakpoint(base, off_a, off_b, w, e) - h;
                double r = rise * inv_t[e] - kappa * t;
                best = r > best ? r : best;
                best = piece_peak(best, kappa, t_prev, r_prev, t, rise);
                t_prev = t;
                r_prev = rise;
            }
            if (stop_every > 0 && (zmax - h) * inv_t[e1 - 1] <= best) {
                n_valid = 0; /* nothing further can count, the end included */
                break;
            }
        }
        if (p->end_k >= 0 && n_valid > p->end_k + 1) {
            double t = 1.0 / p->end_inv_t;
            double rise = hf_hz_pattern_end(base, off_a, off_b, w, p->end_k, p->end_f) - h;
            double r = rise * p->end_inv_t - kappa * t;
            best = r > best ? r : best;
            best = piece_peak(best, kappa, t_prev, r_prev, t, rise);
        }
        out[v] = best;
    }
}

void hf_horizon_pattern(const double *H, int64_t rows, int64_t cols, const hf_hz_pattern *p,
                        double zmax, int64_t stop_every, double kappa, int64_t start, int64_t stop,
                        double *out) {
    const double *inv_t = p->inv_t, *w = p->w;
    const int64_t *off_a = p->off_a, *off_b = p->off_b;
    int64_t chunk = stop_every > 0 ? stop_every : p->n + 1;
    if (kappa != 0.0) {
        pattern_curved(H, rows, cols, p, zmax, stop_every, kappa, start, stop, out);
        return;
    }
    for (int64_t v = start; v < stop; v++) {
        int64_t j = v / cols, i = v - j * cols;
        int64_t n = p->limit_x[cols - 1 - i];
        int64_t ny = p->limit_y[rows - 1 - j];
        int64_t n_valid;
        const double *base = H + v;
        double h = base[0], best = -HF_HZ_INF;
        if (ny < n) n = ny;
        n_valid = n;
        if (p->end_k >= 0 && n > p->end_k + 1) n = p->end_k + 1;
        for (int64_t e0 = 0; e0 < n; e0 += chunk) {
            int64_t e1 = e0 + chunk < n ? e0 + chunk : n;
            for (int64_t e = e0; e < e1; e++) {
                double r = hf_hz_ratio(hf_hz_breakpoint(base, off_a, off_b, w, e), h, inv_t[e]);
                best = r > best ? r : best;
            }
            if (stop_every > 0 && (zmax - h) * inv_t[e1 - 1] <= best) {
                n_valid = 0; /* nothing further can count, the end included */
                break;
            }
        }
        if (p->end_k >= 0 && n_valid > p->end_k + 1) {
            double r = hf_hz_ratio(hf_hz_pattern_end(base, off_a, off_b, w, p->end_k, p->end_f), h,
                                   p->end_inv_t);
            best = r > best ? r : best;
        }
        out[v] = best;
    }
}

/* ---- rational sweep with an upper convex hull --------------------------------------- */

/* Lines are taken in order of c = p x - q y, so that neighbouring lines, which read the
 * same cache lines of H, follow each other. Each line is generated from its far end
 * backwards, straight into the hull: no buffer. */
static void sweep_line(const double *H, int64_t rows, int64_t cols, int64_t q, int64_t p,
                       int64_t i0, int64_t j0, int64_t n_entries, const double *tfrac,
                       const int64_t *rel_a, const int64_t *rel_b, const double *w,
                       const int64_t *mx, const int64_t *my, double inv_norm, double *ht,
                       double *hs, double *out) {
    int64_t periods = (cols - 1 - i0) / q, top = 0;
    if (p > 0 && (rows - 1 - j0) / p < periods) periods = (rows - 1 - j0) / p;
    for (int64_t m = periods; m >= 0; m--) {
        int64_t vi = i0 + m * q, vj = j0 + m * p, base = vj * cols + vi;
        int64_t last = n_entries - 1;
        if (m == periods) { /* the partial period: its breakpoints inside the footprint */
            last = -1;
            while (last + 1 < n_entries && vi + mx[last + 1] <= cols - 1 &&
                   vj + my[last + 1] <= rows - 1)
                last++;
        }
        for (int64_t e = last; e >= 0; e--) {
            double sp = hf_lerp(H[base + rel_a[e]], H[base + rel_b[e]], w[e]);
            double tp = (double)m + tfrac[e];
            while (top >= 2 && (hs[top - 1] - sp) * (ht[top - 2] - tp) <=
                                   (hs[top - 2] - sp) * (ht[top - 1] - tp))
                top--;
            if (e == n_entries - 1) /* the next vertex on the line */
                out[base + p * cols + q] =
                    top ? (hs[top - 1] - sp) / (ht[top - 1] - tp) * inv_norm : -HF_HZ_INF;
            ht[top] = tp;
            hs[top] = sp;
            top++;
        }
    }
    {
        double sp = H[j0 * cols + i0], tp = 0.0;
        while (top >= 2 &&
               (hs[top - 1] - sp) * (ht[top - 2] - tp) <= (hs[top - 2] - sp) * (ht[top - 1] - tp))
            top--;
        out[j0 * cols + i0] = top ? (hs[top - 1] - sp) / (ht[top - 1] - tp) * inv_norm : -HF_HZ_INF;
    }
}

int hf_horizon_sweep(const double *H, int64_t rows, int64_t cols, int64_t q, int64_t p,
                     int64_t n_entries, const double *tfrac, const int64_t *dxa, const int64_t *dya,
                     const int64_t *dxb, const int64_t *dyb, const double *w, const int64_t *mx,
                     const int64_t *my, double norm, int64_t k_lo, int64_t k_hi, double *out) {
    int64_t max_periods = (cols - 1) / q + 2;
    int64_t cap = 1 + max_periods * n_entries;
    int64_t c_min = -q * (rows - 1), c_max = p * (cols - 1), n_c = c_max - c_min + 1;
    double *ht = malloc((size_t)cap * sizeof *ht), *hs = malloc((size_t)cap * sizeof *hs);
    int64_t *rel_a = malloc((size_t)n_entries * sizeof *rel_a);
    int64_t *rel_b = malloc((size_t)n_entries * sizeof *rel_b);
    int64_t *first = malloc((size_t)n_c * sizeof *first);
    if (!ht || !hs || !rel_a || !rel_b || !first) {
        free(ht);
        free(hs);
        free(rel_a);
        free(rel_b);
        free(first);
        return -1;
    }
    for (int64_t e = 0; e < n_entries; e++) {
        rel_a[e] = dya[e] * cols + dxa[e];
        rel_b[e] = dyb[e] * cols + dxb[e];
    }
    for (int64_t k = 0; k < n_c; k++) first[k] = -1;
    for (int64_t j0 = 0; j0 < rows; j0++) {
        /* a line's first vertex is one whose predecessor (i - q, j - p) is outside */
        int64_t imax = j0 < p ? cols : (q < cols ? q : cols);
        for (int64_t i0 = 0; i0 < imax; i0++) first[p * i0 - q * j0 - c_min] = j0 * cols + i0;
    }
    if (k_lo < 0) k_lo = 0;
    if (k_hi > n_c) k_hi = n_c;
    for (int64_t k = k_lo; k < k_hi; k++) {
        int64_t v = first[k];
        if (v < 0) continue;
        sweep_line(H, rows, cols, q, p, v % cols, v / cols, n_entries, tfrac, rel_a, rel_b, w, mx,
                   my, 1.0 / norm, ht, hs, out);
    }
    free(ht);
    free(hs);
    free(rel_a);
    free(rel_b);
    free(first);
    return 0;
}

/* ---- per-vertex and line-of-sight walks --------------------------------------------- */

/* The ray over the footprint, its breakpoints and the tile step: terrain/ray_walk.h. */
typedef hf_hz_ray walk_ray;

static int64_t first_index(double o, int s, int64_t n) {
    /* the cell holding the points just after o, moving with sign s (s = 0: [i, i+1)) */
    int64_t i = s < 0 ? (int64_t)ceil(o) - 1 : (int64_t)floor(o);
    if (s == 0 && i == n) i = n - 1; /* on the far edge of the footprint, moving along it */
    return i;
}

static void walk_init(walk_ray *r, int64_t rows, int64_t cols, double ox, double oy, double dx,
                      double dy) {
    r->ox = ox;
    r->oy = oy;
    hf_hz_ray_direction(r, rows, cols, dx, dy);
}

/* Skip the largest tile around cell (ci, cj) that `can_skip` allows. On success moves the
 * cell to the one after the tile, sets *t_in to the tile's exit and returns 1; returns 2
 * when the tile covers the rest of the ray, 0 when no tile can be skipped. */
typedef int (*skip_test)(const void *ctx, double tile_max, double t_in, double t_exit);

static int try_skip(const double *H, int64_t rows, int64_t cols, const walk_ray *r,
                    const hf_hz_mip *mip, int *level_io, int64_t *ci, int64_t *cj, double *t_in,
                    double *s_in, double t_end, skip_test test, const void *ctx) {
    for (int level = hf_hz_skip_start(mip, *level_io); level >= 0; level--) {
        const hf_hz_tile e = hf_hz_tile_at(r, mip, level, *ci, *cj, t_end);
        if (!test(ctx, e.max, *t_in, e.t_exit)) continue;
        *level_io = level;
        *t_in = e.t_exit;
        if (e.t_exit >= t_end) return 2; /* the rest of the ray is covered */
        /* the surface where the ray leaves the tile: the next cell's entry */
        hf_hz_tile_leave(H, rows, cols, r, &e, level, ci, cj, s_in);
        return 1;
    }
    *level_io = 0;
    return 0;
}

/* The breakpoints of one ray in [0, t_end]: every exit of a cell, every diagonal crossing
 * inside a cell and the end. The surface there is s + delta (delta is nonzero only at the
 * end, which is given relative to the breakpoint before it, so that a visitor can subtract
 * its reference height before adding a tiny delta). visit returns nonzero to stop.
 * visit_tile_exits: also visit where a skipped tile ends (a visitor that needs every
 * piece: curvature). */
typedef int (*visit_fn)(void *ctx, double t, double s, double delta);

static void walk_ray_breakpoints(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip,
                                 const walk_ray *r, double t_end, double s_origin, visit_fn visit,
                                 skip_test test, void *ctx, int visit_tile_exits,
                                 hf_hz_stats *stats) {
    int64_t ci = first_index(r->ox, r->sx, r->nx), cj = first_index(r->oy, r->sy, r->ny);
    double t_in = 0.0, s_in = s_origin, ddiag = r->dx - r->dy, c0 = r->ox - r->oy;
    int level = 0;
    int64_t cells = 0, skips = 0;
    if (!(t_end > 0.0)) return;
    while (ci >= 0 && ci < r->nx && cj >= 0 && cj < r->ny) {
        hf_hz_cell c;
        if (mip && test) {
            int moved =
                try_skip(H, rows, cols, r, mip, &level, &ci, &cj, &t_in, &s_in, t_end, test, ctx);
            if (moved) {
                skips++;
                if (moved == 2) break;
                /* the tile's exit starts the next piece */
                if (visit_tile_exits && visit(ctx, t_in, s_in, 0.0)) break;
                continue;
            }
        }
        cells++;
        c = hf_hz_cell_breakpoints(H, cols, r, ci, cj, t_in, ddiag, c0);
        if (c.crossed && c.td < t_end && visit(ctx, c.td, c.sd, 0.0)) break;
        if (c.t_out >= t_end) {
            const hf_hz_point end = hf_hz_end_point(H, rows, cols, r, &c, t_in, s_in, t_end);
            visit(ctx, end.t, end.s, end.delta);
            break;
        }
        s_in = hf_hz_exit_value(H, rows, cols, r, c.X, c.Y, c.tX, c.tY); /* the next entry */
        if (visit(ctx, c.t_out, s_in, 0.0)) break;
        if (c.tX <= c.tY) ci += r->sx;
        if (c.tY <= c.tX) cj += r->sy;
        t_in = c.t_out;
    }
    if (stats) {
        stats->cells += cells;
        stats->skips += skips;
    }
}

typedef struct {
    double h, best;
    double kappa, t_prev, r_prev; /* curvature, and the previous breakpoint's (t, rise) */
} horizon_ctx;

static int horizon_visit(void *vctx, double t, double s, double delta) {
    horizon_ctx *c = vctx;
    double rise = (s - c->h) + delta;
    if (rise > c->best * t) c->best = rise / t;
    return 0;
}

/* With curvature: the lowered ratio at the breakpoint, and the peak or slope limit of the
 * piece that ends there. */
static int horizon_visit_curved(void *vctx, double t, double s, double delta) {
    horizon_ctx *c = vctx;
    double rise = (s - c->h) + delta;
    double r = rise / t - c->kappa * t;
    if (r > c->best) c->best = r;
    c->best = piece_peak(c->best, c->kappa, c->t_prev, c->r_prev, t, rise);
    c->t_prev = t;
    c->r_prev = rise;
    return 0;
}

static int horizon_skip(const void *vctx, double tile_max, double t_in, double t_exit) {
    const horizon_ctx *c = vctx;
    if (c->best == -HF_HZ_INF) return 0;
    return tile_max - c->h <= c->best * (c->best >= 0 ? t_in : t_exit);
}

void hf_horizon_walk(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip, double dx,
                     double dy, double max_distance, double kappa, int64_t start, int64_t stop,
                     double *out, hf_hz_stats *stats) {
    /* a raised surface (kappa < 0) may rise above a tile's maximum: no skipping */
    if (kappa < 0.0) mip = NULL;
    for (int64_t v = start; v < stop; v++) {
        int64_t j = v / cols, i = v - j * cols;
        walk_ray r;
        horizon_ctx c;
        double t_end;
        walk_init(&r, rows, cols, (double)i, (double)j, dx, dy);
        t_end = hf_hz_footprint_exit(&r);
        if (max_distance < t_end) t_end = max_distance;
        c.h = H[v];
        c.best = -HF_HZ_INF;
        c.kappa = kappa;
        c.t_prev = c.r_prev = 0.0;
        walk_ray_breakpoints(H, rows, cols, mip, &r, t_end, c.h,
                             kappa != 0.0 ? horizon_visit_curved : horizon_visit, horizon_skip, &c,
                             kappa != 0.0, stats);
        out[v] = c.best;
    }
}

typedef struct {
    double z0, slope, drop2, eps; /* drop2 = drop * |d|^2 */
    int uncertain, blocked;
} los_ctx;

static int los_visit(void *vctx, double t, double s, double delta) {
    los_ctx *c = vctx;
    double margin;
    /* the target itself (t = 1) is never tested. A crossing computed within 1e-12 of it
     * is the target up to rounding: the next breakpoint of a segment between lattice
     * points lies at least 1 / (2 * 2^24) before it */
    if (t > 1.0 - 1e-12) return 0;
    margin = s + delta - c->drop2 * t * t - (c->z0 + c->slope * t);
    if (margin > c->eps) {
        c->blocked = 1;
        return 1;
    }
    if (margin > -c->eps) c->uncertain = 1;
    return 0;
}

static int los_skip(const void *vctx, double tile_max, double t_in, double t_exit) {
    const los_ctx *c = vctx;
    double low = c->z0 + c->slope * (c->slope >= 0 ? t_in : t_exit);
    return tile_max + c->eps < low;
}

void hf_viewshed(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip, double ox,
                 double oy, double z0, double target_height, double drop, double eps, int64_t start,
                 int64_t stop, uint8_t *out, hf_hz_stats *stats) {
    const double s_observer = surface_at(H, rows, cols, ox, oy);
    for (int64_t v = start; v < stop; v++) {
        int64_t j = v / cols, i = v - j * cols;
        double dx = (double)i - ox, dy = (double)j - oy;
        walk_ray r;
        los_ctx c;
        if (dx == 0.0 && dy == 0.0) {
            out[v] = 0;
            continue;
        }
        walk_init(&r, rows, cols, ox, oy, dx, dy);
        c.z0 = z0;
        c.drop2 = drop * (dx * dx + dy * dy);
        c.slope = H[v] - c.drop2 + target_height - z0; /* the target sinks with the surface */
        c.eps = eps;
        c.uncertain = c.blocked = 0;
        /* t in [0, 1): the target vertex itself is never strictly above its own segment */
        walk_ray_breakpoints(H, rows, cols, mip, &r, 1.0, s_observer, los_visit, los_skip, &c, 0,
                             stats);
        out[v] = c.blocked ? 1 : c.uncertain ? 2 : 0;
    }
}

/* ---- viewshed thresholds ------------------------------------------------------------ */

/* The segment from the eye (t = 0, height z0) to the target top (t = 1, height z1) clears
 * a breakpoint (t, sigma) when z0 + (z1 - z0) t >= sigma. Raising the target: z1 >= z0 +
 * (sigma - z0) / t; raising the eye: z0 >= (sigma - z1 t) / (1 - t). Each bound is one
 * maximum over the breakpoints in (0, 1), which this walk returns. */
typedef struct {
    double z0, z1, drop2, best;
    int kind;
} threshold_ctx;

static int threshold_visit(void *vctx, double t, double s, double delta) {
    threshold_ctx *c = vctx;
    double sigma, r;
    if (t > 1.0 - 1e-12) return 0; /* the target itself never counts (see los_visit) */
    sigma = s + delta - c->drop2 * t * t;
    r = c->kind == HF_VS_TARGET ? (sigma - c->z0) / t : (sigma - c->z1 * t) / (1.0 - t);
    if (r > c->best) c->best = r;
    return 0;
}

/* A tile is skipped when no point of it can raise the bound: its highest surface lies on
 * or below the line that the bound found so far defines (the lowered surface is lower). */
static int threshold_skip(const void *vctx, double tile_max, double t_in, double t_exit) {
    const threshold_ctx *c = vctx;
    double slope, base, low;
    if (c->best == -HF_HZ_INF) return 0;
    if (c->kind == HF_VS_TARGET) {
        base = c->z0;
        slope = c->best;
    } else {
        base = c->best;
        slope = c->z1 - c->best;
    }
    low = base + slope * (slope >= 0 ? t_in : t_exit);
    return tile_max < low;
}

void hf_viewshed_threshold(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip,
                           double ox, double oy, double z0, double target_height, double drop,
                           int kind, int64_t start, int64_t stop, double *out, hf_hz_stats *stats) {
    const double s_observer = surface_at(H, rows, cols, ox, oy);
    for (int64_t v = start; v < stop; v++) {
        int64_t j = v / cols, i = v - j * cols;
        double dx = (double)i - ox, dy = (double)j - oy;
        walk_ray r;
        threshold_ctx c;
        if (dx == 0.0 && dy == 0.0) { /* no breakpoint between eye and target */
            out[v] = -HF_HZ_INF;
            continue;
        }
        walk_init(&r, rows, cols, ox, oy, dx, dy);
        c.kind = kind;
        c.z0 = z0;
        c.drop2 = drop * (dx * dx + dy * dy);
        c.z1 = H[v] - c.drop2 + target_height; /* the target sinks with the surface */
        c.best = -HF_HZ_INF;
        walk_ray_breakpoints(H, rows, cols, mip, &r, 1.0, s_observer, threshold_visit,
                             threshold_skip, &c, 0, stats);
        out[v] = c.best;
    }
}

/* ---- the r.horizon-style marcher ---------------------------------------------------- */

void hf_horizon_march(const double *H, int64_t rows, int64_t cols, double dx, double dy,
                      double step, double max_distance, double zmax, double kappa, int64_t start,
                      int64_t stop, double *out, hf_hz_stats *stats) {
    int64_t samples = 0;
    double xmax = (double)(cols - 1), ymax = (double)(rows - 1);
    for (int64_t v = start; v < stop; v++) {
        int64_t j = v / cols, i = v - j * cols;
        double h = H[v], best = -HF_HZ_INF;
        for (int64_t k = 1;; k++) {
            double t = (double)k * step, x, y, s;
            if (t > max_distance) break;
            x = (double)i + t * dx;
            y = (double)j + t * dy;
            if (x < 0.0 || y < 0.0 || x > xmax || y > ymax) break;
            s = surface_at(H, rows, cols, x, y) - kappa * t * t; /* curvature: lowered */
            samples++;
            if (s - h > best * t) best = (s - h) / t;
            if (kappa >= 0.0 && (zmax - h) <= best * t) break;
        }
        out[v] = best;
    }
    if (stats) stats->cells += samples;
}
