/* Fast horizon kernels on the two-triangle surface (split u = v in the grid's own frame):
 * the row-vectorised shared pattern for bounded radii, and the chain walk, a per-vertex
 * breakpoint walk that skips along max-trees of strips parallel to the direction and
 * starts from a lower bound borrowed from a vertex further along almost the same line. Conventions
 * as in terrain.h; algos/terrain.py validates every argument and builds the patterns and the
 * neighbour lists. */
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
    int64_t skips;      /* strip stretches skipped                                    */
    int64_t tile_tests; /* strip bins tested (any level)                              */
    int64_t bounded;    /* vertices that started with a borrowed lower bound          */
    int64_t cell_skips; /* cells stepped past by their highest corner                 */
} hf_chain_stats;

/* Strips along one direction (the chain walk's bound, shared by parallel rays). With the
 * unit direction (dx, dy), a point (x, y) lies at c = dx y - dy x across the direction and
 * a = dx x + dy y along it. Strip k holds the lines c in [c_min + k width, c_min + (k + 1)
 * width); its bin b at level l covers a in [a_min + b bin 2^l, a_min + (b + 1) bin 2^l)
 * and holds the largest corner height of every cell that a line of the strip crosses
 * there (each cell's c and a ranges widened by HF_STRIP_SLACK against rounding), so it
 * bounds the two-triangle surface at every point of every ray of the strip in that range.
 * Level l + 1 is the pairwise maximum of level l; the top level has one bin. Levels are
 * concatenated in data, level l at offset[l], n_bins[l] rows of n_strips values (bin b of
 * strip k at offset[l] + b n_strips + k): the vertices of a grid row lie in neighbouring
 * strips at almost the same distance along, so their walks read neighbouring values. */
typedef struct {
    int32_t n_levels;
    int64_t n_strips;
    const int64_t *n_bins; /* (n_levels,) */
    const int64_t *offset; /* (n_levels,) */
    const float *data;     /* rounded up from the heights: bounds still */
    double c_min, a_min, width, bin;
    double inv_bin; /* 1 / bin, exact: bin is a power of two */
} hf_hz_strips;

/* The widening of every cell's c and a ranges (cells): far above the rounding of the
 * coordinates of grids up to 2^24 a side (about 1e-8), far below a cell. */
#define HF_STRIP_SLACK 1e-6

/* The strips' frame for a grid of rows x cols vertices and the unit direction (dx, dy):
 * c_min, a_min, the strips and the level-0 bins per strip (every footprint point inside,
 * with two strips and bins of margin on each side). width, bin > 0. Returns 0, or -1 when
 * the counts would not fit in int64 arithmetic (a caller's error). */
int hf_horizon_strips_frame(int64_t rows, int64_t cols, double dx, double dy, double width,
                            double bin, double *c_min, double *a_min, int64_t *n_strips,
                            int64_t *n_bins0);

/* Fill the strips (s->data writable through `data`, the frame from
 * hf_horizon_strips_frame, offsets and bins per level as above). */
void hf_horizon_strips_build(const double *H, int64_t rows, int64_t cols, double dx, double dy,
                             const hf_hz_strips *s, float *data);

/* Horizon tangents along the unit direction (dx, dy) (grid frame) by per-vertex walks over
 * the breakpoints, each skipping the stretches of its ray where the strips (above) prove
 * that no point can beat its pruning bound, and each started with the best lower bound
 * borrowed from its neighbours v + (nb_x[k], nb_y[k]), k < n_nb: vertices further along
 * almost the same line (nb_d[k] is the neighbour's distance along the direction). A
 * neighbour whose occluder lies at distance occ[w] from it gives v the surface point at
 * distance nb_d[k] + occ[w] on v's own ray, a true lower bound of v's supremum (less a
 * rounding margin), so more is skipped and the result is unchanged: the maximum over v's
 * own breakpoints, as in hf_horizon_walk. Rows are taken in blocks of block_rows, in order
 * of rank (rank 0: the row furthest along dy), far vertices first within a row; only
 * neighbours in the same block are borrowed from, so results do not depend on how blocks
 * are shared out. Blocks [block_start, block_stop). occ[v] receives the distance of v's
 * maximum (NaN: none). max_distance: inf for unlimited. */
void hf_horizon_chain(const double *H, int64_t rows, int64_t cols, const hf_hz_strips *strips,
                      double dx, double dy, double max_distance, int64_t n_nb, const int64_t *nb_x,
                      const int64_t *nb_y, const double *nb_d, int64_t block_rows,
                      int64_t block_start, int64_t block_stop, double *out, double *occ,
                      hf_chain_stats *stats);

#endif
