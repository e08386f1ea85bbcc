/* Rasterisers of a height field: the "convert to polygons" road of the seeds, against which
 * the tracers are measured.
 *
 * - zbuffer: scan conversion of the field's two triangles per cell (the split of
 *   CONVENTIONS "triangles", Embree's vertices) with a depth buffer; trapezoid
 *   decomposition, edge trackers with the sub-pixel start and incremental depth along spans
 *   (the Portuguese lecture), 1/w interpolated in screen space (perspective-correct).
 * - painter: the reverse painter (the Czech chapter): cells front to back in an order read
 *   off the camera's position on the grid, each drawn through a coverage mask; stops when
 *   the mask is full.
 * - floating_horizon: the chapter's algorithm for z = F(x, y), in its shaded column form:
 *   each image column marches front to back over the field and draws only above its
 *   current horizon. Approximate by design.
 * - hidden_lines: the floating horizon's line drawing: the grid's row sections front to
 *   back, zig-zagging through the column segments that join consecutive rows, each point
 *   drawn when it lies above the upper or below the lower horizon of the sections drawn
 *   before it (one point per image column and segment).
 * - watkins (watkins.c): Watkins' scanline algorithm: per image row an active list of the
 *   triangles crossing it, their edge crossings sorted into spans, one depth decision per
 *   span.
 * - warnock (warnock.c): Warnock's area subdivision: a screen region is classified
 *   against the projected bounds of the max-mipmap's tiles (empty, hidden behind a
 *   surrounding triangle, or split in four) down to the pixels that need a depth test.
 *
 * The camera is the pinhole of algos.camera: pixel (c, k) (column, row; row 0
 * at the top) looks along d = forward + sx[c] right + sy[k] up, and the depth written is the
 * ray parameter t of the unit direction d / |d|, as the tracers write it.
 *
 * The box of the field is [0, cols-1] x [0, rows-1]; below its surface the field is solid,
 * so a ray that enters through a side face below the surface hits that face (a wall, as
 * the tracers report it). The rasterisers draw those faces as skirts down to z_bottom. */
#ifndef HFTRACE_RASTER_H
#define HFTRACE_RASTER_H

#include <stddef.h>
#include <stdint.h>

#include "raster/frame.h"

/* Render one region of an image. Returns 0 (HF_OK), HF_ERR_ARGUMENT for an unknown
 * algorithm or a region outside the image, or HF_ERR_MEMORY when watkins or warnock cannot
 * allocate their tables. No allocation in the other rasterisers (watkins and warnock
 * allocate their triangle table or tile pyramid once per call, before drawing);
 * thread-safe for disjoint regions; the GIL may be released around it. */
int hf_raster_render(int algorithm, hf_raster *r);

/* The size of hf_raster.vertex_rows, in doubles (0: not used by this algorithm). */
size_t hf_raster_workspace_doubles(int algorithm, int32_t cols, int32_t width);

#endif
