/* The max-mipmap tile step (Tevs, Ihrke & Seidel 2008), shared by its three consumers:
 * the cell walk of dda_maxmip (hierarchies/maxmip.h), the run walk of runs_maxmip (runs.c) and the
 * terrain products' skip (terrain.c). Each consumer keeps its own floor walk (cells, runs,
 * breakpoints); the tile geometry and the bound are written once, here.
 *
 * Names, in every consumer: `level` is a mipmap level, whose tiles hold 2^level x 2^level
 * cells (level 0: one cell; `floor_level`: the finest level a walk descends to);
 * `tile_i`, `tile_j` are a tile's indices at its level; `t_exit_x`, `t_exit_y` are the
 * parameters at which the ray leaves the tile through its x and y exit faces, and
 * `t_exit` the smaller of the two, clipped to the ray's end. A direction component's
 * `forward` is 1 when it is positive (the exit face of index k is then k + 1), else 0. */
#ifndef HFTRACE_MIPMAP_H
#define HFTRACE_MIPMAP_H

#include <math.h>
#include <stdint.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

/* x clamped to [-2^30, 2^30], NaN to -2^30: with SSE2 (the x86-64 baseline) by maxsd,
 * which gives its second operand when either is NaN, and minsd, without jumps. */
static inline double hf_clamp_2p30(double x) {
#if defined(__SSE2__)
    const __m128d lo = _mm_set_sd(-1073741824.0), hi = _mm_set_sd(1073741824.0);
    return _mm_cvtsd_f64(_mm_min_sd(_mm_max_sd(_mm_set_sd(x), lo), hi));
#else
    const double above = x > -1073741824.0 ? x : -1073741824.0;
    return above < 1073741824.0 ? above : 1073741824.0;
#endif
}

/* The index of the cell holding coordinate x along one axis, by the forward rule: [k, k+1)
 * moving forward (or along the axis), (k, k+1] moving back; x is clamped to +-2^30 first
 * (every grid lies inside; NaN goes to -2^30), so the conversion is always defined. floor and ceil
 * by truncation: without SSE4.1 they would be library calls. */
static inline int64_t hf_index_of(double x, int forward) {
    const double c = hf_clamp_2p30(x);
    const int64_t k = (int64_t)c;            /* c rounded toward zero */
    if (forward) return k - ((double)k > c); /* floor(c) */
    return k + ((double)k < c) - 1;          /* ceil(c) - 1 */
}

/* The grid coordinate of the exit face of tile `tile` at `level` along one axis. */
static inline int64_t hf_tile_face(int64_t tile, int level, int forward) {
    return (tile + forward) << level;
}

/* The ray's parameter at the grid line `face` of one axis (origin o, inverse direction
 * inv): the same expression as the exact cell interval's, so both round alike. */
static inline double hf_face_t(int64_t face, double o, double inv) {
    return ((double)face - o) * inv;
}

/* Which faces of a tile the ray leaves by, and where: t_exit_x, t_exit_y are its exit
 * parameters through the x and y exit faces (inf along an axis it does not move on) and
 * t1 the end of its range. Returns t_exit, the first of the three (x before the end, y
 * before both, ties to the earlier one as written), and sets *exits: bit 0 when it leaves
 * through the x face, bit 1 through the y face (both at a corner), 0 when the range ends
 * first. Written with selects and comparisons only: which face a random ray leaves by is
 * a coin toss, and a conditional jump on it is mispredicted about every other tile. */
static inline double hf_tile_exit(double t_exit_x, double t_exit_y, double t1, int *exits) {
    const int ax = t_exit_x < t1;
    const double m = ax ? t_exit_x : t1;
    const int ay = t_exit_y < m, both = ax & (t_exit_y == m);
    *exits = (ax & !ay) | ((ay | both) << 1);
    return ay ? t_exit_y : m;
}

/* The ray's lowest z over a tile it crosses on [t_in, t_exit]: z at the exit when it
 * descends, else z at the entry. The tile is skipped when this is above its maximum. */
static inline double hf_tile_zlow(double oz, double dz, int descending, double t_in,
                                  double t_exit) {
    return oz + (descending ? t_exit : t_in) * dz;
}

/* The first and last cell index of tile `tile` at `level` along an axis of n cells. */
static inline void hf_tile_cells(int64_t tile, int level, int64_t n, int64_t *lo, int64_t *hi) {
    *lo = tile << level;
    *hi = ((tile + 1) << level) - 1;
    if (*hi > n - 1) *hi = n - 1;
}

/* The cell index along one axis after leaving tile `tile`:
 * - through this axis's exit face: the first cell of the next tile (one past the tile in
 *   the travel direction; outside the grid when the tile was the last);
 * - through the other axis's face: the cell holding coordinate x at the exit (forward
 *   rule: [k, k+1) moving forward, (k, k+1] moving back), clamped into the tile just
 *   left, so rounding never moves the walk backwards or into a tile it did not test. */
static inline int64_t hf_tile_next_cell(int exits_here, int64_t tile, int level, int64_t n,
                                        int forward, double x) {
    int64_t lo, hi, c;
    if (exits_here) return forward ? (tile + 1) << level : (tile << level) - 1;
    hf_tile_cells(tile, level, n, &lo, &hi);
    c = hf_index_of(x, forward);
    return c < lo ? lo : (c > hi ? hi : c);
}

#endif
