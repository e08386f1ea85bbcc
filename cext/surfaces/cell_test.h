/* First hits: the per-cell surface tests and per-run culling of the walks in HF_MODE_HIT
 * (docs/CONVENTIONS.md). The walk lists cells in order of t; each test runs in float64 on
 * the caller's 3D ray over [ta, tb], its interval over the cell clipped to [t0, t1]. */
#ifndef HFTRACE_CELL_TEST_H
#define HFTRACE_CELL_TEST_H

#include <float.h>
#include <math.h>
#include <string.h>
#include <stddef.h>
#include <stdint.h>
#include "core/mipmap.h"
#include "surfaces/exact_cell.h"
#include "surfaces/rmq.h"
#include "surfaces/surfaces.h"

/* HF_COLD: out of line (a rare path kept out of a hot loop); HF_HOT: always inlined. */
#if defined(__GNUC__) || defined(__clang__)
#define HF_COLD static __attribute__((noinline))
#define HF_HOT  static inline __attribute__((always_inline))
#else
#define HF_COLD static
#define HF_HOT  static inline
#endif

enum hf_surface { HF_FLAT = 0, HF_PLANE3 = 1, HF_TRIANGLES = 2, HF_BILINEAR = 3 };

typedef struct {
    /* the field: heights H[j * cols + i] and cell maxima M[j * (cols-1) + i] */
    const float *heights;
    const float *cellmax;
    int32_t rows, cols;
    const hf_rmq *row_max; /* runs along x; NULL: no run culling */
    const hf_rmq *col_max; /* runs along y                      */
    int surface;
    int cull_cells;
    /* the ray, clipped to [t0, t1]; entry_axis: the box face it entered by at t0 (0 x,
     * 1 y, 2 z) or -1 when t0 is tmin */
    double ox, oy, oz, dx, dy, dz, inv_dx, inv_dy, t0, t1;
    /* the gaps z - s within +-window of 0 are decided exactly (hf_hit_window); habs: the
     * largest |height| of the field; [tmin, tmax]: the caller's range (exact_cell.h) */
    double window, habs, tmin, tmax, grid_span; /* grid_span: cols + rows + 2 */
    /* oz lowered by the rounding bound (hf_hit_rounding): every cull's z, so that no cull
     * rejects a cell the exact ray touches at its maximum (a peak vertex at t = 57/13) */
    double oz_cull;
    int entry_axis;
    /* The tight path (hf_hit_prepare): with cell culling on and no grid-line special
     * case, a cell (or a run) is first rejected by a bound computed from its index along
     * one axis alone; only the survivors pay for the exact interval. */
    int fast;                  /* cell kernels: use the bound                               */
    int cell_axis;             /* the axis whose slab bounds a cell of a cell kernel       */
    int fast_runs;             /* run kernels: use it too (descending rays, dz < 0)         */
    int bound_off[2];          /* per axis: 1 when the low-z end of cell k is boundary k+1 */
    double bound_lo, bound_hi; /* clamp of that boundary's parameter to [t0, t1]       */
    double o_axis[2], inv_axis[2];
    /* the result */
    int found; /* 1 a hit, 2 a hit decided in exact arithmetic (hf_surface_exact) */
    double t;
    int32_t i, j;
    int wall_axis; /* -1: the surface; 0/1: a vertical wall facing -x/-y travel */
    double su, sv; /* surface slope ds/du, ds/dv at the hit (for the normal)  */
    int64_t cells_visited, cells_tested, runs_visited, runs_culled, tiles_skipped;
} hf_hit;

/* The cell index along one axis (n cells) holding the ray at parameter t, by the forward
 * rule ([k, k+1) moving forward or along the axis, (k, k+1] moving back), clamped into
 * the grid: where a walk starts, or lands after a skip. */
static inline int32_t hf_cell_at(double o, double d, double t, int32_t n) {
    const int64_t k = hf_index_of(o + t * d, d >= 0);
    return (int32_t)(k < 0 ? 0 : (k > n - 1 ? n - 1 : k));
}

/* ---- the surface of one cell ----------------------------------------------------------- */
static inline double hf_height(const hf_hit *h, int32_t i, int32_t j) {
    return (double)h->heights[(int64_t)j * h->cols + i];
}

/* A record's result and statistics, empty: where each ray's set-up starts (ray_begin in
 * dispatch/intersect.c, plane_begin in dispatch/plane.c), on a record whose other fields
 * it rewrites (or, on a miss of the box, leaves unread). */
static inline void hf_hit_clear(hf_hit *h) {
    h->found = 0;
    h->t = 0;
    h->i = h->j = 0;
    h->wall_axis = 0;
    h->su = h->sv = 0;
    h->cells_visited = h->cells_tested = h->runs_visited = h->runs_culled = h->tiles_skipped = 0;
}

/* Record a hit at t in cell (i, j). */
static inline int hf_hit_at(hf_hit *h, double t, int32_t i, int32_t j, int wall_axis, double su,
                            double sv) {
    h->found = 1;
    h->t = t;
    h->i = i;
    h->j = j;
    h->wall_axis = wall_axis;
    h->su = su;
    h->sv = sv;
    return 1;
}

/* The triangles surface's two pieces on [ta, tb] of cell (i, j) (corners h00 .. h11), from
 * the 2D ray alone: the slopes of the triangle under the ray just after ta (lower: u >= v)
 * and of the other, and where the ray crosses u = v inside (ta, tb) (else tb). ua, va (ub,
 * vb): u, v at ta (tb). A crossing that rounds onto ta (a tiny dx entering by the lower edge
 * at u = 0+) leaves no first piece: the ray heads into one triangle for all of (ta, tb]. */
static inline void hf_tri_pieces(const hf_hit *h, double h00, double h10, double h01, double h11,
                                 double ta, double tb, double ua, double va, double ub, double vb,
                                 double *su1, double *sv1, double *su2, double *sv2,
                                 double *t_split) {
    int lower_first = (ua - va) > 0 || ((ua - va) == 0 && (ub - vb) >= 0);
    const double w = (h->dx - h->dy);
    *t_split = tb;
    if (w != 0) {
        const double ts = ta - (ua - va) / w;
        if (ts > ta) {
            if (ts < tb) *t_split = ts;
        } else if ((ua - va) != 0) {
            lower_first = w > 0; /* the side it heads into (unchanged unless ts rounded) */
        }
    }
    if (lower_first) {
        hf_lower_triangle_slopes(h00, h10, h11, su1, sv1);
        hf_upper_triangle_slopes(h00, h01, h11, su2, sv2);
    } else {
        hf_upper_triangle_slopes(h00, h01, h11, su1, sv1);
        hf_lower_triangle_slopes(h00, h10, h11, su2, sv2);
    }
}

/* A cell met at one point only (ta == tb) in a range that is not one point is not visited
 * (half-open rule): that point is the entered cell's (the last cell's at the box's side). */
static inline int hf_one_point_cell(const hf_hit *h, double ta, double tb) {
    return !(ta < tb) && h->t0 < h->t1;
}

/* Whether p(t) lies on cell (i, j)'s exit face into the grid: then (*ni, *nj) holds p(t). */
static inline int hf_exit_into_grid(const hf_hit *h, int32_t i, int32_t j, double t, int32_t *ni,
                                    int32_t *nj) {
    const double x = h->ox + t * h->dx, y = h->oy + t * h->dy;
    const int sx = (h->dx > 0) - (h->dx < 0), sy = (h->dy > 0) - (h->dy < 0);
    const int ex = sx != 0 && x == (double)i + (sx > 0), ey = sy != 0 && y == (double)j + (sy > 0);
    *ni = i + ex * sx;
    *nj = j + ey * sy;
    return (ex || ey) && *ni >= 0 && *ni <= h->cols - 2 && *nj >= 0 && *nj <= h->rows - 2;
}

/* Whether a flat/plane3 cell holds its tb: it ends the range, not on an exit into the grid. */
static inline int hf_end_closed(const hf_hit *h, int32_t i, int32_t j, double tb) {
    int32_t ni, nj;
    return tb >= h->t1 && !hf_exit_into_grid(h, i, j, tb, &ni, &nj);
}

/* What the cold path reads (exact_cell.h) of cell (i, j) on [ta, tb] of the ray in h. */
static inline void hf_exact_cell_of(const hf_hit *h, int32_t i, int32_t j, double ta, double tb,
                                    double t_split, hf_exact_cell *c) {
    c->ox = h->ox, c->oy = h->oy, c->oz = h->oz, c->dx = h->dx, c->dy = h->dy, c->dz = h->dz;
    c->t0 = h->t0, c->t1 = h->t1, c->tmin = h->tmin, c->tmax = h->tmax;
    c->cols = h->cols, c->rows = h->rows, c->surface = h->surface, c->i = i, c->j = j;
    c->ta = ta, c->tb = tb, c->t_split = t_split;
    c->h00 = hf_height(h, i, j), c->h10 = hf_height(h, i + 1, j);
    c->h01 = hf_height(h, i, j + 1), c->h11 = hf_height(h, i + 1, j + 1);
}

/* The cold path of the cell tests: the cell decided in exact arithmetic (exact_cell.h).
 * Returns 1 on a hit, 0 on none, -1 when it cannot decide (the caller's float64 does).
 * t_split: where the caller's first triangles piece ends (tb: one piece). */
HF_COLD int hf_surface_exact(hf_hit *h, int32_t i, int32_t j, double ta, double tb, int wall,
                             double t_split) {
    hf_exact_cell c;
    hf_exact_answer r;
    double su = 0, sv = 0;
    if (h->surface == HF_BILINEAR) return -1;
    hf_exact_cell_of(h, i, j, ta, tb, t_split, &c);
    r = hf_exact_cell_decide(&c);
    if (r.kind <= 0) return r.kind;
    if (r.piece == 3) { /* triangles: the cell entered, on the triangle it heads into */
        const double u = h->ox + r.t * h->dx - r.i, v = h->oy + r.t * h->dy - r.j;
        r.piece = (u - v) > 0 || ((u - v) == 0 && h->dx >= h->dy) ? 1 : 2;
        c.h00 = hf_height(h, r.i, r.j), c.h10 = hf_height(h, r.i + 1, r.j);
        c.h01 = hf_height(h, r.i, r.j + 1), c.h11 = hf_height(h, r.i + 1, r.j + 1);
    }
    if (h->surface == HF_PLANE3) hf_plane3_slopes(c.h00, c.h10, c.h01, &su, &sv);
    if (h->surface == HF_TRIANGLES && r.piece == 1)
        hf_lower_triangle_slopes(c.h00, c.h10, c.h11, &su, &sv);
    if (h->surface == HF_TRIANGLES && r.piece == 2)
        hf_upper_triangle_slopes(c.h00, c.h01, c.h11, &su, &sv);
    if (r.kind == 1)
        (void)hf_hit_at(h, ta, i, j, wall, su, sv);
    else
        (void)hf_hit_at(h, r.t, r.i, r.j, -1, su, sv);
    h->found = 2; /* decided exactly: the cell that holds the point too (border_point) */
    return 1;
}

/* Whether a gap f is within the ray's rounding window of 0 (then its sign is decided
 * exactly); a cold path tried first, whose -1 leaves the float64 decision. */
#define HF_NEAR_ZERO(f) ((f) >= -h->window && (f) <= h->window)
#define HF_TRY_EXACT(f, split)                                                 \
    do {                                                                       \
        if (HF_NEAR_ZERO(f)) {                                                 \
            const int exact_ = hf_surface_exact(h, i, j, ta, tb, wall, split); \
            if (exact_ >= 0) return exact_;                                    \
        }                                                                      \
    } while (0)

/* Test cell (i, j) on [ta, tb]; 1 on a hit. `wall`: the axis (0 x, 1 y) of the wall met at ta
 * if the ray is below the surface there, or -1 when that is no wall (a start inside). */
static inline int hf_surface_test_float(hf_hit *h, int32_t i, int32_t j, double ta, double tb,
                                        int wall) {
    const double h00 = hf_height(h, i, j), h10 = hf_height(h, i + 1, j);
    const double h01 = hf_height(h, i, j + 1), h11 = hf_height(h, i + 1, j + 1);
    const double ua = h->ox + ta * h->dx - i, va = h->oy + ta * h->dy - j;
    const double ub = h->ox + tb * h->dx - i, vb = h->oy + tb * h->dy - j;
    const double za = h->oz + ta * h->dz, zb = h->oz + tb * h->dz;
    h->cells_tested += 1;
    if (hf_one_point_cell(h, ta, tb)) return 0;
    switch (h->surface) {
    /* flat and plane3 jump at cell borders, where a point belongs to the cell the ray
     * enters (docs/CONVENTIONS.md, "Points on a cell border"): the cell's interval is
     * [ta, tb) unless tb ends the range (hf_end_closed; an entered cell decides p(t1) after
     * the walk, border_point in intersect.c). So a touch exactly at its exit is not a hit
     * of this cell: the next cell decides it. (One-point cells: hf_one_point_cell.) */
    case HF_FLAT: {
        const double c = hf_flat_height(h00, h10, h01, h11);
        const double fa = za - c, fb = zb - c;
        if (fa <= h->window) {
            HF_TRY_EXACT(fa, tb);
            if (za <= c) return hf_hit_at(h, ta, i, j, wall, 0, 0);
        }
        if (fb <= h->window) {
            HF_TRY_EXACT(fb, tb);
            if (zb < c || (zb == c && hf_end_closed(h, i, j, tb)))
                return hf_hit_at(h, hf_linear_root(ta, tb, fa, fb), i, j, -1, 0, 0);
        }
        return 0;
    }
    case HF_PLANE3: {
        double a, b;
        hf_plane3_slopes(h00, h10, h01, &a, &b);
        {
            const double fa = za - hf_plane_height(h00, a, b, ua, va);
            const double fb = zb - hf_plane_height(h00, a, b, ub, vb);
            if (fa <= h->window) {
                HF_TRY_EXACT(fa, tb);
                if (fa <= 0) return hf_hit_at(h, ta, i, j, wall, a, b);
            }
            if (fb <= h->window) {
                HF_TRY_EXACT(fb, tb);
                if (fb < 0 || (fb == 0 && hf_end_closed(h, i, j, tb)))
                    return hf_hit_at(h, hf_linear_root(ta, tb, fa, fb), i, j, -1, a, b);
            }
        }
        return 0;
    }
    case HF_TRIANGLES: {
        double su1, sv1, su2, sv2, t_split, f_split, fa;
        hf_tri_pieces(h, h00, h10, h01, h11, ta, tb, ua, va, ub, vb, &su1, &sv1, &su2, &sv2,
                      &t_split);
        fa = za - hf_plane_height(h00, su1, sv1, ua, va);
        if (fa <= h->window) {
            HF_TRY_EXACT(fa, t_split);
            if (fa <= 0) return hf_hit_at(h, ta, i, j, wall, su1, sv1);
        }
        {
            /* first piece [ta, t_split] on the first triangle; one shared value at the
             * split so the diagonal is watertight */
            const double us = h->ox + t_split * h->dx - i, vs = h->oy + t_split * h->dy - j;
            const double zs = h->oz + t_split * h->dz;
            f_split = zs - hf_plane_height(h00, su1, sv1, us, vs);
            if (f_split <= h->window) {
                HF_TRY_EXACT(f_split, t_split);
                if (f_split <= 0)
                    return hf_hit_at(h, hf_linear_root(ta, t_split, fa, f_split), i, j, -1, su1,
                                     sv1);
            }
        }
        if (t_split < tb) {
            /* second piece [t_split, tb] on the other triangle. Its own value at the split
             * too: the two planes meet on the diagonal, and either one at or below the
             * ray there is a hit at the split (a ray lying in the second plane, where the
             * first plane's value may round a hair above it, is the case this catches). */
            const double us = h->ox + t_split * h->dx - i, vs = h->oy + t_split * h->dy - j;
            const double zs = h->oz + t_split * h->dz;
            const double f_split2 = zs - hf_plane_height(h00, su2, sv2, us, vs);
            const double fb = zb - hf_plane_height(h00, su2, sv2, ub, vb);
            if (f_split2 <= h->window) {
                HF_TRY_EXACT(f_split2, t_split);
                if (f_split2 <= 0) return hf_hit_at(h, t_split, i, j, -1, su2, sv2);
            }
            if (fb <= h->window) {
                HF_TRY_EXACT(fb, t_split);
                if (fb <= 0)
                    return hf_hit_at(h, hf_linear_root(t_split, tb, f_split2, fb), i, j, -1, su2,
                                     sv2);
            }
        }
        return 0;
    }
    default: { /* HF_BILINEAR: s = h00 + a u + b v + c u v, quadratic along the ray */
        const hf_bilinear q = hf_bilinear_of(h00, h10, h01, h11);
        const double fa = za - hf_bilinear_height(h00, &q, ua, va);
        const double qa = -q.c * h->dx * h->dy;
        const double qb = h->dz - q.a * h->dx - q.b * h->dy - q.c * (ua * h->dy + va * h->dx);
        double tau, t, u, v;
        if (fa <= 0) { return hf_hit_at(h, ta, i, j, wall, q.a + q.c * va, q.b + q.c * ua); }
        tau = hf_quadratic_first(qa, qb, fa, tb - ta);
        if (tau < 0) {
            /* the range's closed end t1 at or below the surface: on a hair-thin interval
             * (the z clip's) the local polynomial may round it a hair above; the direct
             * gap decides there, as the brute force's does */
            if (tb >= h->t1 && zb <= hf_bilinear_height(h00, &q, ub, vb))
                return hf_hit_at(h, tb, i, j, -1, q.a + q.c * vb, q.b + q.c * ub);
            return 0;
        }
        t = ta + tau;
        u = h->ox + t * h->dx - i;
        v = h->oy + t * h->dy - j;
        return hf_hit_at(h, t, i, j, -1, q.a + q.c * v, q.b + q.c * u);
    }
    }
}

/* A hit in a cell whose float interval is a sliver (a few units of rounding long): a float
 * walk passes through a side cell where the ray crosses a grid vertex exactly at a
 * parameter that is not a float, and the cell entered there is the diagonal one. Such a
 * cell is not visited (exact_cell.h, hf_exact_visits): its hit is dropped. Checked only on
 * hits, once per ray. */
HF_COLD int hf_sliver_hit(hf_hit *h, int32_t i, int32_t j, double ta, double tb) {
    hf_exact_cell c;
    hf_exact_cell_of(h, i, j, ta, tb, tb, &c);
    if (hf_exact_visits(&c) != 0) return 1;
    h->found = 0;
    return 0;
}

static inline int hf_is_sliver(const hf_hit *h, double ta, double tb) {
    return tb - ta <= 0x1p-44 * (fabs(ta) + fabs(tb)) && h->t0 < h->t1;
}

/* Test cell (i, j) on [ta, tb]; 1 on a hit (hf_surface_test_float, then hf_sliver_hit). */
static inline int hf_surface_test(hf_hit *h, int32_t i, int32_t j, double ta, double tb, int wall) {
    if (!hf_surface_test_float(h, i, j, ta, tb, wall)) return 0;
    return hf_is_sliver(h, ta, tb) ? hf_sliver_hit(h, i, j, ta, tb) : 1;
}

/* A triangles cell's test split in two (plane_maxmip, dispatch/plane.c): what depends on
 * the cell and on the 2D ray over [ta, tb] alone (the pieces, and each piece's heights at
 * its ends, hf_surface_test's very expressions) is kept in a record, which serves every
 * ray of the same 2D line over the same interval, bit for bit; hf_tri_cell_test then
 * adds what depends on the ray's z, and decides as hf_surface_test does. */
typedef struct {
    int32_t i, j;
    double ta, tb;             /* the interval the record was built on */
    double t_split;            /* where the first piece ends (tb: one piece) */
    double su1, sv1, su2, sv2; /* the slopes of the first and the second piece */
    double p1a, p1s, p2s, p2b; /* piece 1 at ta and t_split, piece 2 at t_split and tb */
} hf_tri_cell;

static inline void hf_tri_cell_build(const hf_hit *h, int32_t i, int32_t j, double ta, double tb,
                                     hf_tri_cell *c) {
    const double h00 = hf_height(h, i, j), h10 = hf_height(h, i + 1, j);
    const double h01 = hf_height(h, i, j + 1), h11 = hf_height(h, i + 1, j + 1);
    const double ua = h->ox + ta * h->dx - i, va = h->oy + ta * h->dy - j;
    const double ub = h->ox + tb * h->dx - i, vb = h->oy + tb * h->dy - j;
    double us, vs;
    hf_tri_pieces(h, h00, h10, h01, h11, ta, tb, ua, va, ub, vb, &c->su1, &c->sv1, &c->su2, &c->sv2,
                  &c->t_split);
    us = h->ox + c->t_split * h->dx - i;
    vs = h->oy + c->t_split * h->dy - j;
    c->i = i;
    c->j = j;
    c->ta = ta;
    c->tb = tb;
    c->p1a = hf_plane_height(h00, c->su1, c->sv1, ua, va);
    c->p1s = hf_plane_height(h00, c->su1, c->sv1, us, vs);
    c->p2s = hf_plane_height(h00, c->su2, c->sv2, us, vs);
    c->p2b = hf_plane_height(h00, c->su2, c->sv2, ub, vb);
}

/* hf_surface_test's triangles case on the record's cell and interval [ta, tb] (the
 * record's own, bit for bit), `wall` as there. Returns 1 on a hit. */
static inline int hf_tri_cell_test_float(hf_hit *h, const hf_tri_cell *c, int wall) {
    const double ta = c->ta, tb = c->tb, t_split = c->t_split;
    const double za = h->oz + ta * h->dz, zb = h->oz + tb * h->dz, zs = h->oz + t_split * h->dz;
    const double fa = za - c->p1a;
    double f_split;
    const int32_t i = c->i, j = c->j;
    h->cells_tested += 1;
    if (hf_one_point_cell(h, ta, tb)) return 0;
    if (fa <= h->window) {
        HF_TRY_EXACT(fa, t_split);
        if (fa <= 0) return hf_hit_at(h, ta, i, j, wall, c->su1, c->sv1);
    }
    f_split = zs - c->p1s;
    if (f_split <= h->window) {
        HF_TRY_EXACT(f_split, t_split);
        if (f_split <= 0)
            return hf_hit_at(h, hf_linear_root(ta, t_split, fa, f_split), i, j, -1, c->su1, c->sv1);
    }
    if (t_split < tb) {
        const double f_split2 = zs - c->p2s, fb = zb - c->p2b;
        if (f_split2 <= h->window) {
            HF_TRY_EXACT(f_split2, t_split);
            if (f_split2 <= 0) return hf_hit_at(h, t_split, i, j, -1, c->su2, c->sv2);
        }
        if (fb <= h->window) {
            HF_TRY_EXACT(fb, t_split);
            if (fb <= 0)
                return hf_hit_at(h, hf_linear_root(t_split, tb, f_split2, fb), i, j, -1, c->su2,
                                 c->sv2);
        }
    }
    return 0;
}

static inline int hf_tri_cell_test(hf_hit *h, const hf_tri_cell *c, int wall) {
    if (!hf_tri_cell_test_float(h, c, wall)) return 0;
    return hf_is_sliver(h, c->ta, c->tb) ? hf_sliver_hit(h, c->i, c->j, c->ta, c->tb) : 1;
}

/* Slab clipping, the one step every interval of the ray is built from (the field's box,
 * a cell, a run): a and b are the ray's parameters at the slab's two faces, in either
 * order; [*lo, *hi] narrows to the slab, and *axis becomes face_axis when the slab's
 * entry face raises *lo. A NaN face parameter narrows nothing. */
HF_HOT void hf_slab_clip(double a, double b, int face_axis, double *lo, double *hi, int *axis) {
    if (a > b) {
        const double s = a;
        a = b;
        b = s;
    }
    if (a > *lo) {
        *lo = a;
        *axis = face_axis;
    }
    if (b < *hi) *hi = b;
}

/* 1 / d for a direction component d, as every face parameter (face - o) * inv uses it;
 * +inf for d = 0 (the walks test d != 0 first). Where |d| < DBL_MIN (a subnormal beside a
 * normal component), +-DBL_MAX instead of an overflowing 1 / d: a face the ray starts on is
 * then at t = 0, where 0 * inf would give NaN, which the slab clips ignore. Any other face
 * stays beyond every parameter reached in the box, unless the origin lies within 2^-500 of
 * the line 0 without lying on it. A normal d costs one predictable branch. */
static inline double hf_inverse(double d) {
    if (fabs(d) >= DBL_MIN) return 1.0 / d;
    return d == 0 ? (double)INFINITY : copysign(DBL_MAX, d);
}

/* The hair by which the box's z slab [hmin, hmax] is widened: rounding in z(t) can then
 * never push a hit that lies exactly on hmin or hmax (a flat field has both) out of the
 * interval; the widening only adds parameters that are tested exactly anyway. */
static inline double hf_box_z_margin(double hmin, double hmax) {
    return 1e-9 * (1.0 + fabs(hmin) + fabs(hmax));
}

/* The field box's z slab [zlo, zhi] (widened by the caller) on [*t0, *t1] of a ray with
 * height oz and slope dz: *axis becomes 2 when the top face raises *t0. Below zlo every
 * point of the footprint is inside the solid, so the hit lies no later than where z
 * reaches zlo, which ends the interval (at *t0 when the ray is already below). Returns 0
 * when the interval is empty. Shared by the box clip of every ray (dispatch/intersect.c)
 * and the per-ray part of a plane's clip (dispatch/plane.c), so both round alike. */
HF_HOT int hf_box_clip_z(double oz, double dz, double zlo, double zhi, double *t0, double *t1,
                         int *axis) {
    if (dz < 0) {
        const double above = (zhi - oz) / dz, below = (zlo - oz) / dz;
        if (above > *t0) {
            *t0 = above;
            *axis = 2;
        }
        if (!(*t0 <= *t1)) return 0; /* still above zhi when it leaves */
        if (below < *t1) *t1 = below > *t0 ? below : *t0;
    } else if (dz > 0) {
        const double above = (zhi - oz) / dz;
        if (above < *t1) *t1 = above;
    } else if (oz > zhi) {
        return 0;
    }
    return *t0 <= *t1;
}

/* The parameter interval of the ray over cell (i, j), clipped to [t0, t1]; returns the
 * axis of the grid line crossed at ta (0, 1), or -1 when ta is t0 (then the box entry
 * face, if any, is h->entry_axis). Empty when *ta > *tb. */
static inline int hf_cell_interval(const hf_hit *h, int32_t i, int32_t j, double *ta, double *tb) {
    double lo = h->t0, hi = h->t1;
    int axis = -1;
    if (h->dx != 0)
        hf_slab_clip((i - h->ox) * h->inv_dx, (i + 1 - h->ox) * h->inv_dx, 0, &lo, &hi, &axis);
    if (h->dy != 0)
        hf_slab_clip((j - h->oy) * h->inv_dy, (j + 1 - h->oy) * h->inv_dy, 1, &lo, &hi, &axis);
    *ta = lo;
    *tb = hi;
    return axis;
}

/* A ray lying exactly on a grid line (dx = 0 at integer x, or dy = 0 at integer y) of a
 * surface that jumps at cell borders (flat, plane3). By the conventions' border rule it
 * reads only the cells that the half-open rule gives (for a zero component, the cell on
 * the + side): a taller neighbour that it touches along the line is not hit. Such a ray
 * takes the general per-cell path: the tight path's slab bound would multiply a zero
 * offset by an infinite inverse direction, and the hierarchies walk their base kernel. */
static inline int hf_on_grid_line(const hf_hit *h) {
    return (h->surface == HF_FLAT || h->surface == HF_PLANE3) &&
           ((h->dx == 0 && h->ox == floor(h->ox)) || (h->dy == 0 && h->oy == floor(h->oy)));
}

/* ---- the tight path -----------------------------------------------------------------
 * The exact per-cell test works on [t0, t1] intersected with the cell's x and y slabs
 * (hf_cell_interval), and culls when min(z(ta), z(tb)) > cellmax. One axis's slab alone is
 * wider, so z over it reaches at least as low: its parameter at the low-z end of cell k is
 * ((k + off) - o) * inv, the exact interval's own expression, clamped to [t0, t1]. Rounding
 * is monotone, so a cell this bound rejects the exact cull rejects too (outputs stay
 * bit-identical). A subtract, a multiply, a clamp and a multiply-add per cell. */
/* The window of hf_hit's `window`: a gap z - s computed in float64 at a cell's event point
 * (surfaces/exact_cell.h) is within it of the exact gap at the exact event, so a gap
 * outside it has the exact sign. The rounding of the gap scales with M = |oz| + T |dz| +
 * Hm + 2 Hm X + X |dz| / (|dx| + |dy|) (taken as X |dz| min(|1/dx|, |1/dy|), no smaller),
 * X = |ox| + |oy| + T (|dx| + |dy|) + cols + rows + 2,
 * T = max |t| over [t0, t1], Hm the largest |height|: the ray's z, the surface's terms
 * (slopes up to 2 Hm times coordinates up to X), and the diagonal crossing's parameter,
 * whose error X u / |dx - dy| moves z by |dz| times as much. The window is 2^-36 M, at
 * least 2^10 times the few units of rounding (u = 2^-53) these expressions carry once
 * |dx - dy| >= 2^-12 (|dx| + |dy|). A triangles ray nearer the diagonal's direction gets an
 * unbounded window (every gap is decided exactly); a ray whose M is not finite gets none
 * (float64 decides, as before). */
/* The terms of M that come from the ray's 2D line alone, apart: the rays of a plane share
 * them (dispatch/plane.c), and each ray adds its own. */
typedef struct {
    double o_sum; /* |ox| + |oy| */
    double d_sum; /* |dx| + |dy| */
    double slope; /* min(|1 / dx|, |1 / dy|) >= 1 / (|dx| + |dy|) */
} hf_line_bound;

static inline void hf_line_bound_of(const hf_hit *h, hf_line_bound *l) {
    l->o_sum = fabs(h->ox) + fabs(h->oy);
    l->d_sum = fabs(h->dx) + fabs(h->dy);
    l->slope = fabs(h->inv_dx) < fabs(h->inv_dy) ? fabs(h->inv_dx) : fabs(h->inv_dy);
}

/* 2^-36 M of the ray in h on its line l, or 0 where M is not finite. The range is never
 * reversed (t0 <= t1: the clips return no other), so T = max(|t0|, |t1|) is max(t1, -t0),
 * the same value (a zero's sign aside, which the sums below drop). */
static inline double hf_hit_rounding(const hf_hit *h, const hf_line_bound *l) {
    const double t = h->t1 > -h->t0 ? h->t1 : -h->t0, adz = fabs(h->dz);
    const double x = l->o_sum + t * l->d_sum + h->grid_span;
    const double m =
        (fabs(h->oz) + t * adz + h->habs + x * (2 * h->habs + adz * l->slope)) * 0x1p-36;
    return m < (double)INFINITY ? m : 0;
}

/* The window and the culls' z (hf_hit's window and oz_cull) from the rounding bound. */
static inline void hf_hit_window(hf_hit *h, const hf_line_bound *l) {
    const double m = hf_hit_rounding(h, l);
    h->window = m;
    h->oz_cull = h->oz - m;
    if (h->surface == HF_TRIANGLES) {
        /* behind a jump: as a flag selected for every ray it cost 8 instructions more */
        const double w = fabs(h->dx - h->dy);
        if (w < 0x1p-12 * l->d_sum && w != 0) h->window = DBL_MAX;
    }
}

static inline void hf_hit_prepare(hf_hit *h) {
    const int descending = h->dz < 0;
    hf_line_bound line;
    int k;
    h->o_axis[0] = h->ox;
    h->o_axis[1] = h->oy;
    h->inv_axis[0] = h->inv_dx;
    h->inv_axis[1] = h->inv_dy;
    for (k = 0; k < 2; ++k) {
        const double d = k == 0 ? h->dx : h->dy;
        h->bound_off[k] = descending == (d > 0);
    }
    /* descending: the exit face, clamped to t1; else the entry face, clamped to t0 */
    h->bound_lo = descending ? -(double)INFINITY : h->t0;
    h->bound_hi = descending ? h->t1 : (double)INFINITY;
    h->fast = h->cull_cells && !hf_on_grid_line(h) && (h->dx != 0 || h->dy != 0);
    h->fast_runs = h->fast && descending;
    h->cell_axis = fabs(h->dx) >= fabs(h->dy) ? 0 : 1;
    hf_line_bound_of(h, &line);
    hf_hit_window(h, &line);
}

/* z at the low-end face of slab k along `axis`, unclamped; with the floor z(t1) or z(t0)
 * it bounds z over the cell: max(z(T), z(t_end)) is z(clamp(T)) for monotone z. */
static inline double hf_axis_zlow_unclamped(const hf_hit *h, int axis, int32_t k) {
    const double t = ((double)(k + h->bound_off[axis]) - h->o_axis[axis]) * h->inv_axis[axis];
    return h->oz_cull + t * h->dz;
}

/* The lowest z the exact test can see in a cell whose index along `axis` is k. */
static inline double hf_axis_zlow(const hf_hit *h, int axis, int32_t k) {
    double t = ((double)(k + h->bound_off[axis]) - h->o_axis[axis]) * h->inv_axis[axis];
    t = t > h->bound_lo ? t : h->bound_lo;
    t = t < h->bound_hi ? t : h->bound_hi;
    return h->oz_cull + t * h->dz;
}

static inline float hf_cellmax(const hf_hit *h, int32_t i, int32_t j) {
    return h->cellmax[(int64_t)j * (h->cols - 1) + i];
}

/* ---- the bound carried by a walk ------------------------------------------------------
 * A walk keeps z at the low end of each axis's current slab in locals and adds a constant
 * per step: z[a] for index k is z(T), T = ((k + off) - o) * inv, and a step adds dz |inv|.
 * `margin` bounds the sum's rounding drift over the longest walk (and the direct
 * expression's own error) and is subtracted from every value, so the carried bound is never
 * above hf_axis_zlow's: the cull stays conservative, the outputs bit-identical. The margin
 * is about 1e-12 of the z range on a 1024^2 grid. */
typedef struct {
    const float *cellmax;
    int64_t stride;
    double z[2];    /* bound for the current index along x and y (-inf: no slab)   */
    double step[2]; /* dz |inv| per step, 0 for an axis the ray does not cross     */
    double zfloor;  /* z at t1 (descending) or t0, minus the margin                */
    double margin;
    int64_t cell;         /* offset of the current cell's maximum in cellmax              */
    int64_t cell_step[2]; /* its change per step along x and y                      */
    int32_t k[2];         /* the current index along x and y                             */
    int32_t sign[2];      /* the direction of travel along x and y                       */
    int fast;             /* the bound applies (else every cell takes hf_hit_cell)        */
    int64_t visited;      /* cells that went through the bound                          */
} hf_cull;

/* The bound of index k along axis a, directly (for a start, or a jump). */
static inline double hf_cull_direct(const hf_hit *h, const hf_cull *c, int a, int32_t k) {
    return hf_axis_zlow_unclamped(h, a, k) - c->margin;
}

static inline void hf_cull_init(hf_cull *c, const hf_hit *h, int32_t i, int32_t j, int runs) {
    const double n = (double)h->cols + (double)h->rows + 16.0;
    double span = fabs(h->t0) > fabs(h->t1) ? fabs(h->t0) : fabs(h->t1);
    int a;
    c->fast = runs ? h->fast_runs : h->fast;
    c->visited = 0;
    c->cellmax = h->cellmax;
    c->stride = h->cols - 1;
    for (a = 0; a < 2; ++a)
        if (h->inv_axis[a] != (double)INFINITY) span += 2.0 * fabs(h->inv_axis[a]);
    /* |z| along the walk <= |oz| + |dz| span; each of <= n steps and the direct
     * expression add at most a few units of 2^-53 of that */
    c->margin = (fabs(h->oz) + fabs(h->dz) * span + 1.0) * n * 0x1p-46;
    if (!(c->margin < (double)INFINITY)) c->fast = 0;
    c->k[0] = i;
    c->k[1] = j;
    c->cell = (int64_t)j * c->stride + i;
    for (a = 0; a < 2; ++a) {
        const double d = a == 0 ? h->dx : h->dy;
        c->sign[a] = d > 0 ? 1 : -1;
        c->cell_step[a] = a == 0 ? c->sign[a] : c->sign[a] * c->stride;
        if (d != 0 && h->inv_axis[a] != (double)INFINITY) {
            c->step[a] = h->dz * fabs(h->inv_axis[a]);
            c->z[a] = hf_cull_direct(h, c, a, a == 0 ? i : j);
        } else {
            c->step[a] = 0;
            c->z[a] = -(double)INFINITY;
        }
    }
    c->zfloor = h->oz_cull + (h->dz < 0 ? h->t1 : h->t0) * h->dz - c->margin;
    if (!c->fast) {
        /* no bound: every cell goes on to the general path */
        c->z[0] = c->z[1] = c->zfloor = -(double)INFINITY;
        c->step[0] = c->step[1] = 0;
    }
}

/* One step along axis a in the travel direction. */
static inline void hf_cull_step(hf_cull *c, int a) {
    c->k[a] += c->sign[a];
    c->z[a] += c->step[a];
    c->cell += c->cell_step[a];
}

/* Move axis a to index k: one step, or a direct start (never a long sum). */
static inline void hf_cull_goto(hf_cull *c, const hf_hit *h, int a, int32_t k) {
    if (k == c->k[a]) return;
    if (k == c->k[a] + c->sign[a]) {
        hf_cull_step(c, a);
        return;
    }
    c->k[a] = k;
    c->cell = (int64_t)c->k[1] * c->stride + c->k[0];
    if (c->step[a] != 0 || c->z[a] != -(double)INFINITY) c->z[a] = hf_cull_direct(h, c, a, k);
}

/* The bound of the current cell: z over it is at least this. */
static inline double hf_cull_zlow(const hf_cull *c) {
    const double z = c->z[0] > c->z[1] ? c->z[0] : c->z[1];
    return z > c->zfloor ? z : c->zfloor;
}

static inline int hf_hit_cell_open(const hf_hit *h, int32_t i, int32_t j, int culled,
                                   double *ta_out, double *tb_out, int *wall_out);

/* One visited cell: the exact interval, cull, then test. Returns 1 on a hit. `culled`:
 * the caller has already made this very cull (z at the interval's low-z end against the
 * cell's maximum, the same expressions: a descending ray's floor walk, maxmip.h), so it is
 * not made twice. */
static inline int hf_hit_cell_exact_culled(hf_hit *h, int32_t i, int32_t j, int culled) {
    double ta, tb;
    int wall;
    if (!hf_hit_cell_open(h, i, j, culled, &ta, &tb, &wall)) return 0;
    return hf_surface_test(h, i, j, ta, tb, wall);
}

/* hf_hit_cell_exact_culled up to its surface test: the exact interval [*ta, *tb], the wall
 * and the cull. Returns 1 when the surface must be tested there, 0 when the cell is
 * rejected. */
static inline int hf_hit_cell_open(const hf_hit *h, int32_t i, int32_t j, int culled,
                                   double *ta_out, double *tb_out, int *wall_out) {
    double ta, tb;
    const int axis = hf_cell_interval(h, i, j, &ta, &tb);
    int wall;
    if (!(ta <= tb)) return 0; /* the float ray misses this cell of the rounded walk */
    /* Walls: at t0 the box's side faces (every surface); inside the grid the cell borders,
     * where flat and plane3 jump. Entering below a continuous surface (triangles,
     * bilinear) at a border can only be rounding, and gets the surface's normal. */
    if (ta == h->t0)
        wall = (h->entry_axis == 0 || h->entry_axis == 1) ? h->entry_axis : -1;
    else
        wall = (h->surface == HF_FLAT || h->surface == HF_PLANE3) ? axis : -1;
    if (h->cull_cells && !culled) {
        /* the ray's lowest z over the cell is above every corner: no hit */
        const double za = h->oz_cull + ta * h->dz, zb = h->oz_cull + tb * h->dz;
        if ((za < zb ? za : zb) > (double)h->cellmax[(int64_t)j * (h->cols - 1) + i]) return 0;
    }
    *ta_out = ta;
    *tb_out = tb;
    *wall_out = wall;
    return 1;
}

static inline int hf_hit_cell_exact(hf_hit *h, int32_t i, int32_t j) {
    return hf_hit_cell_exact_culled(h, i, j, 0);
}

/* One visited cell of a cell kernel: the cheap bound first (along the axis that crosses
 * the ray travels fastest), then the exact path. */
static inline int hf_hit_cell_uncounted(hf_hit *h, int32_t i, int32_t j) {
    if (h->fast) {
        const int axis = h->cell_axis;
        if (hf_axis_zlow(h, axis, axis == 0 ? i : j) > (double)hf_cellmax(h, i, j)) return 0;
    }
    return hf_hit_cell_exact(h, i, j);
}

static inline int hf_hit_cell(hf_hit *h, int32_t i, int32_t j) {
    h->cells_visited += 1;
    return hf_hit_cell_uncounted(h, i, j);
}

#endif
