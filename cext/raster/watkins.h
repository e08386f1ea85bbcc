/* Watkins' scanline renderer (watkins.c), called by hf_raster_render on a cleared region
 * (band_top and band_bottom set). Returns HF_OK or HF_ERR_MEMORY. */
#ifndef HFTRACE_RASTER_WATKINS_H
#define HFTRACE_RASTER_WATKINS_H

#include "raster/frame.h"

int hf_watkins(hf_raster *r);

#endif
