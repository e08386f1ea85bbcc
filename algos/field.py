"""A height field prepared for first hits: validated heights plus acceleration
structures, each built on first use and kept (build once per field, build only what the
requested kernels use).

Structures (all float32; ``nx = cols - 1``, ``ny = rows - 1`` cells):

* ``cellmax`` (ny, nx): an upper bound of each cell's surface, so a ray whose lowest z
  over a cell is above it cannot hit there. For ``flat``, ``triangles`` and ``bilinear``
  it is the maximum of the four corners (each surface stays within their hull); the
  ``plane3`` plane through three corners reaches ``h10 + h01 - h00`` at the fourth, so
  its bound includes that value (and so do its ``hmin``/``hmax``). ``4 nx ny`` bytes per
  bound kind.
* ``row_max`` / ``col_max``: range maxima of ``cellmax`` along rows (runs along x) and
  along columns (runs along y), answered in O(1) for a run spanning two blocks of
  ``2**RMQ_BLOCK_SHIFT`` (8) cells: per-cell prefix and suffix maxima within blocks plus a
  sparse table over block maxima (``cext/hit.h``, ``hf_rmq_query``). About
  ``(3 + log2(nx / 8) / 8) * 4 nx ny`` bytes per direction (the column one keeps a
  transposed copy of ``cellmax``).
* ``mip``: the maximum mipmap (Tevs, Ihrke & Seidel 2008): level 0 is ``cellmax``, level
  k holds maxima over 2^k x 2^k cells, sizes rounded up so every grid size works. About
  ``4/3 * 4 nx ny`` bytes.

Bytes per cell each intersector needs besides the heights (4 B per sample, float32; a
memory-mapped ``.npy`` is used in place, never copied):

=====================================  =========================================
dda, dda_f32, midpoint, runs*          4 (cellmax)
runs* with ``cull_runs=True``          4 + about 2 x (12 + log2(n / 8) / 2)
dda_maxmip, runs_maxmip                4 x 4/3 (cellmax is mip level 0)
runs_maxmip on ``Field(lean=True)``    4 x 4/3 / 4^fine_level (0.08 at level 3)
marching                               0
embree                                 measured: ``build_stats["embree"]``
=====================================  =========================================

Validation, ``cellmax`` and every mipmap level are built in streaming passes over bands
of ``BAND_SAMPLES`` samples, so the extra memory of those builds is their result plus a
few MiB. The range-maximum tables of run culling are built whole (temporaries about as
large as the tables): on a field near the memory limit, leave ``cull_runs`` off or use
the lean layout.

``Field(heights, lean=True)`` is the layout for fields near the memory limit:
``runs_maxmip`` then runs without per-cell culling (measured about 5 % slower at fbm
2048^2, reports/scaling) on mipmap levels from ``fine_level`` up, built from the heights
directly; the other intersectors build what they need as usual.
"""
from __future__ import annotations

import time

import numpy as np

from .lattice import MAX_GRID_SIDE
from .traverse import _as_float_array

__all__ = ["Field", "RMQ_BLOCK_SHIFT", "as_field", "bound_kind"]

RMQ_BLOCK_SHIFT = 3


def _validate_heights(heights) -> np.ndarray:
    h = _as_float_array(heights, "heights")
    if h.ndim != 2:
        raise ValueError(f"heights: expected a 2D array (rows, cols), got shape {h.shape}")
    if h.shape[0] < 2 or h.shape[1] < 2:
        raise ValueError(f"heights: a height field needs at least 2 x 2 samples, got {h.shape}")
    if max(h.shape) > MAX_GRID_SIDE:
        raise ValueError(f"heights: shape {h.shape} exceeds the limit of 2**24 samples per side")
    # no copy when it already is C-contiguous native float32 (a memory-mapped .npy too)
    h = np.require(h, dtype=np.float32, requirements=["C", "A"])
    step = _band_rows(h.shape[1])
    for r0 in range(0, h.shape[0], step):  # bounded temporaries
        bad = ~np.isfinite(h[r0:r0 + step])
        if bad.any():
            row, col = (int(v) for v in np.argwhere(bad)[0])
            row += r0
            raise ValueError(f"heights: sample (row {row}, col {col}) is {h[row, col]}; heights "
                             "must be finite (datasets_gen.load_file has an explicit nodata policy)")
    return h


#: samples per band of the streaming passes (their temporaries stay this small)
BAND_SAMPLES = 1 << 20


def _band_rows(cols: int) -> int:
    return max(1, BAND_SAMPLES // max(cols, 1))


def _cellmax_rows(h: np.ndarray, kind: str, r0: int, r1: int) -> np.ndarray:
    """Rows ``r0:r1`` of the cell maxima (see the module docstring), from heights rows
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


def _tile_max_rows(h: np.ndarray, kind: str, level: int) -> np.ndarray:
    """Mipmap level ``level`` (maxima over 2^level x 2^level cells) straight from the
    heights, one band of tile rows at a time: no full-size cellmax."""
    size = 1 << level
    ny, nx = h.shape[0] - 1, h.shape[1] - 1
    out_rows, out_cols = -(-ny // size), -(-nx // size)
    out = np.empty((out_rows, out_cols), dtype=np.float32)
    tiles_per_band = max(1, _band_rows(h.shape[1]) // size)
    for t0 in range(0, out_rows, tiles_per_band):
        t1 = min(out_rows, t0 + tiles_per_band)
        cm = _cellmax_rows(h, kind, t0 * size, min(ny, t1 * size))
        padded = np.full(((t1 - t0) * size, out_cols * size), -np.inf, dtype=np.float32)
        padded[:cm.shape[0], :nx] = cm
        out[t0:t1] = padded.reshape(t1 - t0, size, out_cols, size).max(axis=(1, 3))
    return out


def _range_max(lines: np.ndarray, shift: int):
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


def _halve(a: np.ndarray) -> np.ndarray:
    """Maxima over 2 x 2 blocks (a side of odd length padded with -inf), in bands of
    rows: the extra memory is a band, not a copy of ``a``."""
    r, c = a.shape
    rows_out, cols_out = -(-r // 2), -(-c // 2)
    out = np.empty((rows_out, cols_out), dtype=a.dtype)
    step = max(1, _band_rows(c) // 2)
    for o0 in range(0, rows_out, step):
        o1 = min(rows_out, o0 + step)
        block = a[2 * o0:min(r, 2 * o1)]
        padded = np.full((2 * (o1 - o0), 2 * cols_out), -np.inf, dtype=a.dtype)
        padded[:block.shape[0], :c] = block
        out[o0:o1] = padded.reshape(o1 - o0, 2, cols_out, 2).max(axis=(1, 3))
    return out


def _mipmap(cellmax: np.ndarray) -> list[np.ndarray]:
    levels = [cellmax]
    while max(levels[-1].shape) > 1:
        levels.append(_halve(levels[-1]))
    return levels


class Field:
    """Heights (float32, validated) and their lazily built acceleration structures.

    Structures are built per *bound kind* (:func:`bound_kind` of the surface) on first
    use; ``build_stats`` maps each one built so far (``"cellmax"``,
    ``"cellmax/plane3"``, ...) to ``{"seconds", "bytes"}``.
    """

    def __init__(self, heights, *, lean=False):
        self.heights = _validate_heights(heights)
        self.lean = bool(lean)
        self.rows, self.cols = self.heights.shape
        self.hmin = float(self.heights.min())
        self.hmax = float(self.heights.max())
        self.build_stats: dict[str, dict] = {}
        self._cache: dict[str, object] = {}

    def _build(self, name, make):
        if name not in self._cache:
            start = time.perf_counter()
            value = make()
            seconds = time.perf_counter() - start
            arrays = value if isinstance(value, (list, tuple)) else [value]
            nbytes = sum(a.nbytes for a in arrays if isinstance(a, np.ndarray))
            if name.startswith("row_max"):  # shares `values` with cellmax
                nbytes -= value[0].nbytes
            if name.startswith("mip") and value[0] is not None:  # level 0 is cellmax
                nbytes -= value[0].nbytes
            self._cache[name] = value
            self.build_stats[name] = {"seconds": seconds, "bytes": int(nbytes)}
        return self._cache[name]

    @staticmethod
    def _key(name, kind):
        return name if kind == "corners" else f"{name}/{kind}"

    def cellmax_for(self, kind="corners") -> np.ndarray:
        h = self.heights

        def make():  # in bands: the only full-size array is the result
            out = np.empty((self.rows - 1, self.cols - 1), dtype=np.float32)
            step = _band_rows(self.cols)
            for r0 in range(0, self.rows - 1, step):
                r1 = min(self.rows - 1, r0 + step)
                out[r0:r1] = _cellmax_rows(h, kind, r0, r1)
            return out

        return self._build(self._key("cellmax", kind), make)

    def zrange_for(self, kind="corners") -> tuple[float, float]:
        """Lowest and highest surface height over the field, for the box clip."""
        if kind == "corners":
            return self.hmin, self.hmax
        h = self.heights.astype(np.float64)
        fourth = h[:-1, 1:] + h[1:, :-1] - h[:-1, :-1]
        return min(self.hmin, float(fourth.min())), max(self.hmax, float(fourth.max()))

    def row_max_for(self, kind="corners"):
        return self._build(self._key("row_max", kind),
                           lambda: _range_max(self.cellmax_for(kind), RMQ_BLOCK_SHIFT))

    def col_max_for(self, kind="corners"):
        return self._build(self._key("col_max", kind),
                           lambda: _range_max(self.cellmax_for(kind).T, RMQ_BLOCK_SHIFT))

    def mip_for(self, kind="corners", from_level=0) -> list:
        """The maximum mipmap; with ``from_level`` > 0 (the lean layout) the levels below
        it are ``None`` and the rest are built from the heights in bands, without the
        full-size cell maxima."""
        if from_level <= 0:
            return self._build(self._key("mip", kind), lambda: _mipmap(self.cellmax_for(kind)))

        def make():
            return [None] * from_level + _mipmap(_tile_max_rows(self.heights, kind, from_level))

        return self._build(self._key(f"mip{from_level}", kind), make)

    # the structures for the three surfaces that stay within their corners
    cellmax = property(lambda self: self.cellmax_for())
    row_max = property(lambda self: self.row_max_for())
    col_max = property(lambda self: self.col_max_for())
    mip = property(lambda self: self.mip_for())

    @property
    def nbytes(self) -> int:
        """Bytes of the heights plus every structure built so far."""
        return self.heights.nbytes + sum(s["bytes"] for s in self.build_stats.values()
                                         if isinstance(s.get("bytes"), int))


def bound_kind(surface: str) -> str:
    """Which surface bounds a surface needs: "plane3" for plane3, else "corners"."""
    return "plane3" if surface == "plane3" else "corners"


def as_field(heights) -> Field:
    """A :class:`Field` for ``heights`` (returned as is when it already is one)."""
    return heights if isinstance(heights, Field) else Field(heights)
