/* The walk of one ray over the footprint's cells that every per-vertex terrain kernel
 * shares (terrain.c: horizons, viewsheds; horizon_fast.c: the chain walk): the ray, the
 * breakpoints of one cell (its exit faces and its diagonal crossing), the surface where it
 * leaves a cell, the end of the ray on its last linear piece, and the max-mipmap tile step
 * (Tevs, Ihrke & Seidel 2008; tile geometry: core/mipmap.h). Each kernel keeps its own
 * loop, what it does at a breakpoint (its visitor) and its skip test; the expressions are
 * written here once, so the kernels round alike. */
#ifndef HFTRACE_RAY_WALK_H
#define HFTRACE_RAY_WALK_H

#include <math.h>
#include <stdint.h>
#include "core/mipmap.h"
#include "surfaces/surfaces.h"

/* The one infinity of the terrain kernels (a ray parameter never reached). */
#define HF_HZ_INF HUGE_VAL

/* A max-mipmap of the cell maxima: level k holds tiles of 2^k x 2^k cells. */
typedef struct {
    int32_t n_levels;
    const double *data;    /* every level, concatenated                           */
    const int64_t *offset; /* (n_levels,) start of each level in data             */
    const int64_t *rows;   /* (n_levels,) tile rows per level                     */
    const int64_t *cols;   /* (n_levels,) tile columns per level                  */
} hf_hz_mip;

/* A ray o + t d over the cells of the footprint [0, nx] x [0, ny]. */
typedef struct {
    double ox, oy, dx, dy, inv_dx, inv_dy;
    int sx, sy;     /* the sign of dx, dy: -1, 0 or 1 */
    int64_t nx, ny; /* cells: cols - 1, rows - 1 */
} hf_hz_ray;

/* The ray's direction and the grid; the origin is set per vertex. */
static inline void hf_hz_ray_direction(hf_hz_ray *r, int64_t rows, int64_t cols, double dx,
                                       double dy) {
    r->dx = dx;
    r->dy = dy;
    r->sx = dx > 0 ? 1 : dx < 0 ? -1 : 0;
    r->sy = dy > 0 ? 1 : dy < 0 ? -1 : 0;
    r->inv_dx = r->sx ? 1.0 / dx : 0.0;
    r->inv_dy = r->sy ? 1.0 / dy : 0.0;
    r->nx = cols - 1;
    r->ny = rows - 1;
}

/* Where the ray leaves the footprint [0, nx] x [0, ny]. */
static inline double hf_hz_footprint_exit(const hf_hz_ray *r) {
    double tx = r->sx > 0   ? ((double)r->nx - r->ox) * r->inv_dx
                : r->sx < 0 ? -r->ox * r->inv_dx
                            : HF_HZ_INF;
    double ty = r->sy > 0   ? ((double)r->ny - r->oy) * r->inv_dy
                : r->sy < 0 ? -r->oy * r->inv_dy
                            : HF_HZ_INF;
    return tx < ty ? tx : ty;
}

/* floor(x) clamped to [lo, hi], by truncation: equal to clamping floor(x) whenever
 * lo >= 0 (truncation and floor differ only on (-1, 0) and below, all clamped to lo), and
 * no libm call. */
static inline int64_t hf_hz_clamped_floor(double x, int64_t lo, int64_t hi) {
    const int64_t v = (int64_t)x;
    return v < lo ? lo : v > hi ? hi : v;
}

/* The surface where the ray leaves its cell through the face x = X (tX < tY), y = Y
 * (tY < tX) or the vertex (X, Y): the two-triangle surface on a grid line is the lerp of
 * its two ends (w = 1 on the far border). */
static inline double hf_hz_exit_value(const double *H, int64_t rows, int64_t cols,
                                      const hf_hz_ray *r, int64_t X, int64_t Y, double tX,
                                      double tY) {
    if (tX < tY) { /* on the column x = X */
        double y = r->oy + tX * r->dy;
        int64_t j = hf_hz_clamped_floor(y, 0, rows - 2);
        return hf_lerp_ends(H[j * cols + X], H[(j + 1) * cols + X], y - (double)j);
    }
    if (tY < tX) { /* on the row y = Y */
        double x = r->ox + tY * r->dx;
        int64_t i = hf_hz_clamped_floor(x, 0, cols - 2);
        return hf_lerp_ends(H[Y * cols + i], H[Y * cols + i + 1], x - (double)i);
    }
    return H[Y * cols + X];
}

/* ---- the breakpoints of one cell ------------------------------------------------------ */
/* Cell (ci, cj), entered at t_in: the faces X, Y it leaves by and their parameters tX, tY
 * (inf on an axis the ray does not cross), t_out = min(tX, tY), and the crossing td of
 * the diagonal u = v inside (t_in, t_out) with the surface sd there (crossed = 0 and
 * td = -inf when there is none). ddiag = dx - dy and c0 = ox - oy are the ray's. The
 * crossing is divided, not multiplied by an inverse: exact at vertices. */
typedef struct {
    int64_t X, Y;
    double tX, tY, t_out, td, sd;
    int crossed;
} hf_hz_cell;

/* The exit faces of cell (ci, cj) alone (X, Y, tX, tY, t_out; no diagonal): what a walk
 * needs to step past a cell it proves below its bound. */
static inline hf_hz_cell hf_hz_cell_faces(const hf_hz_ray *r, int64_t ci, int64_t cj) {
    hf_hz_cell c;
    c.X = r->sx > 0 ? ci + 1 : ci;
    c.Y = r->sy > 0 ? cj + 1 : cj;
    c.tX = r->sx ? ((double)c.X - r->ox) * r->inv_dx : HF_HZ_INF;
    c.tY = r->sy ? ((double)c.Y - r->oy) * r->inv_dy : HF_HZ_INF;
    c.t_out = c.tX < c.tY ? c.tX : c.tY;
    c.td = -HF_HZ_INF;
    c.sd = 0.0;
    c.crossed = 0;
    return c;
}

/* Step from cell (*ci, *cj), whose faces c holds, to the next cell along the ray, and
 * update c to the new cell's faces: only the face parameters of the axes stepped along
 * change, each by the expression of hf_hz_cell_faces (so the values are the same bits). */
static inline void hf_hz_cell_step(const hf_hz_ray *r, hf_hz_cell *c, int64_t *ci, int64_t *cj) {
    const int step_x = c->tX <= c->tY, step_y = c->tY <= c->tX;
    if (step_x) {
        *ci += r->sx;
        c->X += r->sx;
        c->tX = ((double)c->X - r->ox) * r->inv_dx;
    }
    if (step_y) {
        *cj += r->sy;
        c->Y += r->sy;
        c->tY = ((double)c->Y - r->oy) * r->inv_dy;
    }
    c->t_out = c->tX < c->tY ? c->tX : c->tY;
}

/* The diagonal crossing of cell (ci, cj) entered at t_in, into c, which holds the cell's
 * faces (hf_hz_cell_faces). */
static inline void hf_hz_cell_diagonal(const double *H, int64_t cols, const hf_hz_ray *r,
                                       hf_hz_cell *c, int64_t ci, int64_t cj, double t_in,
                                       double ddiag, double c0) {
    c->td = ddiag != 0.0 ? ((double)(ci - cj) - c0) / ddiag : -HF_HZ_INF;
    c->sd = 0.0;
    c->crossed = c->td > t_in && c->td < c->t_out;
    if (c->crossed) {
        double u = r->ox + c->td * r->dx - (double)ci;
        const double *corner = H + cj * cols + ci;
        u = u < 0.0 ? 0.0 : u > 1.0 ? 1.0 : u;
        c->sd = hf_lerp(corner[0], corner[cols + 1], u);
    } else {
        c->td = -HF_HZ_INF;
    }
}

static inline hf_hz_cell hf_hz_cell_breakpoints(const double *H, int64_t cols, const hf_hz_ray *r,
                                                int64_t ci, int64_t cj, double t_in, double ddiag,
                                                double c0) {
    hf_hz_cell c = hf_hz_cell_faces(r, ci, cj);
    hf_hz_cell_diagonal(H, cols, r, &c, ci, cj, t_in, ddiag, c0);
    return c;
}

/* ---- the end of the ray --------------------------------------------------------------- */
/* A breakpoint handed to a visitor: the surface there is s + delta. */
typedef struct {
    double t, s, delta;
} hf_hz_point;

/* The end t_end of a ray, in the last cell c (entered at t_in where the surface is s_in;
 * t_end <= c.t_out). The end lies on the linear piece from the last breakpoint before it
 * (the diagonal crossing, the cell's entry, or the origin) to the first after it.
 * Interpolating between them keeps the ratio exact however close the end is to the
 * origin, where o + t d would round back onto o: on the first piece the ratio to the
 * origin is constant, so its far end is used, exact however small t_end is; elsewhere the
 * end is taken from the nearer end of its piece, with delta relative to it, so a visitor
 * can subtract its reference height before adding a tiny delta (no cancellation). */
static inline hf_hz_point hf_hz_end_point(const double *H, int64_t rows, int64_t cols,
                                          const hf_hz_ray *r, const hf_hz_cell *c, double t_in,
                                          double s_in, double t_end) {
    const double t0 = c->td > t_in && c->td <= t_end ? c->td : t_in;
    const double s0 = t0 == c->td ? c->sd : s_in;
    double t1, s1;
    hf_hz_point p;
    if (c->td > t_end) {
        t1 = c->td;
        s1 = c->sd;
    } else {
        t1 = c->t_out;
        s1 = hf_hz_exit_value(H, rows, cols, r, c->X, c->Y, c->tX, c->tY);
    }
    if (t0 == 0.0) {
        p.t = t1;
        p.s = s1;
        p.delta = 0.0;
    } else {
        const double f = t1 > t0 ? (t_end - t0) / (t1 - t0) : 0.0;
        p.t = t_end;
        if (f <= 0.5) {
            p.s = s0;
            p.delta = (s1 - s0) * f;
        } else {
            p.s = s1;
            p.delta = (s0 - s1) * (1.0 - f);
        }
    }
    return p;
}

/* ---- breakpoints of a shared pattern --------------------------------------------------
 * A shared pattern (hf_hz_pattern, horizon_rows) lists one direction's breakpoints once
 * for every vertex: breakpoint e lies between the vertices at offsets off_a[e] and
 * off_b[e] from the vertex, with weight w[e], at distance 1 / inv_t[e]. */

/* The horizon ratio (rise over distance) of surface s seen from height h. */
static inline double hf_hz_ratio(double s, double h, double inv_t) {
    return (s - h) * inv_t;
}

/* The surface at breakpoint e, from the vertex at `base`. */
static inline double hf_hz_breakpoint(const double *base, const int64_t *off_a,
                                      const int64_t *off_b, const double *w, int64_t e) {
    return hf_lerp(base[off_a[e]], base[off_b[e]], w[e]);
}

/* The surface at the pattern's end (max_distance), a fraction end_f of the way from
 * breakpoint k to breakpoint k + 1. */
static inline double hf_hz_pattern_end(const double *base, const int64_t *off_a,
                                       const int64_t *off_b, const double *w, int64_t k,
                                       double end_f) {
    const double sa = hf_hz_breakpoint(base, off_a, off_b, w, k);
    const double sb = hf_hz_breakpoint(base, off_a, off_b, w, k + 1);
    return hf_lerp(sa, sb, end_f);
}

/* ---- the max-mipmap tile step --------------------------------------------------------- */
/* The tile at `level` around cell (ci, cj): its maximum, its exit faces X1, Y1 (on the
 * footprint's border at the latest), the parameters there and t_exit, the smaller,
 * clipped to t_end. */
typedef struct {
    double max;
    int64_t X1, Y1;
    double t_exit_x, t_exit_y, t_exit;
} hf_hz_tile;

static inline hf_hz_tile hf_hz_tile_at(const hf_hz_ray *r, const hf_hz_mip *mip, int level,
                                       int64_t ci, int64_t cj, double t_end) {
    const int64_t tile_i = ci >> level, tile_j = cj >> level;
    hf_hz_tile e;
    e.max = mip->data[mip->offset[level] + tile_j * mip->cols[level] + tile_i];
    e.X1 = hf_tile_face(tile_i, level, r->sx > 0);
    e.Y1 = hf_tile_face(tile_j, level, r->sy > 0);
    if (e.X1 > r->nx) e.X1 = r->nx;
    if (e.Y1 > r->ny) e.Y1 = r->ny;
    e.t_exit_x = r->sx ? hf_face_t(e.X1, r->ox, r->inv_dx) : HF_HZ_INF;
    e.t_exit_y = r->sy ? hf_face_t(e.Y1, r->oy, r->inv_dy) : HF_HZ_INF;
    e.t_exit = e.t_exit_x < e.t_exit_y ? e.t_exit_x : e.t_exit_y;
    if (e.t_exit > t_end) e.t_exit = t_end;
    return e;
}

/* After skipping tile e at `level`: the cell the ray enters next, into (*ci, *cj) (through
 * the last tile's exit face the next index is the footprint's edge: the walk ends there),
 * and the surface there into *s_in. */
static inline void hf_hz_tile_leave(const double *H, int64_t rows, int64_t cols, const hf_hz_ray *r,
                                    const hf_hz_tile *e, int level, int64_t *ci, int64_t *cj,
                                    double *s_in) {
    const int64_t tile_i = *ci >> level, tile_j = *cj >> level;
    *s_in = hf_hz_exit_value(H, rows, cols, r, e->X1, e->Y1, e->t_exit_x, e->t_exit_y);
    *ci = e->t_exit_x <= e->t_exit_y
              ? (r->sx > 0 ? e->X1 : e->X1 - 1)
              : hf_tile_next_cell(0, tile_i, level, r->nx, r->sx >= 0, r->ox + e->t_exit * r->dx);
    *cj = e->t_exit_y <= e->t_exit_x
              ? (r->sy > 0 ? e->Y1 : e->Y1 - 1)
              : hf_tile_next_cell(0, tile_j, level, r->ny, r->sy >= 0, r->oy + e->t_exit * r->dy);
}

/* The first level a skip tries: one above the last skipped (or 0), at most the top. */
static inline int hf_hz_skip_start(const hf_hz_mip *mip, int level) {
    const int top = mip->n_levels - 1;
    return level + 1 < top ? level + 1 : top;
}

#endif
