/* The dda_maxmip walk (Tevs, Ihrke & Seidel 2008) as a resumable state machine, shared by
 * the per-ray kernel (dispatch/intersect.c) and the packet kernel (packet.c): a ray's walk is its
 * constants (hf_mip_ray) and its state (hf_mip_walk: the current cell, parameter and
 * level), and one iteration tests the tile around the cell at the current level, then
 * skips it (and climbs), descends, or walks it cell by cell at the floor level.
 *
 * The packet kernel runs these very functions on each ray, in the same order per ray, so
 * its outputs (t, cell, normal and the statistics) are those of the per-ray kernel bit for
 * bit; it only shares between rays what does not depend on the ray (the tile's maximum,
 * the level's bookkeeping) and computes the per-ray exit parameters of a tile side by side.
 * Tile geometry: mipmap.h; the cell test: cell_test.h (hf_hit_cell_exact). */
#ifndef HFTRACE_MAXMIP_H
#define HFTRACE_MAXMIP_H

#include <math.h>
#include <stdint.h>
#include "surfaces/hitbatch.h"
#include "core/mipmap.h"

/* The constants of one ray's walk (from its clipped hf_hit and the batch). */
typedef struct {
    int32_t nx, ny;
    int top, floor_level, descending, cull, has_x, has_y;
    int32_t sx, sy, fx, fy; /* travel direction; exit face of index k is k + f */
    int32_t gx, gy;         /* the forward rule of hf_index_of: dx >= 0, dy >= 0 */
    double ox, oy, oz, dx, dy, dz, inv_x, inv_y, t1;
    /* the origin the face parameters subtract: ox (oy), or -inf along an axis the ray does
     * not move on, whose inverse direction is +inf (hf_inverse): ((double)face - fox) *
     * inv_x is then the exit parameter, or +inf, with no jump on has_x */
    double fox, foy;
    int64_t guard_max; /* iterations after which the walk gives up (a miss) */
} hf_mip_ray;

/* The state of one ray's walk: the current cell, the parameter where the walk is, the
 * level whose tile around the cell is tested next, and the iterations done. */
typedef struct {
    int32_t i, j;
    double t;
    int level;
    int64_t guard;
} hf_mip_walk;

/* The level a walk starts at, and returns to after a floor tile: one above the floor. */
static inline int hf_mip_restart_level(const hf_mip_ray *r) {
    return r->floor_level + 1 < r->top ? r->floor_level + 1 : r->top;
}

/* The ray's constants that come from its clipped hf_hit alone (every field but top,
 * floor_level and guard_max): what a floor tile's walk reads (hf_floor_walk). */
HF_HOT void hf_mip_ray_of(const hf_hit *h, hf_mip_ray *r) {
    r->nx = h->cols - 1;
    r->ny = h->rows - 1;
    r->descending = h->dz < 0;
    r->cull = h->cull_cells;
    r->has_x = h->dx != 0;
    r->has_y = h->dy != 0;
    r->sx = h->dx > 0 ? 1 : -1;
    r->sy = h->dy > 0 ? 1 : -1;
    r->fx = h->dx > 0;
    r->fy = h->dy > 0;
    r->gx = h->dx >= 0;
    r->gy = h->dy >= 0;
    r->ox = h->ox;
    r->oy = h->oy;
    r->oz = h->oz_cull; /* the culls' z (cell_test.h) */
    r->dx = h->dx;
    r->dy = h->dy;
    r->dz = h->dz;
    r->inv_x = h->inv_dx;
    r->inv_y = h->inv_dy;
    r->t1 = h->t1;
    r->fox = r->has_x ? h->ox : -(double)INFINITY;
    r->foy = r->has_y ? h->oy : -(double)INFINITY;
}

static inline void hf_mip_setup(const hf_hit *h, const hf_hit_batch *b, hf_mip_ray *r,
                                hf_mip_walk *w) {
    hf_mip_ray_of(h, r);
    r->top = b->mip_levels - 1;
    r->floor_level = b->floor_level < r->top ? b->floor_level : r->top;
    r->guard_max = 4 * ((int64_t)r->nx + r->ny) + 64;
    w->t = h->t0;
    w->i = hf_cell_at(h->ox, h->dx, w->t, r->nx);
    w->j = hf_cell_at(h->oy, h->dy, w->t, r->ny);
    w->level = hf_mip_restart_level(r);
    w->guard = 0;
}

/* The tile around the walk's cell at its level: its indices, the parameter where the ray
 * leaves it (clipped to t1) and the faces it leaves by (hf_tile_exit: bit 0 x, bit 1 y,
 * 0 when the ray ends first). */
typedef struct {
    int32_t tile_i, tile_j;
    double t_exit;
    int exits;
} hf_mip_tile;

static inline hf_mip_tile hf_mip_tile_of(const hf_mip_ray *r, int32_t tile_i, int32_t tile_j,
                                         double t_exit_x, double t_exit_y) {
    hf_mip_tile e;
    int exits;
    e.tile_i = tile_i;
    e.tile_j = tile_j;
    e.t_exit = hf_tile_exit(t_exit_x, t_exit_y, r->t1, &exits);
    e.exits = exits;
    return e;
}

/* The ray's exit parameter from tile `tile` at `level` along x (y): inf when the ray does
 * not move along that axis (fox is then -inf and inv_x +inf: no jump). */
static inline double hf_mip_exit_x(const hf_mip_ray *r, int32_t tile, int level) {
    return hf_face_t(hf_tile_face(tile, level, r->fx), r->fox, r->inv_x);
}

static inline double hf_mip_exit_y(const hf_mip_ray *r, int32_t tile, int level) {
    return hf_face_t(hf_tile_face(tile, level, r->fy), r->foy, r->inv_y);
}

static inline hf_mip_tile hf_mip_tile_exit(const hf_mip_ray *r, const hf_mip_walk *w) {
    const int32_t tile_i = w->i >> w->level, tile_j = w->j >> w->level;
    return hf_mip_tile_of(r, tile_i, tile_j, hf_mip_exit_x(r, tile_i, w->level),
                          hf_mip_exit_y(r, tile_j, w->level));
}

/* The tile's maximum at the walk's level. */
static inline double hf_mip_tile_max(const hf_hit_batch *b, int level, int32_t tile_i,
                                     int32_t tile_j) {
    return (double)b->mip[level][(int64_t)tile_j * b->mip_cols[level] + tile_i];
}

/* A floor walk's cell test in place of hf_hit_cell_exact_culled (same arguments, and
 * `ctx`), or NULL for that one: plane_maxmip's, which keeps the surface of the cell it
 * hits for the ray above (dispatch/plane.c). At every call site the choice is a constant,
 * and the walk is always inlined, so it folds away. */
typedef int (*hf_cell_test)(hf_hit *h, int32_t i, int32_t j, int culled, void *ctx);

/* A floor tile's cell bounds as the compact tree's leaf codes (compact.h): the bound of
 * the cell in slot k = 4 (j & 3) + (i & 3) is hf_leaf_bound(lo, step, code[k]), at or
 * above its float32 maximum. */
typedef struct {
    const uint8_t *code;
    double lo, step;
} hf_leaf_codes;

/* A leaf code's bound, in the one expression the tree's build (compact.c) and the floor
 * walk share: code * step is exact (compact.h, hf_compact_leaf_step), so a fused
 * multiply-add rounds it the same way. */
static inline double hf_leaf_bound(double lo, double step, unsigned code) {
    return lo + (double)code * step;
}

/* The floor-tile walk, the one home of the cell walk inside a tile that a hierarchy could
 * not skip (dda_maxmip, packet_maxmip and dda_compact): from cell (*ci, *cj), entered at
 * t_start, cell by cell through the tile of cells [ilo, ilo + iw] x [jlo, jlo + jw]; mx, my:
 * the exit faces of the current cell, recomputed only on the axis that stepped. A cell is
 * culled by z at its exit face (descending) or at its entry (else) against its bound:
 * with the row-major grid's cell maxima `maxima` (`leaf` NULL) for a descending ray that
 * is exactly the exact test's cull, so only the cells it passes pay for the interval and
 * the surface test; for the compact tree, the tile's leaf codes (`leaf`, 16 bytes of one
 * line) decode to a bound at or above the maximum, a coarser cull whose extra cells the
 * exact test rejects. `leaf` is a constant (NULL or not) at every call site, so the
 * choice folds away. Returns 1 on a hit (then (*ci, *cj) is the hit cell and *t_entered
 * the parameter the walk entered it at), 0 when the ray ends or leaves the grid, -1 when
 * it leaves the tile: then (*ci, *cj) is the cell it entered and *t_entered the parameter
 * where it did. */
HF_HOT int hf_floor_walk(hf_hit *h, const hf_mip_ray *r, int32_t ilo, int32_t jlo, uint32_t iw,
                         uint32_t jw, const float *maxima, const hf_leaf_codes *leaf, int32_t *ci,
                         int32_t *cj, double t_start, double *t_entered, hf_cell_test test,
                         void *ctx) {
    const int32_t nx = r->nx, ny = r->ny, sx = r->sx, sy = r->sy, fx = r->fx, fy = r->fy;
    const double ox = r->ox, oy = r->oy, oz = r->oz, dz = r->dz, inv_x = r->inv_x;
    const double inv_y = r->inv_y, t1 = r->t1;
    const int descending = r->descending, cull = r->cull;
    /* the exact test's own cull is this one when the ray descends (z at the cell's exit,
     * tb: min(mx, my, t1) is the exact interval's tb, the same expressions) against the
     * grid's cell maximum (no leaf; the compact tree's leaf bound is coarser) */
    const int culled = !leaf && cull && descending;
    int32_t i = *ci, j = *cj;
    double t_in = t_start;
    double mx = ((double)(i + fx) - r->fox) * inv_x; /* inf along an axis not moved on */
    double my = ((double)(j + fy) - r->foy) * inv_y;
    for (;;) {
        const double tb = mx < my ? (mx < t1 ? mx : t1) : (my < t1 ? my : t1);
        h->cells_visited += 1;
        if (!cull ||
            !(oz + (descending ? tb : t_in) * dz >
              (leaf ? hf_leaf_bound(leaf->lo, leaf->step, leaf->code[((j & 3) << 2) | (i & 3)])
                    : (double)maxima[(int64_t)j * nx + i]))) {
            if (test ? test(h, i, j, culled, ctx) : hf_hit_cell_exact_culled(h, i, j, culled)) {
                /* the hit cell and the parameter the walk entered it at: where
                 * plane_maxmip resumes the ray above (dispatch/plane.c) */
                *ci = i;
                *cj = j;
                *t_entered = t_in;
                return 1;
            }
        }
        if (!(tb < t1)) return 0;
        if (mx < my) {
            i += sx;
            t_in = mx;
            mx = ((double)(i + fx) - ox) * inv_x;
        } else if (my < mx) {
            j += sy;
            t_in = my;
            my = ((double)(j + fy) - oy) * inv_y;
        } else {
            i += sx;
            j += sy;
            t_in = mx;
            mx = ((double)(i + fx) - ox) * inv_x;
            my = ((double)(j + fy) - oy) * inv_y;
        }
        if ((uint32_t)(i - ilo) > iw || (uint32_t)(j - jlo) > jw) break;
    }
    if ((uint32_t)i >= (uint32_t)nx || (uint32_t)j >= (uint32_t)ny) return 0;
    *ci = i;
    *cj = j;
    *t_entered = t_in;
    return -1;
}

/* Walk the floor tile (tile_i, tile_j) of the max mipmap (hf_floor_walk on the row-major
 * cell maxima). Returns 1 on a hit, 0 when the ray ends or leaves the grid, -1 when it
 * leaves the tile (the walk goes on from the cell it entered, one level above the floor). */
static inline int hf_mip_floor_walk_by(hf_hit *h, const hf_mip_ray *r, hf_mip_walk *w,
                                       int32_t tile_i, int32_t tile_j, hf_cell_test test,
                                       void *ctx) {
    const int floor_level = r->floor_level;
    const int32_t nx = r->nx, ny = r->ny;
    const int32_t ilo = tile_i << floor_level, jlo = tile_j << floor_level;
    const uint32_t iw =
        (uint32_t)((((int64_t)tile_i + 1) << floor_level) < nx ? (1 << floor_level) : nx - ilo) - 1;
    const uint32_t jw =
        (uint32_t)((((int64_t)tile_j + 1) << floor_level) < ny ? (1 << floor_level) : ny - jlo) - 1;
    double t_in;
    const int status = hf_floor_walk(h, r, ilo, jlo, iw, jw, h->cellmax, NULL, &w->i, &w->j, w->t,
                                     &t_in, test, ctx);
    if (status == 0) return 0;
    w->t = t_in > w->t ? t_in : w->t; /* on a hit too: the state plane_maxmip resumes from */
    if (status > 0) return 1;
    /* a walk with its own cell test (plane_maxmip's, whose hits are near) goes on at the
     * floor level, the others one above */
    w->level = test ? r->floor_level : hf_mip_restart_level(r);
    return -1;
}

/* hf_mip_floor_walk_by with the exact cell test (`test` NULL). */
static inline int hf_mip_floor_walk(hf_hit *h, const hf_mip_ray *r, hf_mip_walk *w, int32_t tile_i,
                                    int32_t tile_j) {
    return hf_mip_floor_walk_by(h, r, w, tile_i, tile_j, NULL, NULL);
}

/* hf_mip_floor_walk kept out of line: the packet kernel's call (packet.c passes
 * `outline` = 1 below). Its loop over the packet's rays stays small that way; inlined
 * there, the instructions per ray of packet_maxmip grow by about 3 %. */
HF_COLD int hf_mip_floor_walk_outlined(hf_hit *h, const hf_mip_ray *r, hf_mip_walk *w,
                                       int32_t tile_i, int32_t tile_j) {
    return hf_mip_floor_walk(h, r, w, tile_i, tile_j);
}

/* Leave a skipped tile into the next tile at its level: an integer step on the exit axis,
 * the other index recomputed at the exit and clamped into the tile just left. Returns 0
 * when the ray ends or leaves the grid, else -1 (the walk goes on, one level coarser). */
static inline int hf_mip_leave_tile(const hf_mip_ray *r, hf_mip_walk *w, const hf_mip_tile *e) {
    int64_t ni, nj;
    /* (the range ends first exactly when no face is left: then t_exit is t1) */
    if (!(e->t_exit < r->t1)) return 0;
    ni = hf_tile_next_cell(e->exits & 1, e->tile_i, w->level, r->nx, r->gx,
                           r->ox + e->t_exit * r->dx);
    nj = hf_tile_next_cell(e->exits >> 1, e->tile_j, w->level, r->ny, r->gy,
                           r->oy + e->t_exit * r->dy);
    if ((uint64_t)ni >= (uint64_t)r->nx || (uint64_t)nj >= (uint64_t)r->ny) return 0;
    w->i = (int32_t)ni;
    w->j = (int32_t)nj;
    w->t = e->t_exit > w->t ? e->t_exit : w->t;
    if (w->level < r->top) ++w->level;
    return -1;
}

/* One iteration of the walk, once the tile e has been tested (`skip`: the ray's lowest z
 * over its stretch in the tile, hf_tile_zlow, is above the tile's maximum): skip it and
 * climb, descend one level, or walk the floor tile. Returns 1 on a hit, 0 when the walk
 * ends without one, -1 when it goes on. */
static inline int hf_mip_iterate_by(hf_hit *h, const hf_mip_ray *r, hf_mip_walk *w,
                                    const hf_mip_tile *e, int skip, const int outline,
                                    hf_cell_test test, void *ctx) {
    int status;
    if (skip) {
        h->tiles_skipped += 1;
        status = hf_mip_leave_tile(r, w, e);
    } else if (w->level > r->floor_level) {
        --w->level;
        status = -1;
    } else {
        status = outline ? hf_mip_floor_walk_outlined(h, r, w, e->tile_i, e->tile_j)
                         : hf_mip_floor_walk_by(h, r, w, e->tile_i, e->tile_j, test, ctx);
    }
    ++w->guard;
    return status;
}

static inline int hf_mip_iterate(hf_hit *h, const hf_mip_ray *r, hf_mip_walk *w,
                                 const hf_mip_tile *e, int skip, const int outline) {
    return hf_mip_iterate_by(h, r, w, e, skip, outline, NULL, NULL);
}

/* The rest of one ray's walk from its state, alone: the per-ray kernel dda_maxmip, and a
 * ray that left its packet (`outline` 1: the floor walk out of line, as hf_mip_iterate).
 * Returns 1 on a hit. */
static inline int hf_mip_walk_alone_by(hf_hit *h, const hf_hit_batch *b, const hf_mip_ray *r,
                                       hf_mip_walk *w, const int outline, hf_cell_test test,
                                       void *ctx) {
    while (w->guard <= r->guard_max) {
        const hf_mip_tile e = hf_mip_tile_exit(r, w);
        const int skip = hf_tile_zlow(r->oz, r->dz, r->descending, w->t, e.t_exit) >
                         hf_mip_tile_max(b, w->level, e.tile_i, e.tile_j);
        const int status = hf_mip_iterate_by(h, r, w, &e, skip, outline, test, ctx);
        if (status >= 0) return status;
    }
    return 0;
}

/* hf_mip_walk_alone_by with the exact cell test (`test` NULL). */
static inline int hf_mip_walk_alone(hf_hit *h, const hf_hit_batch *b, const hf_mip_ray *r,
                                    hf_mip_walk *w, const int outline) {
    return hf_mip_walk_alone_by(h, b, r, w, outline, NULL, NULL);
}

#endif
