/* Warnock's area-subdivision renderer of a height field (see raster.h), and the projected
 * bound of a box that it shares with any per-pixel lower bound (hf_project_box).
 *
 * The polygons Warnock classifies against a screen region are here the tiles of a min-max
 * mipmap of the field (level L: tiles of 2^L x 2^L cells, each with the lowest and highest
 * sample under it). A tile's projected bound is the screen rectangle and depth range of its box.
 * A region and its candidate tiles (those whose rectangle holds a pixel centre of the
 * region) fall into one of the classic cases:
 * - empty: no candidate; every pixel of the region misses;
 * - a surrounding triangle in front: a candidate cell's triangle covers every pixel centre
 *   of the region, and every other candidate tile lies farther away than that triangle's
 *   farthest point over the region; those tiles are dropped (hidden), and the region is
 *   drawn from that one cell;
 * - one or a few cells left (an intersecting or a contained polygon), or a region of at
 *   most 16 x 16 pixels: drawn from the cells of its candidates with a depth test per pixel
 *   centre;
 * - too complex: the region is split in four, and each quarter keeps the candidates that
 *   overlap it. A candidate tile whose rectangle is larger than the region is replaced by its
 *   four children first, so the candidates stay about as large as the region: the
 *   hierarchy of the mipmap follows the hierarchy of the regions.
 * The skirts (the box's side faces) are drawn last through the same depth test: each is a
 * strip reaching towards the vertical vanishing point, whose screen rectangle would
 * overlap most regions. A pixel's triangle is therefore the nearest of all triangles whose
 * tile bound holds its centre, which is every triangle covering it: the image is the
 * zbuffer's (the same pixel
 * centre tests as watkins, screen_triangle in raster_geometry.h, and the same tie order). */
#include <stdlib.h>
#include <string.h>
#include "core/hftrace.h"
#include "raster/warnock.h"
#include "raster/raster_geometry.h"

/* ---- the projected bound of a box ------------------------------------------------------ */
int hf_project_box(const hf_raster *r, const double lo[3], const double hi[3], box_bound *b) {
    /* corner k has x from bit 0, y from bit 1, z from bit 2 */
    cam_vertex corner[8], points[8 + 12];
    int k, n = 0, axis;
    for (k = 0; k < 8; ++k)
        corner[k] =
            to_camera(r, k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]);
    for (k = 0; k < 8; ++k)
        if (corner[k].w >= r->near) points[n++] = corner[k];
    if (n == 0) return 0;
    if (n < 8) {
        /* the twelve edges: a corner and its neighbour along each axis */
        for (k = 0; k < 8; ++k) {
            for (axis = 0; axis < 3; ++axis) {
                const int other = k | (1 << axis);
                if (other == k) continue;
                if ((corner[k].w >= r->near) != (corner[other].w >= r->near))
                    points[n++] = corner[k].w >= r->near ? near_cut(r, corner[k], corner[other])
                                                         : near_cut(r, corner[other], corner[k]);
            }
        }
    }
    b->X_min = b->Y_min = b->w_min = INFINITY;
    b->X_max = b->Y_max = b->w_max = -INFINITY;
    for (k = 0; k < n; ++k) {
        /* comparisons, not fmin/fmax (library calls without fast-math); a NaN is never
         * taken, and the rectangle of a box with a NaN corner stays empty */
        const screen_vertex s = project(r, points[k]);
        if (s.X < b->X_min) b->X_min = s.X;
        if (s.X > b->X_max) b->X_max = s.X;
        if (s.Y < b->Y_min) b->Y_min = s.Y;
        if (s.Y > b->Y_max) b->Y_max = s.Y;
        if (points[k].w < b->w_min) b->w_min = points[k].w;
        if (points[k].w > b->w_max) b->w_max = points[k].w;
    }
    /* Numerical hazard: the triangles inside are projected from other points than these
     * corners; widen by far more than the rounding of a projection */
    b->X_min -= 1e-7 * (1.0 + fabs(b->X_min));
    b->X_max += 1e-7 * (1.0 + fabs(b->X_max));
    b->Y_min -= 1e-7 * (1.0 + fabs(b->Y_min));
    b->Y_max += 1e-7 * (1.0 + fabs(b->Y_max));
    b->w_min *= 1.0 - 1e-12;
    b->w_max *= 1.0 + 1e-12;
    return 1;
}

/* ---- the min-max mipmap ----------------------------------------------------------------- */
#define MAX_LEVELS  32
#define STORED_FROM 2 /* levels 0 and 1 are read off the samples (at most 3 x 3 of them) */
/* A region of at most LEAF_PIXELS pixels (16 x 16), or one left with at most LEAF_CELLS
 * candidate cells, is drawn from its candidates' cells with a depth test per pixel. Chosen
 * by callgrind instructions per pixel (fbm 256^2 overview at 320x180 and 512^2 grazing at
 * 640x360): 6707 and 4299 with regions of 4 pixels, 4560 and 2929 with 16, 2957 and 1779
 * with 256, 2672 and 1547 with 1024; larger leaves trade the hierarchy for a plain zbuffer
 * over the region. */
#define LEAF_PIXELS 256
#define LEAF_CELLS  8

typedef struct {
    box_bound bound;
    int32_t ti, tj, level;
} tile;

typedef struct {
    hf_raster *r;
    int32_t nx, ny, top_level;
    int32_t tiles_x[MAX_LEVELS], tiles_y[MAX_LEVELS];
    float *zmin[MAX_LEVELS], *zmax[MAX_LEVELS];
    tile *list, *pending; /* the candidates of the regions being split; the refinement queue */
    int64_t n_list, cap_list, n_pending, cap_pending;
} warnock_state;

static int grow(tile **buffer, int64_t *capacity, int64_t need) {
    if (need > *capacity) {
        int64_t capacity_new = *capacity ? 2 * *capacity : 256;
        tile *grown;
        while (capacity_new < need) capacity_new *= 2;
        grown = realloc(*buffer, (size_t)capacity_new * sizeof *grown);
        if (!grown) return 0;
        *buffer = grown;
        *capacity = capacity_new;
    }
    return 1;
}

/* The cells [i0, i1] x [j0, j1] of tile (ti, tj) at `level`. */
static void tile_cells(const warnock_state *s, int32_t level, int32_t ti, int32_t tj, int32_t *i0,
                       int32_t *i1, int32_t *j0, int32_t *j1) {
    *i0 = ti << level;
    *j0 = tj << level;
    *i1 = (int32_t)((((int64_t)ti + 1) << level) - 1);
    *j1 = (int32_t)((((int64_t)tj + 1) << level) - 1);
    if (*i1 > s->nx - 1) *i1 = s->nx - 1;
    if (*j1 > s->ny - 1) *j1 = s->ny - 1;
}

/* The lowest and highest sample of a tile. */
static void tile_heights(const warnock_state *s, int32_t level, int32_t ti, int32_t tj, double *lo,
                         double *hi) {
    if (level >= STORED_FROM) {
        const int64_t k = (int64_t)tj * s->tiles_x[level] + ti;
        *lo = s->zmin[level][k];
        *hi = s->zmax[level][k];
    } else {
        int32_t i0, i1, j0, j1, i, j;
        tile_cells(s, level, ti, tj, &i0, &i1, &j0, &j1);
        *lo = INFINITY;
        *hi = -INFINITY;
        for (j = j0; j <= j1 + 1; ++j) {
            for (i = i0; i <= i1 + 1; ++i) {
                const double z = height_at(s->r, i, j);
                if (z < *lo) *lo = z; /* heights are finite (checked by the caller) */
                if (z > *hi) *hi = z;
            }
        }
    }
}

static int build_mipmap(warnock_state *s) {
    int32_t level;
    s->tiles_x[0] = s->nx;
    s->tiles_y[0] = s->ny;
    for (level = 0; s->tiles_x[level] > 1 || s->tiles_y[level] > 1; ++level) {
        s->tiles_x[level + 1] = (s->tiles_x[level] + 1) / 2;
        s->tiles_y[level + 1] = (s->tiles_y[level] + 1) / 2;
    }
    s->top_level = level;
    for (level = STORED_FROM; level <= s->top_level; ++level) {
        const int64_t n = (int64_t)s->tiles_x[level] * s->tiles_y[level];
        int32_t ti, tj;
        s->zmin[level] = malloc((size_t)n * sizeof(float));
        s->zmax[level] = malloc((size_t)n * sizeof(float));
        if (!s->zmin[level] || !s->zmax[level]) return 0;
        for (tj = 0; tj < s->tiles_y[level]; ++tj) {
            for (ti = 0; ti < s->tiles_x[level]; ++ti) {
                const int64_t k = (int64_t)tj * s->tiles_x[level] + ti;
                double lo = INFINITY, hi = -INFINITY;
                int child;
                for (child = 0; child < 4; ++child) {
                    const int32_t ci = 2 * ti + (child & 1), cj = 2 * tj + (child >> 1);
                    double clo, chi;
                    if (ci >= s->tiles_x[level - 1] || cj >= s->tiles_y[level - 1]) continue;
                    tile_heights(s, level - 1, ci, cj, &clo, &chi);
                    if (clo < lo) lo = clo;
                    if (chi > hi) hi = chi;
                }
                /* the samples are float32, so their extremes are exact in float */
                s->zmin[level][k] = (float)lo;
                s->zmax[level][k] = (float)hi;
            }
        }
    }
    return 1;
}

/* The projected bound of a tile's box; 0 when it lies behind the near plane. */
static int make_tile(const warnock_state *s, int32_t level, int32_t ti, int32_t tj, tile *t) {
    const hf_raster *r = s->r;
    int32_t i0, i1, j0, j1;
    double lo[3], hi[3];
    tile_cells(s, level, ti, tj, &i0, &i1, &j0, &j1);
    tile_heights(s, level, ti, tj, &lo[2], &hi[2]);
    lo[0] = i0;
    lo[1] = j0;
    hi[0] = i1 + 1.0;
    hi[1] = j1 + 1.0;
    t->ti = ti;
    t->tj = tj;
    t->level = level;
    s->r->counts[HF_COUNT_CELLS] += 1;
    return hf_project_box(r, lo, hi, &t->bound);
}

/* ---- regions ---------------------------------------------------------------------------- */
typedef struct {
    int32_t r0, r1, c0, c1; /* rows [r0, r1) x columns [c0, c1) */
} region;

static int overlaps(const box_bound *b, const region *g) {
    return b->X_max >= g->c0 + 0.5 && b->X_min <= g->c1 - 0.5 && b->Y_max >= g->r0 + 0.5 &&
           b->Y_min <= g->r1 - 0.5;
}

/* The candidates of region g from those of its parent (list[first, last)), appended at the
 * end of the list: tiles that do not overlap g are dropped, tiles larger than g on screen
 * are replaced by their children. Returns 0 when out of memory. */
static int refine(warnock_state *s, const region *g, int64_t first, int64_t last) {
    const double width = g->c1 - g->c0, height = g->r1 - g->r0;
    int64_t k;
    if (!grow(&s->pending, &s->cap_pending, last - first)) return 0;
    for (k = first; k < last; ++k) s->pending[s->n_pending++] = s->list[k];
    while (s->n_pending > 0) {
        const tile t = s->pending[--s->n_pending];
        if (!overlaps(&t.bound, g)) {
            s->r->counts[HF_COUNT_CULLED] += 1;
            continue;
        }
        if (t.level > 0 &&
            (t.bound.X_max - t.bound.X_min > width || t.bound.Y_max - t.bound.Y_min > height)) {
            int child;
            if (!grow(&s->pending, &s->cap_pending, s->n_pending + 4)) return 0;
            for (child = 0; child < 4; ++child) {
                const int32_t ci = 2 * t.ti + (child & 1), cj = 2 * t.tj + (child >> 1);
                if (ci >= s->tiles_x[t.level - 1] || cj >= s->tiles_y[t.level - 1]) continue;
                if (make_tile(s, t.level - 1, ci, cj, s->pending + s->n_pending)) ++s->n_pending;
            }
            continue;
        }
        if (!grow(&s->list, &s->cap_list, s->n_list + 1)) return 0;
        s->list[s->n_list++] = t;
    }
    return 1;
}

/* The surrounding case: among the candidate cells, the triangle that covers every pixel
 * centre of g and whose farthest point over g is nearest; every candidate whose nearest
 * point lies beyond that is hidden and dropped. Returns how many candidates remain. */
static int64_t drop_hidden(warnock_state *s, const region *g, int64_t first, int64_t last) {
    const hf_raster *r = s->r;
    double z_far = 0; /* 1/w: larger is nearer; 0: no surrounding triangle */
    int64_t k, kept = first;
    for (k = first; k < last; ++k) {
        const box_bound *b = &s->list[k].bound;
        screen_triangle triangles[12];
        int n, m;
        /* only a cell whose rectangle holds every pixel centre of g can surround it */
        if (s->list[k].level != 0 || b->X_min > g->c0 + 0.5 || b->X_max < g->c1 - 0.5 ||
            b->Y_min > g->r0 + 0.5 || b->Y_max < g->r1 - 0.5)
            continue;
        n = cell_screen_triangles(r, s->list[k].ti, s->list[k].tj, 0, triangles);
        for (m = 0; m < n; ++m) {
            const screen_triangle *t = triangles + m;
            int32_t row, c0, c1;
            double z;
            if (t->row_top > g->r0 || t->row_bottom < g->r1) continue;
            for (row = g->r0; row < g->r1; ++row) {
                screen_triangle_span(r, t, row, &c0, &c1);
                if (c0 > g->c0 || c1 < g->c1) break;
            }
            if (row < g->r1) continue;
            /* 1/w is affine: its smallest value over the region is at a corner pixel */
            z = fmin(fmin(screen_triangle_depth(r, t, g->c0, g->r0),
                          screen_triangle_depth(r, t, g->c1 - 1, g->r0)),
                     fmin(screen_triangle_depth(r, t, g->c0, g->r1 - 1),
                          screen_triangle_depth(r, t, g->c1 - 1, g->r1 - 1)));
            if (z > z_far) z_far = z;
        }
    }
    if (!(z_far > 0)) return last;
    for (k = first; k < last; ++k) {
        /* the tile's nearest point, 1 / w_min, with a margin for the triangles' rounding */
        if (1.0 / s->list[k].bound.w_min < z_far * (1.0 - 1e-9)) {
            s->r->counts[HF_COUNT_CULLED] += 1;
            continue;
        }
        s->list[kept++] = s->list[k];
    }
    return kept;
}

/* The pixel centres of region g inside triangle t, each kept when t is in front there. */
static void draw_triangle_in(hf_raster *r, const region *g, const screen_triangle *t) {
    const int32_t row_first = t->row_top > g->r0 ? t->row_top : g->r0;
    const int32_t row_last = t->row_bottom < g->r1 ? t->row_bottom : g->r1;
    int32_t row, c, c0, c1;
    if (row_first >= row_last) return;
    r->counts[HF_COUNT_TRIANGLES] += 1;
    for (row = row_first; row < row_last; ++row) {
        screen_triangle_span(r, t, row, &c0, &c1);
        if (c0 < g->c0) c0 = g->c0;
        if (c1 > g->c1) c1 = g->c1;
        for (c = c0; c < c1; ++c) {
            const int64_t pixel = (int64_t)row * r->width + c;
            const double z = screen_triangle_depth(r, t, c, row);
            r->counts[HF_COUNT_FRAGMENTS] += 1;
            if (in_front(z, t->id, r->t[pixel], r->primitive[pixel])) {
                r->t[pixel] = z;
                r->primitive[pixel] = t->id;
                r->counts[HF_COUNT_WRITTEN] += 1;
            }
        }
    }
}

/* Draw region g from the cells of its candidate tiles: a depth test per pixel centre. The
 * tiles are about as large as the region on screen, so their cells are drawn without
 * bounding each one first. */
static void draw_tiles(warnock_state *s, const region *g, int64_t first, int64_t last) {
    hf_raster *r = s->r;
    int64_t k;
    for (k = first; k < last; ++k) {
        int32_t i0, i1, j0, j1, i, j;
        tile_cells(s, s->list[k].level, s->list[k].ti, s->list[k].tj, &i0, &i1, &j0, &j1);
        for (j = j0; j <= j1; ++j) {
            for (i = i0; i <= i1; ++i) {
                screen_triangle triangles[12];
                int n, m;
                r->counts[HF_COUNT_DRAWN] += 1;
                n = cell_screen_triangles(r, i, j, 0, triangles);
                for (m = 0; m < n; ++m) draw_triangle_in(r, g, triangles + m);
            }
        }
    }
}

/* The skirts (the box's side faces below the boundary), after the subdivision and through
 * the same depth test: a skirt is a long strip reaching towards the vertical vanishing
 * point, whose screen rectangle would overlap most regions, while it covers few pixels. */
static void draw_skirts_after(hf_raster *r, const region *g) {
    int side;
    for (side = 0; side < 4; ++side) {
        const int32_t n = side < 2 ? r->cols - 1 : r->rows - 1;
        int32_t k;
        for (k = 0; k < n; ++k) {
            cam_vertex q[4];
            int64_t id;
            int half;
            if (!skirt_segment(r, side, k, q, &id)) break; /* the side looks away */
            if (outcode(r, q[0]) & outcode(r, q[1]) & outcode(r, q[2]) & outcode(r, q[3])) continue;
            for (half = 0; half < 2; ++half) {
                const cam_vertex a = q[0], b = q[half + 1], c = q[half + 2];
                screen_vertex v[4];
                screen_triangle t;
                double plane[3];
                const int m = clip_project(r, a, b, c, v);
                if (m < 3 || !camera_plane(a, b, c, plane)) continue;
                if (screen_triangle_setup(r, &v[0], &v[1], &v[2], plane, id, &t))
                    draw_triangle_in(r, g, &t);
                if (m == 4 && screen_triangle_setup(r, &v[0], &v[2], &v[3], plane, id, &t))
                    draw_triangle_in(r, g, &t);
            }
        }
    }
}

/* Classify region g against its parent's candidates list[first, last); 0: out of memory. */
static int subdivide(warnock_state *s, region g, int64_t first, int64_t last) {
    const int64_t pixels = (int64_t)(g.r1 - g.r0) * (g.c1 - g.c0);
    const int small = pixels <= LEAF_PIXELS;
    const int64_t begin = s->n_list;
    int64_t end, k;
    int all_cells = 1;
    s->r->counts[HF_COUNT_SAMPLES] += 1;
    if (!refine(s, &g, first, last)) return 0;
    end = drop_hidden(s, &g, begin, s->n_list);
    s->n_list = end;
    for (k = begin; k < end; ++k) all_cells &= s->list[k].level == 0;
    if (end == begin) {
        /* empty */
    } else if (small || (all_cells && end - begin <= LEAF_CELLS)) {
        draw_tiles(s, &g, begin, end);
    } else {
        /* too complex: split in four (in two along a side of one pixel) */
        const int32_t rm = g.r1 - g.r0 > 1 ? (g.r0 + g.r1) / 2 : g.r1;
        const int32_t cm = g.c1 - g.c0 > 1 ? (g.c0 + g.c1) / 2 : g.c1;
        const region quarters[4] = {
            {g.r0, rm, g.c0, cm}, {g.r0, rm, cm, g.c1}, {rm, g.r1, g.c0, cm}, {rm, g.r1, cm, g.c1}};
        int q;
        for (q = 0; q < 4; ++q) {
            if (quarters[q].r0 >= quarters[q].r1 || quarters[q].c0 >= quarters[q].c1) continue;
            if (!subdivide(s, quarters[q], begin, end)) return 0;
        }
    }
    s->n_list = begin;
    return 1;
}

int hf_warnock(hf_raster *r) {
    warnock_state s;
    region whole;
    int status = HF_ERR_MEMORY, level;
    memset(&s, 0, sizeof s);
    s.r = r;
    s.nx = r->cols - 1;
    s.ny = r->rows - 1;
    if (build_mipmap(&s) && grow(&s.list, &s.cap_list, 1)) {
        whole.r0 = r->row_begin;
        whole.r1 = r->row_end;
        whole.c0 = r->column_begin;
        whole.c1 = r->column_end;
        s.n_list = 0;
        if (make_tile(&s, s.top_level, 0, 0, s.list)) {
            s.n_list = 1;
            if (subdivide(&s, whole, 0, 1)) status = HF_OK;
        } else {
            status = HF_OK; /* the whole field lies behind the camera */
        }
        if (status == HF_OK) draw_skirts_after(r, &whole);
    }
    for (level = 0; level < MAX_LEVELS; ++level) {
        free(s.zmin[level]);
        free(s.zmax[level]);
    }
    free(s.list);
    free(s.pending);
    return status;
}
