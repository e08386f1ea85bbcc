/* First hits on a height field: the per-cell surface tests and per-run culling that the
 * traversal walks call in HF_MODE_HIT (surfaces and rules: CONVENTIONS.md).
 *
 * The traversal decides which cells are visited and in which order (each kernel its own
 * way); every surface test runs in float64 on the caller's 3D ray over the parameter
 * interval [ta, tb] in which that ray lies over the cell, clipped to [t0, t1]. The first
 * cell that reports a hit ends the walk, and cells come in order of t, so it is the first
 * hit. */
#ifndef HFTRACE_HIT_H
#define HFTRACE_HIT_H

#include <math.h>
#include <stdint.h>

enum hf_surface { HF_FLAT = 0, HF_PLANE3 = 1, HF_TRIANGLES = 2, HF_BILINEAR = 3 };

/* Range maximum over one line (a row or a column) of cell maxima, answered in O(1) once
 * the range spans two blocks of 2^block_shift cells: the suffix maximum of the first
 * block, the prefix maximum of the last, and a sparse table over the whole blocks in
 * between. Inside one block the few cells are scanned. */
typedef struct {
    int32_t n_lines, length, block_shift, n_blocks, n_levels;
    const float *values;  /* [line][length]                       */
    const float *prefix;  /* [line][length]: max from block start */
    const float *suffix;  /* [line][length]: max to block end     */
    const float *sparse;  /* [line][level][n_blocks]              */
} hf_rmq;

typedef struct {
    /* the field: heights H[j * cols + i] and cell maxima M[j * (cols-1) + i] */
    const float *heights;
    const float *cellmax;
    int32_t rows, cols;
    const hf_rmq *row_max;  /* runs along x; NULL: no run culling */
    const hf_rmq *col_max;  /* runs along y                      */
    int surface;
    int cull_cells;
    /* the ray, clipped to [t0, t1]; entry_axis: the box face it entered by at t0 (0 x,
     * 1 y, 2 z) or -1 when t0 is tmin */
    double ox, oy, oz, dx, dy, dz, inv_dx, inv_dy, t0, t1;
    int entry_axis;
    /* the result */
    int found;
    double t;
    int32_t i, j;
    int wall_axis;          /* -1: the surface; 0/1: a vertical wall facing -x/-y travel */
    double su, sv;          /* surface slope ds/du, ds/dv at the hit (for the normal)  */
    int64_t cells_visited, cells_tested, runs_visited, runs_culled, tiles_skipped;
} hf_hit;

/* ---- range maximum --------------------------------------------------------------------- */
static inline float hf_rmq_query(const hf_rmq *q, int32_t line, int32_t lo, int32_t hi) {
    const int32_t shift = q->block_shift;
    const int32_t blo = lo >> shift, bhi = hi >> shift;
    const float *values = q->values + (int64_t)line * q->length;
    float best;
    if (blo == bhi) {
        int32_t k;
        best = values[lo];
        for (k = lo + 1; k <= hi; ++k) best = values[k] > best ? values[k] : best;
        return best;
    }
    {
        const float a = q->suffix[(int64_t)line * q->length + lo];
        const float b = q->prefix[(int64_t)line * q->length + hi];
        best = a > b ? a : b;
    }
    if (bhi - blo >= 2) {
        /* whole blocks blo+1 .. bhi-1: two overlapping power-of-two windows */
        const int32_t first = blo + 1, count = bhi - blo - 1;
        int32_t level = 0;
        const float *table;
        float c, d;
        while ((2 << level) <= count) ++level;
        table = q->sparse + ((int64_t)line * q->n_levels + level) * q->n_blocks;
        c = table[first];
        d = table[bhi - (1 << level)];
        best = best > c ? best : c;
        best = best > d ? best : d;
    }
    return best;
}

/* ---- the surface of one cell ----------------------------------------------------------- */
static inline double hf_height(const hf_hit *h, int32_t i, int32_t j) {
    return (double)h->heights[(int64_t)j * h->cols + i];
}

/* Record a hit at t in cell (i, j). */
static inline int hf_hit_at(hf_hit *h, double t, int32_t i, int32_t j, int wall_axis,
                            double su, double sv) {
    h->found = 1;
    h->t = t;
    h->i = i;
    h->j = j;
    h->wall_axis = wall_axis;
    h->su = su;
    h->sv = sv;
    return 1;
}

/* f(t) = z(t) - s(x(t), y(t)) is linear on [ta, tb] with end values fa, fb (fa > 0):
 * the root, kept inside the interval. */
static inline double hf_linear_root(double ta, double tb, double fa, double fb) {
    double t = ta + (tb - ta) * (fa / (fa - fb));
    if (!(t >= ta)) t = ta;  /* also catches NaN from a degenerate interval */
    if (t > tb) t = tb;
    return t;
}

/* The smallest tau in [0, len] with a tau^2 + b tau + c <= 0, given c > 0; -1 if none.
 * Robust where the quadratic degenerates to a linear one and near double roots, and a
 * sign change the closed forms lose to rounding (a root an ulp past the end) is found by
 * bisection. */
static inline double hf_quadratic_first(double a, double b, double c, double len) {
    const double scale = fabs(b) * fabs(b) + 4.0 * fabs(a * c);
    const double slack = 1e-12 * (len > 1 ? len : 1);
    double best = -1.0;
    int k;
    if (fabs(a) * len <= 1e-14 * (fabs(b) + fabs(c) / (len > 0 ? len : 1.0))) {
        /* effectively linear: b tau + c */
        if (b < 0) {
            const double t = -c / b;
            if (t <= len + slack) best = t < len ? t : len;
        }
    } else {
        double disc = b * b - 4.0 * a * c, roots[2];
        int n = 0;
        /* a tangent touch: a discriminant lost in rounding counts as a double root */
        if (disc < 0 && disc > -1e-12 * scale) disc = 0;
        if (disc >= 0) {
            /* the stable pair of formulas: no cancellation between b and sqrt(disc) */
            const double q = -0.5 * (b + (b >= 0 ? sqrt(disc) : -sqrt(disc)));
            if (q != 0) roots[n++] = c / q;
            roots[n++] = q / a;
        }
        for (k = 0; k < n; ++k) {
            const double t = roots[k];
            if (t >= -slack && t <= len + slack) {
                const double tc = t < 0 ? 0 : (t > len ? len : t);
                if (best < 0 || tc < best) best = tc;
            }
        }
    }
    if (best < 0 && (a * len + b) * len + c <= 0) {
        /* the end is at or below the surface but no root was found: bisect the change */
        double lo = 0, hi = len;
        for (k = 0; k < 200; ++k) {
            const double mid = 0.5 * (lo + hi);
            if (mid <= lo || mid >= hi) break;
            if ((a * mid + b) * mid + c <= 0) hi = mid; else lo = mid;
        }
        best = hi;
    }
    return best;
}

/* Test cell (i, j) on [ta, tb]. `wall` is the axis of the vertical wall the ray meets
 * at ta if it is already below the surface there (0 x, 1 y), or -1 when that is not a
 * wall (a start inside the solid). Returns 1 on a hit. */
static inline int hf_surface_test(hf_hit *h, int32_t i, int32_t j, double ta, double tb,
                                  int wall) {
    const double h00 = hf_height(h, i, j), h10 = hf_height(h, i + 1, j);
    const double h01 = hf_height(h, i, j + 1), h11 = hf_height(h, i + 1, j + 1);
    const double ua = h->ox + ta * h->dx - i, va = h->oy + ta * h->dy - j;
    const double ub = h->ox + tb * h->dx - i, vb = h->oy + tb * h->dy - j;
    const double za = h->oz + ta * h->dz, zb = h->oz + tb * h->dz;
    h->cells_tested += 1;
    switch (h->surface) {
    case HF_FLAT: {
        const double c = (h00 + h10 + h01 + h11) / 4.0;
        if (za <= c) return hf_hit_at(h, ta, i, j, wall, 0, 0);
        if (zb <= c) return hf_hit_at(h, hf_linear_root(ta, tb, za - c, zb - c), i, j, -1, 0, 0);
        return 0;
    }
    case HF_PLANE3: {
        const double a = h10 - h00, b = h01 - h00;
        const double fa = za - (h00 + a * ua + b * va);
        const double fb = zb - (h00 + a * ub + b * vb);
        if (fa <= 0) return hf_hit_at(h, ta, i, j, wall, a, b);
        if (fb <= 0) return hf_hit_at(h, hf_linear_root(ta, tb, fa, fb), i, j, -1, a, b);
        return 0;
    }
    case HF_TRIANGLES: {
        /* lower triangle u >= v: s = h00 + (h10-h00) u + (h11-h10) v
         * upper triangle u <  v: s = h00 + (h11-h01) u + (h01-h00) v */
        const double la = h10 - h00, lb = h11 - h10, ua_ = h11 - h01, ub_ = h01 - h00;
        double t_split = tb, f_split, fa;
        int lower_first = (ua - va) > 0 || ((ua - va) == 0 && (ub - vb) >= 0);
        const double w = (h->dx - h->dy);
        /* where the ray crosses the diagonal u = v inside (ta, tb) */
        if (w != 0) {
            const double ts = ta - (ua - va) / w;
            if (ts > ta && ts < tb) t_split = ts;
        }
        if (lower_first) fa = za - (h00 + la * ua + lb * va);
        else fa = za - (h00 + ua_ * ua + ub_ * va);
        if (fa <= 0) {
            return lower_first ? hf_hit_at(h, ta, i, j, wall, la, lb)
                               : hf_hit_at(h, ta, i, j, wall, ua_, ub_);
        }
        {
            /* first piece [ta, t_split] on the first triangle; one shared value at the
             * split so the diagonal is watertight */
            const double us = h->ox + t_split * h->dx - i, vs = h->oy + t_split * h->dy - j;
            const double zs = h->oz + t_split * h->dz;
            f_split = lower_first ? zs - (h00 + la * us + lb * vs) : zs - (h00 + ua_ * us + ub_ * vs);
            if (f_split <= 0) {
                const double t = hf_linear_root(ta, t_split, fa, f_split);
                return lower_first ? hf_hit_at(h, t, i, j, -1, la, lb)
                                   : hf_hit_at(h, t, i, j, -1, ua_, ub_);
            }
        }
        if (t_split < tb) {
            /* second piece [t_split, tb] on the other triangle. Its own value at the split
             * too: the two planes meet on the diagonal, and either one at or below the
             * ray there is a hit at the split (a ray lying in the second plane, where the
             * first plane's value may round a hair above it, is the case this catches). */
            const double us = h->ox + t_split * h->dx - i, vs = h->oy + t_split * h->dy - j;
            const double zs = h->oz + t_split * h->dz;
            const double f_split2 = lower_first ? zs - (h00 + ua_ * us + ub_ * vs)
                                                : zs - (h00 + la * us + lb * vs);
            const double fb = lower_first ? zb - (h00 + ua_ * ub + ub_ * vb)
                                          : zb - (h00 + la * ub + lb * vb);
            if (f_split2 <= 0) {
                return lower_first ? hf_hit_at(h, t_split, i, j, -1, ua_, ub_)
                                   : hf_hit_at(h, t_split, i, j, -1, la, lb);
            }
            if (fb <= 0) {
                const double t = hf_linear_root(t_split, tb, f_split2, fb);
                return lower_first ? hf_hit_at(h, t, i, j, -1, ua_, ub_)
                                   : hf_hit_at(h, t, i, j, -1, la, lb);
            }
        }
        return 0;
    }
    default: { /* HF_BILINEAR: s = h00 + a u + b v + c u v, quadratic along the ray */
        const double a = h10 - h00, b = h01 - h00, c = h00 - h10 - h01 + h11;
        const double fa = za - (h00 + a * ua + b * va + c * ua * va);
        const double qa = -c * h->dx * h->dy;
        const double qb = h->dz - a * h->dx - b * h->dy - c * (ua * h->dy + va * h->dx);
        double tau, t, u, v;
        if (fa <= 0) {
            return hf_hit_at(h, ta, i, j, wall, a + c * va, b + c * ua);
        }
        tau = hf_quadratic_first(qa, qb, fa, tb - ta);
        if (tau < 0) return 0;
        t = ta + tau;
        u = h->ox + t * h->dx - i;
        v = h->oy + t * h->dy - j;
        return hf_hit_at(h, t, i, j, -1, a + c * v, b + c * u);
    }
    }
}

/* The parameter interval of the ray over cell (i, j), clipped to [t0, t1]; returns the
 * axis of the grid line crossed at ta (0, 1), or -1 when ta is t0 (then the box entry
 * face, if any, is h->entry_axis). Empty when *ta > *tb. */
static inline int hf_cell_interval(const hf_hit *h, int32_t i, int32_t j, double *ta, double *tb) {
    double lo = h->t0, hi = h->t1;
    int axis = -1;
    if (h->dx != 0) {
        double a = (i - h->ox) * h->inv_dx, b = (i + 1 - h->ox) * h->inv_dx;
        if (a > b) { const double s = a; a = b; b = s; }
        if (a > lo) { lo = a; axis = 0; }
        if (b < hi) hi = b;
    }
    if (h->dy != 0) {
        double a = (j - h->oy) * h->inv_dy, b = (j + 1 - h->oy) * h->inv_dy;
        if (a > b) { const double s = a; a = b; b = s; }
        if (a > lo) { lo = a; axis = 1; }
        if (b < hi) hi = b;
    }
    *ta = lo;
    *tb = hi;
    return axis;
}

/* A ray lying exactly on an interior grid line (dx = 0 at integer x, or dy = 0 at integer
 * y) touches the closed footprints of the cells on both sides. Where the surface jumps
 * there (flat, plane3) the solid is their union, so every such cell is tested on the same
 * interval and the earliest hit wins. */
static inline int hf_on_grid_line(const hf_hit *h) {
    return (h->surface == HF_FLAT || h->surface == HF_PLANE3) &&
           ((h->dx == 0 && h->ox == floor(h->ox)) || (h->dy == 0 && h->oy == floor(h->oy)));
}

static inline int hf_test_line_neighbours(hf_hit *h, int32_t i, int32_t j, double ta,
                                          double tb, int wall) {
    const int x_line = h->dx == 0 && h->ox == (double)i && i > 0;
    const int y_line = h->dy == 0 && h->oy == (double)j && j > 0;
    hf_hit best = *h, trial;
    int k;
    for (k = 0; k < 4; ++k) {
        const int32_t ci = i - (k & 1), cj = j - (k >> 1);
        if (((k & 1) && !x_line) || ((k >> 1) && !y_line)) continue;
        trial = *h;
        if (hf_surface_test(&trial, ci, cj, ta, tb, wall) && (!best.found || trial.t < best.t)) {
            best = trial;
        }
        h->cells_tested = trial.cells_tested;
        best.cells_tested = trial.cells_tested;
    }
    *h = best;
    return h->found;
}

/* One visited cell: cull, then test. Returns 1 on a hit. */
static inline int hf_hit_cell(hf_hit *h, int32_t i, int32_t j) {
    double ta, tb;
    const int axis = hf_cell_interval(h, i, j, &ta, &tb);
    int wall;
    h->cells_visited += 1;
    if (!(ta <= tb)) return 0;  /* the float ray misses this cell of the rounded walk */
    /* Walls: at t0 the box's side faces (every surface); inside the grid the cell borders,
     * where flat and plane3 jump. Entering below a continuous surface (triangles,
     * bilinear) at a border can only be rounding, and gets the surface's normal. */
    if (ta == h->t0) wall = (h->entry_axis == 0 || h->entry_axis == 1) ? h->entry_axis : -1;
    else wall = (h->surface == HF_FLAT || h->surface == HF_PLANE3) ? axis : -1;
    if (hf_on_grid_line(h)) return hf_test_line_neighbours(h, i, j, ta, tb, wall);
    if (h->cull_cells) {
        /* the ray's lowest z over the cell is above every corner: no hit */
        const double za = h->oz + ta * h->dz, zb = h->oz + tb * h->dz;
        if ((za < zb ? za : zb) > (double)h->cellmax[(int64_t)j * (h->cols - 1) + i]) return 0;
    }
    return hf_surface_test(h, i, j, ta, tb, wall);
}

/* One run (minor, first, last) of a run kernel: reject it whole when the ray's lowest z
 * over the run is above the maximum over the run's cells, else test its cells, each with
 * one multiply-add for its interval along the major axis. */
static inline int hf_hit_run(hf_hit *h, int major_is_x, int32_t minor, int32_t first,
                             int32_t last) {
    const int32_t lo = first < last ? first : last, hi = first < last ? last : first;
    const int32_t step = last >= first ? 1 : -1;
    const double o_min = major_is_x ? h->oy : h->ox, inv_min = major_is_x ? h->inv_dy : h->inv_dx;
    const double o_maj = major_is_x ? h->ox : h->oy, inv_maj = major_is_x ? h->inv_dx : h->inv_dy;
    const double d_min = major_is_x ? h->dy : h->dx, d_maj = major_is_x ? h->dx : h->dy;
    const int axis_maj = major_is_x ? 0 : 1, axis_min = 1 - axis_maj;
    const int jumps = h->surface == HF_FLAT || h->surface == HF_PLANE3;
    double ta_run = h->t0, tb_run = h->t1, t_in;
    int run_entry_axis = -1;
    int32_t k;
    h->runs_visited += 1;
    if (d_maj == 0 || hf_on_grid_line(h)) {
        /* vertical rays and rays on grid lines: the general per-cell path */
        for (k = first;; k += step) {
            if (major_is_x ? hf_hit_cell(h, k, minor) : hf_hit_cell(h, minor, k)) return 1;
            if (k == last) break;
        }
        return 0;
    }
    /* the run's parameter interval: its minor strip and its span of major cells */
    if (d_min != 0) {
        double a = (minor - o_min) * inv_min, b = (minor + 1 - o_min) * inv_min;
        if (a > b) { const double s = a; a = b; b = s; }
        if (a > ta_run) { ta_run = a; run_entry_axis = axis_min; }
        tb_run = b < tb_run ? b : tb_run;
    }
    {
        double a = (lo - o_maj) * inv_maj, b = (hi + 1 - o_maj) * inv_maj;
        if (a > b) { const double s = a; a = b; b = s; }
        if (a > ta_run) { ta_run = a; run_entry_axis = axis_maj; }
        tb_run = b < tb_run ? b : tb_run;
    }
    if (!(ta_run <= tb_run)) {
        h->cells_visited += hi - lo + 1;  /* the float ray misses the rounded walk's run */
        return 0;
    }
    if (h->row_max != NULL) {
        const double za = h->oz + ta_run * h->dz, zb = h->oz + tb_run * h->dz;
        const hf_rmq *q = major_is_x ? h->row_max : h->col_max;
        if ((za < zb ? za : zb) > (double)hf_rmq_query(q, minor, lo, hi)) {
            h->runs_culled += 1;
            h->cells_visited += hi - lo + 1;
            return 0;
        }
    }
    /* the cells in travel order; cell k spans major boundaries k and k + 1 */
    t_in = ta_run;
    for (k = first;; k += step) {
        const double boundary_out = d_maj > 0 ? k + 1 : k;
        double t_out = (boundary_out - o_maj) * inv_maj, ta = t_in;
        int wall;
        const int32_t i = major_is_x ? k : minor, j = major_is_x ? minor : k;
        if (t_out > tb_run) t_out = tb_run;
        h->cells_visited += 1;
        if (ta <= t_out) {
            const double za = h->oz + ta * h->dz, zb = h->oz + t_out * h->dz;
            if (!h->cull_cells ||
                (za < zb ? za : zb) <= (double)h->cellmax[(int64_t)j * (h->cols - 1) + i]) {
                /* walls: the box face at t0, else the grid line crossed at ta (for the
                 * surfaces that jump there) */
                if (ta == h->t0) wall = (h->entry_axis == 0 || h->entry_axis == 1) ? h->entry_axis : -1;
                else if (!jumps) wall = -1;
                else wall = k == first ? run_entry_axis : axis_maj;
                if (hf_surface_test(h, i, j, ta, t_out, wall)) return 1;
            }
        }
        if (k == last) break;
        t_in = t_out > t_in ? t_out : t_in;
    }
    return 0;
}

#endif
