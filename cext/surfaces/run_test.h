/* First hits of the run kernels (docs/CONVENTIONS.md, HF_MODE_HIT): a run's span, its
 * cull by the range maxima of its line (rmq.h), and its cells' tests (cell_test.h). */
#ifndef HFTRACE_RUN_TEST_H
#define HFTRACE_RUN_TEST_H

#include <stdint.h>
#include "surfaces/cell_test.h"
#include "surfaces/rmq.h"

/* ---- runs ------------------------------------------------------------------------------
 * The parameter interval of a run: its minor strip and its span of major cells, within
 * [t0, t1]; entry_axis: the axis whose face sets ta (-1: t0). Empty when ta > tb. */
typedef struct {
    double ta, tb;
    int entry_axis;
} hf_span;

static inline hf_span hf_run_span(const hf_hit *h, int major_is_x, int32_t minor, int32_t lo,
                                  int32_t hi) {
    const double o_min = major_is_x ? h->oy : h->ox, inv_min = major_is_x ? h->inv_dy : h->inv_dx;
    const double o_maj = major_is_x ? h->ox : h->oy, inv_maj = major_is_x ? h->inv_dx : h->inv_dy;
    const double d_min = major_is_x ? h->dy : h->dx;
    hf_span s;
    s.ta = h->t0;
    s.tb = h->t1;
    s.entry_axis = -1;
    /* the x slab first, as hf_cell_interval: where both faces start the span (a vertex),
     * the wall met there is the x face's, for every kernel */
    if (major_is_x)
        hf_slab_clip((lo - o_maj) * inv_maj, (hi + 1 - o_maj) * inv_maj, 0, &s.ta, &s.tb,
                     &s.entry_axis);
    if (d_min != 0)
        hf_slab_clip((minor - o_min) * inv_min, (minor + 1 - o_min) * inv_min, major_is_x ? 1 : 0,
                     &s.ta, &s.tb, &s.entry_axis);
    if (!major_is_x)
        hf_slab_clip((lo - o_maj) * inv_maj, (hi + 1 - o_maj) * inv_maj, 1, &s.ta, &s.tb,
                     &s.entry_axis);
    return s;
}

/* Cell k of a run whose first cell is `first`, on the run's span: the cell's interval
 * runs from the previous cell's exit (or the span's start) to its own exit, each clipped
 * to the span; then the exact cull and the surface test. Cells are not split where the
 * minor strip ends: the span's tb covers that. */
static inline int hf_run_cell(hf_hit *h, int major_is_x, int32_t minor, int32_t first, int32_t k,
                              const hf_span *s) {
    const double o_maj = major_is_x ? h->ox : h->oy, inv_maj = major_is_x ? h->inv_dx : h->inv_dy;
    const double d_maj = major_is_x ? h->dx : h->dy;
    const int32_t i = major_is_x ? k : minor, j = major_is_x ? minor : k;
    double ta = s->ta, t_out = (double)(d_maj > 0 ? k + 1 : k);
    int wall;
    t_out = (t_out - o_maj) * inv_maj;
    if (t_out > s->tb) t_out = s->tb;
    if (k != first) {
        /* the previous cell's exit (the latest); unclamped, so a walked cell the caller's
         * ray reaches only after leaving the strip is empty, as in hf_cell_interval */
        const double t_prev = ((double)(d_maj > 0 ? k : k + 1) - o_maj) * inv_maj;
        ta = t_prev > ta ? t_prev : ta;
    }
    if (!(ta <= t_out)) return 0;
    if (h->cull_cells) {
        const double za = h->oz_cull + ta * h->dz, zb = h->oz_cull + t_out * h->dz;
        if ((za < zb ? za : zb) > (double)hf_cellmax(h, i, j)) return 0;
    }
    /* walls: the box face at t0, else the grid line crossed at ta (for the surfaces that
     * jump there) */
    if (ta == h->t0)
        wall = (h->entry_axis == 0 || h->entry_axis == 1) ? h->entry_axis : -1;
    else if (!(h->surface == HF_FLAT || h->surface == HF_PLANE3))
        wall = -1;
    else
        wall = k == first ? s->entry_axis : (major_is_x ? 0 : 1);
    return hf_surface_test(h, i, j, ta, t_out, wall);
}

/* Below this many cells a run is culled cell by cell: the range-maximum query reads up to
 * four lines of three field-sized tables, which at r ~ 5 cost more than the cell bounds
 * they save (measured: reports/METHOD.md, "The tight first-hit path"). */
#ifndef HF_RUN_RMQ_MIN
#define HF_RUN_RMQ_MIN 16
#endif

/* One run (minor, first, last) of a run kernel, first and last in travel order: the
 * exact span, the run cull, every cell (hf_hit_run_tight is the fast path). */
static inline int hf_hit_run(hf_hit *h, int major_is_x, int32_t minor, int32_t first,
                             int32_t last) {
    const int32_t lo = first < last ? first : last, hi = first < last ? last : first;
    const int32_t step = last >= first ? 1 : -1;
    const double d_maj = major_is_x ? h->dx : h->dy;
    const hf_rmq *q = major_is_x ? h->row_max : h->col_max;
    hf_span s;
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
    s = hf_run_span(h, major_is_x, minor, lo, hi);
    if (!(s.ta <= s.tb)) {
        h->cells_visited += hi - lo + 1; /* the float ray misses the rounded walk's run */
        return 0;
    }
    if (q != NULL) {
        const double za = h->oz_cull + s.ta * h->dz, zb = h->oz_cull + s.tb * h->dz;
        if ((za < zb ? za : zb) > (double)hf_rmq_query(q, minor, lo, hi)) {
            h->runs_culled += 1;
            h->cells_visited += hi - lo + 1;
            return 0;
        }
    }
    for (k = first;; k += step) {
        h->cells_visited += 1;
        if (hf_run_cell(h, major_is_x, minor, first, k, &s)) return 1;
        if (k == last) break;
    }
    return 0;
}

/* The cold parts of the tight run path, out of line so that the hot loop inlines into
 * every run walk: the range-maximum cull of a long run (returns 1 when it rejects the run,
 * given the run's lowest z), and a cell that survived the bound (returns 1 on a
 * hit, -1 when the float ray misses the rounded walk's run, else 0). */

HF_COLD int hf_run_rmq_cull(hf_hit *h, const hf_rmq *q, int32_t minor, int32_t lo, int32_t hi,
                            double zlow) {
    if (zlow > (double)hf_rmq_query(q, minor, lo, hi)) {
        h->runs_culled += 1;
        return 1;
    }
    return 0;
}

HF_COLD int hf_run_survivor(hf_hit *h, int major_is_x, int32_t minor, int32_t first, int32_t last,
                            int32_t k, hf_span *s, int *ready) {
    if (!*ready) {
        const int32_t lo = first < last ? first : last, hi = first < last ? last : first;
        *s = hf_run_span(h, major_is_x, minor, lo, hi);
        if (!(s->ta <= s->tb)) return -1;
        *ready = 1;
    }
    return hf_run_cell(h, major_is_x, minor, first, k, s);
}

/* The tight path for a run (descending rays, cull on; c bounds along the run's major
 * axis): the run is rejected whole when z at its exit face is above the maximum over its
 * cells (a range-maximum query, for runs long enough to pay), else each cell by its own
 * exit face; the run's exact span is computed only once a cell survives. The cells that
 * reach hf_run_cell, and their intervals, are those of hf_hit_run. */
HF_HOT int hf_hit_run_tight(hf_hit *h, hf_cull *c, int major_is_x, int32_t minor, int32_t first,
                            int32_t last) {
    const int32_t step = last >= first ? 1 : -1;
    const int am = major_is_x ? 0 : 1, an = 1 - am;
    const hf_rmq *q = major_is_x ? h->row_max : h->col_max;
    const float *row = major_is_x ? c->cellmax + (int64_t)minor * c->stride : c->cellmax + minor;
    const int64_t k_stride = major_is_x ? 1 : c->stride;
    double zrun, zk, dzk;
    hf_span s;
    int ready = 0;
    int32_t k;
    h->runs_visited += 1;
    hf_cull_goto(c, h, an, minor);
    hf_cull_goto(c, h, am, first);
    zrun = c->z[an] > c->zfloor ? c->z[an] : c->zfloor;
    zk = c->z[am];
    dzk = c->step[am];
    if (q != NULL && (last - first) * step + 1 >= HF_RUN_RMQ_MIN) {
        /* z at the run's exit face: the last cell's bound, directly */
        const double zexit = hf_cull_direct(h, c, am, last);
        if (hf_run_rmq_cull(h, q, minor, first < last ? first : last, first < last ? last : first,
                            zexit > zrun ? zexit : zrun)) {
            c->visited += (int64_t)(last - first) * step + 1;
            c->k[am] = last;
            c->z[am] = zexit;
            c->cell = (int64_t)c->k[1] * c->stride + c->k[0];
            return 0;
        }
    }
    for (k = first;; k += step) {
        c->visited += 1;
        if ((zk > zrun ? zk : zrun) <= (double)row[k * k_stride]) {
            const int r = hf_run_survivor(h, major_is_x, minor, first, last, k, &s, &ready);
            if (r > 0) return 1;
            if (r < 0) {
                /* the float ray misses the rounded walk's run */
                c->visited += (int64_t)(last - k) * step;
                break;
            }
        }
        if (k == last) break;
        zk += dzk;
    }
    /* the carried bound ends on the last cell (k - first steps were summed: within the
     * margin, as for any walk) */
    c->k[am] = last;
    c->z[am] = zk;
    c->cell = (int64_t)c->k[1] * c->stride + c->k[0];
    if (k != last) c->z[am] = hf_cull_direct(h, c, am, last);
    return 0;
}

#endif
