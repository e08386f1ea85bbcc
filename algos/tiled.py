"""Terrain products on Dask arrays: tiles with a halo, for fields larger than memory and
clusters larger than one machine.

A vertex's horizon (and so its shadow and sky-view factor) with a finite
``max_distance`` D depends only on the surface within D of it, which lies in the cells
whose corners are within ``ceil(D) + 1`` samples of the vertex along each axis. So
:func:`tiled_product` maps the in-memory product over the chunks with
``dask.array.map_overlap``, a halo of that depth and no padding at the field's edges
(``boundary="none"``): every tile sees exactly what the whole field would show its
vertices, and the result equals the in-memory one (to the last bits of the C walks'
float coordinates, which are relative to each tile; the tests bound the difference at
1e-12 rad). Unlimited distances cannot be tiled and raise.

A viewshed is not a tile-local product: it needs the observer's window, ``D + 1``
samples around the observer, which is cut from the lazy array and computed in memory;
the rest of the result is known without reading it (out of range: not visible).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["is_dask", "tiled_product", "halo_depth", "tiled_viewshed"]


def is_dask(x) -> bool:
    """A dask array (or a HeightField holding one)."""
    x = getattr(x, "heights", x)
    return type(x).__module__.split(".")[0] == "dask" and hasattr(x, "map_overlap")


def halo_depth(max_distance_cells) -> int:
    """Samples of halo that hold every point within ``max_distance_cells`` of a vertex."""
    if max_distance_cells is None or not math.isfinite(max_distance_cells):
        raise ValueError("max_distance: a tiled (dask) product needs a finite max_distance; "
                         "the halo is that distance")
    return int(math.ceil(max_distance_cells)) + 1


def _unwrap(heights, spacing, north_up=True):
    """(dask array, spacing or None, flipped) from a dask array or a HeightField; with
    ``north_up`` a HeightField whose rows run north is flipped (``flipped`` says so)."""
    if hasattr(heights, "heights") and hasattr(heights, "spacing"):
        params = getattr(heights, "params", {}) or {}
        if spacing is None and getattr(heights, "unit", "cell") != "cell":
            spacing = float(heights.spacing)
        flip = north_up and params.get("north") == "+y"
        return (heights.heights[::-1] if flip else heights.heights), spacing, flip
    return heights, spacing, False


def tiled_product(product, heights, max_distance, spacing, dtype, **kwargs):
    """``product(block, max_distance=..., spacing=..., **kwargs)`` (a 2D in-memory terrain
    product) over a dask array's chunks with a halo of ``max_distance``. Returns a lazy
    dask array shaped like ``heights``."""
    arr, spacing, flipped = _unwrap(heights, spacing)
    if arr.ndim != 2:
        raise ValueError(f"heights: expected a 2D array (rows, cols), got shape {arr.shape}")
    if max_distance is None:
        halo_depth(None)
    md_cells = float(max_distance) / spacing if spacing else float(max_distance)
    depth = halo_depth(md_cells)
    # every chunk at least as deep as the halo (map_overlap takes neighbours only)
    chunks = tuple(max(depth, max(c)) for c in arr.chunks)
    if any(max(c) < depth for c in arr.chunks):
        arr = arr.rechunk(chunks)

    def block(h):
        return product(np.asarray(h), max_distance=max_distance, spacing=spacing, **kwargs)

    out = arr.map_overlap(block, depth=depth, boundary="none", trim=True, dtype=dtype)
    return out[::-1] if flipped else out


def tiled_viewshed(viewshed, heights, observer, max_distance, spacing, **kwargs):
    """A viewshed of a dask array: each observer's window computed in memory (see the
    module docstring). Observers are in the stored array's coordinates (a line of sight
    does not depend on which way is north). Returns a lazy bool (one observer) or uint16
    (count) array."""
    import dask.array as da

    arr, spacing, _ = _unwrap(heights, spacing, north_up=False)
    rows, cols = arr.shape
    md_cells = None if max_distance is None else (
        float(max_distance) / spacing if spacing else float(max_distance))
    depth = halo_depth(md_cells)
    single = np.asarray(observer).ndim == 1
    obs = np.atleast_2d(np.asarray(observer, dtype=np.float64))
    total = da.zeros((rows, cols), dtype=np.uint16, chunks=arr.chunks)
    for k, (x, y) in enumerate(obs):
        if not (math.isfinite(x) and math.isfinite(y) and 0 <= x <= cols - 1 and 0 <= y <= rows - 1):
            raise ValueError(f"observer[{k}]: ({x}, {y}) outside the footprint "
                             f"[0, {cols - 1}] x [0, {rows - 1}]")
        c0, c1 = max(0, int(math.floor(x)) - depth), min(cols, int(math.ceil(x)) + depth + 1)
        r0, r1 = max(0, int(math.floor(y)) - depth), min(rows, int(math.ceil(y)) + depth + 1)
        window = np.ascontiguousarray(arr[r0:r1, c0:c1].compute())
        seen = viewshed(window, (x - c0, y - r0), max_distance=max_distance, spacing=spacing,
                        **kwargs).astype(np.uint16)
        patch = da.pad(da.from_array(seen, chunks=seen.shape),
                       ((r0, rows - r1), (c0, cols - c1)), mode="constant")
        total = total + patch.rechunk(arr.chunks)
    return total.astype(bool) if single else total
