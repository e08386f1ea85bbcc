/* Fast horizon kernels on the two-triangle surface (split u = v in the grid's own frame):
 * the row-vectorised shared pattern for bounded radii, and the chain walk, a per-vertex
 * max-mipmap walk that starts from a lower bound borrowed from a vertex further along
 * almost the same line. Conventions as in terrain.h; algos/terrain.py validates every
 * argument and builds the patterns and the neighbour lists. */
#ifndef HF_HORIZON_FAST_H
#define HF_HORIZON_FAST_H

#include <stdint.h>
#include "terrain/terrain.h"

/* Horizon tangents by one shared pattern, rows [row_start, row_stop) of the grid itself
 * (any direction), with the pattern outermost and a row of vertices innermost, so that the
 * inner loop is a few flops per vertex over contiguous memory (vectorised by the
 * compiler). Breakpoint e is H[v + off_a[e]] * (1 - w[e]) + H[v + off_b[e]] * w[e] at
 * distance 1 / inv_t[e]. It counts for vertex (i, j) when its reads stay inside: rx[e] and
 * ry[e] are the running maxima of |x| and |y| of the offsets read, taken along the signs
 * sx, sy (+1 or -1) of the direction (so i <= cols - 1 - rx[e] when sx > 0, i >= rx[e] when
 * sx < 0; rows alike). Breakpoints [0, n_main) are evaluated; with end_k >= 0
 * (n_main = end_k + 1) max_distance lies end_f of the way from breakpoint end_k to
 * end_k + 1 and is evaluated where end_k + 1 counts. out[v]: the largest ratio, -inf when
 * no breakpoint counts. Bit-identical to hf_horizon_pattern on the same breakpoints. */
void hf_horizon_rows(const double *H, int64_t rows, int64_t cols, int64_t n, const double *inv_t,
                     const int64_t *off_a, const int64_t *off_b, const double *w, const int64_t *rx,
                     const int64_t *ry, int sx, int sy, int64_t n_main, int64_t end_k, double end_f,
                     double end_inv_t, int64_t row_start, int64_t row_stop, double *out);

/* What a chain walk did, summed over a batch. */
typedef struct {
    int64_t cells;      /* cells evaluated (breakpoints: their exits and diagonals)  */
    int64_t skips;      /* mipmap tiles skipped                                       */
    int64_t tile_tests; /* mipmap tiles tested                                        */
    int64_t bounded;    /* vertices that started with a borrowed lower bound          */
} hf_chain_stats;

/* Horizon tangents along the unit direction (dx, dy) (grid frame) by per-vertex max-mipmap
 * walks, each started with the best lower bound borrowed from its neighbours
 * v + (nb_x[k], nb_y[k]), k < n_nb: vertices further along almost the same line (nb_d[k]
 * is the neighbour's distance along the direction). A neighbour whose occluder lies at
 * distance occ[w] from it gives v the surface point at distance nb_d[k] + occ[w] on v's
 * own ray, a true lower bound of v's supremum (less a rounding margin), so the mipmap skips
 * more and the result is unchanged: the maximum over v's own breakpoints, as in
 * hf_horizon_walk. Rows are taken in blocks of block_rows, in order of rank (rank 0: the
 * row furthest along dy), far vertices first within a row; only neighbours in the same
 * block are borrowed from, so results do not depend on how blocks are shared out. Blocks
 * [block_start, block_stop). occ[v] receives the distance of v's maximum (NaN: none).
 * max_distance: inf for unlimited. */
void hf_horizon_chain(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip, double dx,
                      double dy, double max_distance, int64_t n_nb, const int64_t *nb_x,
                      const int64_t *nb_y, const double *nb_d, int64_t block_rows,
                      int64_t block_start, int64_t block_stop, double *out, double *occ,
                      hf_chain_stats *stats);

#endif
