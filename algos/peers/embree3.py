"""The optional C peer against the system Embree 3: grids, triangles, single rays and packets.

embreex (``algos.peers.embree``) reaches Embree's single-ray triangle queries only. This
peer reaches the rest of Embree 3's API for the same height field through a small C file
(``cext/peers/embree3_peer.c``, built by setup.py as ``algos._embree3`` only where
``embree3/rtcore.h`` is found: Debian's ``libembree-dev``, Embree 3.13) loaded with
ctypes, which releases the GIL around each call:

- ``geometry="grid"``: Embree's grid geometry (``RTC_GEOMETRY_TYPE_GRID``), one grid of
  rows x cols vertices (at most 32767 per side). Embree splits a grid quad on the other
  diagonal than docs/CONVENTIONS.md (its triangles are v0 v1 v3 and v2 v3 v1, the
  diagonal u + v = 1), so the grid is laid out mirrored in x, which puts Embree's diagonal
  on the conventions' u = v: the surface is the ``triangles`` surface (shown by
  ``tests/first_hits/test_embree_c.py``; ``geometry="grid_native"`` keeps Embree's order, the other
  surface, for that test only).
- ``geometry="triangles"``: the triangles of ``algos.peers.embree.triangles``.
- ``packet``: 1 (``rtcIntersect1``) or 4, 8, 16 (``rtcIntersect4/8/16``) where the CPU
  runs that width natively (:func:`native_widths`); ``coherent`` sets Embree's
  ``RTC_INTERSECT_CONTEXT_FLAG_COHERENT`` (camera and parallel batches).

Embree's fastest configuration, as its documentation gives it: no robust mode
(``RTC_SCENE_FLAG_NONE``), ``RTC_BUILD_QUALITY_HIGH`` for scene and geometry (the
highest-quality BVH, spatial splits for triangles; the slowest build), every ray's far
bound passed as its ``tfar`` (``algos.peers.embree.far_bounds``) and float32 rays prepared
outside the timed call, as for embreex. Embree computes in float32. The build time and
Embree's own bytes (its memory monitor callback) are in ``field.build_stats``.
"""
from __future__ import annotations

import ctypes
import importlib.util
import time

import numpy as np

from ..parallel import run_ranges
from .embree import far_bounds

__all__ = ["available", "unavailable_reason", "native_widths", "embree3_scene", "embree3_hits",
           "embree3_timed", "GEOMETRIES", "PACKET_WIDTHS"]

#: Geometry names and their codes in cext/peers/embree3_peer.c (enum hfe3_geometry).
GEOMETRIES = {"triangles": 0, "grid": 1, "grid_native": 2}
#: Packet widths: 1 is rtcIntersect1, the others rtcIntersect4/8/16.
PACKET_WIDTHS = (1, 4, 8, 16)
#: RTC_SCENE_FLAG_NONE (no robust mode) and RTC_BUILD_QUALITY_HIGH: the fastest traversal.
SCENE_FLAGS, BUILD_QUALITY = 0, 2
#: The largest grid side Embree accepts (RTCGrid's width and height).
MAX_GRID_SIDE = 32767

_STATUS = {-1: "Embree reported an error", -2: "the packet width is not 1, 4, 8 or 16",
           -3: "this CPU does not run that packet width natively", -4: "a size is out of range"}
_LIB: dict = {}


def _library():
    """The ctypes library of algos._embree3, or raises ImportError saying why not."""
    if "lib" in _LIB:
        return _LIB["lib"]
    if "error" in _LIB:
        raise ImportError(_LIB["error"])
    spec = importlib.util.find_spec("algos._embree3")
    if spec is None or spec.origin is None:
        _LIB["error"] = ("the C Embree 3 peer is not built: install Embree 3's headers "
                         "(apt-get install libembree-dev) and reinstall hftrace")
        raise ImportError(_LIB["error"])
    try:
        lib = ctypes.CDLL(spec.origin)
    except OSError as exc:
        _LIB["error"] = f"the C Embree 3 peer does not load: {exc}"
        raise ImportError(_LIB["error"]) from None
    ptr = ctypes.c_void_p
    lib.hfe3_new.restype = ptr
    lib.hfe3_new.argtypes = [ctypes.c_char_p, ptr, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                             ctypes.c_int, ctypes.c_int, ctypes.POINTER(ctypes.c_int)]
    lib.hfe3_free.argtypes = [ptr]
    lib.hfe3_bytes.restype = ctypes.c_int64
    lib.hfe3_bytes.argtypes = [ptr]
    lib.hfe3_native.argtypes = [ptr, ctypes.c_int]
    lib.hfe3_trace.restype = ctypes.c_int64
    lib.hfe3_trace.argtypes = [ptr, ptr, ptr, ptr, ctypes.c_int64, ctypes.c_int, ctypes.c_int,
                               ptr, ptr, ptr]
    _LIB["lib"] = lib
    return lib


def available() -> bool:
    """True when the C Embree 3 peer is built and loads."""
    try:
        _library()
        return True
    except ImportError:
        return False


def unavailable_reason() -> str:
    """Why the peer is unavailable ("" when it is available)."""
    try:
        _library()
        return ""
    except ImportError as exc:
        return str(exc)


class Embree3Scene:
    """A committed Embree 3 scene of a height field (cell units), freed with the object."""

    def __init__(self, heights, geometry="grid", config=None):
        if geometry not in GEOMETRIES:
            raise ValueError(f"geometry: expected one of {', '.join(GEOMETRIES)}, got {geometry!r}")
        h = np.ascontiguousarray(heights, dtype=np.float64)
        rows, cols = h.shape
        if geometry != "triangles" and max(rows, cols) > MAX_GRID_SIDE:
            raise ValueError(f"heights: Embree's grid geometry takes at most {MAX_GRID_SIDE} "
                             f"vertices per side, got shape {h.shape}")
        self._lib = _library()
        self.geometry, self.shape = geometry, h.shape
        status = ctypes.c_int(0)
        start = time.perf_counter()
        self._handle = self._lib.hfe3_new(None if config is None else config.encode(),
                                          h.ctypes.data, rows, cols, GEOMETRIES[geometry],
                                          SCENE_FLAGS, BUILD_QUALITY, ctypes.byref(status))
        self.build_seconds = time.perf_counter() - start
        if not self._handle:
            raise RuntimeError(f"embree3: building the {geometry} scene of shape {h.shape} "
                               f"failed: {_STATUS.get(status.value, status.value)}")
        self.bytes = int(self._lib.hfe3_bytes(self._handle))

    def native(self, width: int) -> bool:
        """True when this CPU runs packets of ``width`` natively (1 always)."""
        return bool(self._lib.hfe3_native(self._handle, int(width)))

    def trace(self, o32, d32, tfar, width=1, coherent=False, t_out=None, cell_out=None,
              normal_out=None) -> int:
        """Trace float32 rays (n, 3) with far bounds ``tfar`` (n,) into ``t_out`` (n,
        float32, inf on a miss) and, when given, ``cell_out`` (n, 2 int32) and
        ``normal_out`` (n, 3 float32, Embree's unnormalised geometry normals); the
        elapsed ns of the C loop. Trusts its arrays (C-contiguous, right dtypes and
        lengths)."""
        n = len(o32)
        code = self._lib.hfe3_trace(self._handle, o32.ctypes.data, d32.ctypes.data,
                                    tfar.ctypes.data, n, int(width), int(bool(coherent)),
                                    t_out.ctypes.data,
                                    None if cell_out is None else cell_out.ctypes.data,
                                    None if normal_out is None else normal_out.ctypes.data)
        if code < 0:
            raise RuntimeError(f"embree3: tracing with packet = {width} failed: "
                               f"{_STATUS.get(code, code)}")
        return int(code)

    def __del__(self):
        handle, self._handle = getattr(self, "_handle", None), None
        if handle:
            self._lib.hfe3_free(handle)


def native_widths() -> tuple:
    """The packet widths this CPU runs natively with the installed Embree 3 ((1,) at
    least); () when the peer is unavailable."""
    if not available():
        return ()
    probe = Embree3Scene(np.zeros((2, 2)), "triangles")
    return tuple(w for w in PACKET_WIDTHS if probe.native(w))


def _check(geometry, packet, coherent):
    if geometry not in GEOMETRIES:
        raise ValueError(f"geometry: expected one of {', '.join(GEOMETRIES)}, got {geometry!r}")
    if isinstance(packet, bool) or packet not in PACKET_WIDTHS:
        raise ValueError(f"packet: expected one of {PACKET_WIDTHS}, got {packet!r}")
    if not isinstance(coherent, (bool, np.bool_)):
        raise TypeError(f"coherent: expected True or False, got {coherent!r}")


def embree3_scene(field, geometry="grid") -> Embree3Scene:
    """The Embree 3 scene of a Field's cell heights, built on first use and kept on the
    Field (``field.build_stats["embree3-" + geometry]``: seconds and Embree's bytes)."""
    key = f"embree3-{geometry}"
    if field.stored(key) is None:
        scene = Embree3Scene(field.cell_heights, geometry)
        field.store(key, scene, {"seconds": scene.build_seconds, "bytes": scene.bytes,
                                 "bytes_note": "Embree's own allocations (memory monitor)"})
    return field.stored(key)


def _native_or_raise(scene, packet):
    if not scene.native(packet):
        raise ValueError(f"packet: this CPU does not run {packet}-wide Embree packets "
                         f"natively; native widths: {native_widths()}")


def embree3_hits(field, origins, directions, tmin, tmax, geometry="grid", packet=1,
                 coherent=False, threads=1):
    """(t, cell, normal, elapsed_ns) of the first hits on the ``triangles`` surface, in
    float32; t = inf, cell = (-1, -1) and normal = NaN on a miss (normals: unit, facing
    up). Rays (N, 3) float64 start at ``tmin`` (None:
    0) and hits beyond ``tmax`` (None: inf) are misses. ``threads`` > 1 splits the rays
    over Python threads sharing the committed scene."""
    _check(geometry, packet, coherent)
    scene = embree3_scene(field, geometry)
    _native_or_raise(scene, packet)
    n = len(origins)
    lo = np.zeros(n) if tmin is None else np.broadcast_to(tmin, (n,))
    start_points = origins + lo[:, None] * directions
    o32 = np.ascontiguousarray(start_points, dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    far = far_bounds(field, start_points, directions)
    t32 = np.empty(n, np.float32)
    cell = np.empty((n, 2), np.int32)
    ng = np.empty((n, 3), np.float32)
    start = time.perf_counter_ns()
    run_ranges(n, threads, lambda a, b: scene.trace(o32[a:b], d32[a:b], far[a:b], packet,
                                                    coherent, t32[a:b], cell[a:b], ng[a:b]))
    elapsed = time.perf_counter_ns() - start
    t = t32.astype(np.float64) + lo
    hit = np.isfinite(t)
    if tmax is not None:
        hit &= t <= tmax
    t[~hit] = np.inf
    cell[~hit] = -1
    normal = ng.astype(np.float64)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(length > 0, normal / np.where(length > 0, length, 1), np.nan)
    normal *= np.where(normal[:, 2:3] < 0, -1.0, 1.0)  # the side that faces up
    normal[~hit] = np.nan
    return t, cell, normal, elapsed


def embree3_timed(field, origins, directions, geometry="grid", packet=1, coherent=False,
                  threads=1):
    """(run, t) for benchmarks, as ``algos.peers.embree.embree_timed``: each ``run()``
    traces every ray once and returns the elapsed ns of the C loop (with ``threads`` > 1,
    the pool's wall time); ``t()`` gives the latest first-hit parameters (inf on a miss).
    The scene, the float32 rays and the far bounds are made before, untimed."""
    _check(geometry, packet, coherent)
    scene = embree3_scene(field, geometry)
    _native_or_raise(scene, packet)
    o32 = np.ascontiguousarray(origins, dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    far = far_bounds(field, origins, directions)
    t32 = np.empty(len(o32), np.float32)
    scene.trace(o32[:1], d32[:1], far[:1], 1, coherent, t32[:1])  # warm, untimed

    def part(a, b):
        scene.trace(o32[a:b], d32[a:b], far[a:b], packet, coherent, t32[a:b])

    def run():
        if threads == 1:
            return scene.trace(o32, d32, far, packet, coherent, t32)
        start = time.perf_counter_ns()
        run_ranges(len(o32), threads, part)
        return time.perf_counter_ns() - start

    def t():
        return t32.astype(np.float64)

    return run, t
