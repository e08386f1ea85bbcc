/* A cache-compact maximum hierarchy for first hits: a 16-ary max tree
 * (4 x 4 children per node), each node one 64-byte cache line.
 *
 * Levels: a node of level L (L >= 1) covers a tile of 4^L x 4^L cells; its 16 children
 * are the level L-1 tiles (the cells themselves at level 1), slot 4 (tj & 3) + (ti & 3)
 * for child tile (ti, tj). The top level `n_levels` holds the one node over the whole
 * grid. Nodes of one level are stored row by row (nodes_x per row), the levels one after
 * the other from level 1, in one buffer aligned to 64 bytes.
 *
 * - Level 1 (the leaves, hf_compact_leaf): the 16 cell maxima of a 4 x 4 tile as float32,
 *   exactly: the cell maxima in a tiled layout, so a floor tile's bounds share one line.
 * - Levels >= 2 (hf_compact_node): the 16 children's maxima as uint16 codes relative to
 *   the node's own range, rounded up: child k is never above hf_compact_bound(node, k) =
 *   base + q[k] scale, evaluated in double. q[k] (0..65535) is chosen by the build
 *   (compact.c) so that this holds for the child's float32 maximum in the very arithmetic
 *   the walk uses; q[k] * scale is exact in double (16 x 24 significant bits), so a fused
 *   multiply-add rounds the same way. Culling with it is conservative: a tile is skipped
 *   only when the ray is above a number at or above its true maximum.
 * Children outside the grid hold 0 and are never read.
 *
 * The walk (dda_compact, compact.c) is dda_maxmip's (dispatch/intersect.c) on this tree: the tile
 * step of mipmap.h with a tile of level L spanning 2^(2L) cells, a level-1 tile walked cell by cell
 * with the exact cell maxima of its leaf (dda_maxmip's floor cull, on one line), and every
 * surviving cell handed to the shared exact cell test (hf_hit_cell_exact, cell_test.h). */
#ifndef HFTRACE_COMPACT_H
#define HFTRACE_COMPACT_H

#include <stdint.h>
#include "surfaces/cell_test.h"

#define HF_COMPACT_MAX_LEVELS 16 /* 4^16 cells per side: far beyond HF_MAX_GRID_SIDE */
#define HF_COMPACT_NODE_BYTES 64
#define HF_COMPACT_CODE_MAX   65535

/* A leaf (level 1): the cell maxima of a 4 x 4 tile, slot 4 (j & 3) + (i & 3). */
typedef struct {
    float max[16];
} hf_compact_leaf;

/* A node of level >= 2: 64 bytes, one cache line when the buffer is aligned. */
typedef struct {
    float base;    /* the lowest child maximum: code 0                              */
    float scale;   /* code step, >= 0                                               */
    float max;     /* the node's own maximum (float32, exact): its parent's input  */
    uint32_t used; /* bit k: child slot k lies inside the grid                      */
    uint16_t q[16];
    uint8_t spare[16];
} hf_compact_node;

/* (C99 has no static_assert: an array of negative size fails the build) */
typedef char hf_compact_node_is_one_line[sizeof(hf_compact_node) == HF_COMPACT_NODE_BYTES ? 1 : -1];
typedef char hf_compact_leaf_is_one_line[sizeof(hf_compact_leaf) == HF_COMPACT_NODE_BYTES ? 1 : -1];

/* The tree's geometry over an nx x ny cell grid, and its nodes. */
typedef struct {
    int32_t nx, ny;
    int n_levels;                               /* the top level: one node            */
    int64_t offset[HF_COMPACT_MAX_LEVELS + 1];  /* first node of level L (index L)    */
    int32_t nodes_x[HF_COMPACT_MAX_LEVELS + 1]; /* nodes per row of level L           */
    int32_t nodes_y[HF_COMPACT_MAX_LEVELS + 1]; /* rows of nodes of level L           */
    const void *records; /* 64-byte records: leaves (level 1), then nodes (levels >= 2) */
} hf_compact;

/* The bound of child `slot` of `node`: at or above the child's maximum. */
static inline double hf_compact_bound(const hf_compact_node *node, int slot) {
    return (double)node->base + (double)node->q[slot] * (double)node->scale;
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

/* The leaf holding level-1 tile (ti, tj). */
static inline const hf_compact_leaf *hf_compact_leaf_at(const hf_compact *c, int64_t ti,
                                                        int64_t tj) {
    return (const hf_compact_leaf *)c->records + c->offset[1] + tj * c->nodes_x[1] + ti;
}

/* Fill the geometry of an nx x ny grid (records NULL); returns the number of records. */
int64_t hf_compact_layout(int32_t nx, int32_t ny, hf_compact *c);

/* Build every record from the (ny, nx) float32 cell maxima into `records`
 * (hf_compact_layout's count of 64-byte records). */
void hf_compact_build(const float *cellmax, int32_t ny, int32_t nx, void *records);

/* dda_compact: the first hit of one clipped ray (1: found); h->cull_cells switches the
 * cell bound off (tiles are still skipped), as for dda_maxmip. The shared exact cell test
 * runs without its own cull (the walk's floor cull is the same test on the same float32
 * maximum, read from the leaf), so the walk never reads the row-major cell maxima. */
int hf_compact_hit(hf_hit *h, const hf_compact *c);

#endif
