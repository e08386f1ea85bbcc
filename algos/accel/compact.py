"""The compact maximum tree of ``dda_compact``: a cache-compact
maximum hierarchy, built and walked in ``cext/hierarchies/compact.c`` (layout: ``cext/hierarchies/compact.h``).

Each node is one 64-byte cache line and has 4 x 4 children. A node of level ``L >= 1``
covers ``4^L x 4^L`` cells; its children are the level ``L - 1`` tiles, the cells
themselves at level 1. The top level holds one node over the whole grid.

* A **leaf** (level 1) holds the 16 float32 cell maxima of its 4 x 4 tile exactly, slot
  ``k = 4 (j % 4) + i % 4``: the cell maxima in a tiled layout, so the cells of a floor
  tile share one line.
* A **node** (levels >= 2, :data:`NODE_DTYPE`) stores ``base``, ``scale`` (float32; child
  ``k``'s bound is ``base + q[k] * scale`` evaluated in float64, where ``q[k] * scale``
  is exact), ``max`` (float32, the node's own maximum exactly: its parent's input),
  ``used`` (bit ``k`` set when child slot ``k`` lies inside the grid) and ``q`` (16
  uint16): the children's maxima as codes relative to the node's range ``[base, max]``,
  rounded *up*, so every bound is at or above the child's float32 maximum and culling
  stays conservative. The quantisation step is ``(max - base) / 65535``.

Memory: ``64 * sum_L ceil(nx / 4^L) ceil(ny / 4^L)`` bytes, about 4.27 bytes per cell (the
float32 cell maxima plus the maximum mipmap that ``dda_maxmip`` reads: 5.33). The records
of a level are stored row by row, the levels one after the other from level 1, in one
buffer aligned to 64 bytes.

``dda_compact`` walks the tree as ``dda_maxmip`` walks the mipmap (Tevs, Ihrke & Seidel
2008), with 4x wider steps between levels and a climb straight to the coarsest tile it has
newly entered. Its floor tiles are the 4 x 4 leaves, culled cell by cell with the exact
cell maxima as ``dda_maxmip``'s floor walk culls them, and every surviving cell goes to
the same exact cell test as every cell kernel (run without its own cull, which would
repeat the floor cull on the row-major copy): the first hits (t and cell) are those of
``dda_maxmip``.
"""
from __future__ import annotations

import numpy as np

from .. import _kernels, hugepages

__all__ = ["NODE_BYTES", "NODE_DTYPE", "compact_layout", "build_compact", "compact_leaves",
           "compact_nodes", "compact_bounds", "compact_for"]

#: bytes per node: one cache line
NODE_BYTES = 64

#: one node of level >= 2 as NumPy sees it (cext/hierarchies/compact.h, hf_compact_node)
NODE_DTYPE = np.dtype([("base", "<f4"), ("scale", "<f4"), ("max", "<f4"), ("used", "<u4"),
                       ("q", "<u2", (16,)), ("spare", "u1", (16,))])
assert NODE_DTYPE.itemsize == NODE_BYTES


def compact_layout(ny: int, nx: int) -> list[tuple[int, int, int]]:
    """The levels of the tree of an ``ny x nx`` cell grid.

    Returns
    -------
    list of (offset, nodes_y, nodes_x)
        Entry ``L - 1`` describes level ``L``: its first node's index in the buffer and
        its rows and columns of nodes. The last level has one node.
    """
    levels, offset, wy, wx = [], 0, int(ny), int(nx)
    while True:
        wy, wx = -(-wy // 4), -(-wx // 4)
        levels.append((offset, wy, wx))
        offset += wy * wx
        if wy == 1 and wx == 1:
            return levels


def build_compact(cellmax: np.ndarray) -> np.ndarray:
    """The compact maximum tree of a cell-maximum array.

    Parameters
    ----------
    cellmax : ndarray, shape (ny, nx), float32
        An upper bound of each cell's surface (``algos.Field.cellmax_for``).

    Returns
    -------
    ndarray, shape (n_nodes * 64,), uint8
        The nodes (:data:`NODE_DTYPE`, :func:`compact_layout`), the buffer aligned to 64
        bytes.

    Raises
    ------
    ValueError
        If ``cellmax`` is not a non-empty 2D array, or holds NaN.
    """
    m = np.ascontiguousarray(cellmax, dtype=np.float32)
    if m.ndim != 2 or m.size == 0:
        raise ValueError(f"cellmax: expected a non-empty 2D array, got shape {m.shape}")
    if np.isnan(m).any():
        j, i = np.argwhere(np.isnan(m))[0]
        raise ValueError(f"cellmax: NaN at cell (i={i}, j={j})")
    levels = compact_layout(*m.shape)
    n_bytes = (levels[-1][0] + 1) * NODE_BYTES
    raw = hugepages.empty(n_bytes + NODE_BYTES, np.uint8, zero=True)  # 2 MiB-aligned if large
    start = (-raw.ctypes.data) % NODE_BYTES
    tree = raw[start:start + n_bytes]
    _kernels.compact_build(m, tree)
    return tree


def compact_leaves(tree: np.ndarray, ny: int, nx: int) -> np.ndarray:
    """The leaves (level 1) of the tree of an ``ny x nx`` cell grid: float32 of shape
    ``(ceil(ny / 4), ceil(nx / 4), 16)`` (a view)."""
    offset, py, px = compact_layout(ny, nx)[0]
    records = np.asarray(tree).view(np.float32).reshape(-1, 16)
    return records[offset:offset + py * px].reshape(py, px, 16)


def compact_nodes(tree: np.ndarray, ny: int, nx: int, level: int) -> np.ndarray:
    """The nodes of ``level`` (>= 2) of the tree of an ``ny x nx`` cell grid: a structured
    array of :data:`NODE_DTYPE`, shape ``(rows of nodes, nodes per row)`` (a view)."""
    layout = compact_layout(ny, nx)
    if not 2 <= level <= len(layout):
        raise ValueError(f"level: expected 2 to {len(layout)}, got {level}")
    offset, py, px = layout[level - 1]
    return np.asarray(tree).view(NODE_DTYPE)[offset:offset + py * px].reshape(py, px)


def compact_bounds(tree: np.ndarray, ny: int, nx: int, level: int) -> np.ndarray:
    """The bounds the tree gives the tiles of ``level`` (0: the cells), decoded as the
    kernel decodes them.

    Returns
    -------
    ndarray, shape (ceil(ny / 4^level), ceil(nx / 4^level)), float64
        The bound of every tile of that level: a leaf's cell maximum for the cells, else
        from the parent node's codes.
    """
    layout = compact_layout(ny, nx)
    if not 0 <= level < len(layout):
        raise ValueError(f"level: expected 0 to {len(layout) - 1}, got {level}")
    ty, tx = (ny, nx) if level == 0 else layout[level - 1][1:]
    j, i = np.mgrid[0:ty, 0:tx]
    slot = 4 * (j % 4) + i % 4
    if level == 0:
        return compact_leaves(tree, ny, nx)[j // 4, i // 4, slot].astype(np.float64)
    parent = compact_nodes(tree, ny, nx, level + 1)[j // 4, i // 4]
    code = np.take_along_axis(parent["q"], slot[..., None], axis=-1)[..., 0]
    return parent["base"].astype(np.float64) + code.astype(np.float64) * \
        parent["scale"].astype(np.float64)


def compact_for(field, kind: str = "corners") -> np.ndarray:
    """The compact tree of ``field`` for a bound kind (``algos.field.bound_kind``), built
    on first use and kept in the field (``build_stats["compact"]`` or
    ``["compact/plane3"]`` record its seconds and bytes)."""
    key = "compact" if kind == "corners" else f"compact/{kind}"
    return field._build(key, lambda: build_compact(field.cellmax_for(kind)))
