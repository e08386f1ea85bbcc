"""Your own kernel in every table: register a traversal or a first-hit intersector.

Three ways in, one treatment: the public calls (``algos.traverse``, ``algos.intersect``,
``algos.render``), ``hftrace list``, sweeps, ``reproduce --kernels``, the plots (an
``exact=False`` kernel is drawn dashed), the agreement check against the exact reference
and ``regress``. The terrain products (horizon, shadows, sky-view factor, openness,
viewshed) run their own exact sweeps, not an intersector, so plugins do not reach them.

* **Python** (plain, NumPy or Numba callables): :func:`register_traversal` and
  :func:`register_intersector`. The harness times the call with ``time.monotonic_ns``
  (CLOCK_MONOTONIC on Linux, the clock the C kernels read) and interleaves it with the
  built-in kernels on the same rays, caches flushed before each call.
* **C** (a shared library exporting ``cext/hftrace_plugin.h``): :func:`load_c_plugin`
  loads it with ctypes; the call is timed the same way, around the ctypes call (the
  crossing costs about a microsecond per batch, against milliseconds for a batch).
* **Packaging**: a distribution that declares an entry point in the group
  ``hftrace.kernels`` (``[project.entry-points."hftrace.kernels"] mine =
  "mypkg.hftrace:register"``) is registered by :func:`load_entry_points`, which the
  ``hftrace`` command calls at start-up: ``pip install theirs`` makes ``hftrace list``
  show their kernels. The entry point is a callable taking no argument, or a C plugin's
  path (a ``str`` or ``os.PathLike``).

Every failure to load a plugin (a registering function that raises, a library that
cannot be loaded or whose ``hftrace_plugin()`` returns NULL) is a :class:`PluginError`
whose message is one line naming the plugin; the ``hftrace`` command prints it without a
traceback on every route (``--plugin``, a config's ``plugins``, entry points).

Signatures (shapes in the project's conventions, ``docs/CONVENTIONS.md``):

* traversal ``fn(origins, directions, shape) -> checksums or cells``: ``origins``,
  ``directions`` (N, 2) float64, ``shape`` = (nx, ny) cells; return either the per-ray
  visit checksums, (N,) uint64 (the fold :func:`fold_cells` computes), or a sequence of N
  integer arrays of shape (k, 2) holding the visited cells (i, j) in order, which the
  harness folds after the timed call. The rays run over ``[0, inf)``. Only a kernel that
  returns the cells serves ``algos.traverse`` (every output: the runs are grouped from
  the cells, each ray's major axis the larger ``|d|``, x on a tie); a ``tmin``/``tmax``
  there is refused, since the signature takes no ray range.
* first hit ``fn(heights, origins, directions[, surface=...]) -> t``: ``heights``
  (rows, cols) float32, ``H[j, i]`` in cell units; ``origins``, ``directions`` (N, 3)
  float64; returns (N,) float ray parameters of the first hit, ``inf`` (or NaN) on a
  miss. ``surface`` is passed as a keyword only when the kernel registered more than one.
  In ``algos.intersect`` the hit ``cell`` is the cell holding the hit point by the
  half-open rule toward the direction of travel (a hit exactly on a cell border is given
  the cell the ray enters there), and the ``normal`` is the up-facing normal of the
  surface there (``triangles`` and ``bilinear`` only: ``flat`` and ``plane3`` have walls,
  whose hits the returned ``t`` alone cannot tell from a top); ``stats`` and a ray range
  are refused.
* C: the kernels of ``cext/hftrace_plugin.h``; a traversal library that also exports
  ``hftrace_traverse_cells`` serves ``algos.traverse``, one without it only sweeps. A
  first-hit library serves ``algos.intersect`` with ``tmin``/``tmax`` and its own hit
  cells; normals as for Python kernels.

A kernel that raises, returns a non-zero status (C) or takes longer than its time limit
in one call gets an error in its row; the other kernels' rows are kept. ``hftrace sweep
--isolate`` measures the plugin kernels of each group in a child process, so a crash is
contained too.
"""
from __future__ import annotations

import ctypes
import hashlib
import importlib
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass

import numpy as np

from . import registry

__all__ = ["register_traversal", "register_intersector", "load_c_plugin", "unregister",
           "load_entry_points", "load_plugin_spec", "fold_cells", "is_plugin", "plugin_names",
           "traversal_cells", "first_hits", "surface_normals", "PluginError",
           "DEFAULT_TIME_LIMIT", "ENTRY_POINT_GROUP", "PLUGIN_ABI"]

#: The entry-point group a package declares its kernels in.
ENTRY_POINT_GROUP = "hftrace.kernels"
#: Seconds one call of a plugin may take before its row reports an error.
DEFAULT_TIME_LIMIT = 60.0
#: ``HFTRACE_PLUGIN_ABI`` of ``cext/hftrace_plugin.h``.
PLUGIN_ABI = 1
_MASK = (1 << 64) - 1


class PluginError(RuntimeError):
    """A plugin kernel failed: a non-zero status, a wrong output shape, a bad library, or a
    registering function that raised. The message is one line naming the plugin."""


@dataclass(frozen=True)
class Plugin:
    """How to call a registered kernel.

    Attributes
    ----------
    fn : callable
        The Python callable, or the ctypes function of a C plugin.
    language : str
        ``"python"`` or ``"c"``.
    exact : bool
        The kernel claims to equal the exact reference on every ray; a sweep row whose
        agreement is below 1 then carries an error.
    time_limit : float
        Seconds one call may take.
    path : str
        The shared library of a C plugin as given ("" for Python).
    loaded_from : str
        The private copy of that library that was loaded (named by its content hash, so
        a library rebuilt at ``path`` and loaded again runs its new code).
    cells_fn : callable or None
        A C traversal's ``hftrace_traverse_cells`` (None when it does not export one).
    """

    fn: object
    language: str
    exact: bool
    time_limit: float = DEFAULT_TIME_LIMIT
    path: str = ""
    loaded_from: str = ""
    cells_fn: object = None

    def describe(self, name) -> str:
        """``'name' (C plugin /path/lib.so)`` or ``'name' (Python plugin)``: how errors
        name the kernel."""
        if self.language == "c":
            return f"{name!r} (C plugin {self.path})"
        return f"{name!r} (Python plugin)"


def _one_line(exc) -> str:
    """An exception's text on one line (a plugin's message may span several)."""
    return " ".join(str(exc).split())


def _check_name(name):
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"name: expected an identifier (letters, digits, _), got {name!r}")
    builtin = (name in registry.TRAVERSAL_REGISTRY and
               registry.TRAVERSAL_REGISTRY[name].plugin is None) or \
              (name in registry.INTERSECTOR_REGISTRY and
               registry.INTERSECTOR_REGISTRY[name].plugin is None)
    if builtin:
        raise ValueError(f"name: {name!r} is a built-in kernel; choose another name")


def _check_limit(time_limit):
    if time_limit is None:
        return DEFAULT_TIME_LIMIT
    if isinstance(time_limit, bool) or not isinstance(time_limit, (int, float)) or \
            not time_limit > 0:
        raise ValueError(f"time_limit: expected seconds > 0, got {time_limit!r}")
    return float(time_limit)


def register_traversal(name, fn, exact=False, summary="", citation="", time_limit=None,
                       _plugin=None):
    """Register a 2D traversal (visit workload) under ``name``.

    Parameters
    ----------
    name : str
        An identifier not used by a built-in kernel; registering a plugin name again
        replaces it.
    fn : callable
        ``fn(origins, directions, shape)`` (module docstring).
    exact : bool
        True when it claims to visit exactly the reference's cells on every ray.
    summary, citation : str
        Shown by ``hftrace list``.
    time_limit : float, optional
        Seconds one call may take (default :data:`DEFAULT_TIME_LIMIT`).

    Returns
    -------
    algos.Traversal
        The registry entry.

    Raises
    ------
    ValueError
        A bad or built-in name, a bad time limit. ``TypeError``: ``fn`` not callable.
    """
    _check_name(name)
    if not callable(fn):
        raise TypeError(f"fn: expected a callable, got {type(fn).__name__}")
    plugin = _plugin or Plugin(fn, "python", bool(exact), _check_limit(time_limit))
    entry = registry.Traversal(name, -1, bool(exact), "cell", "exact" if exact else "plugin",
                               citation=citation, summary=summary or f"plugin ({plugin.language})",
                               plugin=plugin)
    registry.TRAVERSAL_REGISTRY[name] = entry
    return entry


def register_intersector(name, fn, exact=False, surfaces=("triangles",), summary="",
                         citation="", time_limit=None, _plugin=None):
    """Register a first-hit intersector under ``name``.

    Parameters
    ----------
    name : str
        An identifier not used by a built-in kernel.
    fn : callable
        ``fn(heights, origins, directions[, surface=...])`` (module docstring).
    exact : bool
        True when it claims the exact first hit (``|dt| <= 1e-9 (1 + |t|)`` against the
        exact ``runs`` kernel, same hit or miss) on every ray.
    surfaces : sequence of str
        The cell surfaces (``algos.SURFACES``) it implements.
    summary, citation : str
    time_limit : float, optional
        Seconds one call may take.

    Returns
    -------
    algos.Intersector

    Raises
    ------
    ValueError
        A bad or built-in name, an unknown surface, a bad time limit. ``TypeError``:
        ``fn`` not callable.
    """
    _check_name(name)
    if not callable(fn):
        raise TypeError(f"fn: expected a callable, got {type(fn).__name__}")
    surfaces = (surfaces,) if isinstance(surfaces, str) else tuple(surfaces)
    for k, s in enumerate(surfaces):
        if s not in registry.SURFACES:
            raise ValueError(f"surfaces[{k}]: unknown surface {s!r}; valid: "
                             f"{', '.join(registry.SURFACES)}")
    if not surfaces:
        raise ValueError("surfaces: expected at least one surface")
    plugin = _plugin or Plugin(fn, "python", bool(exact), _check_limit(time_limit))
    entry = registry.Intersector(name, None, "plugin", "exact" if exact else "plugin",
                                 surfaces=surfaces, options={},
                                 summary=summary or f"plugin ({plugin.language})",
                                 citation=citation, plugin=plugin)
    registry.INTERSECTOR_REGISTRY[name] = entry
    return entry


def unregister(name):
    """Remove a registered plugin kernel (traversal and intersector of that name).

    Raises
    ------
    ValueError
        ``name`` is not a registered plugin.
    """
    found = False
    for table in (registry.TRAVERSAL_REGISTRY, registry.INTERSECTOR_REGISTRY):
        entry = table.get(name)
        if entry is not None and entry.plugin is not None:
            del table[name]
            found = True
    if not found:
        raise ValueError(f"name: {name!r} is not a registered plugin")


def is_plugin(name, workload="first_hit") -> bool:
    """True when ``name`` is a registered plugin of the workload's registry."""
    table = registry.INTERSECTOR_REGISTRY if workload == "first_hit" else registry.TRAVERSAL_REGISTRY
    entry = table.get(name)
    return entry is not None and entry.plugin is not None


def plugin_names() -> list:
    """Every registered plugin name, traversals first."""
    names = [n for n, e in registry.TRAVERSAL_REGISTRY.items() if e.plugin is not None]
    return names + [n for n, e in registry.INTERSECTOR_REGISTRY.items()
                    if e.plugin is not None and n not in names]


# ---- the checksum fold ------------------------------------------------------------------
def fold_cells(cells) -> int:
    """The visit checksum of one ray's cells, as the C kernels compute it
    (``hf_fold`` of ``cext/internal.h``, reproduced in ``cext/hftrace_plugin.h``):
    ``hash = rotl(hash, 7) ^ ((i << 32) | j)`` over the cells in order, from 0."""
    h = 0
    for i, j in np.asarray(cells, dtype=np.int64).reshape(-1, 2).tolist():
        key = ((i & 0xFFFFFFFF) << 32) | (j & 0xFFFFFFFF)
        h = (((h << 7) | (h >> 57)) & _MASK) ^ key
    return h


def _checksums(result, n, name):
    """A traversal plugin's output as (N,) uint64 checksums."""
    if isinstance(result, np.ndarray) and result.ndim == 1 and result.dtype == np.uint64:
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
    return np.array([fold_cells(p) for p in paths], dtype=np.uint64)


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
    result = _call(plugin, name, o, d, (nx, ny))
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
        out = _call(plugin, name, h, o, d, **kwargs)
        try:
            t = np.array(out, dtype=np.float64).reshape(-1) if np.ndim(out) == 1 else None
        except (TypeError, ValueError):
            t = None
        if t is None or t.shape != (n,):
            shape = getattr(out, "shape", type(out).__name__)
            raise PluginError(f"{name}: returned t of shape {shape}; expected ({n},)")
        t = np.where(np.isnan(t), np.inf, t)
        cell = _cells_at(o, d, t, rows, cols)
    hit = np.isfinite(t)
    # a first hit lies in the ray's range [tmin, tmax] (default [0, inf))
    low = np.zeros(n) if tmin is None else np.asarray(tmin, dtype=np.float64)
    high = np.full(n, np.inf) if tmax is None else np.asarray(tmax, dtype=np.float64)
    outside = (t < low) | (np.isfinite(t) & (t > high))
    if outside.any():
        k = int(np.argmax(outside))
        raise PluginError(f"{name}: returned t[{k}] = {float(t[k])!r}, outside ray {k}'s "
                          f"range [{float(low[k])!r}, {float(high[k])!r}]")
    cell[~hit] = -1
    inside = (cell[hit, 0] >= 0) & (cell[hit, 0] < cols - 1) & (cell[hit, 1] >= 0) & \
        (cell[hit, 1] < rows - 1)
    if not inside.all():
        k = int(np.flatnonzero(hit)[np.argmin(inside)])
        raise PluginError(f"{name}: ray {k} hits cell ({int(cell[k, 0])}, {int(cell[k, 1])}), "
                          f"outside the {cols - 1} x {rows - 1} cells of the field")
    return t, cell


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

    def run():
        t0 = time.monotonic_ns()
        out = plugin.fn(o, d, (nx, ny))
        elapsed = time.monotonic_ns() - t0
        state["out"] = out
        return elapsed

    def checksums():
        return _checksums(state.get("out"), n, name)

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
        return _timed_c_call(plugin, name, args), lambda: t.copy()
    state = {}
    kwargs = {"surface": surface} if len(entry.surfaces) > 1 else {}

    def run():
        t0 = time.monotonic_ns()
        out = plugin.fn(h, o, d, **kwargs)
        elapsed = time.monotonic_ns() - t0
        state["t"] = out
        return elapsed

    def hits():
        out = np.asarray(state.get("t"), dtype=np.float64)
        if out.shape != (n,):
            raise PluginError(f"{name}: returned t of shape {out.shape}; expected ({n},)")
        return np.where(np.isnan(out), np.inf, out)

    return run, hits


def _ptr(a):
    return a.ctypes.data_as(ctypes.c_void_p)


def _ptr_or_null(a):
    return None if a is None else _ptr(a)


# ---- C plugins ----------------------------------------------------------------------------
class _Info(ctypes.Structure):
    _fields_ = [("abi", ctypes.c_int), ("name", ctypes.c_char_p), ("kind", ctypes.c_char_p),
                ("exact", ctypes.c_int), ("surfaces", ctypes.c_char_p),
                ("summary", ctypes.c_char_p)]


def _exported(lib, symbol, kind, path):
    """The function ``symbol`` of a plugin library, or PluginError naming what is missing."""
    try:
        return getattr(lib, symbol)
    except AttributeError:
        raise PluginError(f"C plugin {path}: declares kind {kind} but does not export "
                          f"{symbol}") from None


def load_c_plugin(path, name=None, time_limit=None):
    """Load a shared library that exports ``cext/hftrace_plugin.h`` and register its kernel.

    Parameters
    ----------
    path : str or os.PathLike
        The library (``cc -O2 -shared -fPIC -I cext mine.c -o mine.so``).
    name : str, optional
        The name to register; default the ``name`` of its ``hftrace_plugin()`` info.
    time_limit : float, optional
        Seconds one call may take.

    Returns
    -------
    algos.Traversal or algos.Intersector
        The registry entry.

    Raises
    ------
    ValueError
        The file does not exist.
    PluginError
        It cannot be loaded, misses a symbol, its ``hftrace_plugin()`` returns NULL, or
        it declares another ABI version or an unknown kind (one line naming the path).

    Notes
    -----
    The library is loaded from a private copy named by its content hash
    (:func:`_private_copy`): a library rebuilt at the same path and loaded again in the
    same process runs its new code, and re-registers the kernel.
    """
    path = os.path.abspath(os.fspath(path))
    if not os.path.isfile(path):
        raise ValueError(f"path: {path} does not exist")
    private = _private_copy(path)
    try:
        lib = ctypes.CDLL(private)
    except OSError as exc:
        raise PluginError(f"C plugin {path}: cannot load it ({exc})") from None
    try:
        info_fn = lib.hftrace_plugin
    except AttributeError:
        raise PluginError(f"C plugin {path}: does not export hftrace_plugin() "
                          "(cext/hftrace_plugin.h)") from None
    info_fn.restype = ctypes.POINTER(_Info)
    info_fn.argtypes = []
    pointer = info_fn()
    if not pointer:
        raise PluginError(f"C plugin {path}: hftrace_plugin() returned NULL; it must return "
                          "a pointer to a static hftrace_plugin_info")
    info = pointer.contents
    if info.abi != PLUGIN_ABI:
        raise PluginError(f"C plugin {path}: declares plugin ABI {info.abi}; this hftrace "
                          f"reads ABI {PLUGIN_ABI}")
    kind = (info.kind or b"").decode(errors="replace")
    name = name or (info.name or b"").decode(errors="replace")
    if not name:
        raise PluginError(f"C plugin {path}: its hftrace_plugin_info has no name")
    summary = (info.summary or b"").decode(errors="replace") or \
        f"C plugin {os.path.basename(path)}"
    limit = _check_limit(time_limit)
    if kind == "traversal":
        fn = _exported(lib, "hftrace_traverse", kind, path)
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_int64, ctypes.c_int64, ctypes.c_int64] + [ctypes.c_void_p] * 6
        cells_fn = getattr(lib, "hftrace_traverse_cells", None)
        if cells_fn is not None:
            cells_fn.restype = ctypes.c_int
            cells_fn.argtypes = [ctypes.c_int64, ctypes.c_int64, ctypes.c_int64] + \
                [ctypes.c_void_p] * 6
        plugin = Plugin(fn, "c", bool(info.exact), limit, path, private, cells_fn)
        return register_traversal(name, fn, plugin.exact, summary, _plugin=plugin)
    if kind == "first_hit":
        fn = _exported(lib, "hftrace_first_hit", kind, path)
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_void_p, ctypes.c_int64, ctypes.c_int64, ctypes.c_int,
                       ctypes.c_int64] + [ctypes.c_void_p] * 6
        surfaces = [s.strip() for s in (info.surfaces or b"triangles").decode().split(",")
                    if s.strip()]
        plugin = Plugin(fn, "c", bool(info.exact), limit, path, private)
        return register_intersector(name, fn, plugin.exact, surfaces, summary, _plugin=plugin)
    raise PluginError(f"C plugin {path}: declares kind {kind!r}; expected 'traversal' or "
                      "'first_hit'")


#: This process's private folder of loaded C plugins (made on first use, removed at exit)
_COPIES = {"folder": None}


def _private_copy(path) -> str:
    """A copy of the library at ``path`` in this process's private folder, named by the
    SHA-256 of its bytes. The dynamic loader caches libraries by path: loading a library
    rebuilt at the same path again would return the old code. A new build has a new hash,
    hence a new path, hence a fresh load; an unchanged one maps to the copy already loaded."""
    with open(path, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()[:20]
    if _COPIES["folder"] is None:
        import atexit

        _COPIES["folder"] = tempfile.mkdtemp(prefix="hftrace-plugins-")
        atexit.register(shutil.rmtree, _COPIES["folder"], True)
    stem, ext = os.path.splitext(os.path.basename(path))
    copy = os.path.join(_COPIES["folder"], f"{stem}-{digest}{ext}")
    if not os.path.exists(copy):
        partial = copy + ".part"
        shutil.copyfile(path, partial)
        os.replace(partial, copy)
    return copy


def _import_callable(spec, bases):
    """The object ``module:callable`` names, importing ``module`` from the folders
    ``bases`` (the config's folder, the current directory) before ``sys.path``."""
    module, _, attr = spec.partition(":")
    added = [b for b in dict.fromkeys(os.path.abspath(b) for b in bases) if b not in sys.path]
    sys.path[:0] = added
    try:
        try:
            target = importlib.import_module(module)
        except ImportError as exc:
            where = ", ".join(added + ["sys.path"]) if added else "sys.path"
            raise PluginError(f"plugin {spec}: cannot import {module} ({_one_line(exc)}; "
                              f"looked in {where})") from None
        except Exception as exc:
            raise PluginError(f"plugin {spec}: importing {module} raised "
                              f"{type(exc).__name__}: {_one_line(exc)}") from None
    finally:
        for b in added:
            if b in sys.path:
                sys.path.remove(b)
    try:
        obj = target
        for part in attr.split("."):
            obj = getattr(obj, part)
    except AttributeError:
        raise PluginError(f"plugin {spec}: module {module} has no {attr}") from None
    return obj


def load_plugin_spec(spec, base=None):
    """Register what ``spec`` names: a C plugin's path (``*.so``, ``*.dylib``, ``*.dll``),
    relative to ``base`` (default the current directory), or ``module:callable`` (a
    function registering kernels), the module looked up in ``base``, then the current
    directory, then ``sys.path``. Returns the names registered.

    Raises
    ------
    ValueError
        ``spec`` is neither form.
    PluginError
        The plugin cannot be loaded, or its function raised: one line naming ``spec``.
    """
    before = set(plugin_names())
    text = os.fspath(spec)
    if text.endswith((".so", ".dylib", ".dll")):
        if base and not os.path.isabs(text):
            text = os.path.join(base, text)
        try:
            load_c_plugin(text)
        except ValueError as exc:
            raise PluginError(f"plugin {spec}: {_one_line(exc)}") from None
    else:
        module, sep, attr = str(text).partition(":")
        if not sep or not module or not attr:
            raise ValueError(f"--plugin: expected a library path or module:callable, got {spec!r}")
        target = _import_callable(text, [b for b in (base, os.getcwd()) if b])
        try:
            target()
        except Exception as exc:
            raise PluginError(f"plugin {spec}: {attr}() raised {type(exc).__name__}: "
                              f"{_one_line(exc)}") from None
    return sorted(set(plugin_names()) - before)


def load_entry_points(warn=None) -> list:
    """Register every kernel of the ``hftrace.kernels`` entry points; returns the names.
    A failing entry point is reported through ``warn`` (one line) and skipped."""
    from importlib.metadata import entry_points

    try:
        points = entry_points(group=ENTRY_POINT_GROUP)
    except TypeError:  # Python < 3.10 API
        points = entry_points().get(ENTRY_POINT_GROUP, [])
    before = set(plugin_names())
    for point in points:
        try:
            target = point.load()
            if isinstance(target, (str, os.PathLike)):
                load_c_plugin(target)
            else:
                target()
        except Exception as exc:  # someone else's package must not stop hftrace
            if warn:
                text = _one_line(exc) if isinstance(exc, PluginError) else \
                    f"{type(exc).__name__}: {_one_line(exc)}"
                warn(f"hftrace: plugin entry point {point.name!r} ({point.value}) failed: {text}")
    return sorted(set(plugin_names()) - before)
