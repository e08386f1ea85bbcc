"""The compact maximum tree of ``dda_compact``: a cache-compact
maximum hierarchy, built and walked in ``cext/hierarchies/compact.c`` (layout: ``cext/hierarchies/compact.h``).

Each record is one 64-byte cache line. A tile of level ``L >= 1`` covers ``4^L x 4^L``
cells and has 4 x 4 children, the level ``L - 1`` tiles (the cells themselves at level
1). The top level (at least level 2) holds one node over the whole grid.

* A **node** (levels >= 2, one per tile, :data:`NODE_DTYPE`) stores ``base``, ``scale``
  (float32; child ``k``'s bound is ``base + q[k] * scale`` evaluated in float64, where
  ``q[k] * scale`` is exact), ``max`` (float32, the node's own maximum exactly: its
  parent's input), ``used`` (bit ``k`` set when child slot ``k`` lies inside the grid),
  ``q`` (16 uint16): the children's maxima as codes relative to the node's range
  ``[base, max]``, rounded *up*, so every bound is at or above the child's float32 maximum
  and culling stays conservative (the step is ``(max - base) / 65535``; ``base`` is the
  lowest child maximum, at level 2 the lowest cell maximum), and 16 spare bytes.
* A **leaf** (level 1) holds the cells of 2 x 2 level-1 tiles (8 x 8 cells) as uint8
  codes: 16 bytes per tile, tile ``2 (tj % 2) + ti % 2``, cell slot
  ``k = 4 (j % 4) + i % 4``. A cell's bound is ``lo + code * step`` in float64, over the
  range the level-2 parent gives its tile: ``hi`` = the tile's bound (``base + q * scale``),
  ``lo`` = the parent's ``base``, ``step`` = ``(hi - lo) / 254`` cut to 21 significant bits
  (:func:`leaf_step`; ``code * step`` is exact). Each code is the smallest whose bound is at
  or above the cell's float32 maximum: a coarser bound than the maximum, by less than one
  step.

Memory: ``64`` bytes per leaf (``ceil(ceil(nx / 4) / 2) ceil(ceil(ny / 4) / 2)`` of them)
plus ``64 * sum_{L >= 2} ceil(nx / 4^L) ceil(ny / 4^L)``: about 1.27 bytes per cell (1 for
the leaves; the float32 cell maxima plus the maximum mipmap that ``dda_maxmip`` reads:
5.33). The records of a level are stored row by row, the levels one after the other from
level 1, in one buffer aligned to 64 bytes.

``dda_compact`` walks the tree as ``dda_maxmip`` walks the mipmap (Tevs, Ihrke & Seidel
2008), with 4x wider steps between levels and a climb straight to the coarsest tile it has
newly entered. Its floor tiles are the 4 x 4 level-1 tiles, culled cell by cell with the
leaf's decoded bounds (one line per 8 x 8 cells), and every surviving cell goes to the
same exact cell test as every cell kernel (run without its own cull, which would read the
row-major copy): the culls only skip cells that cannot be hit, so the first hits (t, cell
and normal) are those of ``dda_maxmip``; more cells are tested exactly than with float
bounds.
"""
from __future__ import annotations

import numpy as np

from .. import _kernels, hugepages

__all__ = ["NODE_BYTES", "NODE_DTYPE", "LEAF_CODE_MAX", "compact_layout", "build_compact",
           "compact_leaves", "compact_nodes", "leaf_step", "compact_bounds", "compact_for"]

#: bytes per node: one cache line
NODE_BYTES = 64

#: one node of level >= 2 as NumPy sees it (cext/hierarchies/compact.h, hf_compact_node)
NODE_DTYPE = np.dtype([("base", "<f4"), ("scale", "<f4"), ("max", "<f4"), ("used", "<u4"),
                       ("q", "<u2", (16,)), ("spare", "u1", (16,))])
assert NODE_DTYPE.itemsize == NODE_BYTES

#: the largest cell code of a leaf
LEAF_CODE_MAX = 255


def compact_layout(ny: int, nx: int) -> list[tuple[int, int, int]]:
    """The levels of the tree of an ``ny x nx`` cell grid.

    Returns
    -------
    list of (offset, tiles_y, tiles_x)
        Entry ``L - 1`` describes level ``L``: its first record's index in the buffer and
        its rows and columns of tiles (of nodes from level 2; level 1 is stored as one
        leaf per 2 x 2 tiles). The last level, at least level 2, has one node.
    """
    levels, offset, wy, wx = [], 0, int(ny), int(nx)
    while True:
        wy, wx = -(-wy // 4), -(-wx // 4)
        levels.append((offset, wy, wx))
        offset += -(-wy // 2) * -(-wx // 2) if len(levels) == 1 else wy * wx
        if wy == 1 and wx == 1 and len(levels) >= 2:
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
    """The cell codes of the level-1 tiles of the tree of an ``ny x nx`` cell grid: uint8
    of shape ``(ceil(ny / 4), ceil(nx / 4), 16)``, slot ``4 (j % 4) + i % 4`` (a copy, out
    of the leaves of 2 x 2 tiles)."""
    offset, py, px = compact_layout(ny, nx)[0]
    ly, lx = -(-py // 2), -(-px // 2)
    records = np.asarray(tree).reshape(-1, NODE_BYTES)[offset:offset + ly * lx]
    tiles = records.reshape(ly, lx, 2, 2, 16).transpose(0, 2, 1, 3, 4)
    return tiles.reshape(2 * ly, 2 * lx, 16)[:py, :px].copy()


def compact_nodes(tree: np.ndarray, ny: int, nx: int, level: int) -> np.ndarray:
    """The nodes of ``level`` (>= 2) of the tree of an ``ny x nx`` cell grid: a structured
    array of :data:`NODE_DTYPE`, shape ``(rows of nodes, nodes per row)`` (a view)."""
    layout = compact_layout(ny, nx)
    if not 2 <= level <= len(layout):
        raise ValueError(f"level: expected 2 to {len(layout)}, got {level}")
    offset, py, px = layout[level - 1]
    return np.asarray(tree).view(NODE_DTYPE)[offset:offset + py * px].reshape(py, px)


def leaf_step(hi: np.ndarray, lo: np.ndarray) -> np.ndarray:
    """The step of a leaf tile's cell codes over ``[lo, hi]`` (float64), as
    ``hf_compact_leaf_step`` computes it: ``(hi - lo) / 254`` with the low 32 bits of the
    float64 cleared (21 significant bits, so ``code * step`` is exact), 0 when
    ``hi == lo``."""
    z = (np.asarray(hi, np.float64) - np.asarray(lo, np.float64)) * (1.0 / 254.0)
    return (z.view(np.uint64) & np.uint64(0xFFFFFFFF00000000)).view(np.float64)


def compact_bounds(tree: np.ndarray, ny: int, nx: int, level: int) -> np.ndarray:
    """The bounds the tree gives the tiles of ``level`` (0: the cells), decoded as the
    kernel decodes them.

    Returns
    -------
    ndarray, shape (ceil(ny / 4^level), ceil(nx / 4^level)), float64
        The bound of every tile of that level: for the cells, ``lo + code * step`` from
        the leaf and its level-2 parent; else from the parent node's codes.
    """
    layout = compact_layout(ny, nx)
    if not 0 <= level < len(layout):
        raise ValueError(f"level: expected 0 to {len(layout) - 1}, got {level}")
    if level == 0:
        j, i = np.mgrid[0:ny, 0:nx]
        ti, tj = i // 4, j // 4
        parent = compact_nodes(tree, ny, nx, 2)[tj // 4, ti // 4]
        slot = 4 * (tj % 4) + ti % 4
        lo, scale = parent["base"].astype(np.float64), parent["scale"].astype(np.float64)
        q = np.take_along_axis(parent["q"], slot[..., None], axis=-1)[..., 0]
        hi = lo + q.astype(np.float64) * scale
        code = compact_leaves(tree, ny, nx)[tj, ti, 4 * (j % 4) + i % 4]
        return lo + code.astype(np.float64) * leaf_step(hi, lo)
    ty, tx = layout[level - 1][1:]
    j, i = np.mgrid[0:ty, 0:tx]
    slot = 4 * (j % 4) + i % 4
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
