/* The cache-compact maximum hierarchy (compact.h): its layout, its build, and the
 * dda_compact first-hit walk. */
#include <math.h>
#include <string.h>
#include "hierarchies/compact.h"
#include "hierarchies/maxmip.h"
#include "walks/walk.h"
#include "core/mipmap.h"

/* ---- layout ------------------------------------------------------------------------------ */
int64_t hf_compact_layout(int32_t nx, int32_t ny, hf_compact *c) {
    int64_t total = 0;
    int level = 0;
    int64_t wx = nx, wy = ny; /* tiles per side at the current level */
    c->nx = nx;
    c->ny = ny;
    c->records = NULL;
    c->offset[0] = 0;
    c->nodes_x[0] = nx;
    c->nodes_y[0] = ny;
    /* one level more until a single node covers the grid, and at least a level-2 node: a
     * leaf's codes are relative to the bounds of its parent node */
    do {
        ++level;
        wx = (wx + 3) >> 2;
        wy = (wy + 3) >> 2;
        c->offset[level] = total;
        c->nodes_x[level] = (int32_t)wx;
        c->nodes_y[level] = (int32_t)wy;
        /* level 1: one leaf per 2 x 2 tiles */
        total += level == 1 ? ((wx + 1) >> 1) * ((wy + 1) >> 1) : wx * wy;
    } while ((wx > 1 || wy > 1 || level < 2) && level < HF_COMPACT_MAX_LEVELS);
    c->leaves_x = (int32_t)((c->nodes_x[1] + 1) >> 1);
    c->n_levels = level;
    return total;
}

/* ---- build ------------------------------------------------------------------------------- */
/* Quantise one node's child maxima (`valid` of the 16 slots, bit k for slot k) to codes
 * whose bound is at or above each maximum in the walk's own arithmetic. The codes start
 * at the lowest child maximum, or at `lowest_cell` if that is lower (a level-2 node: its
 * lowest cell maximum, the low end of its leaves' cell codes, so that no cell lies below
 * it). */
static void quantize_node(hf_compact_node *node, const float value[16], uint32_t valid,
                          float lowest_cell) {
    float lo = lowest_cell, hi = -INFINITY;
    int k;
    for (k = 0; k < 16; ++k) {
        if (!(valid >> k & 1u)) continue;
        lo = value[k] < lo ? value[k] : lo;
        hi = value[k] > hi ? value[k] : hi;
    }
    node->base = lo;
    node->max = hi;
    node->used = valid;
    node->scale = 0.0f;
    if (hi > lo) {
        /* the step that lets code 65535 reach the maximum, rounded up until it does */
        float scale = (float)(((double)hi - (double)lo) / (double)HF_COMPACT_CODE_MAX);
        node->scale = scale;
        while (hf_compact_bound(node, 0) < (double)hi) {
            node->q[0] = HF_COMPACT_CODE_MAX;
            if (hf_compact_bound(node, 0) >= (double)hi) break;
            scale = nextafterf(scale, INFINITY);
            node->scale = scale;
        }
    }
    for (k = 0; k < 16; ++k) {
        double code = 0.0;
        uint32_t q;
        if ((valid >> k & 1u) && node->scale > 0)
            code = ceil(((double)value[k] - (double)lo) / (double)node->scale);
        q = code < 0 ? 0u : (code > HF_COMPACT_CODE_MAX ? HF_COMPACT_CODE_MAX : (uint32_t)code);
        node->q[k] = (uint16_t)q;
        /* rounding in the division: raise the code until the bound covers the maximum
         * (code 65535 always does) */
        while ((valid >> k & 1u) && hf_compact_bound(node, k) < (double)value[k] &&
               node->q[k] < HF_COMPACT_CODE_MAX)
            node->q[k] += 1;
        HF_ASSERT(!(valid >> k & 1u) || hf_compact_bound(node, k) >= (double)value[k],
                  "compact: code %u of slot %d bounds %.17g below %.17g", (unsigned)node->q[k], k,
                  hf_compact_bound(node, k), (double)value[k]);
    }
}

/* The smallest cell code whose bound over [lo, lo + 255 step] is at or above the cell
 * maximum m (lo <= m <= hi). Code 255 always is: 255 step >= (hi - lo) (1 + 2^-9)
 * (hf_compact_leaf_step), so lo + 255 step rounds to at least lo + (hi - lo), which is hi
 * when hi - lo is exact (Sterbenz) and otherwise (|hi|, |lo| <= 2 (hi - lo)) falls short of
 * hi by roundings of 2^-52 (hi - lo) at most, far inside the margin; and m <= hi. */
static uint8_t leaf_code(double lo, double step, float m) {
    double guess = 0.0;
    unsigned code;
    if (step > 0 && (double)m > lo) guess = ceil(((double)m - lo) / step);
    code = guess > HF_COMPACT_LEAF_MAX ? HF_COMPACT_LEAF_MAX : (unsigned)guess;
    /* rounding in the division: the smallest code that covers m, in the walk's arithmetic */
    while (code < HF_COMPACT_LEAF_MAX && hf_leaf_bound(lo, step, code) < (double)m) ++code;
    while (code > 0 && hf_leaf_bound(lo, step, code - 1) >= (double)m) --code;
    HF_ASSERT(hf_leaf_bound(lo, step, code) >= (double)m,
              "compact: cell code %u bounds %.17g below %.17g (lo %.17g, step %.17g)", code,
              hf_leaf_bound(lo, step, code), (double)m, lo, step);
    return (uint8_t)code;
}

/* The leaves: each level-1 tile's cell codes relative to the range its level-2 parent
 * gives it (hi: the tile's bound; lo: the parent's base), as the walk decodes them. */
static void build_leaves(const float *cellmax, const hf_compact *c, void *records) {
    hf_compact_leaf *leaves = (hf_compact_leaf *)records + c->offset[1];
    const hf_compact_node *nodes = (const hf_compact_node *)records;
    const int64_t nx = c->nx, ny = c->ny;
    const int64_t n_leaves = (int64_t)c->leaves_x * ((c->nodes_y[1] + 1) >> 1);
    int64_t ti, tj;
    memset(leaves, 0, (size_t)n_leaves * sizeof *leaves);
    for (tj = 0; tj < c->nodes_y[1]; ++tj) {
        for (ti = 0; ti < c->nodes_x[1]; ++ti) {
            const hf_compact_node *parent =
                nodes + c->offset[2] + (tj >> 2) * c->nodes_x[2] + (ti >> 2);
            const int slot = hf_compact_slot(ti, tj);
            const double hi = hf_compact_bound(parent, slot);
            const double lo = (double)parent->base;
            const double step = hf_compact_leaf_step(hi, lo);
            uint8_t *code =
                leaves[(tj >> 1) * c->leaves_x + (ti >> 1)].code[((tj & 1) << 1) | (ti & 1)];
            int a, b;
            for (b = 0; b < 4; ++b) {
                for (a = 0; a < 4; ++a) {
                    const int64_t ci = 4 * ti + a, cj = 4 * tj + b;
                    if (ci < nx && cj < ny)
                        code[4 * b + a] = leaf_code(lo, step, cellmax[cj * nx + ci]);
                }
            }
        }
    }
}

void hf_compact_build(const float *cellmax, int32_t ny, int32_t nx, void *records) {
    hf_compact c;
    int level;
    hf_compact_node *nodes = (hf_compact_node *)records;
    int32_t ni, nj;
    hf_compact_layout(nx, ny, &c);
    for (level = 2; level <= c.n_levels; ++level) {
        const int32_t child_x = c.nodes_x[level - 1], child_y = c.nodes_y[level - 1];
        for (nj = 0; nj < c.nodes_y[level]; ++nj) {
            for (ni = 0; ni < c.nodes_x[level]; ++ni) {
                hf_compact_node *node =
                    nodes + c.offset[level] + (int64_t)nj * c.nodes_x[level] + ni;
                float value[16], lowest[16];
                uint32_t valid = 0;
                int a, b;
                memset(node, 0, sizeof *node);
                for (b = 0; b < 4; ++b) {
                    for (a = 0; a < 4; ++a) {
                        const int64_t ci = 4 * (int64_t)ni + a, cj = 4 * (int64_t)nj + b;
                        const int slot = 4 * b + a;
                        value[slot] = lowest[slot] = 0.0f;
                        if (ci >= child_x || cj >= child_y) continue;
                        valid |= 1u << slot;
                        if (level == 2) {
                            /* a level-1 tile's highest and lowest cell maxima, over its
                             * cells inside the grid */
                            float m = -INFINITY, l = INFINITY;
                            int k;
                            for (k = 0; k < 16; ++k) {
                                const int64_t i = 4 * ci + (k & 3), j = 4 * cj + (k >> 2);
                                if (i >= nx || j >= ny) continue;
                                m = cellmax[j * nx + i] > m ? cellmax[j * nx + i] : m;
                                l = cellmax[j * nx + i] < l ? cellmax[j * nx + i] : l;
                            }
                            value[slot] = m;
                            lowest[slot] = l;
                        } else {
                            value[slot] = nodes[c.offset[level - 1] + cj * child_x + ci].max;
                        }
                    }
                }
                if (level == 2) {
                    float lowest_cell = INFINITY;
                    int k;
                    for (k = 0; k < 16; ++k)
                        if (valid >> k & 1u)
                            lowest_cell = lowest[k] < lowest_cell ? lowest[k] : lowest_cell;
                    quantize_node(node, value, valid, lowest_cell);
                } else {
                    quantize_node(node, value, valid, INFINITY);
                }
            }
        }
    }
    build_leaves(cellmax, &c, records);
}

/* ---- the walk ---------------------------------------------------------------------------- */
/* The level to test next after moving from cell (oi, oj) to (ni, nj) at `level`: up to the
 * coarsest tile that changed (below the first common ancestor), at most `climb`. A tile
 * the walk has not entered before is never one whose test already failed. The tile of
 * level L changed when the indices differ above bit 2L + 2, so the level is half the
 * highest differing bit (a count of leading zeros where the compiler has one), not a loop
 * whose every test is a jump on the ray's path. */
static inline int compact_climb(int level, int climb, int64_t oi, int64_t oj, int64_t ni,
                                int64_t nj) {
    const uint64_t diff = (uint64_t)((oi ^ ni) | (oj ^ nj));
#if defined(__GNUC__) || defined(__clang__)
    const int top_bit = diff ? 63 - __builtin_clzll(diff) : 0;
#else
    int top_bit = 0;
    uint64_t rest = diff;
    while (rest >>= 1) ++top_bit;
#endif
    const int changed = top_bit >> 1; /* the coarsest level whose tile changed, but 0 */
    const int up = changed > level ? changed : level;
    return up < climb ? up : climb;
}

/* The walk; `quadrant`: -1 for any ray, or (dx > 0) << 1 | (dy > 0) for a ray moving
 * along both axes, a constant at each call site, so the choices on the direction's signs
 * fold away (as dda_maxmip's maxmip_quadrant). */
HF_HOT int compact_walk(hf_hit *h, const hf_compact *c, int cull, const int quadrant) {
    const int32_t nx = h->cols - 1, ny = h->rows - 1;
    const int top = c->n_levels;
    const int climb = top > 1 ? top - 1 : 1; /* the coarsest tile level ever tested */
    const int descending = h->dz < 0;
    /* exit face of index k: k + f; the forward rule of hf_index_of: gx, gy */
    const int32_t fx = quadrant < 0 ? h->dx > 0 : quadrant >> 1;
    const int32_t fy = quadrant < 0 ? h->dy > 0 : quadrant & 1;
    const int gx = quadrant < 0 ? h->dx >= 0 : quadrant >> 1;
    const int gy = quadrant < 0 ? h->dy >= 0 : quadrant & 1;
    double fox, foy; /* the face parameters' origin (hf_mip_ray: -inf along an axis not moved on) */
    const double ox = h->ox, oy = h->oy, oz = h->oz_cull, dz = h->dz;
    const double inv_x = h->inv_dx, inv_y = h->inv_dy, t1 = h->t1;
    const double inf = (double)INFINITY;
    hf_mip_ray ray; /* the constants of the floor tiles' walks */
    double t = h->t0;
    int32_t i = hf_cell_at(h->ox, h->dx, t, nx), j = hf_cell_at(h->oy, h->dy, t, ny);
    int level = climb < 2 ? climb : 2;
    int64_t guard;
    hf_mip_ray_of(h, &ray);
    if (quadrant >= 0) {
        ray.fx = ray.gx = fx;
        ray.fy = ray.gy = fy;
        ray.sx = fx ? 1 : -1;
        ray.sy = fy ? 1 : -1;
    }
    fox = ray.fox;
    foy = ray.foy;
    ray.cull = cull; /* (h->cull_cells is off while the walk runs: see hf_compact_hit) */
    /* every pass skips a tile, walks a floor tile or descends one level; descents are at
     * most top per move */
    for (guard = 0; guard <= (8 + 2 * (int64_t)top) * ((int64_t)nx + ny) + 64; ++guard) {
        const int shift = 2 * level;
        const int64_t tile_i = i >> shift, tile_j = j >> shift;
        const double t_exit_x = hf_face_t(hf_tile_face(tile_i, shift, fx), fox, inv_x);
        const double t_exit_y = hf_face_t(hf_tile_face(tile_j, shift, fy), foy, inv_y);
        /* the tile's bound, from its parent's line (the root's tile has none) */
        const double bound =
            level < top
                ? hf_compact_bound(hf_compact_node_at(c, level + 1, tile_i >> 2, tile_j >> 2),
                                   hf_compact_slot(tile_i, tile_j))
                : inf;
        int exits;
        const double t_exit = hf_tile_exit(t_exit_x, t_exit_y, t1, &exits);
        if (hf_tile_zlow(oz, dz, descending, t, t_exit) > bound) {
            h->tiles_skipped += 1;
        } else if (level > 1) {
            --level;
            continue;
        } else {
            /* walk the 4 x 4 floor tile cell by cell (maxmip.h), each cell culled by its
             * bound decoded from the tile's codes in its leaf (one line), over the range
             * [base, bound] of the parent node (level 2: bound is the tile's, just tested) */
            const hf_compact_node *parent = hf_compact_node_at(c, 2, tile_i >> 2, tile_j >> 2);
            const int32_t ilo = (int32_t)tile_i << 2, jlo = (int32_t)tile_j << 2;
            const uint32_t iw = (uint32_t)(ilo + 4 < nx ? 4 : nx - ilo) - 1;
            const uint32_t jw = (uint32_t)(jlo + 4 < ny ? 4 : ny - jlo) - 1;
            hf_leaf_codes leaf;
            double t_in;
            int status;
            HF_ASSERT(top >= 2, "dda_compact: a floor tile without a parent node (%d levels)", top);
            leaf.code = hf_compact_leaf_codes(c, tile_i, tile_j);
            leaf.lo = (double)parent->base;
            leaf.step = hf_compact_leaf_step(bound, leaf.lo);
            status =
                hf_floor_walk(h, &ray, ilo, jlo, iw, jw, NULL, &leaf, &i, &j, t, &t_in, NULL, NULL);
            if (status >= 0) return status;
            t = t_in > t ? t_in : t;
            level = compact_climb(1, climb, ilo, jlo, i, j);
            continue;
        }
        if (!(t_exit < t1)) return 0;
        {
            /* into the next tile at this level, then up to the coarsest tile that changed */
            const int64_t ni =
                hf_tile_next_cell(exits & 1, tile_i, shift, nx, gx, ox + t_exit * h->dx);
            const int64_t nj =
                hf_tile_next_cell(exits >> 1, tile_j, shift, ny, gy, oy + t_exit * h->dy);
            if ((uint64_t)ni >= (uint64_t)nx || (uint64_t)nj >= (uint64_t)ny) return 0;
            level = compact_climb(level, climb, tile_i << shift, tile_j << shift, ni, nj);
            i = (int32_t)ni;
            j = (int32_t)nj;
            t = t_exit > t ? t_exit : t;
        }
    }
    HF_ASSERT(0, "dda_compact: the walk did not end within %lld passes", (long long)guard);
    return 0;
}

#if defined(__GNUC__)
__attribute__((flatten))
#endif
int hf_compact_hit(hf_hit *h, const hf_compact *c) {
    /* the floor cull (the exact test's own cull, on the leaf's decoded bound, at or above
     * the maximum) replaces the exact test's: that one runs without it, and never reads
     * the row-major cell maxima */
    const int cull = h->cull_cells;
    int found;
    h->cull_cells = 0;
    if (h->dx == 0 || h->dy == 0) {
        found = compact_walk(h, c, cull, -1);
    } else {
        switch ((h->dx > 0) << 1 | (h->dy > 0)) {
        case 0: found = compact_walk(h, c, cull, 0); break;
        case 1: found = compact_walk(h, c, cull, 1); break;
        case 2: found = compact_walk(h, c, cull, 2); break;
        default: found = compact_walk(h, c, cull, 3); break;
        }
    }
    h->cull_cells = cull;
    return found;
}
