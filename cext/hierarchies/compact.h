/* A cache-compact maximum hierarchy for first hits: a 16-ary max tree
 * (4 x 4 children per node), each record one 64-byte cache line.
 *
 * Levels: a tile of level L (L >= 1) covers 4^L x 4^L cells; its 16 children are the
 * level L-1 tiles (the cells themselves at level 1), slot 4 (tj & 3) + (ti & 3) for child
 * tile (ti, tj). The top level `n_levels` (at least 2) holds the one node over the whole
 * grid. Records of one level are stored row by row, the levels one after the other from
 * level 1, in one buffer aligned to 64 bytes.
 *
 * - Levels >= 2 (hf_compact_node, one per tile): the 16 children's maxima as uint16 codes
 *   relative to the node's own range (from its lowest child maximum, at level 2 from its
 *   lowest cell maximum, to its maximum), rounded up: child k is never above
 *   hf_compact_bound(node, k) = base + q[k] scale, evaluated in double. q[k] (0..65535) is
 *   chosen by the build (compact.c) so that this holds for the child's float32 maximum in
 *   the very arithmetic the walk uses; q[k] * scale is exact in double (16 x 24 significant
 *   bits), so a fused multiply-add rounds the same way. Culling with it is conservative: a
 *   tile is skipped only when the ray is above a number at or above its true maximum.
 * - Level 1 (the leaves, hf_compact_leaf: one per 2 x 2 level-1 tiles, 8 x 8 cells): each
 *   tile's 16 cell maxima as uint8 codes relative to the range [lo, hi] its parent node
 *   gives it: hi = the tile's bound hf_compact_bound(parent, slot), which the walk has just
 *   tested, and lo = the parent's base, at or below every cell of the parent (a per-tile
 *   low end in the node's spare bytes was measured: 1.2 % fewer exact tests on fBm, for
 *   more instructions than those tests cost). A cell's bound is lo + code step
 *   (hf_leaf_bound, maxmip.h), with step about (hi - lo) / 254 in 21 significant bits
 *   (hf_compact_leaf_step), so code * step is exact and a fused multiply-add rounds the
 *   same way; the build rounds each code up until that bound, in the walk's arithmetic, is
 *   at or above the cell's float32 maximum.
 *   The bound is coarser than the float maximum (by less than a step), so the floor cull
 *   keeps more cells, and the exact cell test decides them.
 * Children outside the grid hold 0 and are never read.
 *
 * The walk (dda_compact, compact.c) is dda_maxmip's (dispatch/intersect.c) on this tree: the tile
 * step of mipmap.h with a tile of level L spanning 2^(2L) cells, a level-1 tile walked cell by cell
 * and culled with the decoded cell bounds of its leaf (hf_floor_walk's leaf mode, on one line),
 * and every surviving cell handed to the shared exact cell test (hf_hit_cell_exact,
 * cell_test.h). */
#ifndef HFTRACE_COMPACT_H
#define HFTRACE_COMPACT_H

#include <stdint.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "surfaces/cell_test.h"

#define HF_COMPACT_MAX_LEVELS 16 /* 4^16 cells per side: far beyond HF_MAX_GRID_SIDE */
#define HF_COMPACT_NODE_BYTES 64
#define HF_COMPACT_CODE_MAX   65535
#define HF_COMPACT_LEAF_MAX   255 /* the largest cell code */

/* A leaf (level 1): the cell codes of 2 x 2 level-1 tiles (8 x 8 cells), tile
 * 2 (tj & 1) + (ti & 1), within a tile cell slot 4 (j & 3) + (i & 3). */
typedef struct {
    uint8_t code[4][16];
} hf_compact_leaf;

/* A node of level >= 2: 64 bytes, one cache line when the buffer is aligned. */
typedef struct {
    float base;    /* code 0: the lowest child maximum (level 2: lowest cell maximum) */
    float scale;   /* code step, >= 0                                               */
    float max;     /* the node's own maximum (float32, exact): its parent's input  */
    uint32_t used; /* bit k: child slot k lies inside the grid                      */
    uint16_t q[16];
    uint8_t spare[16];
} hf_compact_node;

/* (C99 has no static_assert: an array of negative size fails the build) */
typedef char hf_compact_node_is_one_line[sizeof(hf_compact_node) == HF_COMPACT_NODE_BYTES ? 1 : -1];
typedef char hf_compact_leaf_is_one_line[sizeof(hf_compact_leaf) == HF_COMPACT_NODE_BYTES ? 1 : -1];

/* The tree's geometry over an nx x ny cell grid, and its records. */
typedef struct {
    int32_t nx, ny;
    int n_levels;                               /* the top level: one node, at least 2 */
    int64_t offset[HF_COMPACT_MAX_LEVELS + 1];  /* first record of level L (index L)   */
    int32_t nodes_x[HF_COMPACT_MAX_LEVELS + 1]; /* tiles per row of level L            */
    int32_t nodes_y[HF_COMPACT_MAX_LEVELS + 1]; /* rows of tiles of level L            */
    int32_t leaves_x;    /* leaves per row of level 1: ceil(nodes_x[1] / 2)              */
    const void *records; /* 64-byte records: leaves (level 1), then nodes (levels >= 2) */
} hf_compact;

/* The bound of child `slot` of `node`: at or above the child's maximum. */
static inline double hf_compact_bound(const hf_compact_node *node, int slot) {
    return (double)node->base + (double)node->q[slot] * (double)node->scale;
}

/* The step of a leaf's cell codes over [lo, hi] (hi >= lo, both from the parent node):
 * (hi - lo) / 254 cut to 20 bits after the leading one (the low 32 bits of the double
 * cleared, no libm), so 255 steps reach at least hi - lo (by 255 / 254 of it, far beyond
 * the roundings; code 255 bounds every cell of the tile) and code * step (8 x 21
 * significant bits) is exact. (hi - lo) / 254 is 0 or at least 2^-157 (float32 maxima), a
 * normal double. The build and the walk share this one expression, so they compute the
 * same double. */
static inline double hf_compact_leaf_step(double hi, double lo) {
    const double z = (hi - lo) * (1.0 / 254.0);
#if defined(__SSE2__)
    /* one AND of the register (the portable bit copies below give the same bits in four
     * instructions) */
    const __m128d mask = _mm_castsi128_pd(_mm_set_epi64x(0, (long long)0xffffffff00000000ull));
    return _mm_cvtsd_f64(_mm_and_pd(_mm_set_sd(z), mask));
#else
    uint64_t bits;
    double step;
    memcpy(&bits, &z, sizeof bits);
    bits &= UINT64_C(0xffffffff00000000);
    memcpy(&step, &bits, sizeof step);
    return step;
#endif
}

/* The slot of child tile (ti, tj) (indices at the child's level) in its parent. */
static inline int hf_compact_slot(int64_t ti, int64_t tj) {
    return (int)(((tj & 3) << 2) | (ti & 3));
}

/* The node of level L >= 2 holding tile (ti, tj) of level L (its own indices). */
static inline const hf_compact_node *hf_compact_node_at(const hf_compact *c, int level, int64_t ti,
                                                        int64_t tj) {
    return (const hf_compact_node *)c->records + c->offset[level] + tj * c->nodes_x[level] + ti;
}

/* The 16 cell codes of level-1 tile (ti, tj), slot 4 (j & 3) + (i & 3): a quarter of the
 * leaf of its 2 x 2 tiles. */
static inline const uint8_t *hf_compact_leaf_codes(const hf_compact *c, int64_t ti, int64_t tj) {
    const hf_compact_leaf *leaf =
        (const hf_compact_leaf *)c->records + c->offset[1] + (tj >> 1) * c->leaves_x + (ti >> 1);
    return leaf->code[((tj & 1) << 1) | (ti & 1)];
}

/* Fill the geometry of an nx x ny grid (records NULL); returns the number of records. */
int64_t hf_compact_layout(int32_t nx, int32_t ny, hf_compact *c);

/* Build every record from the (ny, nx) float32 cell maxima into `records`
 * (hf_compact_layout's count of 64-byte records). */
void hf_compact_build(const float *cellmax, int32_t ny, int32_t nx, void *records);

/* dda_compact: the first hit of one clipped ray (1: found); h->cull_cells switches the
 * cell bound off (tiles are still skipped), as for dda_maxmip. The shared exact cell test
 * runs without its own cull (the walk's floor cull is that test on the leaf's decoded
 * bound, at or above the float32 maximum: only an optimisation, the exact test decides),
 * so the walk never reads the row-major cell maxima. */
int hf_compact_hit(hf_hit *h, const hf_compact *c);

#endif
