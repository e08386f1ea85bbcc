/* The geometry every rasteriser shares (raster.c, watkins.c, warnock.c): camera
 * coordinates, the view frustum's outcodes, the projection to pixels, near-plane clipping,
 * the cells' facing triangles and the skirts, and the screen triangle that the scanline
 * and area-subdivision renderers test pixel centres against.
 *
 * Screen space: X grows to the right and Y downwards, both in pixels, with the centre of
 * pixel (c, k) at (c + 0.5, k + 0.5); Z is 1/w, w the depth along the viewing direction.
 * Every function here is a pure function of its arguments, so a vertex or an edge shared
 * by two triangles gets the same floats in both, in every renderer. */
#ifndef HFTRACE_RASTER_GEOMETRY_H
#define HFTRACE_RASTER_GEOMETRY_H

#include <math.h>
#include <stdint.h>
#include "raster/frame.h"

typedef struct {
    double a, b, w; /* camera coordinates */
} cam_vertex;

typedef struct {
    double X, Y, Z; /* pixel coordinates and 1/w */
} screen_vertex;

/* ---- camera --------------------------------------------------------------------------- */
/* Camera coordinates of a world point. Every rasteriser goes through this one function, so
 * a vertex shared by several triangles gets the same coordinates in all of them. */
static inline cam_vertex to_camera(const hf_raster *r, double x, double y, double z) {
    const double qx = x - r->position[0], qy = y - r->position[1], qz = z - r->position[2];
    cam_vertex v;
    v.a = qx * r->right[0] + qy * r->right[1] + qz * r->right[2];
    v.b = qx * r->up[0] + qy * r->up[1] + qz * r->up[2];
    v.w = qx * r->forward[0] + qy * r->forward[1] + qz * r->forward[2];
    return v;
}

/* Which of the five half-spaces of the view frustum (near, left, right, and the bottom
 * and top of the region's rows) a point lies outside of, one bit each. A cell whose four
 * corners share a bit is culled. */
static inline int outcode(const hf_raster *r, cam_vertex v) {
    int code = 0;
    if (v.w < r->near) code |= 1;
    if (v.a < -r->half_w * v.w) code |= 2;
    if (v.a > r->half_w * v.w) code |= 4;
    if (v.b < r->band_bottom * v.w) code |= 8;
    if (v.b > r->band_top * v.w) code |= 16;
    return code;
}

static inline screen_vertex project(const hf_raster *r, cam_vertex v) {
    screen_vertex s;
    s.X = (v.a / (v.w * r->half_w) + 1.0) * 0.5 * (double)r->width;
    s.Y = (1.0 - v.b / (v.w * r->half_h)) * 0.5 * (double)r->height;
    s.Z = 1.0 / v.w;
    return s;
}

/* The first row (or column) whose centre is at or after coordinate y, clamped to [0, n].
 * Numerical hazard: near the near plane coordinates can be huge; clamp before converting. */
static inline int32_t first_index(double y, int32_t n) {
    const double k = ceil(y - 0.5);
    if (!(k > 0)) return 0;
    if (k >= (double)n) return n;
    return (int32_t)k;
}

/* ---- near-plane clipping ------------------------------------------------------------ */
/* The point of edge (inside, outside) on the near plane; computed from the edge's inside
 * end, so two triangles sharing the edge get the same point. */
static inline cam_vertex near_cut(const hf_raster *r, cam_vertex in, cam_vertex out) {
    const double s = (in.w - r->near) / (in.w - out.w);
    cam_vertex v;
    v.a = in.a + s * (out.a - in.a);
    v.b = in.b + s * (out.b - in.b);
    v.w = r->near;
    return v;
}

/* A triangle in camera space clipped against w >= near (Sutherland-Hodgman) and
 * projected: writes 0, 3 or 4 screen vertices (a quad is drawn as (0, 1, 2) and (0, 2, 3))
 * and returns how many. */
static inline int clip_project(const hf_raster *r, cam_vertex v0, cam_vertex v1, cam_vertex v2,
                               screen_vertex s[4]) {
    const cam_vertex v[3] = {v0, v1, v2};
    cam_vertex polygon[4];
    int n = 0, k;
    if (v0.w >= r->near && v1.w >= r->near && v2.w >= r->near) {
        s[0] = project(r, v0);
        s[1] = project(r, v1);
        s[2] = project(r, v2);
        return 3;
    }
    for (k = 0; k < 3; ++k) {
        const cam_vertex cur = v[k], next = v[(k + 1) % 3];
        const int cur_in = cur.w >= r->near, next_in = next.w >= r->near;
        if (cur_in) polygon[n++] = cur;
        if (cur_in != next_in)
            polygon[n++] = cur_in ? near_cut(r, cur, next) : near_cut(r, next, cur);
    }
    if (n < 3) return 0;
    for (k = 0; k < n; ++k) s[k] = project(r, polygon[k]);
    return n;
}

/* ---- cells and skirts ------------------------------------------------------------------ */
static inline double height_at(const hf_raster *r, int32_t i, int32_t j) {
    return (double)r->heights[(int64_t)j * r->cols + i];
}

/* Which triangles of cell (i, j) face the camera (the camera above its plane; a back face
 * is hidden by the front of the solid); returns the cell's primitive id base. */
static inline int64_t cell_faces(const hf_raster *r, int32_t i, int32_t j, int *lower_faces,
                                 int *upper_faces) {
    const double h00 = height_at(r, i, j), h10 = height_at(r, i + 1, j);
    const double h01 = height_at(r, i, j + 1), h11 = height_at(r, i + 1, j + 1);
    const double px = r->position[0] - i, py = r->position[1] - j, pz = r->position[2] - h00;
    *lower_faces = pz - (h10 - h00) * px - (h11 - h10) * py > 0;
    *upper_faces = pz - (h11 - h01) * px - (h01 - h00) * py > 0;
    return ((int64_t)j * (r->cols - 1) + i) * 4;
}

/* The skirt segment k of side `side` (0: y = 0, 1: y = rows-1, 2: x = 0, 3: x = cols-1):
 * its corners top_a, top_b, bottom_b, bottom_a in camera coordinates (drawn as the
 * triangles (q0, q1, q2) and (q0, q2, q3)) and its primitive id. Returns 0 when the camera
 * is not outside that side (the face looks away), else 1. */
static inline int skirt_segment(const hf_raster *r, int side, int32_t k, cam_vertex q[4],
                                int64_t *id) {
    const int32_t rows = r->rows, cols = r->cols;
    const int along_x = side < 2;
    const double fixed = side == 0 || side == 2 ? 0.0 : (double)(along_x ? rows - 1 : cols - 1);
    const double p = r->position[along_x ? 1 : 0];
    const int32_t ia = along_x ? k : (int32_t)fixed, ja = along_x ? (int32_t)fixed : k;
    const int32_t ib = along_x ? k + 1 : ia, jb = along_x ? ja : k + 1;
    const int32_t ci = along_x ? k : (side == 2 ? 0 : cols - 2);
    const int32_t cj = along_x ? (side == 0 ? 0 : rows - 2) : k;
    if (side == 0 || side == 2 ? !(p < fixed) : !(p > fixed)) return 0;
    q[0] = to_camera(r, ia, ja, height_at(r, ia, ja));
    q[1] = to_camera(r, ib, jb, height_at(r, ib, jb));
    q[2] = to_camera(r, ib, jb, r->z_bottom);
    q[3] = to_camera(r, ia, ja, r->z_bottom);
    *id = ((int64_t)cj * (cols - 1) + ci) * 4 + (along_x ? HF_KIND_WALL_Y : HF_KIND_WALL_X);
    return 1;
}

/* ---- the screen triangle of the scanline and area-subdivision renderers ----------------- */
/* A projected triangle with what a pixel-centre test needs: its corners sorted by Y, the
 * rows its centres span, and its plane. Unlike the zbuffer's incremental edge trackers, an
 * edge's x on a row and a pixel's 1/w are evaluated directly, so a pixel's answer does not
 * depend on which rows or columns were visited before it (a region of the image can be
 * decided alone). An edge's x depends only on its two end points and the row, as in the
 * zbuffer, so the fill rule stays watertight. */
typedef struct {
    screen_vertex top, mid, bottom;
    double plane_sx, plane_sy, plane_1;   /* 1/w = plane_sx sx + plane_sy sy + plane_1     */
    double z_lo, z_hi;                    /* the corners' range of 1/w                      */
    int32_t row_top, row_mid, row_bottom; /* centre rows: [row_top, row_bottom)         */
    int32_t mid_left;                     /* the middle corner is on the left           */
    int64_t id;                           /* cell_index * 4 + kind                      */
} screen_triangle;

/* The plane of a camera-space triangle as 1/w over the image plane: a pixel's ray is
 * (sx, sy, 1) w in camera coordinates, and it meets the plane n . v = n . v0 at
 * 1/w = (n_a sx + n_b sy + n_w) / (n . v0), evaluated from the 3D triangle, not
 * interpolated from its (possibly clipped, far off-screen) projected corners. Returns 0 for
 * a plane through the camera (seen edge-on). */
static inline int camera_plane(cam_vertex v0, cam_vertex v1, cam_vertex v2, double plane[3]) {
    const double ea = v1.a - v0.a, eb = v1.b - v0.b, ew = v1.w - v0.w;
    const double fa = v2.a - v0.a, fb = v2.b - v0.b, fw = v2.w - v0.w;
    const double na = eb * fw - ew * fb, nb = ew * fa - ea * fw, nw = ea * fb - eb * fa;
    const double offset = na * v0.a + nb * v0.b + nw * v0.w;
    if (!(offset != 0)) return 0;
    plane[0] = na / offset;
    plane[1] = nb / offset;
    plane[2] = nw / offset;
    return 1;
}

/* Fill in `t` from three projected corners and the triangle's plane; returns 0 when no
 * pixel centre row lies inside (degenerate on screen, NaN, or between two centre rows). */
static inline int screen_triangle_setup(const hf_raster *r, const screen_vertex *p0,
                                        const screen_vertex *p1, const screen_vertex *p2,
                                        const double plane[3], int64_t id, screen_triangle *t) {
    const screen_vertex *top = p0, *mid = p1, *bottom = p2, *swap;
    double area2;
    if (mid->Y < top->Y) swap = top, top = mid, mid = swap;
    if (bottom->Y < mid->Y) swap = mid, mid = bottom, bottom = swap;
    if (mid->Y < top->Y) swap = top, top = mid, mid = swap;
    area2 = (mid->X - top->X) * (bottom->Y - top->Y) - (bottom->X - top->X) * (mid->Y - top->Y);
    if (!(area2 != 0)) return 0;
    t->row_top = first_index(top->Y, r->height);
    t->row_mid = first_index(mid->Y, r->height);
    t->row_bottom = first_index(bottom->Y, r->height);
    if (t->row_top >= t->row_bottom) return 0;
    t->top = *top;
    t->mid = *mid;
    t->bottom = *bottom;
    t->mid_left = area2 < 0;
    t->plane_sx = plane[0];
    t->plane_sy = plane[1];
    t->plane_1 = plane[2];
    t->z_lo = fmin(top->Z, fmin(mid->Z, bottom->Z));
    t->z_hi = fmax(top->Z, fmax(mid->Z, bottom->Z));
    t->id = id;
    return 1;
}

/* The x of edge (upper, lower) at the centre of `row`. */
static inline double edge_x(const screen_vertex *upper, const screen_vertex *lower, int32_t row) {
    const double x_inc = (lower->X - upper->X) / (lower->Y - upper->Y);
    return upper->X + ((double)row + 0.5 - upper->Y) * x_inc;
}

/* The columns [*c0, *c1) whose centres on `row` (inside [row_top, row_bottom)) lie in the
 * triangle by the top-left rule: x_left <= x < x_right. */
static inline void screen_triangle_span(const hf_raster *r, const screen_triangle *t, int32_t row,
                                        int32_t *c0, int32_t *c1) {
    const double x_long = edge_x(&t->top, &t->bottom, row);
    const double x_short =
        row < t->row_mid ? edge_x(&t->top, &t->mid, row) : edge_x(&t->mid, &t->bottom, row);
    *c0 = first_index(t->mid_left ? x_short : x_long, r->width);
    *c1 = first_index(t->mid_left ? x_long : x_short, r->width);
}

/* 1/w of the triangle's plane on the ray of pixel (column, row). Numerical hazard: on a
 * plane seen nearly edge-on the three terms cancel; 1/w is affine over the triangle, so
 * clamp it to the corners' range. */
static inline double screen_triangle_depth(const hf_raster *r, const screen_triangle *t,
                                           int32_t column, int32_t row) {
    const double z = t->plane_sx * r->sx[column] + t->plane_sy * r->sy[row] + t->plane_1;
    return z < t->z_lo ? t->z_lo : (z > t->z_hi ? t->z_hi : z);
}

/* Whether a fragment (Z, id) is in front of the pixel's current one (best_z, best_id;
 * best_id < 0: nothing yet). Nearer is a larger 1/w; an exact tie goes to the surface over
 * a skirt, then to the smaller id, which is the zbuffer's drawing order (cells in row-major
 * order, the u >= v triangle first, skirts last), so every renderer breaks ties alike. */
static inline int in_front(double z, int64_t id, double best_z, int64_t best_id) {
    int wall, best_wall;
    if (best_id < 0) return 1;
    if (z != best_z) return z > best_z;
    wall = (id & 3) >= HF_KIND_WALL_X;
    best_wall = (best_id & 3) >= HF_KIND_WALL_X;
    return wall != best_wall ? !wall : id < best_id;
}

/* Append the facing triangles of cell (i, j) (and, for a boundary cell with `skirts`, its
 * skirts on the sides the camera is outside of) to `out` as screen triangles that hold at
 * least one pixel centre row. `out` has room for 12; returns how many were written. */
static inline int cell_screen_triangles(const hf_raster *r, int32_t i, int32_t j, int skirts,
                                        screen_triangle *out) {
    const cam_vertex v00 = to_camera(r, i, j, height_at(r, i, j));
    const cam_vertex v10 = to_camera(r, i + 1, j, height_at(r, i + 1, j));
    const cam_vertex v01 = to_camera(r, i, j + 1, height_at(r, i, j + 1));
    const cam_vertex v11 = to_camera(r, i + 1, j + 1, height_at(r, i + 1, j + 1));
    cam_vertex tri[6][3];
    int64_t ids[6];
    int n_tri = 0, n = 0, k, lower_faces, upper_faces, side;
    const int64_t id = cell_faces(r, i, j, &lower_faces, &upper_faces);
    if (lower_faces) {
        tri[n_tri][0] = v00, tri[n_tri][1] = v10, tri[n_tri][2] = v11;
        ids[n_tri++] = id + HF_KIND_LOWER;
    }
    if (upper_faces) {
        tri[n_tri][0] = v00, tri[n_tri][1] = v11, tri[n_tri][2] = v01;
        ids[n_tri++] = id + HF_KIND_UPPER;
    }
    for (side = 0; side < (skirts ? 4 : 0); ++side) {
        /* the skirt segment of this cell on a boundary side, if any */
        const int along_x = side < 2;
        const int32_t edge_index = along_x ? i : j;
        const int on_side = side == 0   ? j == 0
                            : side == 1 ? j == r->rows - 2
                            : side == 2 ? i == 0
                                        : i == r->cols - 2;
        cam_vertex q[4];
        int64_t skirt_id;
        if (!on_side || !skirt_segment(r, side, edge_index, q, &skirt_id)) continue;
        tri[n_tri][0] = q[0], tri[n_tri][1] = q[1], tri[n_tri][2] = q[2];
        ids[n_tri++] = skirt_id;
        tri[n_tri][0] = q[0], tri[n_tri][1] = q[2], tri[n_tri][2] = q[3];
        ids[n_tri++] = skirt_id;
    }
    for (k = 0; k < n_tri; ++k) {
        screen_vertex s[4];
        double plane[3];
        const int m = clip_project(r, tri[k][0], tri[k][1], tri[k][2], s);
        if (m < 3 || !camera_plane(tri[k][0], tri[k][1], tri[k][2], plane)) continue;
        n += screen_triangle_setup(r, &s[0], &s[1], &s[2], plane, ids[k], out + n);
        if (m == 4) n += screen_triangle_setup(r, &s[0], &s[2], &s[3], plane, ids[k], out + n);
    }
    return n;
}

/* ---- the projected bound of an axis-aligned box ----------------------------------------- */
/* The screen rectangle and depth range of the box [lo, hi] clipped to w >= near: the
 * vertices of the clipped box (its corners in front of the near plane and the points where
 * its twelve edges cross it) projected, so every point of the box in front of the near
 * plane projects inside [X_min, X_max] x [Y_min, Y_max] and has w_min <= w <= w_max.
 * This is the one bound of a max-mipmap tile against a camera: Warnock's classification
 * asks it of each tile, and a per-pixel lower bound on the first hit (a conservative start
 * for pitched cameras: t >= w_min |d| for a pixel inside the rectangle, d its unnormalised
 * direction) can ask it of the same tiles. */
typedef struct {
    double X_min, X_max, Y_min, Y_max; /* pixels, widened by a rounding margin */
    double w_min, w_max;               /* depth along the viewing direction    */
} box_bound;

#endif
