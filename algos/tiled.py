"""Terrain products on Dask arrays: tiles with a halo, for fields larger than memory and
clusters larger than one machine.

A vertex's horizon (and so its shadow and sky-view factor) with a finite
``max_distance`` D (a length in the field's unit) depends only on the surface within D
of it, which lies in the cells whose corners are within ``ceil(D / dy) + 1`` rows and
``ceil(D / dx) + 1`` columns of the vertex. So :func:`tiled_product` maps the in-memory
product over the chunks with ``dask.array.map_overlap``, a halo of that depth per axis
and no padding at the field's edges (``boundary="none"``): every tile sees exactly what
the whole field would show its vertices, and the result equals the in-memory one (to
the last bits of the C walks' float coordinates, which are relative to each tile; the
tests bound the difference at 1e-12 rad). Unlimited distances cannot be tiled and raise.

Voids in a lazy field are NaN heights (:func:`datasets_gen.open_lazy` reads nodata as
NaN); each tile finds its own.

A viewshed is not a tile-local product: it needs the observer's window, ``D + 1``
samples around the observer, which is cut from the lazy array and computed in memory;
the rest of the result is known without reading it (out of range: not visible).
"""
from __future__ import annotations

import math

import numpy as np

from .field import HeightField, is_dask
from .validate import check_spacing

__all__ = ["is_dask", "tiled_product", "halo_depth", "tiled_viewshed"]


def halo_depth(max_distance_cells) -> int:
    """Samples of halo that hold every point within ``max_distance_cells`` of a vertex."""
    if max_distance_cells is None or not math.isfinite(max_distance_cells):
        raise ValueError("max_distance: a tiled (dask) product needs a finite max_distance; "
                         "the halo is that distance")
    return int(math.ceil(max_distance_cells)) + 1


def _unwrap(heights, spacing, north_up=True):
    """``(dask array, wrap, (dx, dy) or None, back, extra)`` of a dask array or a
    HeightField holding one. ``wrap(block)`` makes a product's input of a NumPy block (a
    HeightField with the field's units, or the block itself); ``(dx, dy)`` is the pixel
    size that turns ``max_distance`` into cells (None: cell units). With ``north_up`` a
    field whose rows run north is flipped (:meth:`HeightField.to_north_up`), and ``back``
    is that flip, for the result (None: nothing to undo); ``extra`` holds the keywords a
    raw block needs (its ``spacing``)."""
    if isinstance(heights, HeightField):
        field = heights
        if spacing is not None and check_spacing(spacing) != (field.dx, field.dy):
            raise ValueError(f"spacing: {spacing!r}, but {field.name} carries its own pixel "
                             f"size ({field.dx:g}, {field.dy:g}); leave spacing out")
        flip = north_up and not field.north_up
        arr = field.to_north_up(field.heights) if north_up else field.heights

        def wrap(block):
            return HeightField(block, field.name, spacing=field.spacing, unit=field.unit,
                               height_unit=field.height_unit, params=field.params,
                               north="-y" if (flip or field.north_up) else "+y")

        pixel = (field.dx, field.dy) if field.unit != "cell" else None
        return arr, wrap, pixel, (field.to_north_up if flip else None), {}
    pixel = check_spacing(spacing) if spacing is not None else None
    return heights, (lambda block: block), pixel, None, {"spacing": spacing}


def tiled_product(product, heights, max_distance, spacing, dtype, **kwargs):
    """``product(block, max_distance=..., **kwargs)`` (a 2D in-memory terrain product)
    over a dask array's chunks with a halo of ``max_distance`` (a length in the field's
    unit). Returns a lazy dask array shaped like ``heights``."""
    arr, wrap, pixel, back, extra = _unwrap(heights, spacing)
    if arr.ndim != 2:
        raise ValueError(f"heights: expected a 2D array (rows, cols), got shape {arr.shape}")
    if max_distance is None:
        halo_depth(None)
    md = float(max_distance)
    dx, dy = pixel if pixel is not None else (1.0, 1.0)
    # no data lies beyond the array: a halo of the whole array is as good as a deeper one
    depth = {0: min(halo_depth(md / dy), arr.shape[0] - 1),
             1: min(halo_depth(md / dx), arr.shape[1] - 1)}
    # every chunk at least as deep as the halo (map_overlap takes neighbours only)
    if any(max(c) < depth[axis] for axis, c in enumerate(arr.chunks)):
        arr = arr.rechunk(tuple(max(depth[axis], max(c)) for axis, c in enumerate(arr.chunks)))

    def block(h):
        return product(wrap(np.asarray(h)), max_distance=max_distance, **extra, **kwargs)

    out = arr.map_overlap(block, depth=depth, boundary="none", trim=True, dtype=dtype)
    return out if back is None else back(out)


def tiled_viewshed(viewshed, heights, observer, max_distance, spacing, **kwargs):
    """A viewshed of a dask array: each observer's window computed in memory (see the
    module docstring). Observers are in the stored array's coordinates (a line of sight
    does not depend on which way is north). Returns a lazy bool (one observer) or uint16
    (count) array."""
    import dask.array as da

    arr, wrap, pixel, _, extra = _unwrap(heights, spacing, north_up=False)
    rows, cols = arr.shape
    dx, dy = pixel if pixel is not None else (1.0, 1.0)
    md = None if max_distance is None else float(max_distance)
    depth_y = halo_depth(None if md is None else md / dy)
    depth_x = halo_depth(md / dx)
    single = np.asarray(observer).ndim == 1
    obs = np.atleast_2d(np.asarray(observer, dtype=np.float64))
    total = da.zeros((rows, cols), dtype=np.uint16, chunks=arr.chunks)
    for k, (x, y) in enumerate(obs):
        if not (math.isfinite(x) and math.isfinite(y) and 0 <= x <= cols - 1 and 0 <= y <= rows - 1):
            raise ValueError(f"observer[{k}]: ({x}, {y}) outside the footprint "
                             f"[0, {cols - 1}] x [0, {rows - 1}]")
        c0, c1 = max(0, int(math.floor(x)) - depth_x), min(cols, int(math.ceil(x)) + depth_x + 1)
        r0, r1 = max(0, int(math.floor(y)) - depth_y), min(rows, int(math.ceil(y)) + depth_y + 1)
        window = np.ascontiguousarray(arr[r0:r1, c0:c1].compute())
        seen = viewshed(wrap(window), (x - c0, y - r0), max_distance=max_distance, **extra,
                        **kwargs).astype(np.uint16)
        patch = da.pad(da.from_array(seen, chunks=seen.shape),
                       ((r0, rows - r1), (c0, cols - c1)), mode="constant")
        total = total + patch.rechunk(arr.chunks)
    return total.astype(bool) if single else total
