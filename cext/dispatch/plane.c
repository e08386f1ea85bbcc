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
 * monotone) and every ray without a partner take dda_maxmip's per-ray walk. The proof
 * and its limits: docs/plane.md. Outputs (t, cell, normal) equal dda_maxmip's bit for
 * bit; the statistics count the work this kernel did. */
#include <stdlib.h>
#include <string.h>
#include "core/hftrace.h"
#include "dispatch/plane.h"
#include "hierarchies/maxmip.h"

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
    return memcmp(b->origins + 3 * r, b->origins + 3 * s, 2 * sizeof(double)) == 0 &&
           memcmp(b->directions + 3 * r, b->directions + 3 * s, 2 * sizeof(double)) == 0;
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
} plane_chain;

/* One ray of a plane, above every ray the chain came from: its first hit, equal to
 * dda_maxmip's. Updates the chain. */
static int plane_ray(hf_hit_batch *b, const hf_ray_steps *steps, int64_t ray, plane_chain *chain) {
    hf_hit h;
    hf_mip_ray r;
    hf_mip_walk w;
    double t0, t1;
    int entry_axis, status = 0, walked = 1;
    if (!steps->begin(b, ray, &h, &t0, &t1, &entry_axis)) {
        steps->end(b, ray, &h);
        return HF_OK;
    }
    if (!(t0 < t1) || hf_on_grid_line(&h)) {
        /* a single parameter, or a ray on a grid line: dda_maxmip's own per-ray paths */
        const int solved = steps->solve(b, ray, &h, t0, t1, entry_axis);
        if (solved != HF_OK) return solved;
        steps->end(b, ray, &h);
        return HF_OK;
    }
    hf_mip_setup(&h, b, &r, &w);
    if (chain->miss_valid && h.oz >= chain->miss_oz && h.dz >= chain->miss_dz &&
        t0 >= chain->miss_t_start && t1 == chain->miss_t1) {
        /* A ray below missed over this very range but for a later start: every cell
         * after this ray's first has the same interval for both, so only the first one,
         * cut short by the later start, can hold a hit. */
        if (t0 != chain->miss_t_start) {
            h.cells_visited += 1;
            status = hf_hit_cell_exact(&h, w.i, w.j);
        }
        walked = 0;
    } else if (chain->valid && h.oz >= chain->oz && h.dz >= chain->dz && t0 >= chain->t_start &&
               t0 < chain->t && chain->t_enter < t1) {
        /* Resume only where every cell before the chain's cell has the same interval for
         * this ray as for the ray that cleared it: the ray starts no earlier than that ray
         * (and at t >= 0, where z grows with oz and dz), before the resume point, and its
         * range goes on past the hit cell's entry (strictly: a walk never enters a cell
         * at its t1, so a cell whose interval is [t1, t1] is not one it tests). */
        if (t0 == chain->t_start || (w.i == chain->i && w.j == chain->j)) {
            w.i = chain->i;
            w.j = chain->j;
            w.t = chain->t;
            w.level = r.floor_level; /* the hit is near: start at the floor tile */
        } else {
            /* a later start cuts the first cell short: test it on this ray's interval,
             * then the cells up to the chain's cell have the same intervals */
            h.cells_visited += 1;
            status = hf_hit_cell_exact(&h, w.i, w.j);
            if (!status) {
                w.i = chain->i;
                w.j = chain->j;
                w.t = chain->t;
                w.level = r.floor_level;
            }
        }
    }
    if (!status && walked) status = hf_mip_walk_alone(&h, b, &r, &w, 0);
    if (status > 0) {
        /* the walk's state at the hit cell (maxmip.h records it) is the next start */
        double ta, tb;
        (void)hf_cell_interval(&h, h.i, h.j, &ta, &tb);
        chain->valid = t0 >= 0; /* z grows with oz and dz only where t >= 0 */
        chain->oz = h.oz;
        chain->dz = h.dz;
        chain->t_start = t0;
        chain->t_enter = ta;
        chain->t = w.t;
        chain->i = h.i;
        chain->j = h.j;
    } else if (!walked || w.guard <= r.guard_max) {
        /* the whole range [t0, t1] is clear for this ray (a walk that gave up proves
         * nothing) */
        chain->miss_valid = t0 >= 0;
        chain->miss_oz = h.oz;
        chain->miss_dz = h.dz;
        chain->miss_t_start = t0;
        chain->miss_t1 = t1;
    }
    steps->end(b, ray, &h);
    return HF_OK;
}

/* The rays of one plane, members[0 .. count), traced bottom up. */
static int plane_trace(hf_hit_batch *b, const hf_ray_steps *steps, plane_member *members,
                       int64_t count) {
    plane_chain chain;
    int64_t k;
    int ascending = 1, descending = 1;
    for (k = 1; k < count; ++k) {
        if (!member_below(&members[k - 1], &members[k])) ascending = 0;
        if (!member_below(&members[k], &members[k - 1])) descending = 0;
    }
    if (descending && !ascending) {
        /* an image column listed top down: reverse it (ties keep their order reversed,
         * which changes nothing: equal rays give equal hits) */
        for (k = 0; k < count / 2; ++k) {
            const plane_member m = members[k];
            members[k] = members[count - 1 - k];
            members[count - 1 - k] = m;
        }
    } else if (!ascending) {
        qsort(members, (size_t)count, sizeof *members, member_order);
    }
    memset(&chain, 0, sizeof chain);
    for (k = 0; k < count; ++k) {
        const int status = plane_ray(b, steps, members[k].ray, &chain);
        if (status != HF_OK) {
            b->bad_ray = members[k].ray;
            return status;
        }
    }
    return HF_OK;
}

int hf_plane_batch(hf_hit_batch *b, const hf_ray_steps *steps) {
    const int64_t n = b->n_rays;
    int64_t slots = 16, ray, *table = NULL, *next = NULL, *last = NULL;
    plane_member *members = NULL;
    int status = HF_OK;
    if (b->mip_levels < 1) return HF_ERR_ARGUMENT;
    b->bad_ray = -1;
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
            for (member = ray; member >= 0; member = next[member]) {
                members[count].oz = b->origins[3 * member + 2];
                members[count].dz = b->directions[3 * member + 2];
                members[count].ray = member;
                ++count;
            }
            status = plane_trace(b, steps, members, count);
        } else if (last[ray] >= 0 || !plane_eligible(b, ray)) {
            /* a ray alone in its plane, or one that shares none: dda_maxmip's walk */
            plane_chain alone;
            memset(&alone, 0, sizeof alone);
            status = plane_ray(b, steps, ray, &alone);
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
