/* Cone step mapping (Dummer 2006), made exact for first hits.
 *
 * The structure (built by algos/cone.py, one pair of float32 per cell c):
 *   cone_top[c]   T_c, the highest cell maximum among c and its 8 neighbours;
 *   cone_slope[c] k_c >= 0, rounded up, such that every surface point q of the field
 *                 (walls included) satisfies s(q) <= T_c + k_c d(q, c), where d is the
 *                 Chebyshev (L-infinity) distance from q to the closed square of c.
 * So the set {z > T_c + k_c d} is empty of solid: an upward cone over the cell, with a
 * flat top T_c over the cell itself. A ray point p(t) over cell c with z(t) > T_c moves
 * by at most `speed` = max(|dx|, |dy|) per unit t in that distance, so it stays in the
 * cone while z(t) - T_c > s (k_c speed - dz): the cone step s = (z(t) - T_c) /
 * (k_c speed - dz), or the rest of the ray when k_c speed <= dz (no hit at all).
 *
 * Exactness: a step is shortened by a margin that covers the rounding of z(t), of the
 * position and of the step itself (2^-40 of the magnitudes involved, against errors of
 * a few 2^-53), so no skipped parameter can hold a hit. Where the cone is too narrow for
 * a step of at least one cell (near the surface: grazing rays, where cones collapse), the
 * walk tests one cell exactly (hf_hit_cell_exact, as every cell kernel does) and steps to
 * the next cell by its exit faces, as dda_maxmip's floor walk does. A landing cell is
 * accepted only if the ray enters it at or before the landing parameter, so rounding in
 * the landing position can never skip the rest of the cell the ray is really in; a step
 * that fails this check is not taken. Hits are therefore those of the cell walk. */
#include <math.h>
#include "hierarchies/cone.h"
#include "surfaces/hitbatch.h"
#include "walks/walk.h"
#include "core/mipmap.h"

/* A cone step must move the ray at least this many cells (Chebyshev) to be taken. */
#ifndef HF_CONE_MIN_CELLS
#define HF_CONE_MIN_CELLS 1.0
#endif

int hf_cone_hit(hf_hit *h, const float *cone) {
    const int32_t nx = h->cols - 1, ny = h->rows - 1;
    const int descending = h->dz < 0;
    const int fx = h->dx > 0, fy = h->dy > 0; /* exit face of index k: k + f */
    const int32_t sx = fx ? 1 : -1, sy = fy ? 1 : -1;
    const int has_x = h->dx != 0, has_y = h->dy != 0;
    const double ox = h->ox, oy = h->oy, oz = h->oz_cull, dz = h->dz, t1 = h->t1;
    const double inv_x = h->inv_dx, inv_y = h->inv_dy, inf = (double)INFINITY;
    const double speed = fabs(h->dx) > fabs(h->dy) ? fabs(h->dx) : fabs(h->dy);
    const double position_scale = fabs(ox) + fabs(oy);
    const float *cellmax = h->cellmax;
    const int cull = h->cull_cells;
    double t = h->t0;
    int32_t i = hf_cell_at(ox, h->dx, t, nx), j = hf_cell_at(oy, h->dy, t, ny);
    int64_t guard;
    /* every pass moves to another cell (a cone step moves at least one cell) */
    for (guard = 0; guard <= 4 * ((int64_t)nx + ny) + 64; ++guard) {
        const int64_t cell = (int64_t)j * nx + i;
        const double mx = has_x ? hf_face_t((int64_t)i + fx, ox, inv_x) : inf;
        const double my = has_y ? hf_face_t((int64_t)j + fy, oy, inv_y) : inf;
        const double t_out = mx < my ? (mx < t1 ? mx : t1) : (my < t1 ? my : t1);
        const double z = oz + t * dz, top = (double)cone[2 * cell];
        if (z > top) {
            /* above the cone's top: how far the cone over this cell lets the ray go */
            const double slope = (double)cone[2 * cell + 1];
            const double margin =
                0x1p-40 * (1.0 + fabs(z) + fabs(top) + slope * (position_scale + speed * fabs(t)));
            const double gap = z - top - margin;
            const double rate = slope * speed - dz; /* how fast the cone closes on the ray */
            if (gap > 0) {
                double step, t_land;
                if (!(rate > 0)) return 0; /* the ray rises faster than every cone: no hit */
                step = gap / rate * (1.0 - 0x1p-40);
                t_land = t + step;
                if (!(t_land < t1)) return 0; /* the cone covers the rest of the ray */
                if (step * speed >= HF_CONE_MIN_CELLS && t_land > t_out) {
                    const int32_t ni = hf_cell_at(ox, h->dx, t_land, nx);
                    const int32_t nj = hf_cell_at(oy, h->dy, t_land, ny);
                    /* the ray must have entered the landing cell by t_land */
                    const double entry_x = has_x ? hf_face_t((int64_t)ni + !fx, ox, inv_x) : -inf;
                    const double entry_y = has_y ? hf_face_t((int64_t)nj + !fy, oy, inv_y) : -inf;
                    if (entry_x <= t_land && entry_y <= t_land) {
                        h->tiles_skipped += 1;
                        t = t_land;
                        i = ni;
                        j = nj;
                        continue;
                    }
                }
            }
        }
        /* one cell, exactly: the cheap cull by z at its exit (descending) or entry, then
         * the exact interval and surface test */
        h->cells_visited += 1;
        if (!cull || !(oz + (descending ? t_out : t) * dz > (double)cellmax[cell])) {
            if (hf_hit_cell_exact(h, i, j)) return 1;
        }
        if (!(t_out < t1)) return 0;
        if (mx < my) {
            i += sx;
        } else if (my < mx) {
            j += sy;
        } else {
            i += sx;
            j += sy;
        }
        if ((uint32_t)i >= (uint32_t)nx || (uint32_t)j >= (uint32_t)ny) return 0;
        t = t_out > t ? t_out : t;
    }
    return 0;
}

/* ---- relaxed cones (Policarpo & Oliveira 2007), approximate by design -----------------
 * The relaxed cone of a cell s has its apex at the centre of s at the cell's maximum M_s
 * and is the widest circular cone that keeps out every point where a ray entering the
 * solid leaves it again: for each destination cell d within `radius` rings, the ray from
 * the field's top above the centre of s through (centre of d, M_d) is followed past d in
 * half-cell steps while it stays at or below the cell maxima; the point E where it comes
 * out (or leaves the window) bounds the cone's slope by (z_E - M_s) / |E - s|. A viewing
 * ray inside such a cone crosses the surface at most once (up to the half-cell sampling
 * and the window), so a step to the cone's side may end inside the solid, and a binary
 * search then finds the crossing. Slopes are vertical per horizontal (Euclidean). */
void hf_cone_relaxed_build(const float *cellmax, int32_t ny, int32_t nx, int32_t radius,
                           float *slope) {
    const int64_t n_cells = (int64_t)ny * nx;
    double top = -(double)INFINITY;
    int64_t c;
    int32_t si, sj;
    for (c = 0; c < n_cells; ++c) top = (double)cellmax[c] > top ? (double)cellmax[c] : top;
    for (sj = 0; sj < ny; ++sj) {
        for (si = 0; si < nx; ++si) {
            const double apex = (double)cellmax[(int64_t)sj * nx + si];
            const double sx = si + 0.5, sy = sj + 0.5;
            double k = 0;
            int32_t di, dj, step;
            for (dj = sj - radius; dj <= sj + radius; ++dj) {
                for (di = si - radius; di <= si + radius; ++di) {
                    double length, ux, uy, drop, px, py, pz;
                    if (dj < 0 || dj >= ny || di < 0 || di >= nx || (di == si && dj == sj))
                        continue;
                    pz = (double)cellmax[(int64_t)dj * nx + di];
                    if (!(pz < top)) continue; /* the ray from the top would not descend */
                    px = di + 0.5;
                    py = dj + 0.5;
                    length = sqrt((px - sx) * (px - sx) + (py - sy) * (py - sy));
                    ux = (px - sx) / length;
                    uy = (py - sy) / length;
                    drop = (top - pz) / length; /* the ray's fall per unit of horizontal travel */
                    /* past d, in half cells, while the ray stays inside the solid */
                    for (step = 0; step < 4 * radius + 4; ++step) {
                        int32_t ci, cj;
                        px += 0.5 * ux;
                        py += 0.5 * uy;
                        pz -= 0.5 * drop;
                        ci = (int32_t)floor(px);
                        cj = (int32_t)floor(py);
                        if (ci < 0 || ci >= nx || cj < 0 || cj >= ny) break;
                        if (ci < si - radius || ci > si + radius || cj < sj - radius ||
                            cj > sj + radius)
                            break;
                        if (pz > (double)cellmax[(int64_t)cj * nx + ci]) break;
                    }
                    if (pz > apex) {
                        const double h = sqrt((px - sx) * (px - sx) + (py - sy) * (py - sy));
                        if (h > 0 && (pz - apex) / h > k) k = (pz - apex) / h;
                    }
                }
            }
            slope[(int64_t)sj * nx + si] = (float)k;
        }
    }
}
