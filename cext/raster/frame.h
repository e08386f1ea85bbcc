/* The rasterisers' shared types: the algorithm and primitive ids, the counts of the cost
 * model, and hf_raster, the one description of a camera, a field and an image region that
 * every renderer (raster.c, watkins.c, warnock.c) and the shared geometry
 * (raster_geometry.h) read. Types only, so the renderers and the geometry sit below the
 * dispatcher that includes raster.h. */
#ifndef HFTRACE_RASTER_FRAME_H
#define HFTRACE_RASTER_FRAME_H

#include <stddef.h>
#include <stdint.h>

enum hf_raster_algorithm {
    HF_RASTER_ZBUFFER = 0,
    HF_RASTER_PAINTER = 1,
    HF_RASTER_FLOATING_HORIZON = 2,
    HF_RASTER_HIDDEN_LINES = 3, /* the floating horizon's line drawing (whole image only) */
    HF_RASTER_WATKINS = 4,      /* scanline: active edges, one depth decision per span */
    HF_RASTER_WARNOCK = 5,      /* area subdivision against max-mipmap tile bounds     */
    HF_N_RASTER = 6
};

/* primitive kinds stored per pixel (id = cell_index * 4 + kind) */
enum hf_raster_kind {
    HF_KIND_LOWER = 0,  /* triangle (i,j)(i+1,j)(i+1,j+1): u >= v */
    HF_KIND_UPPER = 1,  /* triangle (i,j)(i+1,j+1)(i,j+1): u < v  */
    HF_KIND_WALL_X = 2, /* a skirt on x = 0 or x = cols-1         */
    HF_KIND_WALL_Y = 3  /* a skirt on y = 0 or y = rows-1         */
};

/* the counts of the cost model, in this order in hf_raster.counts */
enum hf_raster_count {
    HF_COUNT_CELLS = 0,     /* cells the algorithm looked at                          */
    HF_COUNT_CULLED = 1,    /* of them, rejected by the view frustum                  */
    HF_COUNT_DRAWN = 2,     /* cells whose triangles were scan converted              */
    HF_COUNT_TRIANGLES = 3, /* front-facing triangles scan converted (skirts included) */
    HF_COUNT_FRAGMENTS = 4, /* pixel centres found inside a drawn triangle            */
    HF_COUNT_WRITTEN = 5,   /* depth or colour writes                                 */
    HF_COUNT_SAMPLES = 6,   /* floating horizon: surface samples (lines: segments)    */
    HF_COUNT_FULL = 7,      /* painter: 1 when it stopped on a full mask              */
    HF_N_COUNTS = 8
};

typedef struct {
    /* the field: H[j * cols + i] */
    const float *heights;
    int32_t rows, cols;
    double hmin, hmax;
    /* the camera: an orthonormal frame and the per-column / per-row screen offsets */
    double position[3], forward[3], right[3], up[3];
    double half_w, half_h; /* tan of half the horizontal / vertical field of view */
    int32_t width, height;
    const double *sx, *sy; /* (width,), (height,) */
    double near;           /* geometry closer than this depth is clipped away    */
    double z_bottom;       /* the skirts' lower edge                             */
    double step;           /* floating horizon: march step in cells              */
    /* The region drawn: rows [row_begin, row_end) x columns [column_begin, column_end).
     * Threads draw disjoint regions of one image: zbuffer and painter bands of whole
     * rows, floating_horizon ranges of whole columns. Every pixel gets the value it gets
     * in a whole-image call (the same fragments in the same order), bit for bit. */
    int32_t row_begin, row_end, column_begin, column_end;
    double band_top, band_bottom; /* set by hf_raster_render: the region's vertical tans */
    /* outputs, (height, width) pixels in row-major order; normal and coverage optional */
    double *t;         /* inf where nothing is hit                           */
    int32_t *cell;     /* (i, j); (-1, -1) where nothing is hit              */
    double *normal;    /* unit, NaN where nothing is hit                     */
    int32_t *coverage; /* zbuffer: front-facing fragments per pixel          */
    /* workspace of the caller, never allocated here (whole image; a region uses its part) */
    int64_t *primitive;  /* per pixel: cell_index * 4 + kind, or -1            */
    uint8_t *mask;       /* painter: per pixel; hidden lines: the drawing (output) */
    double *vertex_rows; /* hf_raster_workspace_doubles(algorithm, cols, width)   */
    int64_t counts[HF_N_COUNTS];
} hf_raster;

#endif
