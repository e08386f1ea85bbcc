/* First hits on a height field for every traversal, plus the ray-marching baselines and
 * the max-mipmap skipping variants.
 *
 * Every ray is first clipped to the field's box [0, cols-1] x [0, rows-1] x [hmin, hmax]
 * (the seeds' existence condition): a ray that misses it does no traversal. Below hmin
 * every point of the footprint is inside the solid, so the hit lies at or before the
 * parameter where z reaches hmin, which ends the interval. */
#include <math.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "hierarchies/compact.h"
#include "hierarchies/cone.h"
#include "hierarchies/packet.h"
#include "dispatch/plane.h"
#include "dispatch/ring.h"
#include "surfaces/hitbatch.h"
#include "walks/walk.h"
#include "hierarchies/maxmip.h"
#include "core/mipmap.h"

/* ---- clipping ----------------------------------------------------------------------- */
/* [t0, t1] of the ray inside the box; returns 0 when empty. entry_axis: the face that
 * set t0 (0 x, 1 y, 2 z) or -1 when t0 is tmin. */
static int clip_to_box(const double o[3], const double d[3], const double inv[2], double tmin,
                       double tmax, double x_max, double y_max, double hmin, double hmax,
                       double *t0_out, double *t1_out, int *entry_axis) {
    double t0 = tmin, t1 = tmax;
    int axis = -1, k;
    const double hi[2] = {x_max, y_max};
    for (k = 0; k < 2; ++k) {
        if (d[k] != 0) {
            /* the same expressions as hf_cell_interval, so a face parameter computed here
             * equals the one computed there bit for bit */
            hf_slab_clip((0 - o[k]) * inv[k], (hi[k] - o[k]) * inv[k], k, &t0, &t1, &axis);
        } else if (!(o[k] >= 0 && o[k] <= hi[k])) {
            return 0;
        }
    }
    if (!(t0 <= t1)) return 0; /* misses the footprint (or an empty [tmin, tmax]) */
    /* robust slab bounds: the z slab widened by a hair (hf_box_z_margin) */
    {
        const double margin = hf_box_z_margin(hmin, hmax);
        hmin -= margin;
        hmax += margin;
    }
    /* the z slab; at or below hmin the ray is inside the solid, which ends the interval */
    if (!hf_box_clip_z(o[2], d[2], hmin, hmax, &t0, &t1, &axis)) return 0;
    *t0_out = t0;
    *t1_out = t1;
    *entry_axis = axis;
    return 1;
}

/* ---- ray marching (approximate by design; the Hungarian lab's three variants) ---------- */
/* z - s(x, y) at one point, with the cell clamped into the grid; also its slopes. */
static double field_gap(hf_hit *h, double t, int32_t *ci, int32_t *cj, double *su, double *sv) {
    const double x = h->ox + t * h->dx, y = h->oy + t * h->dy, z = h->oz + t * h->dz;
    int32_t i = (int32_t)floor(x), j = (int32_t)floor(y);
    double u, v, h00, h10, h01, h11, s;
    if (i < 0) i = 0;
    if (i > h->cols - 2) i = h->cols - 2;
    if (j < 0) j = 0;
    if (j > h->rows - 2) j = h->rows - 2;
    u = x - i;
    v = y - j;
    h00 = hf_height(h, i, j);
    h10 = hf_height(h, i + 1, j);
    h01 = hf_height(h, i, j + 1);
    h11 = hf_height(h, i + 1, j + 1);
    switch (h->surface) {
    case HF_FLAT:
        s = hf_flat_height(h00, h10, h01, h11);
        *su = 0;
        *sv = 0;
        break;
    case HF_PLANE3:
        hf_plane3_slopes(h00, h10, h01, su, sv);
        s = hf_plane_height(h00, *su, *sv, u, v);
        break;
    case HF_TRIANGLES:
        if (u >= v)
            hf_lower_triangle_slopes(h00, h10, h11, su, sv);
        else
            hf_upper_triangle_slopes(h00, h01, h11, su, sv);
        s = hf_plane_height(h00, *su, *sv, u, v);
        break;
    default: {
        const hf_bilinear q = hf_bilinear_of(h00, h10, h01, h11);
        s = hf_bilinear_height(h00, &q, u, v);
        *su = q.a + q.c * v;
        *sv = q.b + q.c * u;
    }
    }
    *ci = i;
    *cj = j;
    return z - s;
}

static void march(hf_hit *h, const hf_hit_batch *b, int kernel) {
    const double span = h->t1 - h->t0;
    double t = h->t0, prev = h->t0, step, su, sv;
    int32_t i, j, k;
    if (field_gap(h, t, &i, &j, &su, &sv) <= 0) {
        hf_hit_at(h, t, i, j, -1, su, sv);
        return;
    }
    if (kernel == HF_HIT_MARCH_GROWING) {
        step = span * b->march_first_fraction;
        for (k = 0; k < 100000 && prev < h->t1; ++k) {
            step = step > b->march_min_step ? step : b->march_min_step;
            t = prev + step;
            if (t > h->t1) t = h->t1;
            h->cells_tested += 1;
            if (field_gap(h, t, &i, &j, &su, &sv) <= 0) {
                hf_hit_at(h, t, i, j, -1, su, sv);
                return;
            }
            prev = t;
            step *= b->march_growth;
        }
        return;
    }
    /* linear search with a fixed number of equal steps over [t0, t1] */
    step = span / b->march_steps;
    for (k = 1; k <= b->march_steps; ++k) {
        t = h->t0 + step * k;
        h->cells_tested += 1;
        if (field_gap(h, t, &i, &j, &su, &sv) <= 0) break;
        prev = t;
    }
    if (k > b->march_steps) return;
    if (kernel == HF_HIT_MARCH_BINARY) {
        /* halve the bracket [prev (outside), t (inside)] */
        double lo = prev, hi = t;
        for (k = 0; k < b->march_refinements; ++k) {
            const double mid = 0.5 * (lo + hi);
            h->cells_tested += 1;
            if (field_gap(h, mid, &i, &j, &su, &sv) <= 0)
                hi = mid;
            else
                lo = mid;
        }
        t = hi;
    }
    (void)field_gap(h, t, &i, &j, &su, &sv);
    hf_hit_at(h, t, i, j, -1, su, sv);
}

/* cone_relaxed (Policarpo & Oliveira 2007; approximate by design): from a point above the
 * surface the ray steps to the side of the relaxed cone of the cell below it (cone.c),
 * at least half a cell, until a sample lies at or below the surface; march_refinements
 * halvings then narrow the bracket. A ray that crosses a ridge and comes out again
 * within one step misses it: that is the error the accuracy study measures. */
static void march_relaxed_cone(hf_hit *h, const hf_hit_batch *b) {
    const int32_t nx = h->cols - 1;
    const double speed = sqrt(h->dx * h->dx + h->dy * h->dy);
    double t = h->t0, prev = h->t0, su, sv, gap;
    int32_t i, j, k;
    int inside = 0;
    gap = field_gap(h, t, &i, &j, &su, &sv);
    if (gap <= 0) {
        hf_hit_at(h, t, i, j, -1, su, sv);
        return;
    }
    for (k = 0; k < b->march_steps && t < h->t1; ++k) {
        const int64_t cell = (int64_t)j * nx + i;
        const double z = h->oz + t * h->dz, apex = (double)h->cellmax[cell];
        const double rate = (double)b->cone[cell] * speed - h->dz;
        /* at least half a cell (a vertical ray: down to the surface sampled here) */
        double step = speed > 0 ? 0.5 / speed : gap / -h->dz;
        if (z > apex) {
            if (!(rate > 0)) return; /* rises out of every relaxed cone: taken as a miss */
            if ((z - apex) / rate > step) step = (z - apex) / rate;
        }
        prev = t;
        t = t + step < h->t1 ? t + step : h->t1;
        h->tiles_skipped += 1;
        h->cells_tested += 1;
        gap = field_gap(h, t, &i, &j, &su, &sv);
        if (gap <= 0) {
            inside = 1;
            break;
        }
    }
    if (!inside) return;
    {
        /* halve the bracket [prev (outside), t (inside)] */
        double lo = prev, hi = t;
        for (k = 0; k < b->march_refinements; ++k) {
            const double mid = 0.5 * (lo + hi);
            h->cells_tested += 1;
            if (field_gap(h, mid, &i, &j, &su, &sv) <= 0)
                hi = mid;
            else
                lo = mid;
        }
        (void)field_gap(h, hi, &i, &j, &su, &sv);
        hf_hit_at(h, hi, i, j, -1, su, sv);
    }
}

/* ---- max-mipmap skipping (Tevs, Ihrke & Seidel 2008) ------------------------------------
 * Level 0 holds the cell maxima; level k the maxima of 2x2 blocks of level k-1 (the last
 * row/column of an odd size stands alone), so every size works. From the current cell the
 * walk tests the tile around it with the ray's lowest z over the ray's stretch inside the
 * tile, climbs one level after every skip, descends one level when a tile cannot be
 * skipped, and walks the tiles of a floor level cell by cell (dda_maxmip, below) or run
 * by run (runs_maxmip, runs.c). Cell indices are carried as integers and clamped into the
 * current tile, so rounding never stalls the walk. */
/* dda_maxmip: the walk stops descending at `floor_level`, whose 2^floor x 2^floor tiles
 * it walks cell by cell with face parameters computed directly (no drift: the exact
 * interval's own expressions); the walk itself is in maxmip.h, shared with the packet
 * kernel (packet.c). */
/* The walk of a ray moving along both axes, with its direction's signs constants (gx:
 * dx > 0, gy: dy > 0): every choice on them (the exit faces, the steps, the forward rule
 * of the next cell) folds away, and no jump on a sign that a batch of random rays mixes is
 * left in the loop. */
HF_HOT int maxmip_quadrant(hf_hit *h, const hf_hit_batch *b, const hf_mip_ray *r, hf_mip_walk *w,
                           const int gx, const int gy) {
    hf_mip_ray q = *r;
    q.fx = q.gx = gx;
    q.fy = q.gy = gy;
    q.sx = gx ? 1 : -1;
    q.sy = gy ? 1 : -1;
    return hf_mip_walk_alone(h, b, &q, w, 0);
}

#if defined(__GNUC__)
__attribute__((flatten))
#endif
static int
maxmip_tight(hf_hit *h, const hf_hit_batch *b) {
    hf_mip_ray r;
    hf_mip_walk w;
    hf_mip_setup(h, b, &r, &w);
    if (!r.has_x || !r.has_y) return hf_mip_walk_alone(h, b, &r, &w, 0);
    switch (r.fx << 1 | r.fy) {
    case 0: return maxmip_quadrant(h, b, &r, &w, 0, 0);
    case 1: return maxmip_quadrant(h, b, &r, &w, 0, 1);
    case 2: return maxmip_quadrant(h, b, &r, &w, 1, 0);
    default: return maxmip_quadrant(h, b, &r, &w, 1, 1);
    }
}

/* ---- the batch ------------------------------------------------------------------------ */
static hf_hit_walk walk_of(int kernel) {
    switch (kernel) {
    case HF_DDA: return hf_batch_dda_hit;
    case HF_DDA_F32: return hf_batch_dda_f32_hit;
    case HF_MIDPOINT: return hf_batch_midpoint_hit;
    case HF_RUNS: return hf_batch_runs_hit;
    case HF_RUNS_F64: return hf_batch_runs_f64_hit;
    case HF_RUNS_PERIODIC: return hf_batch_runs_periodic_hit;
    case HF_HIT_DDA_MAXMIP: return hf_batch_dda_hit;
    case HF_HIT_PACKET_MAXMIP: return hf_batch_dda_hit;
    case HF_HIT_RUNS_MAXMIP: return hf_batch_runs_hit;
    case HF_HIT_CONE: return hf_batch_dda_hit;
    case HF_HIT_DDA_COMPACT: return hf_batch_dda_hit;
    default: return NULL;
    }
}

/* ---- one ray of the batch, in three steps ------------------------------------------- */
/* Zero a hit record with 16-byte stores (SSE2, the x86-64 baseline): a memset of its 336
 * bytes compiles to a `rep stos`, whose start-up costs more than the stores (and which
 * callgrind counts as a branch per 8 bytes). */
static inline void zero_hit(hf_hit *h) {
#if defined(__SSE2__)
    /* 21 stores written out: a loop of them would be recognised as a memset again */
    char *p = (char *)h;
    const __m128i z = _mm_setzero_si128();
#define HF_ZERO_32(at)                          \
    _mm_storeu_si128((__m128i *)(p + (at)), z); \
    _mm_storeu_si128((__m128i *)(p + (at) + 16), z)
    HF_ZERO_32(0);
    HF_ZERO_32(32);
    HF_ZERO_32(64);
    HF_ZERO_32(96);
    HF_ZERO_32(128);
    HF_ZERO_32(160);
    HF_ZERO_32(192);
    HF_ZERO_32(224);
    HF_ZERO_32(256);
    HF_ZERO_32(288);
    _mm_storeu_si128((__m128i *)(p + 320), z);
#undef HF_ZERO_32
#else
    memset(h, 0, sizeof *h);
#endif
}
/* (C99 has no static_assert: an array of negative size fails the build) */
typedef char hf_hit_is_336_bytes[sizeof(hf_hit) == 336 ? 1 : -1];

/* A record for the rays of batch b (the steps' `start`): zeroed, with the batch's fields
 * (hf_hit_fill_batch). ray_begin then rewrites, per ray, only what depends on the ray. */
static void hit_start(const hf_hit_batch *b, hf_hit *h) {
    zero_hit(h);
    hf_hit_fill_batch(h, b);
}

/* Its set-up: clip ray `ray` to the box and fill h, a record started for b (hit_start) or
 * left by an earlier ray of b: its result and statistics are cleared and every other field
 * a walk reads is rewritten (the box's miss leaves [t0, t1] = [0, 0] and the rest unread:
 * ray_end reads nothing else). Returns 1 when there is a walk to do, 0 when the ray misses
 * the box. */
HF_HOT int ray_begin(const hf_hit_batch *b, int64_t ray, hf_hit *h, double *t0_out, double *t1_out,
                     int *entry_axis_out) {
    const double *o = b->origins + 3 * ray, *d = b->directions + 3 * ray;
    const double tmin = b->tmin ? b->tmin[ray] : 0.0;
    const double tmax = b->tmax ? b->tmax[ray] : (double)INFINITY;
    /* the inverse direction, once: the clip and every walk's face parameters use it */
    const double inv[2] = {hf_inverse(d[0]), hf_inverse(d[1])};
    double t0, t1;
    int entry_axis;
    hf_hit_clear(h);
    if (!clip_to_box(o, d, inv, tmin, tmax, b->cols - 1, b->rows - 1, b->hmin, b->hmax, &t0, &t1,
                     &entry_axis)) {
        h->t0 = h->t1 = 0;
        return 0;
    }
    hf_hit_fill_line(h, o, d, inv);
    h->oz = o[2];
    h->dz = d[2];
    h->t0 = t0;
    h->t1 = t1;
    h->tmin = tmin;
    h->tmax = tmax;
    h->entry_axis = entry_axis;
    hf_hit_prepare(h);
    *t0_out = t0;
    *t1_out = t1;
    *entry_axis_out = entry_axis;
    return 1;
}

/* The one-ray batch b2 of a base walk (walk.h) on [*lo, *hi] for ray `ray`, and its 2D
 * origin and direction o2, d2: built only for the walks that read it (runs_maxmip and the
 * base walks), not for the max-mipmap, compact and cone walks, which take h alone. */
static void ray_base_batch(int kernel, const hf_hit_batch *b, int64_t ray, hf_batch *b2,
                           double o2[2], double d2[2], double *lo, double *hi, int parallel,
                           hf_direction *direction_cache) {
    const double *o = b->origins + 3 * ray, *d = b->directions + 3 * ray;
    memset(b2, 0, sizeof *b2);
    o2[0] = o[0];
    o2[1] = o[1];
    d2[0] = d[0];
    d2[1] = d[1];
    /* A ray lying in the far box face x = cols-1 (or y = rows-1) has no half-open
     * cell there; walk the last column (row) instead. Moving the 2D walk's origin
     * by 3/4 of a lattice unit keeps it in that column even after the exact
     * kernels' rounding; the surface tests still use the caller's ray. */
    if ((kernel == HF_MIDPOINT || kernel == HF_RUNS || kernel == HF_RUNS_PERIODIC ||
         kernel == HF_HIT_RUNS_MAXMIP) &&
        (fabs(d[0]) * 0x1p29 < fabs(d[1]) || fabs(d[1]) * 0x1p29 < fabs(d[0]))) {
        /* The exact kernels walk the ray rounded onto the lattice (walks/lattice.c), where
         * a component below 2^-30 of the other (a subnormal one, or zero) becomes zero:
         * only such rays are rounded here. One on a grid line then lies on the line, and
         * reads the column its own sign gives, (k-1, k] when negative and the last column
         * on the far face, as the caller's ray does; the clip and the surface tests use
         * the caller's ray. */
        double oq[2], dq[2];
        int k;
        hf_quantize_ray(o, d, oq, dq);
        for (k = 0; k < 2; ++k)
            if (dq[k] == 0 && oq[k] == floor(oq[k]) &&
                (d[k] < 0 || oq[k] == (k ? b->rows : b->cols) - 1))
                o2[k] = oq[k] - 0.75 / HF_ONE;
    } else {
        if (d[0] == 0 && o[0] == b->cols - 1) o2[0] = o[0] - 0.75 / HF_ONE;
        if (d[1] == 0 && o[1] == b->rows - 1) o2[1] = o[1] - 0.75 / HF_ONE;
    }
    b2->n_rays = 1;
    b2->origins = o2;
    b2->directions = d2;
    b2->tmin = lo;
    b2->tmax = hi;
    b2->nx = b->cols - 1;
    b2->ny = b->rows - 1;
    if (kernel == HF_DDA_F32) {
        /* the float32 walk casts its range to float: round it outward, so a
         * hair-thin interval (a flat field) cannot collapse to nothing; the surface
         * tests still use the float64 interval */
        *lo = (double)nextafterf((float)*lo, -INFINITY);
        *hi = (double)nextafterf((float)*hi, INFINITY);
    }
    b2->max_denominator = b->max_denominator;
    b2->direction_cache = parallel ? direction_cache : NULL;
    b2->pattern = b->pattern;
}

/* Its walk with intersector `kernel` on [t0, t1]: HF_OK, or the walk's error status.
 * `compact`: the tree's geometry for dda_compact (compact.h), NULL for the others. */
HF_HOT int ray_solve(int kernel, hf_hit_batch *b, int64_t ray, hf_hit *h, double t0, double t1,
                     int entry_axis, hf_hit_walk walk, int parallel, hf_direction *direction_cache,
                     hf_pattern *pattern, const hf_compact *compact) {
    const int marching = kernel == HF_HIT_MARCH_LINEAR || kernel == HF_HIT_MARCH_GROWING ||
                         kernel == HF_HIT_MARCH_BINARY;
    const int cone = kernel == HF_HIT_CONE;
    const int relaxed = kernel == HF_HIT_CONE_RELAXED;
    if (marching) {
        march(h, b, kernel);
    } else if (relaxed) {
        march_relaxed_cone(h, b);
    } else if (t0 == t1) {
        /* a single parameter (the ray touches the box there, or is already below
         * hmin when it enters): test that point directly */
        const int32_t i = hf_cell_at(h->ox, h->dx, t0, b->cols - 1);
        const int32_t j = hf_cell_at(h->oy, h->dy, t0, b->rows - 1);
        h->cells_visited += 1;
        (void)hf_surface_test(h, i, j, t0, t0,
                              (entry_axis == 0 || entry_axis == 1) ? entry_axis : -1);
    } else if (kernel == HF_HIT_DDA_MAXMIP && !hf_on_grid_line(h)) {
        maxmip_tight(h, b);
    } else if (kernel == HF_HIT_DDA_COMPACT && !hf_on_grid_line(h)) {
        hf_compact_hit(h, compact);
    } else if (cone && !hf_on_grid_line(h)) {
        hf_cone_hit(h, b->cone);
    } else {
        hf_batch b2;
        hf_sink sink;
        double o2[2], d2[2], lo = t0, hi = t1;
        int status;
        ray_base_batch(kernel, b, ray, &b2, o2, d2, &lo, &hi, parallel, direction_cache);
        sink.hit = h;
        if (kernel == HF_HIT_RUNS_MAXMIP && !hf_on_grid_line(h)) {
            hf_mipmap m;
            m.levels = b->mip;
            m.cols = b->mip_cols;
            m.n_levels = b->mip_levels;
            m.floor_level = b->floor_level;
            status = hf_runs_maxmip_hit(&b2, &sink, &m);
        } else {
            /* (a maxmip, compact or cone kernel on a grid line, where neighbouring cells
             * matter, walks every cell with its base kernel) */
            status = walk(&b2, &sink, kernel == HF_RUNS_PERIODIC ? (void *)pattern : NULL);
        }
        if (status != HF_OK) {
            b->bad_ray = ray;
            return status;
        }
    }
    return HF_OK;
}

/* The cell that holds a point on a cell border (docs/CONVENTIONS.md, "Points on a cell
 * border"): the one the half-open rule gives for this ray's direction, which is the cell
 * entered there. Two cases need it after the walk:
 * - a hit at t that lies on the exit face of the cell it was found in (a touch where the
 *   ray leaves a triangles or bilinear cell, whose neighbour reaches the same t, or a hit
 *   at t0 on a face the ray starts on): the entered cell decides that point;
 * - no hit, and the caller's tmax ends the range inside the grid on a border: every walk
 *   stopped in the cell it leaves, which held [ta, t1] closed, and the entered cell
 *   decides p(t1).
 * The entered cell is tested at that one point (a wall there is hit): its hit, if any,
 * is the record. Otherwise the walk's record stands: on flat and plane3 the cell test
 * already left such a touch at t1 to the entered cell (hf_end_closed), and a hit
 * the cell left found exactly on its exit face is a root rounded onto it (or, on the
 * continuous surfaces, a point where the two cells' surfaces meet and rounding parts
 * them). A point on the box's far side keeps the last cell (the closed box). Returns h
 * itself, or `decided` holding the record (h is left as the walk gave it: a plane's
 * chain resumes from it). */
/* (border_point's test: the record of cell (i, j), entered at t across the wall of `axis`,
 * tested at that one point, or h when it does not reach the point) */
HF_COLD const hf_hit *border_test(const hf_hit *h, hf_hit *decided, double t, int32_t i, int32_t j,
                                  int axis) {
    *decided = *h;
    decided->found = 0;
    decided->cells_visited += 1;
    decided->t0 = decided->t1 = t; /* the one point, closed */
    return hf_surface_test(decided, i, j, t, t, axis) ? decided : h;
}

/* (border_point for a hit on its cell's exit face, or near it) */
HF_COLD const hf_hit *border_exit(const hf_hit *h, hf_hit *decided) {
    int32_t i, j;
    if (!hf_exit_into_grid(h, h->i, h->j, h->t, &i, &j)) return h;
    return border_test(h, decided, h->t, i, j, i != h->i ? 0 : 1);
}

/* (border_point for a miss whose range tmax ends) */
HF_COLD const hf_hit *border_end(const hf_hit_batch *b, int64_t ray, const hf_hit *h,
                                 hf_hit *decided) {
    const double t = h->t1;
    double x, y;
    int on_x, on_y;
    int32_t i, j;
    /* (a ray that misses the box has the range [0, 0], and its other fields are not read) */
    if (!(h->t0 < h->t1) || h->t1 != b->tmax[ray]) return h;
    x = h->ox + t * h->dx;
    y = h->oy + t * h->dy;
    /* on a grid line, exactly (beyond 2^31 the point is off the grid anyway): x = 4 in
     * float64 at t1 = 0.6666666666666666 from 2 + 3 t1, but the exact point is short of it */
    on_x = h->dx != 0 && fabs(x) < 0x1p31 && hf_exact_on_line(h->ox, h->dx, t, nearbyint(x));
    on_y = h->dy != 0 && fabs(y) < 0x1p31 && hf_exact_on_line(h->oy, h->dy, t, nearbyint(y));
    if (!on_x && !on_y) return h; /* p(t1) inside the cell the walk ended in */
    i = on_x ? (int32_t)hf_index_of(x, h->dx > 0) : hf_cell_at(h->ox, h->dx, t, b->cols - 1);
    j = on_y ? (int32_t)hf_index_of(y, h->dy > 0) : hf_cell_at(h->oy, h->dy, t, b->rows - 1);
    if (i < 0 || i > b->cols - 2 || j < 0 || j > b->rows - 2) return h; /* the box's side */
    return border_test(h, decided, t, i, j, on_x ? 0 : 1);
}

HF_HOT const hf_hit *border_point(const hf_hit_batch *b, int64_t ray, const hf_hit *h,
                                  hf_hit *decided) {
    if (h->found == 2) return h; /* decided exactly, the cell that holds it included */
    if (h->found) {
        /* one compare per axis first: almost every hit lies inside its cell */
        const double fx = (double)h->i + (h->dx > 0), fy = (double)h->j + (h->dy > 0);
        if ((h->dx != 0 && h->ox + h->t * h->dx == fx) ||
            (h->dy != 0 && h->oy + h->t * h->dy == fy))
            return border_exit(h, decided);
        return h;
    }
    return b->tmax ? border_end(b, ray, h, decided) : h;
}

/* Its outputs, each only when asked for. */
HF_HOT void ray_end(hf_hit_batch *b, int64_t ray, const hf_hit *h) {
    const double *d = b->directions + 3 * ray;
    hf_hit decided;
    h = border_point(b, ray, h, &decided);
    if (b->t) b->t[ray] = h->found ? h->t : (double)INFINITY;
    if (b->cell) {
        b->cell[2 * ray] = h->found ? h->i : -1;
        b->cell[2 * ray + 1] = h->found ? h->j : -1;
    }
    if (b->normal) {
        double *n = b->normal + 3 * ray;
        if (!h->found) {
            n[0] = n[1] = n[2] = NAN;
        } else if (h->wall_axis == 0 || h->wall_axis == 1) {
            /* a vertical wall facing the ray */
            n[0] = n[1] = n[2] = 0;
            n[h->wall_axis] = d[h->wall_axis] > 0 ? -1.0 : 1.0;
        } else {
            const double norm = sqrt(h->su * h->su + h->sv * h->sv + 1.0);
            n[0] = -h->su / norm;
            n[1] = -h->sv / norm;
            n[2] = 1.0 / norm;
        }
    }
    if (b->stats) {
        int64_t *s = b->stats + 5 * ray;
        s[0] = h->cells_visited;
        s[1] = h->cells_tested;
        s[2] = h->runs_visited;
        s[3] = h->runs_culled;
        s[4] = h->tiles_skipped;
    }
}

/* packet_maxmip: the batch in packets of b->packet_width consecutive rays (the last one
 * shorter). The rays of a packet that have a max-mipmap walk to do walk together
 * (hf_packet_maxmip, packet.c); the others take dda_maxmip's own per-ray paths (a single
 * parameter, a ray on a grid line), with its base walk. Outputs are written in ray
 * order. */
static int packet_batch(hf_hit_batch *b) {
    hf_hit hits[HF_PACKET_MAX];
    hf_pattern pattern; /* (unused by the cell walk) */
    const int width = b->packet_width;
    int64_t first;
    int k;
    if (width < 1 || width > HF_PACKET_MAX || b->mip_levels < 1) return HF_ERR_ARGUMENT;
    pattern.p = pattern.q = pattern.position_step = 0;
    pattern.lengths = b->pattern;
    b->bad_ray = -1;
    for (k = 0; k < width; ++k) hit_start(b, &hits[k]);
    for (first = 0; first < b->n_rays; first += width) {
        const int n = b->n_rays - first < width ? (int)(b->n_rays - first) : width;
        unsigned members = 0;
        for (k = 0; k < n; ++k) {
            double t0, t1;
            int entry_axis;
            if (!ray_begin(b, first + k, &hits[k], &t0, &t1, &entry_axis)) continue;
            if (t0 < t1 && !hf_on_grid_line(&hits[k])) {
                members |= 1u << k;
            } else {
                const int status = ray_solve(HF_HIT_DDA_MAXMIP, b, first + k, &hits[k], t0, t1,
                                             entry_axis, hf_batch_dda_hit, 0, NULL, &pattern, NULL);
                if (status != HF_OK) return status;
            }
        }
        if (members) hf_packet_maxmip(hits, members, b);
        for (k = 0; k < n; ++k) ray_end(b, first + k, &hits[k]);
    }
    return HF_OK;
}

/* The steps of one ray with dda_maxmip's walk, for plane_maxmip (plane.c), ring_maxmip
 * (ring.c) and pitched_maxmip (raster/pitched.c). */
static void maxmip_start(const hf_hit_batch *b, hf_hit *h) {
    hit_start(b, h);
}

static int maxmip_begin(const hf_hit_batch *b, int64_t ray, hf_hit *h, double *t0, double *t1,
                        int *entry_axis) {
    return ray_begin(b, ray, h, t0, t1, entry_axis);
}

static int maxmip_solve(hf_hit_batch *b, int64_t ray, hf_hit *h, double t0, double t1,
                        int entry_axis) {
    hf_pattern pattern; /* (unused by the cell walk) */
    pattern.p = pattern.q = pattern.position_step = 0;
    pattern.lengths = b->pattern;
    return ray_solve(HF_HIT_DDA_MAXMIP, b, ray, h, t0, t1, entry_axis, hf_batch_dda_hit, 0, NULL,
                     &pattern, NULL);
}

static void maxmip_end(hf_hit_batch *b, int64_t ray, const hf_hit *h) {
    ray_end(b, ray, h);
}

static const hf_ray_steps maxmip_steps = {maxmip_start, maxmip_begin, maxmip_solve, maxmip_end};

const hf_ray_steps *hf_maxmip_steps(void) {
    return &maxmip_steps;
}

int hf_intersect_batch(int kernel, hf_hit_batch *b) {
    hf_pattern pattern;
    hf_direction direction_cache; /* the exact walks' per-direction set-up, across rays */
    int parallel;
    const hf_hit_walk walk = walk_of(kernel);
    const int marching = kernel == HF_HIT_MARCH_LINEAR || kernel == HF_HIT_MARCH_GROWING ||
                         kernel == HF_HIT_MARCH_BINARY;
    const int maxmip = kernel == HF_HIT_DDA_MAXMIP || kernel == HF_HIT_RUNS_MAXMIP;
    const int cone = kernel == HF_HIT_CONE;
    const int relaxed = kernel == HF_HIT_CONE_RELAXED;
    hf_compact compact; /* dda_compact: the tree's geometry (compact.h) */
    hf_hit h;
    int64_t ray;
    if (kernel == HF_HIT_PACKET_MAXMIP) return packet_batch(b);
    if (kernel == HF_HIT_PLANE_MAXMIP) return hf_plane_batch(b, &maxmip_steps);
    if (kernel == HF_HIT_RING_MAXMIP) return hf_ring_batch(b, &maxmip_steps);
    if (walk == NULL && !marching && !relaxed) return HF_ERR_ARGUMENT;
    if (kernel == HF_RUNS_PERIODIC && (b->pattern == NULL || b->max_denominator < 1))
        return HF_ERR_ARGUMENT;
    if (maxmip && b->mip_levels < 1) return HF_ERR_ARGUMENT;
    if (cone && b->cone == NULL) return HF_ERR_ARGUMENT;
    if (kernel == HF_HIT_DDA_COMPACT && b->compact == NULL) return HF_ERR_ARGUMENT;
    hf_compact_layout(b->cols - 1, b->rows - 1, &compact);
    compact.records = b->compact;
    if (relaxed && (b->cone == NULL || b->cellmax == NULL || b->march_steps < 1))
        return HF_ERR_ARGUMENT;
    direction_cache.valid = 0;
    {
        /* parallel rays (one horizontal direction for the whole batch) share the exact
         * walks' per-direction set-up; other batches set up each ray afresh, as sharing
         * would only add the comparison */
        for (ray = 1; ray < b->n_rays; ++ray) {
            if (b->directions[3 * ray] != b->directions[0] ||
                b->directions[3 * ray + 1] != b->directions[1])
                break;
        }
        parallel = ray >= b->n_rays;
    }
    pattern.p = pattern.q = pattern.position_step = 0;
    pattern.lengths = b->pattern;
    b->bad_ray = -1;
    hit_start(b, &h); /* one record for every ray (ray_begin) */
    for (ray = 0; ray < b->n_rays; ++ray) {
        double t0, t1;
        int entry_axis;
        if (ray_begin(b, ray, &h, &t0, &t1, &entry_axis)) {
            const int status = ray_solve(kernel, b, ray, &h, t0, t1, entry_axis, walk, parallel,
                                         &direction_cache, &pattern, &compact);
            if (status != HF_OK) return status;
        }
        ray_end(b, ray, &h);
    }
    return HF_OK;
}
