/* Watkins' scanline renderer of a height field (see raster.h).
 *
 * The picture is built one image row (scanline) at a time. The triangles of the field
 * (the two of each facing cell, and the skirts) are projected once and bucketed by their
 * first centre row: the edge table. On each row the active list holds the triangles whose
 * rows include it; each contributes its two edge crossings (the columns where its span of
 * pixel centres begins and ends, by the zbuffer's top-left rule). Sorted by column, the
 * crossings cut the row into spans over which the set of triangles covering a pixel centre
 * does not change. The triangles of a height field meet only along shared edges, never
 * through each other, so within a span their depth order is fixed: one depth decision per
 * span, at its middle pixel, picks the visible triangle, and only that triangle's depth is
 * evaluated at the span's pixels.
 *
 * On a height field the spans follow the field's cell rows: seen from a camera, each row of
 * cells projects to a band of the image, and a scanline crosses the bands front to back;
 * the crossings of a scanline are the projected cell borders of the cell rows it passes.
 *
 * The pixel centre tests are those of screen_triangle (raster_geometry.h), so a pixel gets
 * the triangle the zbuffer gives it (ties broken by in_front, the zbuffer's order), except
 * where its centre lies within rounding of a projected edge (the zbuffer tracks its edges
 * incrementally, this renderer evaluates them directly). */
#include <stdlib.h>
#include <string.h>
#include "core/hftrace.h"
#include "raster/watkins.h"
#include "raster/raster_geometry.h"

/* one edge crossing of a scanline: triangle `triangle` starts (enter = 1) or stops covering
 * pixel centres at `column` */
typedef struct {
    int32_t column, enter, triangle;
} crossing;

static int by_column(const void *a, const void *b) {
    const int32_t ca = ((const crossing *)a)->column, cb = ((const crossing *)b)->column;
    return (ca > cb) - (ca < cb);
}

/* The edge table of the region: every screen triangle holding a pixel centre row of the
 * region, in the order the cells are enumerated (row-major, skirts with their cell). */
typedef struct {
    screen_triangle *triangles;
    int64_t n, capacity;
} edge_table;

static int table_reserve(edge_table *table, int64_t more) {
    if (table->n + more > table->capacity) {
        int64_t capacity = table->capacity ? 2 * table->capacity : 1024;
        screen_triangle *grown;
        while (capacity < table->n + more) capacity *= 2;
        if (capacity > INT32_MAX) return 0; /* triangle indices are int32 */
        grown = realloc(table->triangles, (size_t)capacity * sizeof *grown);
        if (!grown) return 0;
        table->triangles = grown;
        table->capacity = capacity;
    }
    return 1;
}

/* Whether a triangle of at most two centre rows holds a pixel centre of the region (a
 * taller one is kept unasked): far from the camera most triangles are smaller than a pixel
 * and hold none, and the table stays about as large as the image. */
static int holds_a_centre(const hf_raster *r, const screen_triangle *t) {
    int32_t row, c0, c1;
    if (t->row_bottom - t->row_top > 2) return 1;
    for (row = t->row_top; row < t->row_bottom; ++row) {
        if (row < r->row_begin || row >= r->row_end) continue;
        screen_triangle_span(r, t, row, &c0, &c1);
        if (c0 < c1) return 1;
    }
    return 0;
}

/* Project the field's triangles into the edge table; cells outside the region's frustum
 * are culled as the zbuffer culls them (a boundary cell is kept for its skirts). */
static int build_edge_table(hf_raster *r, edge_table *table) {
    const int32_t nx = r->cols - 1, ny = r->rows - 1;
    int32_t i, j;
    for (j = 0; j < ny; ++j) {
        for (i = 0; i < nx; ++i) {
            const int boundary = i == 0 || j == 0 || i == nx - 1 || j == ny - 1;
            int n, k, kept;
            r->counts[HF_COUNT_CELLS] += 1;
            if (!boundary) {
                const int code = outcode(r, to_camera(r, i, j, height_at(r, i, j))) &
                                 outcode(r, to_camera(r, i + 1, j, height_at(r, i + 1, j))) &
                                 outcode(r, to_camera(r, i, j + 1, height_at(r, i, j + 1))) &
                                 outcode(r, to_camera(r, i + 1, j + 1, height_at(r, i + 1, j + 1)));
                if (code) {
                    r->counts[HF_COUNT_CULLED] += 1;
                    continue;
                }
            }
            r->counts[HF_COUNT_DRAWN] += 1;
            if (!table_reserve(table, 12)) return 0;
            n = cell_screen_triangles(r, i, j, 1, table->triangles + table->n);
            /* keep the triangles with a centre row inside the region */
            for (k = 0, kept = 0; k < n; ++k) {
                const screen_triangle *t = table->triangles + table->n + k;
                if (t->row_bottom <= r->row_begin || t->row_top >= r->row_end) continue;
                if (!holds_a_centre(r, t)) continue;
                if (kept != k) table->triangles[table->n + kept] = *t;
                ++kept;
            }
            table->n += kept;
        }
    }
    return 1;
}

/* One span [a, b) of a scanline covered by the `n_in` triangles in `in_span`: decide the
 * visible one at the middle pixel and write its depth on the span's pixels. */
static void draw_span(hf_raster *r, const screen_triangle *triangles, const int32_t *in_span,
                      int32_t n_in, int32_t row, int32_t a, int32_t b) {
    const int32_t middle = a + (b - a - 1) / 2;
    const screen_triangle *best = NULL;
    double best_z = 0;
    int32_t k, c;
    r->counts[HF_COUNT_SAMPLES] += 1;
    r->counts[HF_COUNT_FRAGMENTS] += n_in;
    for (k = 0; k < n_in; ++k) {
        const screen_triangle *t = triangles + in_span[k];
        const double z = screen_triangle_depth(r, t, middle, row);
        if (in_front(z, t->id, best_z, best ? best->id : -1)) {
            best = t;
            best_z = z;
        }
    }
    for (c = a; c < b; ++c) {
        const int64_t pixel = (int64_t)row * r->width + c;
        r->t[pixel] = screen_triangle_depth(r, best, c, row);
        r->primitive[pixel] = best->id;
    }
    r->counts[HF_COUNT_WRITTEN] += b - a;
}

int hf_watkins(hf_raster *r) {
    const int32_t band = r->row_end - r->row_begin;
    edge_table table = {NULL, 0, 0};
    int32_t *bucket = NULL, *order = NULL, *active = NULL, *in_span = NULL, *slot = NULL;
    crossing *crossings = NULL;
    int32_t row, k, n_active = 0;
    int status = HF_ERR_MEMORY;
    if (!build_edge_table(r, &table)) goto done;
    r->counts[HF_COUNT_TRIANGLES] = table.n;
    /* the edge table's buckets: triangles by their first row in the region (counting sort) */
    bucket = calloc((size_t)band + 1, sizeof *bucket);
    order = malloc(((size_t)table.n + 1) * sizeof *order);
    active = malloc(((size_t)table.n + 1) * sizeof *active);
    in_span = malloc(((size_t)table.n + 1) * sizeof *in_span);
    slot = malloc(((size_t)table.n + 1) * sizeof *slot);
    crossings = malloc((2 * (size_t)table.n + 1) * sizeof *crossings);
    if (!bucket || !order || !active || !in_span || !slot || !crossings) goto done;
    for (k = 0; k < (int32_t)table.n; ++k) {
        const int32_t first =
            table.triangles[k].row_top > r->row_begin ? table.triangles[k].row_top : r->row_begin;
        bucket[first - r->row_begin + 1] += 1;
    }
    for (row = 0; row < band; ++row) bucket[row + 1] += bucket[row];
    {
        /* stable: a bucket keeps the enumeration order */
        int32_t *fill = malloc(((size_t)band + 1) * sizeof *fill);
        if (!fill) goto done;
        memcpy(fill, bucket, ((size_t)band + 1) * sizeof *fill);
        for (k = 0; k < (int32_t)table.n; ++k) {
            const int32_t first = table.triangles[k].row_top > r->row_begin
                                      ? table.triangles[k].row_top
                                      : r->row_begin;
            order[fill[first - r->row_begin]++] = k;
        }
        free(fill);
    }
    for (row = r->row_begin; row < r->row_end; ++row) {
        int32_t n_crossings = 0, n_in = 0, e, kept = 0, previous = 0;
        /* the active list: add the triangles starting here, drop those that ended */
        for (k = bucket[row - r->row_begin]; k < bucket[row - r->row_begin + 1]; ++k)
            active[n_active++] = order[k];
        for (k = 0; k < n_active; ++k)
            if (table.triangles[active[k]].row_bottom > row) active[kept++] = active[k];
        n_active = kept;
        /* the crossings of this scanline */
        for (k = 0; k < n_active; ++k) {
            int32_t c0, c1;
            screen_triangle_span(r, table.triangles + active[k], row, &c0, &c1);
            if (c0 >= c1) continue;
            crossings[n_crossings].column = c0;
            crossings[n_crossings].enter = 1;
            crossings[n_crossings++].triangle = active[k];
            crossings[n_crossings].column = c1;
            crossings[n_crossings].enter = 0;
            crossings[n_crossings++].triangle = active[k];
        }
        qsort(crossings, (size_t)n_crossings, sizeof *crossings, by_column);
        /* walk the spans: between two crossing columns the covering set is in_span */
        for (e = 0; e < n_crossings;) {
            const int32_t column = crossings[e].column;
            if (n_in > 0 && previous < column)
                draw_span(r, table.triangles, in_span, n_in, row, previous, column);
            for (; e < n_crossings && crossings[e].column == column; ++e) {
                const int32_t t = crossings[e].triangle;
                if (crossings[e].enter) {
                    slot[t] = n_in;
                    in_span[n_in++] = t;
                } else {
                    /* remove t: the last member takes its slot */
                    const int32_t last = in_span[--n_in];
                    in_span[slot[t]] = last;
                    slot[last] = slot[t];
                }
            }
            previous = column;
        }
    }
    status = HF_OK;
done:
    free(table.triangles);
    free(bucket);
    free(order);
    free(active);
    free(in_span);
    free(slot);
    free(crossings);
    return status;
}
