/* ring_maxmip: the dda_maxmip walks (maxmip.h; Tevs, Ihrke & Seidel 2008) of independent
 * rays, several in flight at once, each advanced one step in turn, with a software
 * prefetch of what each ray's next step will read (the interleaving of independent
 * pointer-chasing lookups of asynchronous memory-access chaining: Kocberber, Falsafi &
 * Grot 2015).
 *
 * The ring has HF_RING_SLOTS slots. A slot holds one ray's walk: its hit record, its
 * constants (hf_mip_ray), its state (hf_mip_walk) and the tile its next step tests. A step
 * is one iteration of dda_maxmip's loop (hf_mip_walk_alone): test the tile, then skip it
 * and climb, descend, or walk the floor tile cell by cell. After a step the ray's next
 * tile is known (its cell, level and exit come from the ray's 2D line alone), so its
 * maximum is prefetched, and at the floor level also the cell maxima and height rows
 * that a walk of that tile reads; by the time the ring comes back to the slot, the lines
 * are on their way. A ray whose walk ends writes its outputs and its slot takes the
 * next ray of the batch; rays without a max-mipmap walk (missing the box, a single
 * parameter, a ray on a grid line) are solved on the spot with dda_maxmip's own step.
 *
 * Each ray takes exactly dda_maxmip's steps, in its order, with the same functions and
 * arithmetic; only the order between rays changes, and no ray reads another's state. So
 * t, cell, normal and the statistics (each ray's own work) are bit-identical to
 * dda_maxmip's (docs/ring.md). */
#include <stdint.h>
#include "core/hftrace.h"
#include "hierarchies/maxmip.h"
#include "dispatch/ring.h"

/* HF_RING_PREFETCH=0 (CFLAGS=-DHF_RING_PREFETCH=0) turns the prefetches off, to time the
 * interleaving alone; outputs never depend on it. Non-GNU compilers have no prefetch. */
#ifndef HF_RING_PREFETCH
#define HF_RING_PREFETCH 1
#endif
#if HF_RING_PREFETCH && (defined(__GNUC__) || defined(__clang__))
#define HF_PREFETCH(address) __builtin_prefetch((address), 0, 3)
#else
#define HF_PREFETCH(address) ((void)(address))
#endif

/* One ray in flight: `tile` is the tile its next step tests (hf_mip_tile_exit of its
 * present state, computed once the state is known so that its lines can be prefetched). */
typedef struct {
    hf_hit h;
    hf_mip_ray r;
    hf_mip_walk w;
    hf_mip_tile tile;
    int64_t ray;
} ring_slot;

/* Prefetch what the slot's next step reads: the maximum of its tile and, when that is a
 * floor tile (a walk of it may follow), the cell maxima and height rows that the walk
 * reads: those of the current cell, of the cell holding the tile's exit point (clamped
 * into the tile, so every address lies in the grid; a NaN exit, from a vertical ray
 * without end, clamps too) and of the row half way between (a tile's row of maxima or
 * heights spans one or two lines). A fixed set of addresses, no loop. The starting cell
 * alone costs fewer instructions but hid less: timed on a busy machine, it left the ring
 * slower than dda_maxmip at 4096^2 where this set did not (docs/ring.md).
 * Always inlined: GCC 12 takes a function whose only effect is __builtin_prefetch for a
 * const one and deletes its calls, prefetches and all; inlined first, they stay. */
HF_HOT void ring_prefetch(const hf_hit_batch *b, const ring_slot *s) {
    const hf_mip_walk *w = &s->w;
    const hf_mip_ray *r = &s->r;
    const int level = w->level;
    HF_PREFETCH(&b->mip[level][(int64_t)s->tile.tile_j * b->mip_cols[level] + s->tile.tile_i]);
    if (level == r->floor_level) {
        int64_t ilo, ihi, jlo, jhi, i_exit, j_exit, middle;
        hf_tile_cells(s->tile.tile_i, level, r->nx, &ilo, &ihi);
        hf_tile_cells(s->tile.tile_j, level, r->ny, &jlo, &jhi);
        i_exit = hf_index_of(r->ox + s->tile.t_exit * r->dx, r->fx);
        j_exit = hf_index_of(r->oy + s->tile.t_exit * r->dy, r->fy);
        i_exit = i_exit < ilo ? ilo : (i_exit > ihi ? ihi : i_exit);
        j_exit = j_exit < jlo ? jlo : (j_exit > jhi ? jhi : j_exit);
        middle = (w->j + j_exit) >> 1;
        if (b->cellmax != NULL) {
            HF_PREFETCH(&b->cellmax[(int64_t)w->j * r->nx + w->i]);
            HF_PREFETCH(&b->cellmax[middle * r->nx + i_exit]);
            HF_PREFETCH(&b->cellmax[j_exit * r->nx + i_exit]);
        }
        HF_PREFETCH(&b->heights[(int64_t)w->j * b->cols + w->i]);
        HF_PREFETCH(&b->heights[((int64_t)w->j + 1) * b->cols + w->i]);
        HF_PREFETCH(&b->heights[(middle + 1) * b->cols + i_exit]);
        HF_PREFETCH(&b->heights[j_exit * b->cols + i_exit]);
        HF_PREFETCH(&b->heights[(j_exit + 1) * b->cols + i_exit]);
    }
}

/* Give the slot the next ray of the batch that has a max-mipmap walk to do, finishing on
 * the way every ray that has none (dda_maxmip's own step, then its outputs). Returns 1
 * when the slot holds a ray, 0 when the batch is exhausted or a step failed (*status). */
static int ring_take(hf_hit_batch *b, const hf_ray_steps *steps, int64_t *next, ring_slot *s,
                     int *status) {
    while (*next < b->n_rays) {
        const int64_t ray = (*next)++;
        double t0, t1;
        int entry_axis;
        if (steps->begin(b, ray, &s->h, &t0, &t1, &entry_axis)) {
            if (t0 < t1 && !hf_on_grid_line(&s->h)) {
                /* dda_maxmip's walk (intersect.c, maxmip_tight): set up, then in steps */
                s->ray = ray;
                hf_mip_setup(&s->h, b, &s->r, &s->w);
                s->tile = hf_mip_tile_exit(&s->r, &s->w);
                ring_prefetch(b, s);
                return 1;
            }
            *status = steps->solve(b, ray, &s->h, t0, t1, entry_axis);
            if (*status != HF_OK) return 0;
        }
        steps->end(b, ray, &s->h);
    }
    return 0;
}

/* The slot's walk, one pass of hf_mip_walk_alone's loop at a time, up to the next step that
 * reads a level at or below `cold_level` (whose maxima, or the floor tile's cells, are
 * likely out of cache): that step's tile is prefetched and the ring moves on. Steps at
 * coarser levels read small, cached arrays and follow at once. Returns 1 on a hit, 0
 * when the walk ends without one (or gives up at its guard, as that loop does), -1 when
 * it goes on. */
static inline int ring_advance(const hf_hit_batch *b, ring_slot *s, int cold_level) {
    for (;;) {
        int status, skip;
        if (s->w.guard > s->r.guard_max) return 0;
        skip = hf_tile_zlow(s->r.oz, s->r.dz, s->r.descending, s->w.t, s->tile.t_exit) >
               hf_mip_tile_max(b, s->w.level, s->tile.tile_i, s->tile.tile_j);
        status = hf_mip_iterate(&s->h, &s->r, &s->w, &s->tile, skip, 0);
        if (status >= 0) return status;
        s->tile = hf_mip_tile_exit(&s->r, &s->w);
        if (s->w.level <= cold_level) {
            ring_prefetch(b, s);
            return -1;
        }
    }
}

/* The finest level whose tile maxima take more than HF_RING_WARM_BYTES (at least the
 * floor level, whose walks read the cells): the levels the ring yields at. */
static int ring_cold_level(const hf_hit_batch *b) {
    const int top = b->mip_levels - 1;
    const int floor_level = b->floor_level < top ? b->floor_level : top;
    int level, cold = floor_level;
    for (level = floor_level + 1; level <= top; ++level) {
        const int64_t rows = (((int64_t)b->rows - 1) + ((int64_t)1 << level) - 1) >> level;
        if (rows * b->mip_cols[level] * (int64_t)sizeof(float) > HF_RING_WARM_BYTES) cold = level;
    }
    return cold;
}

int hf_ring_batch(hf_hit_batch *b, const hf_ray_steps *steps) {
    ring_slot slots[HF_RING_SLOTS];
    int order[HF_RING_SLOTS]; /* the slots in flight, order[0 .. live) */
    int live = 0, k, status = HF_OK, cold_level;
    int64_t next = 0;
    b->bad_ray = -1;
    if (b->mip_levels < 1) return HF_ERR_ARGUMENT;
    cold_level = ring_cold_level(b);
    for (k = 0; k < HF_RING_SLOTS; ++k) steps->start(b, &slots[k].h); /* each serves many rays */
    /* fill the ring */
    for (k = 0; k < HF_RING_SLOTS; ++k) {
        if (!ring_take(b, steps, &next, &slots[k], &status)) break;
        order[live++] = k;
    }
    if (status != HF_OK) return status;
    /* each slot in turn advances to its next cold step; a finished ray's slot takes the next ray,
     * or leaves the ring when the batch is exhausted (its place taken by the last slot in flight)
     */
    while (live > 0) {
        for (k = 0; k < live;) {
            ring_slot *s = &slots[order[k]];
            if (ring_advance(b, s, cold_level) < 0) {
                ++k;
                continue;
            }
            steps->end(b, s->ray, &s->h);
            if (ring_take(b, steps, &next, s, &status)) {
                ++k;
                continue;
            }
            if (status != HF_OK) return status;
            order[k] = order[--live];
        }
    }
    return HF_OK;
}
