/* A cache-compact maximum hierarchy for first hits (issue 22, item 4): a 16-ary max tree
 * (4 x 4 children per node), each node one 64-byte cache line holding its 16 children's
 * maxima as uint16 codes relative to the node's own range, rounded up.
 *
 * Levels: a node of level L (L >= 1) covers a tile of 4^L x 4^L cells; its 16 children
 * are the level L-1 tiles (the cells themselves at level 1), slot 4 (tj & 3) + (ti & 3)
 * for child tile (ti, tj). The top level `n_levels` holds the one node over the whole
 * grid. Nodes of one level are stored row by row (nodes_x per row), the levels one after
 * the other from level 1, in one buffer aligned to 64 bytes.
 *
 * The bound: child k of a node is never above hf_compact_bound(node, k) = base + q[k]
 * scale, evaluated in double. q[k] (0..65535) is chosen by the build (compact.c) so that
 * this holds for the child's float32 maximum (a cell maximum of algos.Field.cellmax_for,
 * or a child node's `max`) in the very arithmetic the walk uses; q[k] * scale is exact in
 * double (16 x 24 significant bits), so a fused multiply-add rounds the same way. Culling
 * with it is therefore conservative: a tile or cell is skipped only when the ray is above
 * a number at or above its true maximum, never below it. Children outside the grid hold
 * code 0 and are never read.
 *
 * The walk (dda_compact, compact.c) is dda_maxmip's (hit.c) on this tree: the tile step
 * of mipmap.h with a tile of level L spanning 2^(2L) cells, a level-1 tile walked cell by
 * cell with the cell bounds of its one node, and every surviving cell handed to the
 * shared exact cell test (hf_hit_cell_exact, hit.h). */
#ifndef HFTRACE_COMPACT_H
#define HFTRACE_COMPACT_H

#include <stdint.h>
#include "hit.h"

#define HF_COMPACT_MAX_LEVELS 16 /* 4^16 cells per side: far beyond HF_MAX_GRID_SIDE */
#define HF_COMPACT_NODE_BYTES 64
#define HF_COMPACT_CODE_MAX   65535

/* One node: 64 bytes, one cache line when the buffer is aligned. */
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

/* The tree's geometry over an nx x ny cell grid, and its nodes. */
typedef struct {
    int32_t nx, ny;
    int n_levels;                               /* the top level: one node            */
    int64_t offset[HF_COMPACT_MAX_LEVELS + 1];  /* first node of level L (index L)    */
    int32_t nodes_x[HF_COMPACT_MAX_LEVELS + 1]; /* nodes per row of level L           */
    int32_t nodes_y[HF_COMPACT_MAX_LEVELS + 1]; /* rows of nodes of level L           */
    const hf_compact_node *nodes;
} hf_compact;

/* The bound of child `slot` of `node`: at or above the child's maximum. */
static inline double hf_compact_bound(const hf_compact_node *node, int slot) {
    return (double)node->base + (double)node->q[slot] * (double)node->scale;
}

/* The slot of child tile (ti, tj) (indices at the child's level) in its parent. */
static inline int hf_compact_slot(int64_t ti, int64_t tj) {
    return (int)(((tj & 3) << 2) | (ti & 3));
}

/* The node of level L holding tile (ti, tj) of level L (its own indices). */
static inline const hf_compact_node *hf_compact_node_at(const hf_compact *c, int level, int64_t ti,
                                                        int64_t tj) {
    return c->nodes + c->offset[level] + tj * c->nodes_x[level] + ti;
}

/* Fill the geometry of an nx x ny grid (nodes NULL); returns the number of nodes. */
int64_t hf_compact_layout(int32_t nx, int32_t ny, hf_compact *c);

/* Build every node from the (ny, nx) float32 cell maxima into `nodes` (hf_compact_layout's
 * count of them). */
void hf_compact_build(const float *cellmax, int32_t ny, int32_t nx, hf_compact_node *nodes);

/* dda_compact: the first hit of one clipped ray (1: found); h->cull_cells switches the
 * cell bound off (tiles are still skipped), as for dda_maxmip. */
int hf_compact_hit(hf_hit *h, const hf_compact *c);

#endif
