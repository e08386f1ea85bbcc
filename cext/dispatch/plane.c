/* plane_maxmip: dda_maxmip for batches whose rays come in vertical planes from one eye
 * (vertical-ray coherence: Cohen-Or & Shaked 1993; Lee & Shin 1995; the walk: Tevs,
 * Ihrke & Seidel 2008).
 *
 * Rays whose horizontal origin (ox, oy) and direction (dx, dy) are equal bit for bit
 * follow one 2D line with one parameterisation: every cell's parameter interval is the
 * same for all of them, and only z(t) = oz + t dz differs. A ray with oz and dz both at
 * least another's lies above it at every t >= 0 (the rays of one eye ordered by
 * elevation; the rows of an orthographic column whose origins stand on a vertical film),
 * and since rounding is monotone, every float test of the surface (flat, plane3,
 * triangles) that rejects a cell for the ray below on an interval rejects it for the ray
 * above on the same interval. So the ray above resumes the walk at the state the ray
 * below had in its hit cell: every cell before it is already known to be clear; and a
 * ray whose range ends where that of a ray below that missed ends misses too. Where the
 * intervals might differ (a later entry t0, an end t1 before the hit cell) the ray tests
 * its own first cell, or walks on its own; bilinear cells (whose root solve is not shown
 * monotone) and every ray without a partner take dda_maxmip's per-ray walk.
 *
 * A batch laid out as an image of plane columns (the level and orthographic cameras) is
 * traced column by column, eight columns side by side, with no grouping; any other batch
 * is grouped with a hash table. The rays of a plane share its set-up (the 2D clip, the
 * hit record's and the walk's constants); each ray adds only what depends on its oz, dz
 * and range. The proof, the design and its counts: docs/plane.md. Outputs (t, cell,
 * normal) equal dda_maxmip's bit for bit; the statistics count the work this kernel did. */
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include "core/hftrace.h"
#include "dispatch/plane.h"
#include "hierarchies/maxmip.h"
#include "walks/walk.h" /* HF_ASSERT */

/* One ray of a plane, ordered by oz, then dz, then index. */
typedef struct {
    double oz, dz;
    int64_t ray;
} plane_member;

static int member_order(const void *a, const void *b) {
    const plane_member *p = (const plane_member *)a, *q = (const plane_member *)b;
    if (p->oz != q->oz) return p->oz < q->oz ? -1 : 1;
    if (p->dz != q->dz) return p->dz < q->dz ? -1 : 1;
    return p->ray < q->ray ? -1 : (p->ray > q->ray);
}

/* p before q in that order (ties in oz and dz: equal rays, either order) */
static int member_below(const plane_member *p, const plane_member *q) {
    return p->oz < q->oz || (p->oz == q->oz && p->dz <= q->dz);
}

/* The key of a ray's plane: its horizontal origin and direction, compared by their bits
 * (so -0 and +0 are different planes; NaN never reaches a kernel). */
static int same_plane(const hf_hit_batch *b, int64_t r, int64_t s) {
    uint64_t p[4], q[4];
    memcpy(p, b->origins + 3 * r, 2 * sizeof(double));
    memcpy(p + 2, b->directions + 3 * r, 2 * sizeof(double));
    memcpy(q, b->origins + 3 * s, 2 * sizeof(double));
    memcpy(q + 2, b->directions + 3 * s, 2 * sizeof(double));
    return ((p[0] ^ q[0]) | (p[1] ^ q[1]) | (p[2] ^ q[2]) | (p[3] ^ q[3])) == 0;
}

static uint64_t plane_hash(const hf_hit_batch *b, int64_t r) {
    uint64_t words[4], h = 0x9e3779b97f4a7c15ULL;
    int k;
    memcpy(words, b->origins + 3 * r, 2 * sizeof(double));
    memcpy(words + 2, b->directions + 3 * r, 2 * sizeof(double));
    for (k = 0; k < 4; ++k) {
        h ^= words[k];
        h *= 0xff51afd7ed558ccdULL;
        h ^= h >> 32;
    }
    return h;
}

/* A ray may share a plane: it moves horizontally and the surface's test is monotone. */
static int plane_eligible(const hf_hit_batch *b, int64_t r) {
    const double *d = b->directions + 3 * r;
    return b->surface != HF_BILINEAR && (d[0] != 0 || d[1] != 0);
}

/* What every ray of one plane shares, set up once from any one of them: the 2D line's
 * clip to the box's footprint (its face parameters, as the box clip of intersect.c
 * computes them), the box's widened z slab, and the fields of the hit record and of the
 * walk's constants that do not depend on oz, dz or the ray's range. A ray's own set-up is
 * then its [tmin, tmax] against the footprint's faces, its z clip and what depends on
 * dz (plane_begin): the same values as dda_maxmip's per-ray set-up, with no division
 * but the z clip's. */
typedef struct {
    int outside;                 /* a zero component outside the footprint: every ray misses */
    int moves[2];                /* dx != 0, dy != 0 */
    double face_a[2], face_b[2]; /* the parameters at the footprint's faces 0 and cols-1 (rows-1) */
    double zlo, zhi;             /* the box's z slab, widened (hf_box_z_margin) */
    hf_hit hit;                  /* the hit record: shared fields set, the rest per ray */
    hf_line_bound line;          /* the line's terms of the rounding bound (hf_hit_window) */
    hf_mip_ray ray;              /* the walk's constants: shared fields set, the rest per ray */
} plane_shared;

/* The shared set-up of the plane of ray `ray`. Returns 0 when its rays must take
 * dda_maxmip's own per-ray paths (a line on a grid line of flat or plane3). */
static int plane_shared_init(const hf_hit_batch *b, int64_t ray, plane_shared *s) {
    const double *o = b->origins + 3 * ray, *d = b->directions + 3 * ray;
    const double side[2] = {b->cols - 1, b->rows - 1};
    const double margin = hf_box_z_margin(b->hmin, b->hmax);
    const double inv[2] = {hf_inverse(d[0]), hf_inverse(d[1])};
    hf_hit *h = &s->hit;
    int k;
    memset(s, 0, sizeof *s);
    for (k = 0; k < 2; ++k) {
        s->moves[k] = d[k] != 0;
        if (s->moves[k]) {
            s->face_a[k] = (0 - o[k]) * inv[k];
            s->face_b[k] = (side[k] - o[k]) * inv[k];
        } else if (!(o[k] >= 0 && o[k] <= side[k])) {
            s->outside = 1;
        }
    }
    s->zlo = b->hmin - margin;
    s->zhi = b->hmax + margin;
    /* the hit record as ray_begin fills it, but for oz, dz, the range and what
     * hf_hit_prepare derives from dz (plane_begin) */
    hf_hit_fill_batch(h, b);
    hf_hit_fill_line(h, o, d, inv);
    hf_hit_prepare(h);
    hf_line_bound_of(h, &s->line);
    /* the walk's constants (hf_mip_setup), but for oz, dz, descending and t1 */
    hf_mip_ray_of(h, &s->ray);
    s->ray.top = b->mip_levels - 1;
    s->ray.floor_level = b->floor_level < s->ray.top ? b->floor_level : s->ray.top;
    s->ray.guard_max = 4 * ((int64_t)s->ray.nx + s->ray.ny) + 64;
    return !hf_on_grid_line(h);
}

/* Ray `ray` of the plane: clip it, and fill h and r (s->hit and s->ray, in place) for it
 * as ray_begin and hf_mip_setup would (a debug build checks this field by field against
 * `steps`). Returns 1 when there is a walk to do, 0 when the ray misses the box (then h
 * is a miss, ready for the outputs). */
HF_HOT int plane_begin(const hf_hit_batch *b, const plane_shared *s, int64_t ray, hf_hit *h,
                       hf_mip_ray *r, double *t0_out, double *t1_out, int *entry_axis_out) {
    const double oz = b->origins[3 * ray + 2], dz = b->directions[3 * ray + 2];
    double t0 = b->tmin ? b->tmin[ray] : 0.0, t1 = b->tmax ? b->tmax[ray] : (double)INFINITY;
    int axis = -1, k, inside = !s->outside;
    hf_hit_clear(h); /* the result and the statistics start empty, as in ray_begin */
    for (k = 0; k < 2; ++k)
        if (s->moves[k]) hf_slab_clip(s->face_a[k], s->face_b[k], k, &t0, &t1, &axis);
    inside = inside && t0 <= t1 && hf_box_clip_z(oz, dz, s->zlo, s->zhi, &t0, &t1, &axis);
    *t0_out = t0;
    *t1_out = t1;
    *entry_axis_out = axis;
    if (!inside) {
        h->t0 = h->t1 = 0; /* a miss's range, as in ray_begin */
        return 0;
    }
    h->oz = oz;
    h->dz = dz;
    h->t0 = t0;
    h->t1 = t1;
    h->tmin = b->tmin ? b->tmin[ray] : 0.0;
    h->tmax = b->tmax ? b->tmax[ray] : (double)INFINITY;
    h->entry_axis = axis;
    /* hf_hit_prepare's fields that depend on dz */
    {
        const int descending = dz < 0;
        h->bound_off[0] = descending == (h->dx > 0);
        h->bound_off[1] = descending == (h->dy > 0);
        h->bound_lo = descending ? -(double)INFINITY : t0;
        h->bound_hi = descending ? t1 : (double)INFINITY;
        h->fast_runs = h->fast && descending;
        hf_hit_window(h, &s->line);
        r->descending = descending;
    }
    r->oz = h->oz_cull;
    r->dz = dz;
    r->t1 = t1;
    return 1;
}

#ifdef HF_DEBUG
/* Debug builds: the plane's set-up of a ray equals dda_maxmip's, field by field. */
static void plane_check_begin(const hf_hit_batch *b, const hf_ray_steps *steps, const hf_hit *mine,
                              const hf_mip_ray *mine_r, int64_t ray, int inside) {
    hf_hit h;
    hf_mip_ray r;
    hf_mip_walk w;
    double t0, t1;
    int axis, walk;
    steps->start(b, &h);
    walk = steps->begin(b, ray, &h, &t0, &t1, &axis);
    HF_ASSERT(walk == inside, "ray=%lld begin=%d plane=%d", (long long)ray, walk, inside);
    if (!walk) {
        HF_ASSERT(!mine->found && mine->cells_visited == 0, "ray=%lld", (long long)ray);
        return;
    }
    HF_ASSERT(memcmp(&h, mine, sizeof h) == 0, "ray=%lld: the hit record differs", (long long)ray);
    hf_mip_setup(&h, b, &r, &w);
    HF_ASSERT(memcmp(&r, mine_r, sizeof r) == 0, "ray=%lld: the walk's constants differ",
              (long long)ray);
}
#endif

/* The exact test of cell (i, j) (hf_hit_cell_exact) for a ray that starts in it later than
 * the ray below (its interval is its own): a descending ray is first culled by z at the
 * cell's exit, as the floor walk culls (maxmip.h: min(mx, my, t1) is the exact interval's
 * tb, the same expressions), without building the interval; the exact test then skips
 * its own, identical cull. Returns 1 on a hit. */
static int plane_first_cell(hf_hit *h, const hf_mip_ray *r, int32_t i, int32_t j) {
    h->cells_visited += 1;
    if (r->cull && r->descending) {
        const double mx = r->has_x ? ((double)(i + r->fx) - r->ox) * r->inv_x : (double)INFINITY;
        const double my = r->has_y ? ((double)(j + r->fy) - r->oy) * r->inv_y : (double)INFINITY;
        const double tb = mx < my ? (mx < r->t1 ? mx : r->t1) : (my < r->t1 ? my : r->t1);
        if (r->oz + tb * r->dz > (double)h->cellmax[(int64_t)j * r->nx + i]) return 0;
        return hf_hit_cell_exact_culled(h, i, j, 1);
    }
    return hf_hit_cell_exact(h, i, j);
}

/* What the rays below have cleared.
 * - A hit: a ray from height oz with slope dz, whose walk started at t_start, hit in cell
 *   (i, j), whose interval starts at t_enter; its walk stood at parameter t there. Every
 *   cell before (i, j) on the plane's line, from t_start on, rejects every ray with a
 *   higher (or equal) oz and dz.
 * - A miss: a ray from miss_oz with slope miss_dz walked its whole range [miss_t_start,
 *   miss_t1] without a hit: every cell of that range rejects every ray above it. */
typedef struct {
    int valid;
    double oz, dz, t_start, t_enter, t;
    int32_t i, j;
    int miss_valid;
    double miss_oz, miss_dz, miss_t_start, miss_t1;
    /* the last triangles cell tested in a resumed ray's first floor tile (that of the
     * hit, when there was one): the ray above tests that cell on the same interval, and
     * reads its surface from here */
    int cell_valid;
    hf_tri_cell cell;
} plane_chain;

static int same_bits(double a, double b) {
    uint64_t x, y;
    memcpy(&x, &a, sizeof x);
    memcpy(&y, &b, sizeof y);
    return x == y;
}

/* The floor walk's cell test (hf_cell_test, maxmip.h) for a resumed ray: the exact test
 * (hf_hit_cell_exact_culled), but a triangles cell's surface is read from the chain's
 * record when that is of the same cell on the same interval bit for bit (the same float
 * values, so the same hit), else built there first. `ctx`: the plane's chain. */
static int plane_cell_test(hf_hit *h, int32_t i, int32_t j, int culled, void *ctx) {
    plane_chain *chain = (plane_chain *)ctx;
    hf_tri_cell *c = &chain->cell;
    double ta, tb;
    int wall;
    if (!hf_hit_cell_open(h, i, j, culled, &ta, &tb, &wall)) return 0;
    if (h->surface != HF_TRIANGLES) return hf_surface_test(h, i, j, ta, tb, wall);
    if (!(chain->cell_valid && c->i == i && c->j == j && same_bits(c->ta, ta) &&
          same_bits(c->tb, tb))) {
        hf_tri_cell_build(h, i, j, ta, tb, c);
        chain->cell_valid = 1;
    }
    return hf_tri_cell_test(h, c, wall);
}

/* A ray that shares no plane, or whose plane lies on a grid line (flat, plane3): the three
 * steps of dda_maxmip, on h, the batch's record for such rays (the steps' `start`). */
static int plane_alone(hf_hit_batch *b, const hf_ray_steps *steps, int64_t ray, hf_hit *h) {
    double t0, t1;
    int entry_axis;
    if (!steps->begin(b, ray, h, &t0, &t1, &entry_axis)) {
        /* misses the box */
    } else if (t0 < t1 && !hf_on_grid_line(h)) {
        /* dda_maxmip's walk (maxmip_tight), here: its call through `solve` costs more */
        hf_mip_ray r;
        hf_mip_walk w;
        hf_mip_setup(h, b, &r, &w);
        (void)hf_mip_walk_alone(h, b, &r, &w, 0);
    } else {
        const int status = steps->solve(b, ray, h, t0, t1, entry_axis);
        if (status != HF_OK) return status;
    }
    steps->end(b, ray, h);
    return HF_OK;
}

/* One ray of a plane, above every ray the chain came from: its first hit, equal to
 * dda_maxmip's. Updates the chain. `s`: the plane's shared set-up. */
static int plane_ray(hf_hit_batch *b, const hf_ray_steps *steps, plane_shared *s, int64_t ray,
                     plane_chain *chain) {
    /* the plane's records, updated in place: plane_begin rewrites every field that
     * depends on the ray (copying them per ray cost 58 instructions a ray) */
    hf_hit *const h = &s->hit;
    hf_mip_ray *const r = &s->ray;
    hf_mip_walk w;
    double t0, t1;
    int entry_axis, status = 0, walked = 1, resumed = 0;
    int inside;
    inside = plane_begin(b, s, ray, h, r, &t0, &t1, &entry_axis);
#ifdef HF_DEBUG
    plane_check_begin(b, steps, h, r, ray, inside);
#endif
    if (!inside) {
        steps->end(b, ray, h);
        return HF_OK;
    }
    if (!(t0 < t1)) {
        /* a single parameter: dda_maxmip's own per-ray path */
        const int solved = steps->solve(b, ray, h, t0, t1, entry_axis);
        if (solved != HF_OK) return solved;
        steps->end(b, ray, h);
        return HF_OK;
    }
    /* hf_mip_setup's start, but for the cell: set below, at the chain's cell or at the
     * ray's entry */
    w.i = w.j = 0;
    w.t = t0;
    w.level = hf_mip_restart_level(r);
    w.guard = 0;
    if (chain->miss_valid && h->oz >= chain->miss_oz && h->dz >= chain->miss_dz &&
        t0 >= chain->miss_t_start && t1 == chain->miss_t1) {
        /* A ray below missed over this very range but for a later start: every cell
         * after this ray's first has the same interval for both, so only the first one,
         * cut short by the later start, can hold a hit. */
        if (t0 != chain->miss_t_start)
            status = plane_first_cell(h, r, hf_cell_at(h->ox, h->dx, t0, r->nx),
                                      hf_cell_at(h->oy, h->dy, t0, r->ny));
        walked = 0;
    } else if (chain->valid && h->oz >= chain->oz && h->dz >= chain->dz && t0 >= chain->t_start &&
               t0 < chain->t && chain->t_enter < t1) {
        /* Resume only where every cell before the chain's cell has the same interval for
         * this ray as for the ray that cleared it: the ray starts no earlier than that ray
         * (and at t >= 0, where z grows with oz and dz), before the resume point, and its
         * range goes on past the hit cell's entry (strictly: a walk never enters a cell
         * at its t1, so a cell whose interval is [t1, t1] is not one it tests). */
        resumed = 1;
        if (t0 != chain->t_start) {
            /* a later start cuts the first cell short: unless it is the chain's cell,
             * test it on this ray's interval; then the cells up to the chain's cell
             * have the same intervals */
            const int32_t i = hf_cell_at(h->ox, h->dx, t0, r->nx);
            const int32_t j = hf_cell_at(h->oy, h->dy, t0, r->ny);
            if (i != chain->i || j != chain->j) status = plane_first_cell(h, r, i, j);
        }
        if (!status) {
            /* the hit is near: walk the chain cell's floor tile first, with no tile test;
             * then on */
            w.i = chain->i;
            w.j = chain->j;
            w.t = chain->t;
            w.level = r->floor_level;
            status = hf_mip_floor_walk_by(h, r, &w, w.i >> r->floor_level, w.j >> r->floor_level,
                                          plane_cell_test, chain);
            if (status == 0) walked = 0; /* the ray ended, or left the grid: a miss */
            if (status < 0) status = 0;  /* it left the tile: walk on from there */
        }
    }
    if (!resumed && walked) {
        /* a fresh walk from the ray's entry, as hf_mip_setup starts it */
        w.i = hf_cell_at(h->ox, h->dx, t0, r->nx);
        w.j = hf_cell_at(h->oy, h->dy, t0, r->ny);
    }
    /* the cells are tested through the chain's record (plane_cell_test) */
    if (!status && walked) status = hf_mip_walk_alone_by(h, b, r, &w, 0, plane_cell_test, chain);
    if (status > 0) {
        /* the walk's state at the hit cell (maxmip.h records it) is the next start */
        double ta, tb;
        (void)hf_cell_interval(h, h->i, h->j, &ta, &tb);
        chain->valid = t0 >= 0; /* z grows with oz and dz only where t >= 0 */
        chain->oz = h->oz;
        chain->dz = h->dz;
        chain->t_start = t0;
        chain->t_enter = ta;
        chain->t = w.t;
        chain->i = h->i;
        chain->j = h->j;
    } else if (!walked || w.guard <= r->guard_max) {
        /* the whole range [t0, t1] is clear for this ray (a walk that gave up proves
         * nothing) */
        chain->miss_valid = t0 >= 0;
        chain->miss_oz = h->oz;
        chain->miss_dz = h->dz;
        chain->miss_t_start = t0;
        chain->miss_t1 = t1;
    }
    steps->end(b, ray, h);
    return HF_OK;
}

/* One plane being traced: its shared set-up and its chain. `head` is the ray it was set
 * up from; `s` is NULL when that ray shares no plane, or its plane lies on a grid line of
 * flat or plane3 (then every ray is traced alone, plane_alone, on the batch's record
 * `alone`). */
typedef struct {
    plane_shared shared, *s;
    plane_chain chain;
    int64_t head;
    hf_hit *alone;
} plane_column;

static void plane_column_init(const hf_hit_batch *b, int64_t head, hf_hit *alone, plane_column *c) {
    c->head = head;
    c->alone = alone;
    c->s = plane_eligible(b, head) && plane_shared_init(b, head, &c->shared) ? &c->shared : NULL;
    memset(&c->chain, 0, sizeof c->chain);
}

/* The next ray of the plane, above the ones before it. `checked`: the ray is known to
 * share the head's plane; else it is a candidate (an image's column), checked here, and
 * traced alone when it does not. */
static int plane_column_ray(hf_hit_batch *b, const hf_ray_steps *steps, plane_column *c,
                            int64_t ray, int checked) {
    int status;
    if (c->s &&
        (checked || ray == c->head || (plane_eligible(b, ray) && same_plane(b, ray, c->head)))) {
        status = plane_ray(b, steps, c->s, ray, &c->chain);
    } else {
        status = plane_alone(b, steps, ray, c->alone);
    }
    if (status != HF_OK) b->bad_ray = ray;
    return status;
}

/* The `count` rays of one plane, members[0 .. count), ordered bottom up: one chain. */
static int plane_trace(hf_hit_batch *b, const hf_ray_steps *steps, const plane_member *members,
                       int64_t count, hf_hit *alone) {
    plane_column column;
    int64_t k;
    int status = HF_OK;
    plane_column_init(b, members[0].ray, alone, &column);
    for (k = 0; k < count && status == HF_OK; ++k)
        status = plane_column_ray(b, steps, &column, members[k].ray, 1);
    return status;
}

/* How many columns of an image are traced side by side: row by row, each ray of a row
 * in its own column's chain. Neighbouring columns walk neighbouring cells, and the rays
 * of a row lie side by side in the batch, so each cache line that a ray reads serves the
 * next ones; and consecutive rays, in different chains, do not wait on each other. */
#define PLANE_COLUMNS_SIDE_BY_SIDE 8

/* The image of `width` columns: column c holds rays c, c + width, ... below n (the last
 * row may be short, and the first need not be an image's first: a thread's share of a
 * camera's batch), each column bottom up (its last ray in the batch first when
 * top_down), in blocks of columns side by side. */
static int plane_image(hf_hit_batch *b, const hf_ray_steps *steps, int64_t width, int top_down) {
    plane_column columns[PLANE_COLUMNS_SIDE_BY_SIDE];
    int64_t count[PLANE_COLUMNS_SIDE_BY_SIDE], next[PLANE_COLUMNS_SIDE_BY_SIDE];
    const int64_t n = b->n_rays, step = top_down ? -width : width;
    int64_t first, row;
    int status = HF_OK;
    hf_hit alone; /* the record of the rays traced alone */
    steps->start(b, &alone);
    for (first = 0; first < width && status == HF_OK; first += PLANE_COLUMNS_SIDE_BY_SIDE) {
        const int64_t block =
            width - first < PLANE_COLUMNS_SIDE_BY_SIDE ? width - first : PLANE_COLUMNS_SIDE_BY_SIDE;
        int64_t c;
        for (c = 0; c < block; ++c) {
            count[c] = (n - (first + c) + width - 1) / width; /* the rays of column c */
            next[c] = first + c + (top_down ? (count[c] - 1) * width : 0);
            plane_column_init(b, next[c], &alone, &columns[c]);
        }
        /* the rows every column of the block has, then the block's first columns'
         * last ray (they are the longer ones, by one) */
        for (row = 0; row < count[block - 1] && status == HF_OK; ++row) {
            for (c = 0; c < block && status == HF_OK; ++c) {
                status = plane_column_ray(b, steps, &columns[c], next[c], 0);
                next[c] += step;
            }
        }
        for (c = 0; c < block && status == HF_OK && count[c] > count[block - 1]; ++c)
            status = plane_column_ray(b, steps, &columns[c], next[c], 0);
    }
    return status;
}

/* The plane's members in batch order, put bottom up: an image column listed top down is
 * reversed (ties keep their order reversed, which changes nothing: equal rays give equal
 * hits), other orders sorted. */
static void plane_order(plane_member *members, int64_t count) {
    int64_t k;
    int ascending = 1, descending = 1;
    for (k = 1; k < count; ++k) {
        if (!member_below(&members[k - 1], &members[k])) ascending = 0;
        if (!member_below(&members[k], &members[k - 1])) descending = 0;
    }
    if (descending && !ascending) {
        for (k = 0; k < count / 2; ++k) {
            const plane_member m = members[k];
            members[k] = members[count - 1 - k];
            members[count - 1 - k] = m;
        }
    } else if (!ascending) {
        qsort(members, (size_t)count, sizeof *members, member_order);
    }
}

/* The member record of ray r (its height, slope and index). */
static plane_member member_of(const hf_hit_batch *b, int64_t r) {
    plane_member m;
    m.oz = b->origins[3 * r + 2];
    m.dz = b->directions[3 * r + 2];
    m.ray = r;
    return m;
}

/* A batch laid out as an image whose columns are planes, as the level and orthographic
 * cameras give it (row-major): ray 0 shares its plane first with ray w, and every ray of
 * the second row (rays w .. 2w - 1) shares the plane of the ray above it. Returns w (0: not
 * such a batch), and in *top_down whether the columns are listed from the top (ray w
 * below ray 0). Nothing else is assumed: plane_trace checks every ray of a column
 * against the column's first, and the chain's own conditions hold whatever the order
 * (the order only makes the chain resume more often). Columns that share one plane are
 * traced as separate planes, which is exact too. */
static int64_t image_columns(const hf_hit_batch *b, int *top_down) {
    const int64_t n = b->n_rays;
    int64_t width, k;
    for (width = 1; width < n && !same_plane(b, 0, width); ++width) {}
    if (width > n / 2) return 0; /* no complete second row */
    for (k = 0; k < width; ++k)
        if (!plane_eligible(b, k) || !same_plane(b, k, k + width)) return 0;
    {
        const plane_member first = member_of(b, 0), second = member_of(b, width);
        *top_down = member_below(&second, &first) && !member_below(&first, &second);
    }
    return width;
}

int hf_plane_batch(hf_hit_batch *b, const hf_ray_steps *steps) {
    const int64_t n = b->n_rays;
    int64_t slots = 16, ray, *table = NULL, *next = NULL, *last = NULL, width;
    plane_member *members = NULL;
    int status = HF_OK, top_down = 0;
    hf_hit alone; /* the record of the rays traced alone */
    if (b->mip_levels < 1) return HF_ERR_ARGUMENT;
    b->bad_ray = -1;
    width = n > 1 ? image_columns(b, &top_down) : 0;
    if (width > 0) return plane_image(b, steps, width, top_down); /* no grouping to do */
    steps->start(b, &alone);
    /* an open-addressing table of the planes (at most half full), each plane a list of
     * its rays in batch order: next[] links them, last[] holds a list's tail at its head */
    while (slots < 2 * n) slots *= 2;
    table = (int64_t *)malloc((size_t)slots * sizeof *table);
    next = (int64_t *)malloc((size_t)(n > 0 ? n : 1) * sizeof *next);
    last = (int64_t *)malloc((size_t)(n > 0 ? n : 1) * sizeof *last);
    members = (plane_member *)malloc((size_t)(n > 0 ? n : 1) * sizeof *members);
    if (!table || !next || !last || !members) {
        status = HF_ERR_MEMORY;
        goto done;
    }
    memset(table, 0xff, (size_t)slots * sizeof *table); /* every slot -1: empty */
    for (ray = 0; ray < n; ++ray) {
        uint64_t slot;
        next[ray] = -1;
        last[ray] = -1;
        if (!plane_eligible(b, ray)) continue;
        slot = plane_hash(b, ray) & (uint64_t)(slots - 1);
        while (table[slot] >= 0 && !same_plane(b, table[slot], ray))
            slot = (slot + 1) & (uint64_t)(slots - 1);
        if (table[slot] < 0) {
            table[slot] = ray;
            last[ray] = ray;
        } else {
            const int64_t head = table[slot];
            next[last[head]] = ray;
            last[head] = ray;
        }
    }
    for (ray = 0; ray < n && status == HF_OK; ++ray) {
        if (last[ray] >= 0 && next[ray] >= 0) {
            /* the head of a plane of two rays or more: the whole plane */
            int64_t count = 0, member;
            for (member = ray; member >= 0; member = next[member])
                members[count++] = member_of(b, member);
            plane_order(members, count);
            status = plane_trace(b, steps, members, count, &alone);
        } else if (last[ray] >= 0 || !plane_eligible(b, ray)) {
            /* a ray alone in its plane, or one that shares none: dda_maxmip's walk */
            status = plane_alone(b, steps, ray, &alone);
            if (status != HF_OK) b->bad_ray = ray;
        }
    }
done:
    free(table);
    free(next);
    free(last);
    free(members);
    return status;
}
