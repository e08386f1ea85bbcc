/* Rasterisers of a height field: zbuffer, painter, floating_horizon (see raster.h).
 *
 * Screen space: X grows to the right and Y downwards, both in pixels, with the centre of
 * pixel (c, k) at (c + 0.5, k + 0.5). A point at camera coordinates (a, b, w) (along
 * right, up, forward) projects to X = (a / (w half_w) + 1) W / 2, Y = (1 - b / (w half_h)) H / 2.
 * Over a planar triangle 1/w is an affine function of (X, Y): it is the depth that is
 * interpolated (perspective-correct), and the ray parameter of pixel (c, k) is
 * t = |d| / (1/w), with |d| = sqrt(1 + sx[c]^2 + sy[k]^2) the length of its unnormalised
 * direction. While drawing, r->t holds 1/w (0: nothing drawn yet); the last pass turns it
 * into t.
 *
 * Fill rule (top-left): a pixel centre belongs to a triangle when Y_top <= y < Y_bottom and
 * x_left <= x < x_right, with x_left, x_right the triangle's edges on that row. An edge is
 * tracked from its upper end, and its position on a row depends only on its two end points
 * and the row, so two triangles that share an edge see it at the same x bit for bit: a
 * centre on the shared edge goes to exactly one of them (no cracks, no double hits). */
#include <math.h>
#include <stddef.h>
#include <string.h>
#include "core/hftrace.h"
#include "raster/raster.h"
#include "raster/raster_geometry.h"
#include "raster/warnock.h"
#include "raster/watkins.h"

/* ---- the fragment: one pixel centre inside one triangle ------------------------------- */
static inline void fragment(hf_raster *r, const int algorithm, int64_t pixel, double Z,
                            int64_t id) {
    r->counts[HF_COUNT_FRAGMENTS] += 1;
    if (algorithm == HF_RASTER_ZBUFFER) {
        if (r->coverage) r->coverage[pixel] += 1;
        /* nearer means a larger 1/w; a tie keeps the first */
        if (Z > r->t[pixel]) {
            r->t[pixel] = Z;
            r->primitive[pixel] = id;
            r->counts[HF_COUNT_WRITTEN] += 1;
        }
    } else if (!r->mask[pixel]) {
        /* painter: front to back, so the first fragment at a pixel is the visible one */
        r->mask[pixel] = 1;
        r->t[pixel] = Z;
        r->primitive[pixel] = id;
        r->counts[HF_COUNT_WRITTEN] += 1;
    }
}

/* ---- scan conversion of one triangle (the lecture's trapezoids) ----------------------- */
/* An edge tracker (x, z, x_inc, z_inc) on its upper end's first row: the sub-pixel start
 * moves x and z from the end point to the centre of that row. */
typedef struct {
    double x, z, x_inc, z_inc;
} edge_tracker;

static inline edge_tracker edge_start(const screen_vertex *upper, const screen_vertex *lower,
                                      int32_t first_row) {
    edge_tracker e;
    const double dy = lower->Y - upper->Y, offset = (double)first_row + 0.5 - upper->Y;
    e.x_inc = (lower->X - upper->X) / dy;
    e.z_inc = (lower->Z - upper->Z) / dy;
    e.x = upper->X + offset * e.x_inc;
    e.z = upper->Z + offset * e.z_inc;
    return e;
}

static inline void scan_triangle(hf_raster *r, const int algorithm, const screen_vertex *p0,
                                 const screen_vertex *p1, const screen_vertex *p2, int64_t id) {
    const screen_vertex *top = p0, *mid = p1, *bottom = p2, *swap;
    const int32_t width = r->width, height = r->height;
    double area2, dz_dx, z_lo, z_hi;
    int32_t row_top, row_mid, row_bottom, row;
    edge_tracker long_edge, short_edge;
    int mid_left;
    /* sort the corners by Y: top, mid, bottom */
    if (mid->Y < top->Y) swap = top, top = mid, mid = swap;
    if (bottom->Y < mid->Y) swap = mid, mid = bottom, bottom = swap;
    if (mid->Y < top->Y) swap = top, top = mid, mid = swap;
    area2 = (mid->X - top->X) * (bottom->Y - top->Y) - (bottom->X - top->X) * (mid->Y - top->Y);
    if (!(area2 != 0)) return; /* degenerate on screen (or NaN): no pixel centre inside */
    row_top = first_index(top->Y, height);
    row_mid = first_index(mid->Y, height);
    row_bottom = first_index(bottom->Y, height);
    if (row_top >= row_bottom || row_bottom <= r->row_begin || row_top >= r->row_end) return;
    r->counts[HF_COUNT_TRIANGLES] += 1;
    mid_left = area2 < 0;
    /* 1/w along a row: the plane's X gradient */
    dz_dx = ((mid->Z - top->Z) * (bottom->Y - top->Y) - (bottom->Z - top->Z) * (mid->Y - top->Y)) /
            area2;
    /* Numerical hazard: on a nearly edge-on triangle the gradient is huge and the
     * incremental 1/w can leave the corners' range; 1/w is affine, so clamp it there. */
    z_lo = fmin(top->Z, fmin(mid->Z, bottom->Z));
    z_hi = fmax(top->Z, fmax(mid->Z, bottom->Z));
    long_edge = edge_start(top, bottom, row_top);
    /* the upper trapezoid's short edge; the lower one's replaces it on row_mid */
    short_edge = row_top < row_mid ? edge_start(top, mid, row_top) : long_edge;
    /* Rows above the region only advance the trackers, so that a row's edges are where a
     * whole-image call puts them (results do not depend on the split into regions). */
    if (row_bottom > r->row_end) row_bottom = r->row_end;
    for (row = row_top; row < row_bottom; ++row) {
        const edge_tracker *left, *right;
        int32_t c0, c1, c;
        if (row == row_mid) short_edge = edge_start(mid, bottom, row_mid);
        left = mid_left ? &short_edge : &long_edge;
        right = mid_left ? &long_edge : &short_edge;
        c0 = first_index(left->x, width);
        c1 = first_index(right->x, width);
        if (c0 < c1 && row >= r->row_begin) {
            const int64_t base = (int64_t)row * width;
            double z = left->z + ((double)c0 + 0.5 - left->x) * dz_dx;
            for (c = c0; c < c1; ++c) {
                const double zc = z < z_lo ? z_lo : (z > z_hi ? z_hi : z);
                fragment(r, algorithm, base + c, zc, id);
                z += dz_dx;
            }
        }
        long_edge.x += long_edge.x_inc;
        long_edge.z += long_edge.z_inc;
        short_edge.x += short_edge.x_inc;
        short_edge.z += short_edge.z_inc;
    }
}

/* ---- one triangle in camera space: near-plane clipping, then the scan ---------------- */

static inline void draw_triangle(hf_raster *r, const int algorithm, cam_vertex v0, cam_vertex v1,
                                 cam_vertex v2, int64_t id) {
    screen_vertex s[4];
    const int n = clip_project(r, v0, v1, v2, s);
    if (n < 3) return;
    scan_triangle(r, algorithm, &s[0], &s[1], &s[2], id);
    if (n == 4) scan_triangle(r, algorithm, &s[0], &s[2], &s[3], id);
}

/* ---- cells and skirts ------------------------------------------------------------------- */
/* The two triangles of cell (i, j) from its corners' camera coordinates, the facing ones
 * only. `lower_first`: draw the u >= v triangle first (the painter's order). */
static inline void draw_cell(hf_raster *r, const int algorithm, int32_t i, int32_t j,
                             cam_vertex v00, cam_vertex v10, cam_vertex v01, cam_vertex v11,
                             int lower_first) {
    int lower_faces, upper_faces;
    const int64_t id = cell_faces(r, i, j, &lower_faces, &upper_faces);
    r->counts[HF_COUNT_DRAWN] += 1;
    if (lower_first) {
        if (lower_faces) draw_triangle(r, algorithm, v00, v10, v11, id + HF_KIND_LOWER);
        if (upper_faces) draw_triangle(r, algorithm, v00, v11, v01, id + HF_KIND_UPPER);
    } else {
        if (upper_faces) draw_triangle(r, algorithm, v00, v11, v01, id + HF_KIND_UPPER);
        if (lower_faces) draw_triangle(r, algorithm, v00, v10, v11, id + HF_KIND_LOWER);
    }
}

/* The skirts: the box's side faces below the surface, from the boundary's heights down to
 * z_bottom, on the sides the camera is outside of (the others face away). A ray can meet
 * such a face only where it enters the footprint, before any surface point, and two faces
 * never cover the same ray, so the painter may draw them first. */
static void draw_skirts(hf_raster *r, const int algorithm) {
    int side;
    for (side = 0; side < 4; ++side) {
        const int32_t n = side < 2 ? r->cols - 1 : r->rows - 1;
        int32_t k;
        for (k = 0; k < n; ++k) {
            cam_vertex q[4];
            int64_t id;
            if (!skirt_segment(r, side, k, q, &id)) break; /* the side looks away */
            if (outcode(r, q[0]) & outcode(r, q[1]) & outcode(r, q[2]) & outcode(r, q[3])) continue;
            draw_triangle(r, algorithm, q[0], q[1], q[2], id);
            draw_triangle(r, algorithm, q[0], q[2], q[3], id);
        }
    }
}

/* ---- zbuffer: every cell in row order, corners projected once (two rows cached) ------- */
typedef struct {
    cam_vertex v;
    screen_vertex s; /* valid when v.w >= near */
    int code;
} corner;

size_t hf_raster_workspace_doubles(int algorithm, int32_t cols, int32_t width) {
    if (algorithm == HF_RASTER_ZBUFFER)
        return (2 * (size_t)cols * sizeof(corner) + sizeof(double) - 1) / sizeof(double);
    if (algorithm == HF_RASTER_HIDDEN_LINES) return 4 * (size_t)width;
    return 0;
}

static void zbuffer(hf_raster *r) {
    const int32_t rows = r->rows, cols = r->cols;
    corner *cache[2];
    int32_t i, j;
    cache[0] = (corner *)r->vertex_rows;
    cache[1] = cache[0] + cols;
    for (j = 0; j < rows; ++j) {
        /* the corners of row j, projected once for the (up to) six triangles they touch */
        corner *row = cache[j & 1];
        for (i = 0; i < cols; ++i) {
            row[i].v = to_camera(r, i, j, height_at(r, i, j));
            row[i].code = outcode(r, row[i].v);
            if (row[i].v.w >= r->near) row[i].s = project(r, row[i].v);
        }
        if (j == 0) continue;
        {
            const corner *below = cache[(j - 1) & 1], *above = row;
            for (i = 0; i < cols - 1; ++i) {
                const corner *c00 = below + i, *c10 = c00 + 1, *c01 = above + i, *c11 = c01 + 1;
                r->counts[HF_COUNT_CELLS] += 1;
                if (c00->code & c10->code & c01->code & c11->code) {
                    r->counts[HF_COUNT_CULLED] += 1;
                    continue;
                }
                if ((c00->code | c10->code | c01->code | c11->code) & 1) {
                    /* a corner behind the near plane: clip in camera space */
                    draw_cell(r, HF_RASTER_ZBUFFER, i, j - 1, c00->v, c10->v, c01->v, c11->v, 1);
                } else {
                    /* the same screen vertices draw_triangle would compute, cached */
                    int lower_faces, upper_faces;
                    const int64_t id = cell_faces(r, i, j - 1, &lower_faces, &upper_faces);
                    r->counts[HF_COUNT_DRAWN] += 1;
                    if (lower_faces)
                        scan_triangle(r, HF_RASTER_ZBUFFER, &c00->s, &c10->s, &c11->s,
                                      id + HF_KIND_LOWER);
                    if (upper_faces)
                        scan_triangle(r, HF_RASTER_ZBUFFER, &c00->s, &c11->s, &c01->s,
                                      id + HF_KIND_UPPER);
                }
            }
        }
    }
    draw_skirts(r, HF_RASTER_ZBUFFER);
}

/* ---- painter: cells front to back, through the coverage mask --------------------------- */
/* The order: wavefronts of growing Manhattan distance |i - ci| + |j - cj| from the camera's
 * cell (ci, cj) (clamped into the grid). The ground track of a ray from the camera to a
 * point in cell B crosses only cells A with |iA - ci| <= |iB - ci| and |jA - cj| <= |jB - cj|
 * on B's side, so whatever can hide part of B lies on an earlier wavefront (or in B itself,
 * whose triangle on the camera's side of the diagonal goes first). No sorting. */
static void painter(hf_raster *r) {
    const int32_t nx = r->cols - 1, ny = r->rows - 1;
    const int64_t pixels = (int64_t)r->width * (r->row_end - r->row_begin);
    const double cx = r->position[0], cy = r->position[1];
    const int32_t ci = cx < 0 ? 0 : (cx >= nx ? nx - 1 : (int32_t)floor(cx));
    const int32_t cj = cy < 0 ? 0 : (cy >= ny ? ny - 1 : (int32_t)floor(cy));
    const int32_t last =
        (ci > nx - 1 - ci ? ci : nx - 1 - ci) + (cj > ny - 1 - cj ? cj : ny - 1 - cj);
    int32_t distance;
    draw_skirts(r, HF_RASTER_PAINTER);
    for (distance = 0; distance <= last; ++distance) {
        const int32_t i_lo = ci - distance < 0 ? 0 : ci - distance;
        const int32_t i_hi = ci + distance > nx - 1 ? nx - 1 : ci + distance;
        int32_t i;
        if (r->counts[HF_COUNT_WRITTEN] == pixels) {
            r->counts[HF_COUNT_FULL] = 1;
            return;
        }
        for (i = i_lo; i <= i_hi; ++i) {
            const int32_t rest = distance - (i > ci ? i - ci : ci - i);
            int side;
            for (side = 0; side < (rest ? 2 : 1); ++side) {
                const int32_t j = side ? cj + rest : cj - rest;
                cam_vertex v00, v10, v01, v11;
                if (j < 0 || j >= ny) continue;
                r->counts[HF_COUNT_CELLS] += 1;
                v00 = to_camera(r, i, j, height_at(r, i, j));
                v10 = to_camera(r, i + 1, j, height_at(r, i + 1, j));
                v01 = to_camera(r, i, j + 1, height_at(r, i, j + 1));
                v11 = to_camera(r, i + 1, j + 1, height_at(r, i + 1, j + 1));
                if (outcode(r, v00) & outcode(r, v10) & outcode(r, v01) & outcode(r, v11)) {
                    r->counts[HF_COUNT_CULLED] += 1;
                    continue;
                }
                draw_cell(r, HF_RASTER_PAINTER, i, j, v00, v10, v01, v11, cx - i >= cy - j);
            }
        }
    }
}

/* ---- floating horizon, shaded column form -------------------------------------------- */
/* Column c marches outwards from the camera's ground point in steps of `step` cells of
 * horizontal distance D. Its rows [horizon, height) are drawn; each sample (x, y, s(x, y))
 * projects to a row Y, and the rows from Y up to the horizon take that sample, which then
 * becomes the new horizon. The march follows the ground direction of the ray through the
 * pixel just above the horizon (for a level camera that is the whole column's plane; with
 * pitch the column's rays fan out, which is the form's approximation besides the step).
 * A drawn pixel's depth is the parameter at which its own ray reaches distance D. */
static void floating_horizon(hf_raster *r) {
    const int32_t width = r->width, height = r->height, rows = r->rows, cols = r->cols;
    const double px = r->position[0], py = r->position[1], xmax = cols - 1, ymax = rows - 1;
    /* the march's range: from the footprint's nearest point to its farthest corner */
    const double gap_x = px < 0 ? -px : (px > xmax ? px - xmax : 0);
    const double gap_y = py < 0 ? -py : (py > ymax ? py - ymax : 0);
    const double far_x = fmax(fabs(px), fabs(px - xmax)), far_y = fmax(fabs(py), fabs(py - ymax));
    const double d_first = sqrt(gap_x * gap_x + gap_y * gap_y);
    const double d_last = sqrt(far_x * far_x + far_y * far_y);
    int32_t c;
    for (c = r->column_begin; c < r->column_end; ++c) {
        int32_t horizon = height;
        int64_t k;
        double distance;
        for (k = 0;; ++k) {
            double dx, dy, ground, x, y, u, v, s;
            int32_t i, j, row, kind;
            cam_vertex sample;
            distance = d_first + (double)k * r->step;
            if (horizon == 0 || distance > d_last) break;
            /* the ground direction of the ray through the pixel above the horizon */
            dx = r->forward[0] + r->sx[c] * r->right[0] + r->sy[horizon - 1] * r->up[0];
            dy = r->forward[1] + r->sx[c] * r->right[1] + r->sy[horizon - 1] * r->up[1];
            ground = sqrt(dx * dx + dy * dy);
            if (!(ground > 0)) break; /* a vertical ray: no ground direction to march */
            x = px + distance * dx / ground;
            y = py + distance * dy / ground;
            if (!(x >= 0 && x <= xmax && y >= 0 && y <= ymax)) continue;
            r->counts[HF_COUNT_SAMPLES] += 1;
            /* the triangles surface at (x, y) */
            i = (int32_t)floor(x);
            j = (int32_t)floor(y);
            if (i > cols - 2) i = cols - 2;
            if (j > rows - 2) j = rows - 2;
            u = x - i;
            v = y - j;
            if (u >= v) {
                s = height_at(r, i, j) + (height_at(r, i + 1, j) - height_at(r, i, j)) * u +
                    (height_at(r, i + 1, j + 1) - height_at(r, i + 1, j)) * v;
                kind = HF_KIND_LOWER;
            } else {
                s = height_at(r, i, j) + (height_at(r, i + 1, j + 1) - height_at(r, i, j + 1)) * u +
                    (height_at(r, i, j + 1) - height_at(r, i, j)) * v;
                kind = HF_KIND_UPPER;
            }
            sample = to_camera(r, x, y, s);
            if (sample.w < r->near) continue;
            row = first_index(project(r, sample).Y, height);
            if (row >= horizon) continue;
            {
                const int64_t id = ((int64_t)j * (cols - 1) + i) * 4 + kind;
                const double reach = distance > 0 ? distance : r->near;
                int32_t fill;
                for (fill = row; fill < horizon; ++fill) {
                    /* 1/w of pixel (c, fill) at ground distance D: |d_ground| / D */
                    const double ex =
                        r->forward[0] + r->sx[c] * r->right[0] + r->sy[fill] * r->up[0];
                    const double ey =
                        r->forward[1] + r->sx[c] * r->right[1] + r->sy[fill] * r->up[1];
                    const int64_t pixel = (int64_t)fill * width + c;
                    r->t[pixel] = sqrt(ex * ex + ey * ey) / reach;
                    r->primitive[pixel] = id;
                    r->counts[HF_COUNT_WRITTEN] += 1;
                }
            }
            horizon = row;
        }
    }
}

/* ---- hidden lines: the floating horizon's line drawing ------------------------------- */
/* One segment of a section: at each image column it spans, the point of the segment on
 * that column is drawn when it lies above the upper or below the lower horizon of the
 * earlier sections (Y grows downwards: above is smaller Y); the section's own extent is
 * gathered in section_min / section_max and joins the horizons once the section is done. */
static void line_segment(hf_raster *r, cam_vertex a, cam_vertex b, int64_t id, const double *upper,
                         const double *lower, double *section_min, double *section_max) {
    screen_vertex sa, sb, swap;
    int32_t c0, c1, c;
    r->counts[HF_COUNT_SAMPLES] += 1;
    /* a segment reaching behind the near plane is left out (the form's approximation) */
    if (a.w < r->near || b.w < r->near) return;
    sa = project(r, a);
    sb = project(r, b);
    if (sb.X < sa.X) swap = sa, sa = sb, sb = swap;
    c0 = first_index(sa.X, r->width);
    c1 = first_index(sb.X, r->width);
    for (c = c0; c < c1; ++c) {
        const double s = ((double)c + 0.5 - sa.X) / (sb.X - sa.X);
        const double Y = sa.Y + s * (sb.Y - sa.Y), Z = sa.Z + s * (sb.Z - sa.Z);
        r->counts[HF_COUNT_FRAGMENTS] += 1;
        if ((Y < upper[c] || Y > lower[c]) && Y >= 0 && Y < (double)r->height) {
            const int64_t pixel = (int64_t)floor(Y) * r->width + c;
            /* two visible points in one pixel: the nearer one */
            if (!r->mask[pixel] || Z > r->t[pixel]) {
                r->mask[pixel] = 1;
                r->t[pixel] = Z;
                r->primitive[pixel] = id;
                r->counts[HF_COUNT_WRITTEN] += 1;
            }
        }
        if (Y < section_min[c]) section_min[c] = Y;
        if (Y > section_max[c]) section_max[c] = Y;
    }
}

/* The row sections y = j in order of distance from the camera's y (the rows on each side
 * of it separately: a ray from the camera meets only one side, and within a side it
 * meets the rows in this order, so nearer sections are drawn first). Row j's section is
 * its row segments and the column segments joining it to the row before (the zig-zag). */
static void hidden_lines(hf_raster *r) {
    const int32_t width = r->width, rows = r->rows, cols = r->cols;
    double *upper = r->vertex_rows, *lower = upper + width, *section_min = lower + width,
           *section_max = section_min + width;
    const double cy = r->position[1];
    int half;
    for (half = 0; half < 2; ++half) {
        /* half 0: rows at or beyond the camera's y, upwards; half 1: before it, downwards */
        const int32_t step = half == 0 ? 1 : -1;
        int32_t first, j, c, i;
        if (half == 0) {
            first = cy <= 0 ? 0 : (int32_t)ceil(cy);
            if (first > rows - 1) continue;
        } else {
            if (!(cy > 0)) continue;
            first = cy >= rows - 1 ? rows - 1 : (int32_t)ceil(cy) - 1;
        }
        for (c = 0; c < width; ++c) {
            upper[c] = INFINITY;
            lower[c] = -INFINITY;
        }
        for (j = first; j >= 0 && j < rows; j += step) {
            const int32_t previous = j - step;
            const int32_t cell_j = j < rows - 1 ? j : rows - 2;
            for (c = 0; c < width; ++c) {
                section_min[c] = INFINITY;
                section_max[c] = -INFINITY;
            }
            for (i = 0; i < cols - 1; ++i) {
                const cam_vertex a = to_camera(r, i, j, height_at(r, i, j));
                const cam_vertex b = to_camera(r, i + 1, j, height_at(r, i + 1, j));
                const int64_t id = ((int64_t)cell_j * (cols - 1) + i) * 4;
                line_segment(r, a, b, id, upper, lower, section_min, section_max);
            }
            if (previous >= 0 && previous < rows) {
                const int32_t low = previous < j ? previous : j;
                for (i = 0; i < cols; ++i) {
                    const cam_vertex a = to_camera(r, i, previous, height_at(r, i, previous));
                    const cam_vertex b = to_camera(r, i, j, height_at(r, i, j));
                    const int32_t cell_i = i < cols - 1 ? i : cols - 2;
                    const int64_t id = ((int64_t)low * (cols - 1) + cell_i) * 4;
                    line_segment(r, a, b, id, upper, lower, section_min, section_max);
                }
            }
            for (c = 0; c < width; ++c) {
                if (section_min[c] < upper[c]) upper[c] = section_min[c];
                if (section_max[c] > lower[c]) lower[c] = section_max[c];
            }
        }
    }
}

/* ---- the last pass: t, cell and normal from 1/w and the primitive ------------------- */
static void resolve(hf_raster *r) {
    const int32_t width = r->width, height = r->height, nx = r->cols - 1;
    int32_t c, k;
    (void)height;
    for (k = r->row_begin; k < r->row_end; ++k) {
        for (c = r->column_begin; c < r->column_end; ++c) {
            const int64_t pixel = (int64_t)k * width + c;
            const int64_t id = r->primitive[pixel];
            double *n = r->normal ? r->normal + 3 * pixel : NULL;
            if (id < 0 || !(r->t[pixel] > 0)) {
                r->t[pixel] = INFINITY;
                r->cell[2 * pixel] = r->cell[2 * pixel + 1] = -1;
                if (n) n[0] = n[1] = n[2] = NAN;
                continue;
            }
            {
                const int kind = (int)(id & 3);
                const int32_t i = (int32_t)((id >> 2) % nx), j = (int32_t)((id >> 2) / nx);
                const double sx = r->sx[c], sy = r->sy[k];
                r->t[pixel] = sqrt(1.0 + sx * sx + sy * sy) / r->t[pixel];
                r->cell[2 * pixel] = i;
                r->cell[2 * pixel + 1] = j;
                if (!n) continue;
                if (kind == HF_KIND_WALL_X || kind == HF_KIND_WALL_Y) {
                    /* a wall faces the ray */
                    const int axis = kind == HF_KIND_WALL_X ? 0 : 1;
                    const double d = r->forward[axis] + sx * r->right[axis] + sy * r->up[axis];
                    n[0] = n[1] = n[2] = 0;
                    n[axis] = d > 0 ? -1.0 : 1.0;
                } else {
                    const double h00 = height_at(r, i, j), h10 = height_at(r, i + 1, j);
                    const double h01 = height_at(r, i, j + 1), h11 = height_at(r, i + 1, j + 1);
                    const double su = kind == HF_KIND_LOWER ? h10 - h00 : h11 - h01;
                    const double sv = kind == HF_KIND_LOWER ? h11 - h10 : h01 - h00;
                    const double norm = sqrt(su * su + sv * sv + 1.0);
                    n[0] = -su / norm;
                    n[1] = -sv / norm;
                    n[2] = 1.0 / norm;
                }
            }
        }
    }
}

int hf_raster_render(int algorithm, hf_raster *r) {
    const int32_t width = r->width, height = r->height;
    int32_t k, c;
    if (algorithm < 0 || algorithm >= HF_N_RASTER) return HF_ERR_ARGUMENT;
    if (r->row_begin < 0 || r->row_end > height || r->row_begin >= r->row_end ||
        r->column_begin < 0 || r->column_end > width || r->column_begin >= r->column_end)
        return HF_ERR_ARGUMENT;
    if (algorithm != HF_RASTER_FLOATING_HORIZON && (r->column_begin != 0 || r->column_end != width))
        return HF_ERR_ARGUMENT; /* zbuffer and painter split by whole rows */
    if (algorithm == HF_RASTER_FLOATING_HORIZON && (r->row_begin != 0 || r->row_end != height))
        return HF_ERR_ARGUMENT; /* the floating horizon splits by whole columns */
    if (algorithm == HF_RASTER_HIDDEN_LINES && (r->row_begin != 0 || r->row_end != height ||
                                                r->column_begin != 0 || r->column_end != width))
        return HF_ERR_ARGUMENT; /* the line drawing's horizons span the whole image */
    /* the region's top and bottom edges as tans, like sy (exactly +-half_h for the image) */
    r->band_top = (1.0 - 2.0 * r->row_begin / height) * r->half_h;
    r->band_bottom = (1.0 - 2.0 * r->row_end / height) * r->half_h;
    memset(r->counts, 0, sizeof r->counts);
    for (k = r->row_begin; k < r->row_end; ++k) {
        for (c = r->column_begin; c < r->column_end; ++c) {
            const int64_t p = (int64_t)k * width + c;
            r->t[p] = 0;
            r->primitive[p] = -1;
            if (r->coverage) r->coverage[p] = 0;
            if (r->mask) r->mask[p] = 0;
        }
    }
    switch (algorithm) {
    case HF_RASTER_ZBUFFER: zbuffer(r); break;
    case HF_RASTER_PAINTER: painter(r); break;
    case HF_RASTER_FLOATING_HORIZON: floating_horizon(r); break;
    case HF_RASTER_HIDDEN_LINES: hidden_lines(r); break;
    default: {
        const int status = algorithm == HF_RASTER_WATKINS ? hf_watkins(r) : hf_warnock(r);
        if (status != HF_OK) return status;
        break;
    }
    }
    resolve(r);
    return HF_OK;
}
