/* Terrain products on the two-triangle surface: horizon angles and line of sight.
 *
 * Conventions: docs/CONVENTIONS.md ("Terrain products"). Heights are float64,
 * (rows, cols), C order, H[j * cols + i] the height of vertex (i, j). The surface is the
 * two-triangle one, split on the diagonal u = v, or, in a mirrored frame, on u + v = 1.
 *
 * Along a straight line the surface is piecewise linear. Its breakpoints are where the line
 * crosses a grid line x = k, y = k, or a cell diagonal. At every breakpoint the surface is
 * the linear interpolation between the two ends of the edge or diagonal crossed, so every
 * kernel here evaluates it as H[a] * (1 - w) + H[b] * w.
 *
 * The Python layer (algos/terrain.py) validates every argument. It builds the patterns and
 * the octant frames and resolves the uncertain line-of-sight cases exactly. */
#ifndef HF_TERRAIN_H
#define HF_TERRAIN_H

#include <stdint.h>
#include "terrain/ray_walk.h"

/* One breakpoint of a shared pattern, relative to the ray's start vertex. The surface
 * there is H[v + off_a] * (1 - w) + H[v + off_b] * w, where v is the start vertex's linear
 * index. inv_t is 1 / (distance from the start vertex). */
typedef struct {
    int64_t n;              /* breakpoints                                              */
    const double *inv_t;    /* (n,)                                                     */
    const int64_t *off_a;   /* (n,)                                                     */
    const int64_t *off_b;   /* (n,)                                                     */
    const double *w;        /* (n,)                                                     */
    const int64_t *limit_x; /* (cols,): the breakpoints a vertex with cols-1-i = k may use */
    const int64_t *limit_y; /* (rows,): the same for rows-1-j                           */
    int64_t end_k;          /* max_distance ends between breakpoints end_k and end_k + 1  */
                            /* (-1: no end); the main loop stops after end_k             */
    double end_f;           /* the end's fraction of the way from end_k to end_k + 1      */
    double end_inv_t;       /* 1 / max_distance                                         */
} hf_hz_pattern;

/* Curvature (kappa, in every horizon kernel): the surface at distance t from the start
 * vertex is lowered by kappa t^2 (kappa = (1 - refraction) dx / (2 R) in cell units), so
 * the tangent is the supremum of (s - H[v] - kappa t^2) / t. On a linear piece that ratio
 * can peak inside the piece (algos/terrain.py, "Curvature"): the exact kernels evaluate
 * every breakpoint, every piece's interior peak and the first piece's slope limit. A
 * negative kappa raises the surface (no peak, no early stop or tile skipping). kappa = 0
 * runs the uncurved loops, bit for bit. */

/* Horizon tangents by one shared pattern (octant frame: direction dx >= dy >= 0).
 * Vertices [start, stop) in C order; out[v] = sup over the vertex's valid breakpoints of
 * (s - H[v]) / distance, or -inf when it has none. zmax: the highest height, for the early
 * stop (every stop_every breakpoints, the walk ends once (zmax - H[v]) / distance <= best);
 * stop_every = 0 disables it. kappa: curvature (above). */
void hf_horizon_pattern(const double *H, int64_t rows, int64_t cols, const hf_hz_pattern *p,
                        double zmax, int64_t stop_every, double kappa, int64_t start, int64_t stop,
                        double *out);

/* Horizon tangents of every vertex by the rational-direction sweep (octant frame, direction
 * (q, p) with q >= p >= 0, q >= 1, gcd 1). The period pattern holds the breakpoints of one
 * period, from a vertex (exclusive) to the next vertex on its line (inclusive, last): their
 * parameters tfrac in (0, 1], the interpolation offsets (dxa, dya) and (dxb, dyb) relative to
 * the period's first vertex, the weight w, and (mx, my), the largest x and y offsets read.
 * norm = sqrt(q^2 + p^2). Only the lines c = p x - q y with c - c_min in [k_lo, k_hi) are
 * swept (c_min = -q (rows - 1); all lines: 0 and q (rows - 1) + p (cols - 1) + 1), so
 * threads can share the field, each with its own range: lines write disjoint vertices.
 * Returns 0, or -1 when memory runs out. */
int hf_horizon_sweep(const double *H, int64_t rows, int64_t cols, int64_t q, int64_t p,
                     int64_t n_entries, const double *tfrac, const int64_t *dxa, const int64_t *dya,
                     const int64_t *dxb, const int64_t *dyb, const double *w, const int64_t *mx,
                     const int64_t *my, double norm, int64_t k_lo, int64_t k_hi, double *out);

/* Walk statistics, summed over a batch. */
typedef struct {
    int64_t cells; /* cells evaluated                                                */
    int64_t skips; /* tiles (or cells) skipped by the mipmap                          */
} hf_hz_stats;

/* Per-vertex horizon walks in the original frame, along the unit direction (dx, dy):
 * vertices [start, stop), max_distance (inf: to the edge of the footprint), mip NULL for
 * the plain cell walk. out[v] as in hf_horizon_pattern; kappa: curvature (above; kappa < 0
 * ignores mip). */
void hf_horizon_walk(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip, double dx,
                     double dy, double max_distance, double kappa, int64_t start, int64_t stop,
                     double *out, hf_hz_stats *stats);

/* Line of sight from the observer (ox, oy, z0) to every target vertex in [start, stop):
 * the segment to (i, j, H + target_height) is blocked when the surface rises strictly
 * above it. drop > 0 lowers the surface by drop * d^2 (curvature and refraction; d the
 * horizontal distance from the observer). Writes 0 visible, 1 blocked, 2 uncertain (a
 * breakpoint within eps of the segment and none clearly above: resolved by the caller).
 * The target vertex itself is not tested; mip may be NULL. */
void hf_viewshed(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip, double ox,
                 double oy, double z0, double target_height, double drop, double eps, int64_t start,
                 int64_t stop, uint8_t *out, hf_hz_stats *stats);

/* Viewshed thresholds (the kinds of hf_viewshed_threshold). */
enum { HF_VS_TARGET = 0, HF_VS_OBSERVER = 1 };

/* For every target vertex in [start, stop), the maximum over the breakpoints t in (0, 1)
 * of the segment from the observer (ox, oy, z0) to the vertex, of
 *   HF_VS_TARGET:   (sigma - z0) / t          (the target top must reach z0 + that),
 *   HF_VS_OBSERVER: (sigma - z1 t) / (1 - t)  (the eye must reach that),
 * where sigma is the surface lowered by drop * d^2 and z1 = H + target_height - drop * D^2
 * the target top (D the target's distance). -inf where the segment has no breakpoint (the
 * observer's own vertex, or a neighbour along an edge). mip may be NULL. */
void hf_viewshed_threshold(const double *H, int64_t rows, int64_t cols, const hf_hz_mip *mip,
                           double ox, double oy, double z0, double target_height, double drop,
                           int kind, int64_t start, int64_t stop, double *out, hf_hz_stats *stats);

/* The r.horizon-style marcher: samples the surface every `step` along the unit direction,
 * stopping at the footprint, at max_distance, or once (zmax - H) / distance <= best. kappa
 * lowers each sample by kappa t^2 (a baseline: no piece peaks). */
void hf_horizon_march(const double *H, int64_t rows, int64_t cols, double dx, double dy,
                      double step, double max_distance, double zmax, double kappa, int64_t start,
                      int64_t stop, double *out, hf_hz_stats *stats);

#endif
