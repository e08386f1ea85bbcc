"""Calling registered plugin kernels (``algos.plugins``): the public calls
(``algos.traverse``, ``algos.intersect``), the timed calls of the sweeps, and the visit
checksum's fold.

The conventions of what each kind of kernel returns, and what it cannot serve, are in
``algos.plugins``' module docstring; this module checks each output (shape, range, cells
inside the grid) and turns a kernel's failure into one :class:`PluginError` line naming
it. It reads the registry and nothing above it.
"""
from __future__ import annotations

import ctypes
import time

import numpy as np

from . import registry

__all__ = ["PluginError", "fold_cells", "traversal_cells", "first_hits", "surface_normals",
           "prepare_timed_traversal", "prepare_timed_first_hit"]

_MASK = (1 << 64) - 1

class PluginError(RuntimeError):
    """A plugin kernel failed: a non-zero status, a wrong output shape, a bad library, or a
    registering function that raised. The message is one line naming the plugin."""


def _one_line(exc) -> str:
    """An exception's text on one line (a plugin's message may span several)."""
    return " ".join(str(exc).split())


# ---- the checksum fold ------------------------------------------------------------------
def fold_cells(cells) -> int:
    """The visit checksum of one ray's cells, as the C kernels compute it
    (``hf_fold`` of ``cext/walks/walk.h``, reproduced in ``cext/hftrace_plugin.h``):
    ``hash = rotl(hash, 7) ^ ((i << 32) | j)`` over the cells in order, from 0."""
    h = 0
    for i, j in np.asarray(cells, dtype=np.int64).reshape(-1, 2).tolist():
        key = ((i & 0xFFFFFFFF) << 32) | (j & 0xFFFFFFFF)
        h = (((h << 7) | (h >> 57)) & _MASK) ^ key
    return h


def _checksums(result, n, name, shape):
    """A traversal plugin's output as (N,) uint64 checksums; returned cells are checked
    as :func:`traversal_cells` checks them ((k, 2) integers inside the grid of ``shape``
    cells) before they are folded, so a malformed output is an error in the kernel's row,
    never a checksum that merely disagrees."""
    if isinstance(result, np.ndarray) and result.ndim == 1 and result.dtype.kind in "iufb":
        if result.dtype != np.uint64:
            raise PluginError(f"{name}: returned a ({len(result)},) {result.dtype} array; "
                              "checksums are (N,) uint64 (algos.plugins.fold_cells), or "
                              "return N arrays of (i, j) cells")
        if len(result) != n:
            raise PluginError(f"{name}: returned {len(result)} checksums for {n} rays")
        return result
    try:
        paths = list(result)
    except TypeError:
        raise PluginError(f"{name}: returned {type(result).__name__}; expected (N,) uint64 "
                          "checksums or N arrays of cells") from None
    if len(paths) != n:
        raise PluginError(f"{name}: returned {len(paths)} paths for {n} rays")
    offsets, cells = _checked_paths(paths, n, int(shape[0]), int(shape[1]), name)
    return np.array([fold_cells(cells[offsets[k]:offsets[k + 1]]) for k in range(n)],
                    dtype=np.uint64)


def _t_values(out, n, name):
    """A Python first-hit kernel's output as (N,) float64 ray parameters, ``inf`` on a
    miss (a NaN is read as a miss); PluginError naming the shape or dtype otherwise."""
    try:
        t = np.array(out, dtype=np.float64).reshape(-1) if np.ndim(out) == 1 else None
    except (TypeError, ValueError):
        t = None
    if t is None or t.shape != (n,):
        shape = getattr(out, "shape", type(out).__name__)
        dtype = getattr(out, "dtype", None)
        if t is None and np.ndim(out) == 1 and len(out) == n:
            raise PluginError(f"{name}: returned t of dtype {dtype or type(out[0]).__name__}; "
                              f"expected ({n},) numbers (float64, inf on a miss)")
        raise PluginError(f"{name}: returned t of shape {shape}; expected ({n},)")
    return np.where(np.isnan(t), np.inf, t)


# ---- the public calls (algos.traverse, algos.intersect) --------------------------------
def _refuse_range(plugin, name, tmin, tmax):
    """A Python kernel's signature takes no ray range: a given one is refused, not dropped."""
    for arg, value in (("tmin", tmin), ("tmax", tmax)):
        if value is not None:
            raise ValueError(f"{arg}: kernel {plugin.describe(name)} takes no ray range (its "
                             "signature is fn(origins, directions, ...) over [0, inf)); "
                             "leave tmin and tmax unset")


def _checked_paths(paths, n, nx, ny, name):
    """A traversal plugin's N cell arrays as (offsets (N+1,) int64, cells (M, 2) int32);
    PluginError naming the ray when one is not (k, 2) integers inside the grid."""
    offsets = np.zeros(n + 1, dtype=np.int64)
    parts = []
    for k, path in enumerate(paths):
        cells = np.asarray(path)
        if cells.size == 0:
            cells = np.zeros((0, 2), dtype=np.int64)
        if cells.ndim != 2 or cells.shape[1] != 2 or cells.dtype.kind not in "iu":
            raise PluginError(f"{name}: ray {k}: returned cells of shape {cells.shape} and "
                              f"dtype {cells.dtype}; expected (k, 2) integers (i, j)")
        inside = (cells[:, 0] >= 0) & (cells[:, 0] < nx) & (cells[:, 1] >= 0) & (cells[:, 1] < ny)
        if not inside.all():
            i, j = (int(v) for v in cells[int(np.argmin(inside))])
            raise PluginError(f"{name}: ray {k}: returned cell ({i}, {j}) outside the grid of "
                              f"{nx} x {ny} cells")
        offsets[k + 1] = offsets[k] + len(cells)
        parts.append(cells.astype(np.int32))
    cells = np.concatenate(parts) if parts else np.zeros((0, 2), dtype=np.int32)
    return offsets, cells.reshape(-1, 2)


def traversal_cells(name, origins, directions, shape, tmin=None, tmax=None):
    """The visited cells of a traversal plugin, for ``algos.traverse`` (inputs already
    validated: (N, 2) float64 rays, ``shape`` = (nx, ny), ``tmin``/``tmax`` None or (N,)).

    Returns
    -------
    offsets : ndarray of int64, shape (N + 1,)
    cells : ndarray of int32, shape (M, 2)
        Ray k's cells (i, j) in visiting order are ``cells[offsets[k]:offsets[k+1]]``.

    Raises
    ------
    ValueError
        The kernel cannot serve the call: a Python kernel given a ray range, or a C
        library that does not export ``hftrace_traverse_cells``. The message names the
        kernel and what it lacks.
    PluginError
        The kernel raised, returned a non-zero status, checksums only, or cells that are
        not (k, 2) integers inside the grid.
    """
    plugin = registry.TRAVERSAL_REGISTRY[name].plugin
    nx, ny = int(shape[0]), int(shape[1])
    n = len(origins)
    o = np.ascontiguousarray(origins, dtype=np.float64)
    d = np.ascontiguousarray(directions, dtype=np.float64)
    if plugin.language == "c":
        if plugin.cells_fn is None:
            raise ValueError(f"name: kernel {plugin.describe(name)} does not export "
                             "hftrace_traverse_cells, so it gives visit checksums only (what "
                             "sweeps time), not the cells algos.traverse returns "
                             "(cext/hftrace_plugin.h)")
        lo = None if tmin is None else np.ascontiguousarray(tmin, dtype=np.float64)
        hi = None if tmax is None else np.ascontiguousarray(tmax, dtype=np.float64)
        sums = np.zeros(n, dtype=np.uint64)
        counts = np.zeros(n, dtype=np.int64)
        status = plugin.fn(ctypes.c_int64(nx), ctypes.c_int64(ny), ctypes.c_int64(n), _ptr(o),
                           _ptr(d), _ptr_or_null(lo), _ptr_or_null(hi), _ptr(sums), _ptr(counts))
        if status != 0:
            raise PluginError(f"{name}: hftrace_traverse returned status {status}")
        # a ray visits at most nx + ny - 1 cells: a larger count would overrun the buffer
        longest = nx + ny - 1
        bad = (counts < 0) | (counts > longest)
        if bad.any():
            k = int(np.argmax(bad))
            raise PluginError(f"{name}: hftrace_traverse counted {int(counts[k])} cells for "
                              f"ray {k}; a ray visits 0 to {longest} cells of this grid")
        offsets = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(counts, out=offsets[1:])
        cells = np.full((int(offsets[-1]), 2), -1, dtype=np.int32)
        status = plugin.cells_fn(ctypes.c_int64(nx), ctypes.c_int64(ny), ctypes.c_int64(n),
                                 _ptr(o), _ptr(d), _ptr_or_null(lo), _ptr_or_null(hi),
                                 _ptr(offsets), _ptr(cells))
        if status != 0:
            raise PluginError(f"{name}: hftrace_traverse_cells returned status {status}")
        inside = (cells[:, 0] >= 0) & (cells[:, 0] < nx) & (cells[:, 1] >= 0) & (cells[:, 1] < ny)
        if not inside.all():
            m = int(np.argmin(inside))
            k = int(np.searchsorted(offsets, m, side="right") - 1)
            raise PluginError(f"{name}: hftrace_traverse_cells wrote cell "
                              f"({int(cells[m, 0])}, {int(cells[m, 1])}) for ray {k}, outside "
                              f"the grid of {nx} x {ny} cells (or fewer cells than "
                              "hftrace_traverse counted)")
        return offsets, cells
    _refuse_range(plugin, name, tmin, tmax)
    result = _call(plugin, name, _read_only(o), _read_only(d), (nx, ny))
    if isinstance(result, np.ndarray) and result.ndim == 1 and result.dtype == np.uint64:
        raise PluginError(f"{name}: returned visit checksums only; algos.traverse needs the "
                          "visited cells (return N arrays of (i, j) cells)")
    try:
        paths = list(result)
    except TypeError:
        raise PluginError(f"{name}: returned {type(result).__name__}; expected N arrays of "
                          "cells") from None
    if len(paths) != n:
        raise PluginError(f"{name}: returned {len(paths)} paths for {n} rays")
    return _checked_paths(paths, n, nx, ny, name)


def _read_only(array):
    """A read-only view of ``array`` for a Python kernel: its inputs are often the caller's
    own arrays (a field's heights, the rays every kernel of a sweep group reuses), which a
    kernel writing in place would silently change; the write raises instead."""
    view = array.view()
    view.flags.writeable = False
    return view


def _call(plugin, name, *args, **kwargs):
    """A Python kernel's call; what it raises becomes one PluginError line naming it."""
    try:
        return plugin.fn(*args, **kwargs)
    except Exception as exc:
        raise PluginError(f"{name}: the kernel raised {type(exc).__name__}: "
                          f"{_one_line(exc)}") from None


def first_hits(name, heights, origins, directions, surface, tmin=None, tmax=None):
    """The first hits of a first-hit plugin, for ``algos.intersect`` (inputs validated:
    ``heights`` (rows, cols) float32 in cell units, (N, 3) float64 rays, ``tmin``/``tmax``
    None or (N,)).

    Returns
    -------
    t : ndarray of float64, shape (N,)
        ``inf`` on a miss (a kernel's NaN is read as a miss).
    cell : ndarray of int32, shape (N, 2)
        The C kernel's hit cells; for a Python kernel the cell holding the hit point by
        the half-open rule toward the direction of travel (module docstring); ``(-1, -1)``
        on a miss.

    Raises
    ------
    ValueError
        A Python kernel given a ray range (its signature takes none).
    PluginError
        The kernel raised, returned a non-zero status or a t of the wrong shape, or a
        negative or out-of-range hit.
    """
    entry = registry.INTERSECTOR_REGISTRY[name]
    plugin = entry.plugin
    h = np.ascontiguousarray(heights, dtype=np.float32)
    o = np.ascontiguousarray(origins, dtype=np.float64)
    d = np.ascontiguousarray(directions, dtype=np.float64)
    n = len(o)
    rows, cols = h.shape
    if plugin.language == "c":
        lo = None if tmin is None else np.ascontiguousarray(tmin, dtype=np.float64)
        hi = None if tmax is None else np.ascontiguousarray(tmax, dtype=np.float64)
        t = np.full(n, np.inf)
        cell = np.full((n, 2), -1, dtype=np.int32)
        status = plugin.fn(_ptr(h), ctypes.c_int64(rows), ctypes.c_int64(cols),
                           ctypes.c_int(registry.SURFACES.index(surface)), ctypes.c_int64(n),
                           _ptr(o), _ptr(d), _ptr_or_null(lo), _ptr_or_null(hi), _ptr(t),
                           _ptr(cell))
        if status != 0:
            raise PluginError(f"{name}: hftrace_first_hit returned status {status}")
        t = np.where(np.isnan(t), np.inf, t)
    else:
        _refuse_range(plugin, name, tmin, tmax)
        kwargs = {"surface": surface} if len(entry.surfaces) > 1 else {}
        out = _call(plugin, name, _read_only(h), _read_only(o), _read_only(d), **kwargs)
        t = _t_values(out, n, name)
        cell = None  # the cell holding each hit point, once t is known to be in range
    hit = np.isfinite(t)
    # a first hit lies in the ray's range [tmin, tmax] (default [0, inf))
    low = np.zeros(n) if tmin is None else np.asarray(tmin, dtype=np.float64)
    high = np.full(n, np.inf) if tmax is None else np.asarray(tmax, dtype=np.float64)
    outside = (t < low) | (np.isfinite(t) & (t > high))
    if outside.any():
        k = int(np.argmax(outside))
        raise PluginError(f"{name}: returned t[{k}] = {float(t[k])!r}, outside ray {k}'s "
                          f"range [{float(low[k])!r}, {float(high[k])!r}]")
    if cell is None:
        _check_hit_points(name, o, d, t, rows, cols)
        cell = _cells_at(o, d, t, rows, cols)
    cell[~hit] = -1
    inside = (cell[hit, 0] >= 0) & (cell[hit, 0] < cols - 1) & (cell[hit, 1] >= 0) & \
        (cell[hit, 1] < rows - 1)
    if not inside.all():
        k = int(np.flatnonzero(hit)[np.argmin(inside)])
        raise PluginError(f"{name}: ray {k} hits cell ({int(cell[k, 0])}, {int(cell[k, 1])}), "
                          f"outside the {cols - 1} x {rows - 1} cells of the field")
    return t, cell


def _check_hit_points(name, o, d, t, rows, cols):
    """Refuse a Python kernel's hit whose point ``o + t d`` lies outside the field's
    footprint ``[0, cols-1] x [0, rows-1]``: no cell holds it, and clipping it to a
    border cell would report a hit the surface does not have. (The tolerance allows
    for rounding in a hit computed on the footprint's border.)"""
    hit = np.isfinite(t)
    if not hit.any():
        return
    point = o[hit, :2] + t[hit, None] * d[hit, :2]
    upper = np.array([cols - 1, rows - 1], dtype=np.float64)
    slack = 1e-9 * (1.0 + np.abs(point))
    outside = ((point < -slack) | (point > upper + slack)).any(axis=1)
    if outside.any():
        k = int(np.flatnonzero(hit)[np.argmax(outside)])
        x, y = point[np.argmax(outside)]
        raise PluginError(f"{name}: returned t[{k}] = {float(t[k])!r}, whose hit point "
                          f"({float(x)!r}, {float(y)!r}) lies outside the field's footprint "
                          f"[0, {cols - 1}] x [0, {rows - 1}]")


def _cells_at(o, d, t, rows, cols):
    """The cell (i, j) holding each hit point ``o + t d``, half-open toward the direction
    of travel (a point on a border belongs to the cell the ray enters), clipped to the
    field's cells; (-1, -1) where ``t`` is not finite."""
    hit = np.isfinite(t)
    point = o[:, :2] + np.where(hit, t, 0.0)[:, None] * d[:, :2]
    index = np.where(d[:, :2] < 0, np.ceil(point) - 1, np.floor(point))
    upper = np.array([cols - 2, rows - 2])
    cell = np.clip(index, 0, upper).astype(np.int32)
    cell[~hit] = -1
    return cell


def surface_normals(heights, surface, origins, directions, t, cell, tmin=None):
    """The unit normal at each hit point ``o + t d``, (N, 3) float64, NaN on a miss, as
    the built-in kernels give it: where the ray enters the field's box through one of
    its sides below the surface (the hit is the box entry, after ``tmin``), the side's
    horizontal normal facing the ray (x on a tie, at a corner); elsewhere the
    up-facing normal of ``surface`` in the hit cell (``triangles``: the hit triangle's
    plane, ``u >= v`` the lower one; ``bilinear``: the gradient of the patch).

    Raises
    ------
    ValueError
        ``flat`` or ``plane3``: a hit there may lie on a wall, which ``t`` alone does not
        tell from the top.
    """
    if surface not in ("triangles", "bilinear"):
        raise ValueError(f"outputs: the 'normal' of a plugin's hit is computed on the "
                         f"continuous surfaces only (triangles, bilinear), not {surface!r}, "
                         "whose hits may lie on walls")
    h = np.asarray(heights, dtype=np.float64)
    n = len(t)
    normal = np.full((n, 3), np.nan)
    hit = np.isfinite(t)
    if not hit.any():
        return normal
    i, j = cell[hit, 0].astype(np.int64), cell[hit, 1].astype(np.int64)
    point = origins[hit, :2] + t[hit, None] * directions[hit, :2]
    u = np.clip(point[:, 0] - i, 0.0, 1.0)
    v = np.clip(point[:, 1] - j, 0.0, 1.0)
    h00, h10, h01, h11 = h[j, i], h[j, i + 1], h[j + 1, i], h[j + 1, i + 1]
    if surface == "triangles":
        lower = u >= v
        gx = np.where(lower, h10 - h00, h11 - h01)
        gy = np.where(lower, h11 - h10, h01 - h00)
    else:
        gx = (h10 - h00) * (1 - v) + (h11 - h01) * v
        gy = (h01 - h00) * (1 - u) + (h11 - h10) * u
    up = np.stack([-gx, -gy, np.ones_like(gx)], axis=1)
    normal[hit] = up / np.linalg.norm(up, axis=1)[:, None]
    # the box's sides: a ray entering the box below the surface hits the side it enters
    rows, cols = h.shape
    o, d = origins[hit], directions[hit]
    start = np.zeros(len(o)) if tmin is None else np.maximum(np.asarray(tmin)[hit], 0.0)
    entry = np.full((len(o), 2), -np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, size in ((0, cols - 1), (1, rows - 1)):
            side = np.where(d[:, axis] > 0, 0.0, float(size))
            entry[:, axis] = np.where(d[:, axis] != 0, (side - o[:, axis]) / d[:, axis], -np.inf)
    axis = np.where(entry[:, 0] >= entry[:, 1], 0, 1)
    t_entry = entry[np.arange(len(o)), axis]
    z = o[:, 2] + t[hit] * d[:, 2]
    if surface == "triangles":
        s = np.where(u >= v, h00 + (h10 - h00) * u + (h11 - h10) * v,
                     h00 + (h11 - h01) * u + (h01 - h00) * v)
    else:
        s = h00 * (1 - u) * (1 - v) + h10 * u * (1 - v) + h01 * (1 - u) * v + h11 * u * v
    # (the kernel's entry parameter may differ from this one in the last bits: a hit
    # below the surface can only be the entry, so near is enough)
    near = np.abs(t[hit] - t_entry) <= 1e-9 * (1 + np.abs(t_entry))
    wall = (t_entry > start) & near & (z < s - 1e-9 * (1 + np.abs(s)))
    if wall.any():
        rows_hit = np.flatnonzero(hit)[wall]
        normal[rows_hit] = 0.0
        facing = np.where(d[wall, axis[wall]] > 0, -1.0, 1.0)
        normal[rows_hit, axis[wall]] = facing
    return normal


# ---- timed calls (bench.sweep) ----------------------------------------------------------
def _timed_c_call(plugin, name, args):
    """``run()`` for a C plugin: one call of its kernel on ``args``, timed with
    CLOCK_MONOTONIC right around the ctypes call; a non-zero status raises PluginError."""
    def run():
        t0 = time.monotonic_ns()
        status = plugin.fn(*args)
        elapsed = time.monotonic_ns() - t0
        if status != 0:
            raise PluginError(f"{name}: returned status {status}")
        return elapsed

    return run


def prepare_timed_traversal(name, origins, directions, shape):
    """``(run, checksums)`` for a traversal plugin: each ``run()`` calls the kernel on the
    whole batch and returns the elapsed nanoseconds around the call (CLOCK_MONOTONIC);
    ``checksums()`` folds the latest output (outside the timing)."""
    plugin = registry.TRAVERSAL_REGISTRY[name].plugin
    o = np.ascontiguousarray(origins, dtype=np.float64)
    d = np.ascontiguousarray(directions, dtype=np.float64)
    n = len(o)
    nx, ny = int(shape[0]), int(shape[1])
    state = {}
    if plugin.language == "c":
        sums = np.zeros(n, dtype=np.uint64)
        cells = np.zeros(n, dtype=np.int64)
        args = (ctypes.c_int64(nx), ctypes.c_int64(ny), ctypes.c_int64(n), _ptr(o), _ptr(d),
                None, None, _ptr(sums), _ptr(cells))
        return _timed_c_call(plugin, name, args), lambda: sums.copy()
    o, d = _read_only(o), _read_only(d)  # the rays every other kernel of the group reuses

    def run():
        t0 = time.monotonic_ns()
        out = plugin.fn(o, d, (nx, ny))
        elapsed = time.monotonic_ns() - t0
        state["out"] = out
        return elapsed

    def checksums():
        return _checksums(state.get("out"), n, name, (nx, ny))

    return run, checksums


def prepare_timed_first_hit(name, heights, origins, directions, surface):
    """``(run, t)`` for a first-hit plugin, as :func:`prepare_timed_traversal`; ``t()``
    gives the latest (N,) float64 ray parameters."""
    entry = registry.INTERSECTOR_REGISTRY[name]
    plugin = entry.plugin
    if surface not in entry.surfaces:
        raise ValueError(f"surface: {name} supports only {', '.join(entry.surfaces)}")
    h = np.ascontiguousarray(heights, dtype=np.float32)
    o = np.ascontiguousarray(origins, dtype=np.float64)
    d = np.ascontiguousarray(directions, dtype=np.float64)
    n = len(o)
    if plugin.language == "c":
        t = np.full(n, np.inf)
        cells = np.zeros((n, 2), dtype=np.int32)
        surface_id = registry.SURFACES.index(surface)
        args = (_ptr(h), ctypes.c_int64(h.shape[0]), ctypes.c_int64(h.shape[1]),
                ctypes.c_int(surface_id), ctypes.c_int64(n), _ptr(o), _ptr(d), None, None,
                _ptr(t), _ptr(cells))
        return _timed_c_call(plugin, name, args), lambda: _ray_parameters(t, name)
    state = {}
    kwargs = {"surface": surface} if len(entry.surfaces) > 1 else {}
    h, o, d = _read_only(h), _read_only(o), _read_only(d)  # shared with the other kernels

    def run():
        t0 = time.monotonic_ns()
        out = plugin.fn(h, o, d, **kwargs)
        elapsed = time.monotonic_ns() - t0
        state["t"] = out
        return elapsed

    def hits():
        return _ray_parameters(_t_values(state.get("t"), n, name), name)

    return run, hits


def _ray_parameters(t, name):
    """A copy of a timed first-hit call's ``t``, checked as ``algos.intersect`` checks it:
    a NaN is a miss (``inf``), a ``t`` before 0 (``-inf`` included) is an error naming the
    ray, never a miss or a hit that merely disagrees."""
    t = np.where(np.isnan(t), np.inf, t)
    behind = t < 0
    if behind.any():
        k = int(np.argmax(behind))
        raise PluginError(f"{name}: returned t[{k}] = {float(t[k])!r}, outside ray {k}'s "
                          "range [0.0, inf]")
    return t


def _ptr(a):
    return a.ctypes.data_as(ctypes.c_void_p)


def _ptr_or_null(a):
    return None if a is None else _ptr(a)
