"""Cell maxima and their range maxima: the bounds the first-hit walks cull with.

``cellmax`` (ny, nx) bounds each cell's surface from above, and ``row_max`` / ``col_max``
answer the maximum of a run of cells along a row or a column in O(1) (prefix and suffix
maxima within blocks of ``2**RMQ_BLOCK_SHIFT`` cells plus a sparse table over the block
maxima, read by ``cext/surfaces/cell_test.h``, ``hf_rmq_query``). :class:`algos.field.HeightField` builds
them on first use and keeps them; the layouts and their bytes are in its module
docstring. Everything is built in bands of about :data:`BAND_SAMPLES` samples, so the
extra memory of a build is its result plus a band.
"""
from __future__ import annotations

import numpy as np

__all__ = ["RMQ_BLOCK_SHIFT", "BAND_SAMPLES", "band_rows", "cellmax_rows", "range_max"]

#: log2 of the block length of the range-maximum tables (8 cells)
RMQ_BLOCK_SHIFT = 3


#: samples per band of the streaming passes (their temporaries stay this small)
BAND_SAMPLES = 1 << 20


def band_rows(cols: int) -> int:
    """Rows of ``cols`` samples per band of the streaming passes: about
    :data:`BAND_SAMPLES` samples, at least one row."""
    return max(1, BAND_SAMPLES // max(cols, 1))


def cellmax_rows(h: np.ndarray, kind: str, r0: int, r1: int) -> np.ndarray:
    """Rows ``r0:r1`` of the cell maxima (the package docstring: each
    cell's surface bound for the bound ``kind``, "corners" or "plane3"), from heights rows
    ``r0:r1 + 1`` only."""
    a = h[r0:r1 + 1]
    top = np.maximum(np.maximum(a[:-1, :-1], a[:-1, 1:]), np.maximum(a[1:, :-1], a[1:, 1:]))
    if kind == "plane3":
        # float64, rounded up to float32: the bound must not fall below the value
        fourth = a[:-1, 1:].astype(np.float64) + a[1:, :-1] - a[:-1, :-1]
        fourth32 = fourth.astype(np.float32)
        fourth32 = np.where(fourth32 < fourth, np.nextafter(fourth32, np.float32(np.inf)), fourth32)
        top = np.maximum(top, fourth32)
    return np.ascontiguousarray(top, dtype=np.float32)


def range_max(lines: np.ndarray, shift: int):
    """(values, prefix, suffix, sparse, shift) for range maxima along axis 1."""
    values = np.ascontiguousarray(lines, dtype=np.float32)
    n_lines, length = values.shape
    block = 1 << shift
    n_blocks = -(-length // block)
    padded = np.full((n_lines, n_blocks * block), -np.inf, dtype=np.float32)
    padded[:, :length] = values
    blocks = padded.reshape(n_lines, n_blocks, block)
    prefix = np.maximum.accumulate(blocks, axis=2).reshape(n_lines, -1)[:, :length]
    suffix = np.maximum.accumulate(blocks[:, :, ::-1], axis=2)[:, :, ::-1].reshape(n_lines, -1)[:, :length]
    n_levels = 1
    while (2 << (n_levels - 1)) <= n_blocks:
        n_levels += 1
    sparse = np.empty((n_lines, n_levels, n_blocks), dtype=np.float32)
    sparse[:, 0] = blocks.max(axis=2)
    for level in range(1, n_levels):
        half = 1 << (level - 1)
        prev = sparse[:, level - 1]
        sparse[:, level] = prev
        sparse[:, level, : n_blocks - half] = np.maximum(prev[:, : n_blocks - half], prev[:, half:])
    return (values, np.ascontiguousarray(prefix), np.ascontiguousarray(suffix), sparse, shift)
