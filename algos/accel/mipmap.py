"""The maximum mipmap (Tevs, Ihrke & Seidel 2008): level 0 holds the cell maxima
(:mod:`algos.accel.maxima`), level k the maxima over 2^k x 2^k cells, sides rounded up so
every grid size works, down to 1 x 1. The max-mipmap walks (``dda_maxmip``,
``runs_maxmip``, the terrain products' ``dda_maxmip`` and ``chain``) skip every tile
whose maximum a ray passes above.
"""
from __future__ import annotations

import numpy as np

from .. import hugepages
from .maxima import band_rows, cellmax_rows

__all__ = ["max_mipmap", "tile_max_rows", "mip_levels", "terrain_mipmap"]


def tile_max_rows(h: np.ndarray, kind: str, level: int) -> np.ndarray:
    """Mipmap level ``level`` (maxima over 2^level x 2^level cells) straight from the
    heights, one band of tile rows at a time: no full-size cellmax."""
    size = 1 << level
    ny, nx = h.shape[0] - 1, h.shape[1] - 1
    out_rows, out_cols = -(-ny // size), -(-nx // size)
    out = hugepages.empty((out_rows, out_cols), np.float32)
    tiles_per_band = max(1, band_rows(h.shape[1]) // size)
    for t0 in range(0, out_rows, tiles_per_band):
        t1 = min(out_rows, t0 + tiles_per_band)
        cm = cellmax_rows(h, kind, t0 * size, min(ny, t1 * size))
        padded = np.full(((t1 - t0) * size, out_cols * size), -np.inf, dtype=np.float32)
        padded[:cm.shape[0], :nx] = cm
        out[t0:t1] = padded.reshape(t1 - t0, size, out_cols, size).max(axis=(1, 3))
    return out


def halve(a: np.ndarray) -> np.ndarray:
    """Maxima over 2 x 2 blocks (a side of odd length padded with -inf), in bands of
    rows: the extra memory is a band, not a copy of ``a``."""
    r, c = a.shape
    rows_out, cols_out = -(-r // 2), -(-c // 2)
    out = hugepages.empty((rows_out, cols_out), a.dtype)
    step = max(1, band_rows(c) // 2)
    for o0 in range(0, rows_out, step):
        o1 = min(rows_out, o0 + step)
        block = a[2 * o0:min(r, 2 * o1)]
        padded = np.full((2 * (o1 - o0), 2 * cols_out), -np.inf, dtype=a.dtype)
        padded[:block.shape[0], :c] = block
        out[o0:o1] = padded.reshape(o1 - o0, 2, cols_out, 2).max(axis=(1, 3))
    return out


def max_mipmap(cellmax: np.ndarray) -> list[np.ndarray]:
    """The levels of the maximum mipmap of ``cellmax``: level 0 is ``cellmax``, level k+1
    the maxima over 2 x 2 blocks of level k (odd sides padded with -inf), down to 1 x 1."""
    levels = [cellmax]
    while max(levels[-1].shape) > 1:
        levels.append(halve(levels[-1]))
    return levels


def mip_levels(ny: int, nx: int) -> int:
    """Levels of the maximum mipmap of an ny x nx cell grid (down to 1 x 1)."""
    levels, r, c = 1, ny, nx
    while max(r, c) > 1:
        r, c, levels = -(-r // 2), -(-c // 2), levels + 1
    return levels


def terrain_mipmap(h: np.ndarray):
    """(data, offset, rows, cols): the max-mipmap of the cell maxima of the float64
    heights ``h`` (rows, cols), in float64, its levels concatenated for the terrain
    products' C walks: level k starts at ``data[offset[k]]`` and is ``rows[k] x cols[k]``
    (int64 arrays)."""
    cell = np.maximum(np.maximum(h[:-1, :-1], h[:-1, 1:]), np.maximum(h[1:, :-1], h[1:, 1:]))
    levels = max_mipmap(cell)
    offset = np.cumsum([0] + [lv.size for lv in levels[:-1]]).astype(np.int64)
    return (np.ascontiguousarray(np.concatenate([lv.ravel() for lv in levels])), offset,
            np.array([lv.shape[0] for lv in levels], dtype=np.int64),
            np.array([lv.shape[1] for lv in levels], dtype=np.int64))
