/* pitched_maxmip: dda_maxmip for the rays of one eye, each walk started near its hit.
 *
 * A pitched pinhole camera puts no two rays in one vertical plane (plane_maxmip's
 * coherence is gone), but all its rays leave one eye. Before walking, the batch draws a
 * coarse image of the field's tile boxes as seen from that eye, the image of the bounds
 * Warnock's subdivision classifies (hf_project_box, warnock.c); each coarse pixel keeps the
 * smallest depth of any box whose projected rectangle touches it. A ray's depth bound,
 * divided by the depth its direction gains per unit of t, bounds its first hit from below,
 * and dda_maxmip's walk (maxmip.h) starts in the cell holding that parameter.
 *
 * Why the bound is conservative, by construction (the proof in docs/pitched.md):
 * - Every point a first hit can lie on (on the surface, on a cell's wall, or inside the
 *   solid where a ray starts below it) lies in the closed box of some tile of the cut
 *   below: the tile's cells, from below both the clip height hmin (where a descending
 *   ray's range ends) and the eye (a level or rising ray never goes lower) up to the
 *   tile's maximum (every surface lies at or below its cell's corner maximum). The boxes
 *   are a cut of the max mipmap: tiles of 2^L cells (L = floor_level +
 *   BOX_LEVEL_ABOVE_FLOOR), split down to single cells near the eye; each is widened by
 *   a hair against rounding.
 * - Camera frame: forward f is the mean of the rays' unit directions; every ray used has
 *   cos(d, f) >= c_min >= MIN_COSINE. Depth is w(p) = (p - eye) . f, so a point p = eye +
 *   t d has w = t (d . f).
 * - Near plane: near = D c_min / 4, where D is the distance from the eye to the nearest
 *   box of the cut. A point of a ray (t >= 0) with w < near is closer to the eye than
 *   near / c_min = D / 4, so it lies in no box. So the hit point p, in box B, has
 *   w(p) >= near: it lies in the part of B that hf_project_box bounds (its corners in
 *   front of the near plane and the edges' cuts with it), whose projected rectangle
 *   therefore holds the ray's screen point, and w(p) >= the box's smallest depth.
 * - The ray's screen point lies in its coarse pixel, which the box's rectangle (widened
 *   by COVER_MARGIN of a pixel) touches; so the pixel's depth is <= w(p) and
 *   t = w(p) / (d . f) >= pixel depth / (d . f). A pixel that no rectangle touches holds
 *   rays that meet no box: they miss, without a walk.
 * - The walk then starts at the entry of the cell holding the bound (shrunk by
 *   BOUND_SHRINK): every cell before it ends at or before a parameter below the hit, so
 *   none holds dda_maxmip's hit, and the walk from a cell's entry tests the cells after
 *   it exactly as dda_maxmip does (the exact cell test depends only on the cell and the
 *   ray's [t0, t1]). Outputs are bit-identical to dda_maxmip's.
 * Where it does not apply the batch, or the ray, takes dda_maxmip's walk from t0: rays
 * that do not share the first ray's origin bit for bit (then the whole batch), an eye
 * inside (or within a hair of) a box, a cut of more than 4 N + 65536 boxes for N rays (the
 * whole batch), rays outside the cone (cos < MIN_COSINE), rays
 * whose range starts before the eye (t0 < 0), single-parameter rays and rays on a grid
 * line (dda_maxmip's own paths). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "core/hftrace.h"
#include "hierarchies/maxmip.h"
#include "raster/pitched.h"
#include "raster/warnock.h"

/* The image's resolution and boxes. Chosen by callgrind instructions per ray on the
 * 640 x 360 pinhole pitched 2.6 degrees over fBm 2048^2 (bench/studies/pitched_counts.py;
 * dda_maxmip: 2189): 64 rays per square coarse pixel 2048; 16 rays, 4 times more rows
 * than columns (8 x 2 rays) 1963; 8 x 1 rays 1955; 16 rays, 4 x taller, with boxes at the
 * floor level instead of one above it 2015 (the tighter bound costs more boxes). Again on
 * the targets' pitched row (all its rays, warm call), with the sky's early miss: 16 rays,
 * 4 x taller 1902; 12 rays, 6 x taller 1890; 8 rays, 4 x taller 1886 (kept); 8 rays, 8 x
 * taller 1884; 4 rays, 4 x taller 1878 (LL misses 1.42 against 1.41: an image of 57600
 * pixels). */
#define COARSE_RAYS           8    /* rays per coarse pixel, about */
#define COARSE_TALL           4.0  /* ray rows per coarse pixel: 1 / this of its ray columns */
#define BOX_LEVEL_ABOVE_FLOOR 1    /* the largest boxes: this many levels above the floor */
#define COARSE_MAX            2048 /* the coarse image's longest side, in pixels */
#define REFINE_RATIO          2.0  /* a tile closer to the eye than this many sides splits */
#define MIN_COSINE            0.05 /* the widest ray cone used: about 87 degrees */
#define COVER_MARGIN          0.01 /* a rectangle touches pixels within this many pixels */
#define BOUND_SHRINK          (1.0 - 1e-6)
#define MIN_HALF_TAN          1e-6 /* the narrowest half field of view of the coarse image */
#define CONE_SAMPLES          4096 /* rays the cone is measured on, about */
#define CONE_WIDEN            1.02 /* the measured cone's tangents, times this */

typedef struct {
    double lo[3], hi[3];
} tile_box;

typedef struct {
    int32_t level, tile_i, tile_j;
} tile_ref;

/* The coarse image: the camera of the eye, and per pixel the smallest depth of a box
 * touching it (INFINITY: none). */
typedef struct {
    hf_raster camera;
    double c_min, c_min2;    /* the smallest cosine of a ray used with forward, and its square */
    double scale_x, scale_y; /* pixels per unit of a / w and b / w: (width, height) / 2 / half */
    double *depth;
} coarse_image;

static int grow(void **buffer, int64_t *capacity, int64_t need, size_t item) {
    if (need > *capacity) {
        int64_t capacity_new = *capacity ? 2 * *capacity : 1024;
        void *grown;
        while (capacity_new < need) capacity_new *= 2;
        grown = realloc(*buffer, (size_t)capacity_new * item);
        if (!grown) return 0;
        *buffer = grown;
        *capacity = capacity_new;
    }
    return 1;
}

/* The closed box of tile (level, tile_i, tile_j), widened by a hair against rounding. */
static tile_box box_of(const hf_hit_batch *b, const double eye[3], int32_t level, int32_t tile_i,
                       int32_t tile_j) {
    const int64_t nx = b->cols - 1, ny = b->rows - 1;
    const double z_margin = 1e-6 * (1.0 + fabs(b->hmin) + fabs(b->hmax));
    int64_t x1 = ((int64_t)tile_i + 1) << level, y1 = ((int64_t)tile_j + 1) << level;
    tile_box box;
    if (x1 > nx) x1 = nx;
    if (y1 > ny) y1 = ny;
    box.lo[0] = (double)((int64_t)tile_i << level) - 1e-6;
    box.lo[1] = (double)((int64_t)tile_j << level) - 1e-6;
    box.hi[0] = (double)x1 + 1e-6;
    box.hi[1] = (double)y1 + 1e-6;
    /* below hmin a descending ray's range has ended (the clip's own margin is 1e-9 of
     * this); a level or rising ray never goes below the eye */
    box.lo[2] = (b->hmin < eye[2] ? b->hmin : eye[2]) - z_margin;
    box.hi[2] = hf_mip_tile_max(b, level, tile_i, tile_j) + z_margin;
    return box;
}

static double box_distance(const tile_box *box, const double eye[3]) {
    double sum = 0;
    int k;
    for (k = 0; k < 3; ++k) {
        const double gap = eye[k] < box->lo[k] ? box->lo[k] - eye[k]
                                               : (eye[k] > box->hi[k] ? eye[k] - box->hi[k] : 0);
        sum += gap * gap;
    }
    return sqrt(sum);
}

/* The cut of the mipmap: tiles at `coarsest` level or finer, split while nearer the eye
 * than REFINE_RATIO of their side, down to the finest level stored (cells). Appends the
 * boxes to *boxes and sets *nearest to the smallest distance from the eye to one.
 * Returns 1, 0 when out of memory, 2 when the cut would exceed max_boxes (an image that
 * would cost more than the walks it shortens: then no bound). */
static int collect_boxes(const hf_hit_batch *b, const double eye[3], int coarsest,
                         int64_t max_boxes, tile_box **boxes, int64_t *n_boxes, double *nearest) {
    const int top = b->mip_levels - 1;
    int finest = 0;
    int32_t rows_of[HF_MAX_MIP_LEVELS];
    tile_ref *stack = NULL;
    int64_t n_stack = 0, cap_stack = 0, cap_boxes = 0;
    int level;
    int32_t ti, tj;
    rows_of[0] = b->rows - 1;
    for (level = 1; level <= top; ++level) rows_of[level] = (rows_of[level - 1] + 1) / 2;
    while (finest < top && b->mip[finest] == NULL) ++finest; /* a lean mipmap starts higher */
    *n_boxes = 0;
    *nearest = INFINITY;
    if (!grow((void **)&stack, &cap_stack, (int64_t)rows_of[top] * b->mip_cols[top] + 4 * top + 4,
              sizeof *stack))
        return 0;
    for (tj = 0; tj < rows_of[top]; ++tj)
        for (ti = 0; ti < b->mip_cols[top]; ++ti) {
            stack[n_stack].level = top;
            stack[n_stack].tile_i = ti;
            stack[n_stack].tile_j = tj;
            ++n_stack;
        }
    while (n_stack > 0) {
        const tile_ref t = stack[--n_stack];
        const tile_box box = box_of(b, eye, t.level, t.tile_i, t.tile_j);
        const double distance = box_distance(&box, eye);
        if (t.level <= finest ||
            (t.level <= coarsest && distance >= REFINE_RATIO * (double)((int64_t)1 << t.level))) {
            if (*n_boxes >= max_boxes) {
                free(stack);
                return 2;
            }
            if (!grow((void **)boxes, &cap_boxes, *n_boxes + 1, sizeof **boxes)) {
                free(stack);
                return 0;
            }
            (*boxes)[(*n_boxes)++] = box;
            if (distance < *nearest) *nearest = distance;
            continue;
        }
        if (!grow((void **)&stack, &cap_stack, n_stack + 4, sizeof *stack)) {
            free(stack);
            return 0;
        }
        {
            int child;
            for (child = 0; child < 4; ++child) {
                const int32_t ci = 2 * t.tile_i + (child & 1), cj = 2 * t.tile_j + (child >> 1);
                if (ci >= b->mip_cols[t.level - 1] || cj >= rows_of[t.level - 1]) continue;
                stack[n_stack].level = t.level - 1;
                stack[n_stack].tile_i = ci;
                stack[n_stack].tile_j = cj;
                ++n_stack;
            }
        }
    }
    free(stack);
    return 1;
}

/* The camera coordinates of direction d (the same frame as to_camera). */
static cam_vertex direction_to_camera(const hf_raster *r, const double d[3]) {
    cam_vertex v;
    v.a = d[0] * r->right[0] + d[1] * r->right[1] + d[2] * r->right[2];
    v.b = d[0] * r->up[0] + d[1] * r->up[1] + d[2] * r->up[2];
    v.w = d[0] * r->forward[0] + d[1] * r->forward[1] + d[2] * r->forward[2];
    return v;
}

static double norm3(const double v[3]) {
    return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* The ray sampled after `ray`, `stride` further, ending with the last ray (n: none). */
static int64_t next_sample(int64_t ray, int64_t stride, int64_t n) {
    if (ray == n - 1) return n;
    return ray + stride < n ? ray + stride : n - 1;
}

/* Draw the coarse image of the batch's eye (every ray shares origins[0]); returns 1 when
 * it is usable, 0 when the bound does not apply (then img->depth is NULL), -1 when out of
 * memory. */
HF_COLD int coarse_build(const hf_hit_batch *b, coarse_image *img) {
    const double *eye = b->origins;
    hf_raster *cam = &img->camera;
    double f[3] = {0, 0, 0}, right[3], up[3], length, a_max = 0, b_max = 0, nearest;
    double c_min2 = 1.0, pixels, aspect;
    const double min_cosine2 = MIN_COSINE * MIN_COSINE;
    int64_t ray, k, n_cone = 0, n_boxes = 0, stride = b->n_rays / 1024 + 1, sampled;
    const int64_t cone_stride = b->n_rays / CONE_SAMPLES + 1;
    int32_t width, height;
    tile_box *boxes = NULL;
    int coarsest;
    memset(img, 0, sizeof *img);
    /* forward: the mean of the unit directions of up to 1024 rays spread over the batch
     * (any forward axis is correct; the cone below is measured on every ray) */
    for (ray = 0; ray < b->n_rays; ray += stride) {
        const double *d = b->directions + 3 * ray, len = norm3(d);
        if (!(len > 0) || !isfinite(len)) continue;
        f[0] += d[0] / len;
        f[1] += d[1] / len;
        f[2] += d[2] / len;
    }
    length = norm3(f);
    if (!(length > 0) || !isfinite(length)) return 0;
    for (k = 0; k < 3; ++k) f[k] /= length;
    /* right: horizontal where the view is not vertical; up completes the frame */
    length = sqrt(f[0] * f[0] + f[1] * f[1]);
    if (length > 1e-6) {
        right[0] = f[1] / length, right[1] = -f[0] / length, right[2] = 0;
    } else {
        length = sqrt(f[1] * f[1] + f[2] * f[2]);
        right[0] = 0, right[1] = f[2] / length, right[2] = -f[1] / length;
    }
    up[0] = right[1] * f[2] - right[2] * f[1];
    up[1] = right[2] * f[0] - right[0] * f[2];
    up[2] = right[0] * f[1] - right[1] * f[0];
    memcpy(cam->position, eye, sizeof cam->position);
    memcpy(cam->forward, f, sizeof f);
    memcpy(cam->right, right, sizeof right);
    memcpy(cam->up, up, sizeof up);
    /* the cone: c_min and the field of view of the rays inside it, measured on a sample
     * (about CONE_SAMPLES rays spread over the batch, and its last ray) and widened by
     * CONE_WIDEN. Any cone is correct: a ray outside it (coarse_bound) gets no bound. */
    for (ray = 0, sampled = 0; ray < b->n_rays; ray = next_sample(ray, cone_stride, b->n_rays)) {
        const double *d = b->directions + 3 * ray;
        ++sampled;
        const double length2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        const cam_vertex v = direction_to_camera(cam, d);
        /* squared cosines and tangents compared by products: no root, few divisions */
        if (!(length2 > 0) || !isfinite(length2) || !(v.w > 0) ||
            !(v.w * v.w >= min_cosine2 * length2))
            continue;
        if (v.w * v.w < c_min2 * length2) c_min2 = v.w * v.w / length2;
        if (fabs(v.a) > a_max * v.w) a_max = fabs(v.a) / v.w;
        if (fabs(v.b) > b_max * v.w) b_max = fabs(v.b) / v.w;
        ++n_cone;
    }
    if (n_cone == 0) return 0;
    n_cone = (int64_t)((double)n_cone / (double)sampled * (double)b->n_rays) + 1;
    c_min2 *= 1.0 / (CONE_WIDEN * CONE_WIDEN);
    img->c_min2 = c_min2 > min_cosine2 ? c_min2 : min_cosine2;
    img->c_min = sqrt(img->c_min2);
    cam->half_w = (a_max > MIN_HALF_TAN ? a_max : MIN_HALF_TAN) * CONE_WIDEN;
    cam->half_h = (b_max > MIN_HALF_TAN ? b_max : MIN_HALF_TAN) * CONE_WIDEN;
    pixels = (double)n_cone / COARSE_RAYS;
    if (pixels < 1) pixels = 1;
    aspect = cam->half_w / cam->half_h / COARSE_TALL;
    aspect = aspect < 1.0 / 256 ? 1.0 / 256 : (aspect > 256 ? 256 : aspect);
    width = (int32_t)fmin(ceil(sqrt(pixels * aspect)), COARSE_MAX);
    height = (int32_t)fmin(ceil(pixels / width), COARSE_MAX);
    cam->width = width > 0 ? width : 1;
    cam->height = height > 0 ? height : 1;
    img->scale_x = 0.5 * (double)cam->width / cam->half_w;
    img->scale_y = 0.5 * (double)cam->height / cam->half_h;
    /* the boxes and the near plane */
    coarsest = b->floor_level + BOX_LEVEL_ABOVE_FLOOR < b->mip_levels - 1
                   ? b->floor_level + BOX_LEVEL_ABOVE_FLOOR
                   : b->mip_levels - 1;
    {
        const int collected =
            collect_boxes(b, eye, coarsest, 4 * n_cone + 65536, &boxes, &n_boxes, &nearest);
        if (collected == 0) {
            free(boxes);
            return -1;
        }
        if (collected == 2) {
            free(boxes);
            return 0;
        }
    }
    /* Numerical hazard: camera coordinates carry the eye's rounding (about 1e-16 |eye|);
     * an eye this far from every box keeps it under 1e-8 of any depth the image uses, far
     * inside BOUND_SHRINK. Nearer (inside a box, or touching one): no bound. */
    if (!(nearest > 1e-6 * (1.0 + norm3(eye))) || !isfinite(nearest)) {
        free(boxes);
        return 0;
    }
    cam->near = nearest * img->c_min / 4;
    img->depth = (double *)malloc((size_t)cam->width * (size_t)cam->height * sizeof(double));
    if (!img->depth) {
        free(boxes);
        return -1;
    }
    for (k = 0; k < (int64_t)cam->width * cam->height; ++k) img->depth[k] = INFINITY;
    /* each box's smallest depth into every pixel its rectangle touches */
    for (k = 0; k < n_boxes; ++k) {
        box_bound bb;
        double x0, x1, y0, y1;
        int32_t c, c0, c1, r0, r1, row;
        if (!hf_project_box(cam, boxes[k].lo, boxes[k].hi, &bb)) continue; /* behind */
        if (!(bb.X_min <= bb.X_max && bb.Y_min <= bb.Y_max && bb.w_min >= 0)) {
            /* Numerical hazard: a rectangle rounding left empty; taken as everywhere, at 0 */
            bb.X_min = bb.Y_min = -INFINITY;
            bb.X_max = bb.Y_max = INFINITY;
            bb.w_min = 0;
        }
        x0 = bb.X_min - COVER_MARGIN, x1 = bb.X_max + COVER_MARGIN;
        y0 = bb.Y_min - COVER_MARGIN, y1 = bb.Y_max + COVER_MARGIN;
        if (x1 < 0 || y1 < 0 || x0 >= cam->width || y0 >= cam->height) continue;
        /* clamp before converting: rectangles near the near plane can be huge */
        c0 = x0 > 0 ? (int32_t)x0 : 0;
        r0 = y0 > 0 ? (int32_t)y0 : 0;
        c1 = x1 < cam->width - 1 ? (int32_t)x1 : cam->width - 1;
        r1 = y1 < cam->height - 1 ? (int32_t)y1 : cam->height - 1;
        for (row = r0; row <= r1; ++row) {
            double *line = img->depth + (int64_t)row * cam->width;
            for (c = c0; c <= c1; ++c)
                if (bb.w_min < line[c]) line[c] = bb.w_min;
        }
    }
    free(boxes);
    return 1;
}

/* The lower bound on ray d's first hit from the image: 1 with *bound set (0 where the
 * image does not apply to the ray), 0 when the ray meets no box (a miss). */
HF_HOT int coarse_bound(const coarse_image *img, const double d[3], double *bound) {
    const hf_raster *cam = &img->camera;
    const double *f = cam->forward, *right = cam->right, *up = cam->up;
    const double w = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
    const double length2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    double inv_w, X, Y, depth;
    int32_t c, row;
    *bound = 0;
    /* in the cone (cosine with forward at least c_min, compared squared: no root) */
    if (!(w > 0 && w * w >= img->c_min2 * length2 && length2 > 0)) return 1;
    /* the screen point: project()'s, to a few units in the last place (COVER_MARGIN is
     * 1e10 of those) */
    inv_w = 1.0 / w;
    X = (d[0] * right[0] + d[1] * right[1] + d[2] * right[2]) * inv_w * img->scale_x +
        0.5 * cam->width;
    Y = 0.5 * cam->height - (d[0] * up[0] + d[1] * up[1] + d[2] * up[2]) * inv_w * img->scale_y;
    /* within the image by construction; anything else (rounding, NaN) gets no bound */
    if (!(X >= -COVER_MARGIN && X <= cam->width + COVER_MARGIN && Y >= -COVER_MARGIN &&
          Y <= cam->height + COVER_MARGIN))
        return 1;
    c = X > 0 ? (X < cam->width - 1 ? (int32_t)X : cam->width - 1) : 0;
    row = Y > 0 ? (Y < cam->height - 1 ? (int32_t)Y : cam->height - 1) : 0;
    depth = img->depth[(int64_t)row * cam->width + c];
    if (depth == INFINITY) return 0;
    *bound = depth * inv_w * BOUND_SHRINK;
    return 1;
}

/* One ray: dda_maxmip's walk, from the cell holding its bound when the image gives one. h:
 * the batch's hit record (the steps' `start`), which serves every ray in turn. */
static int pitched_ray(hf_hit_batch *b, const hf_ray_steps *steps, int64_t ray,
                       const coarse_image *img, const hf_hit *miss, hf_hit *h) {
    hf_mip_ray r;
    hf_mip_walk w;
    double t0, t1, bound = 0;
    int entry_axis, bounded = 0;
    if (b->bound) b->bound[ray] = INFINITY;
    if (img->depth && (b->tmin ? b->tmin[ray] : 0.0) >= 0) {
        /* A level or rising ray whose range starts at or after the eye (so does its clipped
         * range) and that meets no box misses. It gets a miss's outputs (a zeroed hf_hit,
         * as a ray the box clip rejects) without the clip and the set-up: most of a grazing
         * camera's sky. A descending ray can enter the field's side below hmin, where
         * there is no box, and hit its wall at a single parameter (a range clipped to one
         * point); rays parallel to a grid axis have paths of their own. Both take the
         * steps below. */
        const double *d = b->directions + 3 * ray;
        if (d[2] >= 0 && d[0] != 0 && d[1] != 0) {
            if (!coarse_bound(img, d, &bound)) {
                steps->end(b, ray, miss);
                return HF_OK;
            }
            bounded = 1;
        }
    }
    if (!steps->begin(b, ray, h, &t0, &t1, &entry_axis)) {
        steps->end(b, ray, h);
        return HF_OK;
    }
    if (b->bound) b->bound[ray] = t0;
    if (!(t0 < t1) || hf_on_grid_line(h)) {
        /* a single parameter, or a ray on a grid line: dda_maxmip's own per-ray paths */
        const int status = steps->solve(b, ray, h, t0, t1, entry_axis);
        if (status != HF_OK) return status;
        steps->end(b, ray, h);
        return HF_OK;
    }
    hf_mip_setup(h, b, &r, &w);
    if (img->depth && t0 >= 0) {
        if (!bounded && !coarse_bound(img, b->directions + 3 * ray, &bound)) {
            if (b->bound) b->bound[ray] = INFINITY;
            steps->end(b, ray, h); /* it meets no box: a miss */
            return HF_OK;
        }
        if (bound > t0) {
            if (b->bound) b->bound[ray] = bound;
            /* start at the entry of the cell holding the bound, if the ray crosses it */
            const double start = bound < t1 ? bound : t1;
            const int32_t i = hf_cell_at(h->ox, h->dx, start, r.nx);
            const int32_t j = hf_cell_at(h->oy, h->dy, start, r.ny);
            double ta, tb;
            (void)hf_cell_interval(h, i, j, &ta, &tb);
            if (ta < tb && ta <= start && start <= tb) {
                w.i = i;
                w.j = j;
                w.t = ta;
            }
        }
    }
    (void)hf_mip_walk_alone(h, b, &r, &w, 0);
    steps->end(b, ray, h);
    return HF_OK;
}

int hf_pitched_batch(hf_hit_batch *b, const hf_ray_steps *steps) {
    coarse_image img;
    hf_hit miss, h;
    int64_t ray;
    int shared = 1, status = HF_OK;
    if (b->mip_levels < 1) return HF_ERR_ARGUMENT;
    b->bad_ray = -1;
    memset(&img, 0, sizeof img);
    for (ray = 1; ray < b->n_rays && shared; ++ray)
        shared = memcmp(b->origins, b->origins + 3 * ray, 3 * sizeof(double)) == 0;
    if (b->n_rays > 0 && shared) {
        const int built = coarse_build(b, &img);
        if (built < 0) return HF_ERR_MEMORY;
    }
    memset(&miss, 0, sizeof miss);
    steps->start(b, &h);
    for (ray = 0; ray < b->n_rays && status == HF_OK; ++ray) {
        status = pitched_ray(b, steps, ray, &img, &miss, &h);
        if (status != HF_OK) b->bad_ray = ray;
    }
    free(img.depth);
    return status;
}
