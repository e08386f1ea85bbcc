/* Warnock's area-subdivision renderer (warnock.c), called by hf_raster_render on a cleared
 * region (band_top and band_bottom set); HF_OK or HF_ERR_MEMORY. And the one projected
 * bound of a box (a max-mipmap tile) against the camera, box_bound of raster_geometry.h,
 * which the classification asks of every tile. */
#ifndef HFTRACE_RASTER_WARNOCK_H
#define HFTRACE_RASTER_WARNOCK_H

#include "raster/frame.h"
#include "raster/raster_geometry.h"

int hf_warnock(hf_raster *r);

/* Returns 0 when the whole box lies behind the near plane (nothing to draw), else 1. */
int hf_project_box(const hf_raster *r, const double lo[3], const double hi[3], box_bound *b);

#endif
