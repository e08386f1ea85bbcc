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
samples around the observer (the whole field when D is unlimited), which one task per
observer reads from the chunks it overlaps and computes in memory; one task per output
chunk then takes the windows (or their pieces) that overlap it, and the rest of the result
is known without reading the input (out of range: not visible). :func:`tiled_viewshed` so
builds ``chunks + observers`` tasks, plus a piece per chunk a window spans when it spans
several: not one per chunk per observer.
"""
from __future__ import annotations

import math
import operator
from functools import partial

import numpy as np

from ..field import HeightField, is_dask
from ..validate import check_length, check_spacing

__all__ = ["is_dask", "tiled_product", "halo_depth", "tiled_viewshed", "viewshed_window"]


def halo_depth(max_distance_cells) -> int:
    """Samples of halo that hold every point within ``max_distance_cells`` of a vertex."""
    if max_distance_cells is None or not math.isfinite(max_distance_cells):
        raise ValueError("max_distance: a tiled (dask) product needs a finite max_distance; "
                         "the halo is that distance")
    return int(math.ceil(max_distance_cells)) + 1


def _block_field(block, name, **description):
    """A HeightField of a NumPy block, with a field's name and ``description`` (units,
    north, parameters)."""
    return HeightField(block, name, **description)


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

        # the field's description, not the field: a task holding wrap must not carry the
        # lazy array (and its graph) with it
        wrap = partial(_block_field, name=field.name, spacing=field.spacing, unit=field.unit,
                       height_unit=field.height_unit, params=field.params, crs=field.crs,
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


def _chunk_edges(chunks):
    """The first sample of each of an axis's chunks, then the axis length."""
    return np.concatenate([[0], np.cumsum(chunks, dtype=np.int64)])


def _chunk_span(edges, start, stop):
    """The indices of the chunks (``edges`` from :func:`_chunk_edges`) holding any of the
    samples ``start:stop`` (stop > start)."""
    first = int(np.searchsorted(edges, start, side="right")) - 1
    return range(first, int(np.searchsorted(edges, stop, side="left")))


def viewshed_window(x, y, max_distance, pixel, shape):
    """``(r0, r1, c0, c1)``: the samples ``[r0:r1, c0:c1]`` that decide what an observer at
    grid point (x, y) sees within ``max_distance`` (a length in the field's unit; None:
    unlimited, the whole array). That is the cell holding the observer and
    :func:`halo_depth` ``(D / dy)`` rows and ``(D / dx)`` columns beyond it, cut to the
    array; ``pixel`` = (dx, dy) and ``shape`` = (rows, cols)."""
    rows, cols = shape
    if max_distance is None:
        return 0, rows, 0, cols
    dx, dy = pixel
    depth_y, depth_x = halo_depth(max_distance / dy), halo_depth(max_distance / dx)
    return (max(0, int(math.floor(y)) - depth_y), min(rows, int(math.ceil(y)) + depth_y + 1),
            max(0, int(math.floor(x)) - depth_x), min(cols, int(math.ceil(x)) + depth_x + 1))


#: The in-memory viewshed's refusal of an observer on a void, as it begins
_ON_A_VOID = ") stands on a cell touching a void (nodata) vertex"


def _window_viewshed(viewshed, wrap, x, y, r0, c0, row_cuts, col_cuts, options, blocks, k=0):
    """Observer ``k``'s in-memory viewshed on its window. ``blocks`` are the input chunks
    the window overlaps (rows of chunks, each a list of columns); ``row_cuts[a]`` and
    ``col_cuts[b]`` cut chunk (a, b) to the window. An observer on a void is refused as
    in memory: by its index and its coordinates in the whole array, not the window's."""
    window = np.block([[np.asarray(block)[rows, cols] for block, cols in zip(line, col_cuts)]
                       for line, rows in zip(blocks, row_cuts)])
    try:
        return viewshed(wrap(np.ascontiguousarray(window)), (x - c0, y - r0), **options)
    except ValueError as exc:
        text = str(exc)
        if not (text.startswith("observer[0]: (") and _ON_A_VOID in text):
            raise
        raise ValueError(f"observer[{k}]: ({x:g}, {y:g}{text[text.index(_ON_A_VOID):]}") \
            from None


def _viewshed_chunk(shape, dtype, cuts, *seen):
    """One output chunk: zeros (not visible), then each observer's window result (or its
    piece for this chunk) ``seen[k]``, cut by ``cuts[k]`` = (chunk slices, window slices;
    None: all of it), added (a count) or or-ed (one observer's bool) into place."""
    out = np.zeros(shape, dtype)
    for (into, take), window in zip(cuts, seen):
        part = window if take is None else window[take]
        if dtype == np.bool_:
            out[into] |= part
        else:
            out[into] += part
    return out


def tiled_viewshed(viewshed, heights, observer, max_distance, spacing, **kwargs):
    """A viewshed of a dask array, as a lazy graph of one task per observer and one per
    output chunk: nothing is computed here.

    Observer k's task reads only the input chunks its window overlaps
    (:func:`viewshed_window`: ``max_distance`` plus a cell around the observer, the whole
    array when ``max_distance`` is None), joins them and runs ``viewshed`` (the in-memory
    function) there, with ``spacing`` and ``**kwargs`` passed through. A window over
    several chunks is then cut into one piece per chunk (one task each), so that a chunk
    receives its part only. The task of output chunk (i, j) puts in place the windows or
    pieces that overlap it; every sample outside all windows is not visible, known
    without reading the input. Besides the input's, the graph so has ``chunks +
    observers`` tasks plus one per (observer, chunk) pair of a window spanning several
    chunks: at most ``2 chunks + 1`` for one observer, about ``chunks + 5 observers`` for
    windows smaller than a chunk.

    With ``max_distance`` None every window is the whole array: each observer's task holds
    the field (8 bytes a sample as float64, twice while the chunks are joined) and the
    in-memory viewshed's working arrays on one worker, and is cut into one piece per chunk
    (``chunks + observers x (chunks + 1)`` tasks).

    Observers are in the stored array's coordinates (a line of sight does not depend on
    which way is north). An observer outside the footprint raises ValueError here; one on
    a cell touching a void raises ValueError when the result is computed (the heights are
    read only then). Returns a lazy bool (one observer) or uint16 (counts) array shaped
    and chunked like the input, in its orientation.
    """
    import dask.array as da
    from dask.base import tokenize
    from dask.highlevelgraph import HighLevelGraph

    from .observers import _observers

    arr, wrap, pixel, _, extra = _unwrap(heights, spacing, north_up=False)
    if arr.ndim != 2:
        raise ValueError(f"heights: expected a 2D array (rows, cols), got shape {arr.shape}")
    obs, single = _observers(observer, arr)
    md = check_length(max_distance, "max_distance")
    pixel = pixel if pixel is not None else (1.0, 1.0)
    dtype = np.dtype(bool) if single else np.dtype(np.uint16)
    options = dict(max_distance=max_distance, **extra, **kwargs)
    described = heights if not isinstance(heights, HeightField) else (
        heights.name, heights.spacing, heights.unit, heights.height_unit, heights.north,
        heights.params)
    token = tokenize(arr.name, described, obs, single, max_distance, spacing, kwargs)
    name, window_name = f"viewshed-{token}", f"viewshed-window-{token}"
    piece_name = f"viewshed-piece-{token}"
    row_edges, col_edges = _chunk_edges(arr.chunks[0]), _chunk_edges(arr.chunks[1])

    # one task per observer: the chunks its window overlaps, cut and joined, then viewshed
    window_layer, piece_layer, touching = {}, {}, {}
    for k, (x, y) in enumerate(obs):
        r0, r1, c0, c1 = viewshed_window(x, y, md, pixel, arr.shape)
        chunk_rows = _chunk_span(row_edges, r0, r1)
        chunk_cols = _chunk_span(col_edges, c0, c1)
        row_cuts = [slice(max(r0, row_edges[a]) - row_edges[a], min(r1, row_edges[a + 1])
                          - row_edges[a]) for a in chunk_rows]
        col_cuts = [slice(max(c0, col_edges[b]) - col_edges[b], min(c1, col_edges[b + 1])
                          - col_edges[b]) for b in chunk_cols]
        blocks = [[(arr.name, a, b) for b in chunk_cols] for a in chunk_rows]
        window_layer[(window_name, k)] = (
            partial(_window_viewshed, viewshed, wrap, float(x), float(y), r0, c0, row_cuts,
                    col_cuts, options, k=k), blocks)
        # where the window lands in each output chunk it overlaps; a window over several
        # chunks is cut into one piece per chunk (a task beside it), so that each chunk's
        # task receives its part of the window, not all of it
        spread = len(chunk_rows) * len(chunk_cols) > 1
        for a in chunk_rows:
            top, bottom = max(r0, row_edges[a]), min(r1, row_edges[a + 1])
            for b in chunk_cols:
                left, right = max(c0, col_edges[b]), min(c1, col_edges[b + 1])
                into = (slice(top - row_edges[a], bottom - row_edges[a]),
                        slice(left - col_edges[b], right - col_edges[b]))
                take = (slice(top - r0, bottom - r0), slice(left - c0, right - c0))
                if spread:
                    piece_layer[(piece_name, k, a, b)] = (operator.getitem, (window_name, k), take)
                    touching.setdefault((a, b), []).append(((piece_name, k, a, b), (into, None)))
                else:
                    touching.setdefault((a, b), []).append(((window_name, k), (into, take)))

    # one task per output chunk: the windows (or pieces) that overlap it, or zeros
    chunk_layer = {}
    for a, height in enumerate(arr.chunks[0]):
        for b, width in enumerate(arr.chunks[1]):
            found = touching.get((a, b), ())
            chunk_layer[(name, a, b)] = (
                partial(_viewshed_chunk, (height, width), dtype, [cut for _, cut in found]),
                *[key for key, _ in found])

    graph = HighLevelGraph.from_collections(window_name, window_layer, dependencies=[arr])
    layers, dependencies = dict(graph.layers), dict(graph.dependencies)
    if piece_layer:
        layers[piece_name], dependencies[piece_name] = piece_layer, {window_name}
    layers[name] = chunk_layer
    dependencies[name] = {window_name, piece_name} if piece_layer else {window_name}
    return da.Array(HighLevelGraph(layers, dependencies), name, chunks=arr.chunks, dtype=dtype)
