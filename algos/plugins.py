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
  surface there, or the box side's where the ray enters the field below the surface
  (``triangles`` and ``bilinear`` only: ``flat`` and ``plane3`` have walls, whose hits
  the returned ``t`` alone cannot tell from a top); ``stats`` and a ray range are
  refused.
* A Python kernel's input arrays are read-only views of the caller's field and rays,
  which other kernels reuse: writing into them raises (work on a copy).
* C: the kernels of ``cext/hftrace_plugin.h``; a traversal library that also exports
  ``hftrace_traverse_cells`` serves ``algos.traverse``, one without it only sweeps. A
  first-hit library serves ``algos.intersect`` with ``tmin``/``tmax`` and its own hit
  cells; normals as for Python kernels.

Calling a registered kernel (the public calls, the timed calls, the checks of what it
returns) lives in :mod:`algos.plugin_calls`; this module registers and loads.

A kernel that raises, returns a non-zero status (C) or takes longer than its time limit
in one call gets an error in its row; the other kernels' rows are kept. ``hftrace sweep
--isolate`` measures the plugin kernels of each group in a child process, so a crash is
contained too.
"""
from __future__ import annotations

import contextlib
import ctypes
import hashlib
import importlib
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass

from . import registry
from .plugin_calls import (
    PluginError,
    _one_line,
    first_hits,
    fold_cells,
    prepare_timed_first_hit,
    prepare_timed_traversal,
    surface_normals,
    traversal_cells,
)

__all__ = ["register_traversal", "register_intersector", "load_c_plugin", "unregister",
           "load_entry_points", "load_plugin_spec", "fold_cells", "is_plugin", "plugin_names",
           "traversal_cells", "first_hits", "surface_normals", "PluginError",
           "prepare_timed_traversal", "prepare_timed_first_hit", "DEFAULT_TIME_LIMIT",
           "ENTRY_POINT_GROUP", "PLUGIN_ABI", "plugin_fingerprint"]

#: The entry-point group a package declares its kernels in.
ENTRY_POINT_GROUP = "hftrace.kernels"
#: Seconds one call of a plugin may take before its row reports an error.
DEFAULT_TIME_LIMIT = 60.0
#: ``HFTRACE_PLUGIN_ABI`` of ``cext/hftrace_plugin.h``.
PLUGIN_ABI = 1


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


def _check_name(name):
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"name: expected an identifier (letters, digits, _), got {name!r}")
    builtin = (name in registry.TRAVERSAL_REGISTRY and
               registry.TRAVERSAL_REGISTRY[name].plugin is None) or \
              (name in registry.INTERSECTOR_REGISTRY and
               registry.INTERSECTOR_REGISTRY[name].plugin is None)
    if builtin:
        raise ValueError(f"name: {name!r} is a built-in kernel; choose another name")


def _check_exact(exact) -> bool:
    """``exact`` as a bool; a value that is not True or False (1 or 0) is refused: a
    string such as ``"false"`` would otherwise claim exactness."""
    if isinstance(exact, bool) or (hasattr(exact, "dtype") and getattr(exact, "ndim", 1) == 0
                                   and exact.dtype == bool):
        return bool(exact)
    if isinstance(exact, int) and exact in (0, 1):
        return bool(exact)
    raise TypeError(f"exact: expected True or False, got {exact!r}")


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
        A bad or built-in name, a bad time limit. ``TypeError``: ``fn`` not callable,
        ``exact`` not True or False.
    """
    _check_name(name)
    if not callable(fn):
        raise TypeError(f"fn: expected a callable, got {type(fn).__name__}")
    exact = _check_exact(exact)
    plugin = _plugin or Plugin(fn, "python", exact, _check_limit(time_limit))
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
        ``fn`` not callable, ``exact`` not True or False, ``surfaces`` not a sequence.
    """
    _check_name(name)
    if not callable(fn):
        raise TypeError(f"fn: expected a callable, got {type(fn).__name__}")
    exact = _check_exact(exact)
    try:
        surfaces = (surfaces,) if isinstance(surfaces, str) else tuple(surfaces)
    except TypeError:
        raise TypeError(f"surfaces: expected a sequence of surface names "
                        f"({', '.join(registry.SURFACES)}), got {surfaces!r}") from None
    for k, s in enumerate(surfaces):
        if s not in registry.SURFACES:
            raise ValueError(f"surfaces[{k}]: unknown surface {s!r}; valid: "
                             f"{', '.join(registry.SURFACES)}")
    if not surfaces:
        raise ValueError("surfaces: expected at least one surface")
    plugin = _plugin or Plugin(fn, "python", exact, _check_limit(time_limit))
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


def plugin_fingerprint(name) -> str | None:
    """What identifies the code of registered plugin ``name`` (None for a built-in
    kernel or an unknown name): a C plugin's library by the SHA-256 of its bytes (the name
    of its private copy), a Python kernel by the SHA-256 of its function's source file
    with the function's qualified name, or its module and name when the source cannot be
    read. A sweep records it (``env.json``), and ``--resume`` refuses rows measured with
    another build or edit of the plugin."""
    entry = registry.INTERSECTOR_REGISTRY.get(name) or registry.TRAVERSAL_REGISTRY.get(name)
    plugin = getattr(entry, "plugin", None)
    if plugin is None:
        return None
    if plugin.language == "c":
        return f"c:{os.path.basename(plugin.loaded_from or plugin.path)}"
    fn = plugin.fn
    where = f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', repr(fn))}"
    try:
        import inspect

        source = inspect.getsourcefile(fn)
        with open(source, "rb") as f:
            digest = hashlib.sha256(f.read()).hexdigest()[:20]
    except (TypeError, OSError):
        return f"python:{where}"
    return f"python:{where}:{digest}"


def plugin_names() -> list:
    """Every registered plugin name, traversals first."""
    names = [n for n, e in registry.TRAVERSAL_REGISTRY.items() if e.plugin is not None]
    return names + [n for n, e in registry.INTERSECTOR_REGISTRY.items()
                    if e.plugin is not None and n not in names]


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
        with _naming_library(path):
            return register_traversal(name, fn, plugin.exact, summary, _plugin=plugin)
    if kind == "first_hit":
        fn = _exported(lib, "hftrace_first_hit", kind, path)
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_void_p, ctypes.c_int64, ctypes.c_int64, ctypes.c_int,
                       ctypes.c_int64] + [ctypes.c_void_p] * 6
        surfaces = [s.strip() for s in (info.surfaces or b"triangles").decode().split(",")
                    if s.strip()]
        plugin = Plugin(fn, "c", bool(info.exact), limit, path, private)
        with _naming_library(path):
            return register_intersector(name, fn, plugin.exact, surfaces, summary,
                                        _plugin=plugin)
    raise PluginError(f"C plugin {path}: declares kind {kind!r}; expected 'traversal' or "
                      "'first_hit'")


@contextlib.contextmanager
def _naming_library(path):
    """Turn a refused registration (a built-in name, an unknown surface in the library's
    info) into one PluginError line that names the library, as every other load failure."""
    try:
        yield
    except ValueError as exc:
        raise PluginError(f"C plugin {path}: its hftrace_plugin_info is refused: "
                          f"{_one_line(exc)}") from None


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


def _package_root(base, module):
    """The folder from which ``module`` imports when ``base`` (a config's folder) lies
    inside the package it names: ``examples.plugins.numpy_dda`` named by a config in
    ``/repo/examples`` imports from ``/repo``, whatever the current directory. None when
    ``base`` is not such a folder."""
    if not base:
        return None
    folder = os.path.abspath(base)
    parts = module.split(".")[:-1]
    for k in range(len(parts), 0, -1):
        tail = folder.split(os.sep)[-k:]
        if tail == parts[:k]:
            root = folder
            for _ in range(k):
                root = os.path.dirname(root)
            return root
    return None


def load_plugin_spec(spec, base=None):
    """Register what ``spec`` names: a C plugin's path (``*.so``, ``*.dylib``, ``*.dll``),
    relative to ``base`` (default the current directory), or ``module:callable`` (a
    function registering kernels), the module looked up in ``base``, then (when ``base``
    lies inside the package the module names) that package's parent folder, then the
    current directory, then ``sys.path``. Returns the names registered.

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
        target = _import_callable(text, [b for b in (base, _package_root(base, module),
                                                     os.getcwd()) if b])
        try:
            target()
        except Exception as exc:
            raise PluginError(f"plugin {spec}: {attr}() raised {type(exc).__name__}: "
                              f"{_one_line(exc)}") from None
    return sorted(set(plugin_names()) - before)


#: Whether the entry points were loaded in this process (by the command line at
#: start-up, or by the first lookup of an unregistered name)
_ENTRY_POINTS = {"loaded": False}


def _load_entry_points_on_miss():
    """The registry's miss hook: an unregistered name may belong to an installed package's
    entry point, which ``import algos`` alone has not loaded; load them all, once. A
    failing one is a ``RuntimeWarning`` (one line), as the command line prints it."""
    if _ENTRY_POINTS["loaded"]:
        return
    import warnings

    load_entry_points(warn=lambda text: warnings.warn(text, RuntimeWarning, stacklevel=2))


registry.MISS_HOOKS.append(_load_entry_points_on_miss)


def load_entry_points(warn=None) -> list:
    """Register every kernel of the ``hftrace.kernels`` entry points; returns the names.
    A failing entry point is reported through ``warn`` (one line) and skipped. From
    Python this runs by itself on the first lookup of a name no kernel is registered
    under (``algos.intersect("theirs", ...)``)."""
    from importlib.metadata import entry_points

    _ENTRY_POINTS["loaded"] = True
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
