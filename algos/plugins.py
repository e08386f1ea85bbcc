"""Your own kernel in every table: register a traversal or a first-hit intersector.

Three ways in, one treatment (``hftrace list``, sweeps, ``reproduce --kernels``, the
plots, the agreement check against the exact reference, ``regress``):

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

Signatures (shapes in the project's conventions, ``docs/CONVENTIONS.md``):

* traversal ``fn(origins, directions, shape) -> checksums or cells``: ``origins``,
  ``directions`` (N, 2) float64, ``shape`` = (nx, ny) cells; return either the per-ray
  visit checksums, (N,) uint64 (the fold :func:`fold_cells` computes), or a sequence of N
  integer arrays of shape (k, 2) holding the visited cells (i, j) in order, which the
  harness folds after the timed call.
* first hit ``fn(heights, origins, directions[, surface=...]) -> t``: ``heights``
  (rows, cols) float32, ``H[j, i]`` in cell units; ``origins``, ``directions`` (N, 3)
  float64; returns (N,) float ray parameters of the first hit, ``inf`` (or NaN) on a
  miss. ``surface`` is passed as a keyword only when the kernel registered more than one.

A kernel that raises, returns a non-zero status (C) or takes longer than its time limit
in one call gets an error in its row; the other kernels' rows are kept. ``hftrace sweep
--isolate`` measures the plugin kernels of each group in a child process, so a crash is
contained too.
"""
from __future__ import annotations

import ctypes
import os
import time
from dataclasses import dataclass

import numpy as np

from . import registry

__all__ = ["register_traversal", "register_intersector", "load_c_plugin", "unregister",
           "load_entry_points", "fold_cells", "is_plugin", "plugin_names", "PluginError",
           "DEFAULT_TIME_LIMIT", "ENTRY_POINT_GROUP", "PLUGIN_ABI"]

#: The entry-point group a package declares its kernels in.
ENTRY_POINT_GROUP = "hftrace.kernels"
#: Seconds one call of a plugin may take before its row reports an error.
DEFAULT_TIME_LIMIT = 60.0
#: ``HFTRACE_PLUGIN_ABI`` of ``cext/hftrace_plugin.h``.
PLUGIN_ABI = 1
_MASK = (1 << 64) - 1


class PluginError(RuntimeError):
    """A plugin kernel failed: a non-zero status, a wrong output shape or a bad library."""


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
        The shared library of a C plugin ("" for Python).
    """

    fn: object
    language: str
    exact: bool
    time_limit: float = DEFAULT_TIME_LIMIT
    path: str = ""


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


def _publish():
    """Refresh the name tuples, in the registry module and in ``algos``."""
    import algos

    registry.TRAVERSALS = algos.TRAVERSALS = tuple(registry.TRAVERSAL_REGISTRY)
    registry.INTERSECTORS = algos.INTERSECTORS = tuple(registry.INTERSECTOR_REGISTRY)


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
    _publish()
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
    _publish()
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
    _publish()


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


# ---- C plugins ----------------------------------------------------------------------------
class _Info(ctypes.Structure):
    _fields_ = [("abi", ctypes.c_int), ("name", ctypes.c_char_p), ("kind", ctypes.c_char_p),
                ("exact", ctypes.c_int), ("surfaces", ctypes.c_char_p),
                ("summary", ctypes.c_char_p)]


def _exported(lib, symbol, kind, path):
    """The function ``symbol`` of a plugin library, or ValueError naming what is missing."""
    try:
        return getattr(lib, symbol)
    except AttributeError:
        raise ValueError(f"path: {path} declares kind {kind} but does not export "
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
        The file does not exist or cannot be loaded, misses a symbol, or declares another
        ABI version or an unknown kind.
    """
    path = os.path.abspath(os.fspath(path))
    if not os.path.isfile(path):
        raise ValueError(f"path: {path} does not exist")
    try:
        lib = ctypes.CDLL(path)
    except OSError as exc:
        raise ValueError(f"path: cannot load {path} ({exc})") from None
    try:
        info_fn = lib.hftrace_plugin
    except AttributeError:
        raise ValueError(f"path: {path} does not export hftrace_plugin() "
                         "(cext/hftrace_plugin.h)") from None
    info_fn.restype = ctypes.POINTER(_Info)
    info = info_fn().contents
    if info.abi != PLUGIN_ABI:
        raise ValueError(f"path: {path} declares plugin ABI {info.abi}; this hftrace "
                         f"reads ABI {PLUGIN_ABI}")
    kind = (info.kind or b"").decode()
    name = name or (info.name or b"").decode()
    summary = (info.summary or b"").decode() or f"C plugin {os.path.basename(path)}"
    limit = _check_limit(time_limit)
    if kind == "traversal":
        fn = _exported(lib, "hftrace_traverse", kind, path)
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_int64, ctypes.c_int64, ctypes.c_int64] + [ctypes.c_void_p] * 6
        plugin = Plugin(fn, "c", bool(info.exact), limit, path)
        return register_traversal(name, fn, plugin.exact, summary, _plugin=plugin)
    if kind == "first_hit":
        fn = _exported(lib, "hftrace_first_hit", kind, path)
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_void_p, ctypes.c_int64, ctypes.c_int64, ctypes.c_int,
                       ctypes.c_int64] + [ctypes.c_void_p] * 6
        surfaces = [s.strip() for s in (info.surfaces or b"triangles").decode().split(",") if s.strip()]
        plugin = Plugin(fn, "c", bool(info.exact), limit, path)
        return register_intersector(name, fn, plugin.exact, surfaces, summary, _plugin=plugin)
    raise ValueError(f"path: {path} declares kind {kind!r}; expected 'traversal' or 'first_hit'")


def load_plugin_spec(spec):
    """Register what ``spec`` names: a C plugin's path (``*.so``, ``*.dylib``, ``*.dll``)
    or ``module:callable`` (a Python function registering kernels). Returns the names
    registered. ``ValueError`` names the spec when it cannot be loaded."""
    before = set(plugin_names())
    if os.fspath(spec).endswith((".so", ".dylib", ".dll")):
        load_c_plugin(spec)
    else:
        module, sep, attr = str(spec).partition(":")
        if not sep or not module or not attr:
            raise ValueError(f"--plugin: expected a library path or module:callable, got {spec!r}")
        import importlib

        try:
            target = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise ValueError(f"--plugin {spec}: cannot import ({exc})") from None
        target()
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
                warn(f"hftrace: plugin entry point {point.name!r} ({point.value}) failed: "
                     f"{type(exc).__name__}: {exc}")
    return sorted(set(plugin_names()) - before)
