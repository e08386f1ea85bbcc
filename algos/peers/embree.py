"""Embree (through ``embreex``) on the same triangles: ground truth and the peer to beat.

Cell (i, j) becomes the triangles (i,j)(i+1,j)(i+1,j+1) and (i,j)(i+1,j+1)(i,j+1) with
vertex (i, j, H[j, i]) (docs/CONVENTIONS.md), so primitive ``2 (j nx + i) + k`` is triangle
k of cell (i, j). Embree computes in float32. Its scene is built once per Field; the
build time and the process's resident-memory growth during the build (Embree does not
report its own bytes through embreex) are recorded in ``field.build_stats["embree"]``.
Rays are traced one at a time by embreex's loop; embreex releases the GIL there, so
``threads`` > 1 splits the rays into ranges traced by Python threads sharing the one
committed scene (as Embree users run it on every core).

Two ways in: :func:`embree_hits` (t, cell and normal: embreex's ``output=1`` query,
which allocates five arrays) serves ``algos.intersect`` and the tests, where Embree's
robust mode is ground truth; :func:`embree_timed` is the peer in benchmarks, in its
fastest configuration documented by embreex: a ``DISTANCE`` query (tfar only) into a
preallocated float32 buffer, each ray's far bound passed as its ``tfar`` (where it leaves
the field's box, or reaches the lowest height, after which a hit is certain), and every
allocation and conversion outside the timed call.
"""
from __future__ import annotations

import time

import numpy as np

from ..parallel import run_ranges

__all__ = ["triangles", "embree_scene", "embree_hits"]


def _rss_bytes() -> int:
    try:
        with open("/proc/self/statm") as f:
            import os

            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError):
        return 0


def triangles(heights: np.ndarray):
    """Vertices (rows*cols, 3) float32 and triangle indices (2*nx*ny, 3) int32."""
    rows, cols = heights.shape
    jj, ii = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    vertices = np.stack([ii.ravel(), jj.ravel(), heights.ravel()], axis=1).astype(np.float32)
    ci, cj = np.meshgrid(np.arange(cols - 1), np.arange(rows - 1))
    v00 = (cj * cols + ci).ravel()
    v10, v01, v11 = v00 + 1, v00 + cols, v00 + cols + 1
    tri = np.empty((len(v00), 2, 3), dtype=np.int32)
    tri[:, 0] = np.stack([v00, v10, v11], axis=1)
    tri[:, 1] = np.stack([v00, v11, v01], axis=1)
    return vertices, tri.reshape(-1, 3)


#: The scene flag the peer uses: RTC_SCENE_FLAG_ROBUST off (Embree's fast default). The
#: tests also build a robust scene for ground truth (``embree_scene(field, robust=True)``).
ROBUST = False


def embree_version() -> str:
    """The version of the Embree library embreex loaded (e.g. "4.4.0"), or ""."""
    import ctypes
    import glob
    import os

    import embreex

    root = os.path.dirname(os.path.dirname(embreex.__file__))
    libs = sorted(glob.glob(os.path.join(root, "embreex.libs", "libembree*.so*")))
    try:
        lib = ctypes.CDLL(libs[0]) if libs else ctypes.CDLL("libembree4.so.4")
        lib.rtcNewDevice.restype = ctypes.c_void_p
        lib.rtcNewDevice.argtypes = [ctypes.c_char_p]
        lib.rtcGetDeviceProperty.restype = ctypes.c_ssize_t
        lib.rtcGetDeviceProperty.argtypes = [ctypes.c_void_p, ctypes.c_int]
        lib.rtcReleaseDevice.argtypes = [ctypes.c_void_p]
        device = lib.rtcNewDevice(None)
        version = lib.rtcGetDeviceProperty(device, 0)  # RTC_DEVICE_PROPERTY_VERSION
        lib.rtcReleaseDevice(device)
        return f"{version // 10000}.{version // 100 % 100}.{version % 100}"
    except (OSError, AttributeError, IndexError):
        return ""


def embree_scene(field, robust=ROBUST):
    """The Embree scene of a Field, built on first use and kept on the Field."""
    key = "embree-robust" if robust else "embree"

    def build():
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        vertices, indices = triangles(field.cell_heights)
        before = _rss_bytes()
        start = time.perf_counter()
        scene = rtcs.EmbreeScene(robust=robust)
        mesh = TriangleMesh(scene, vertices, indices)
        scene.run(np.zeros((1, 3), np.float32), np.array([[0, 0, -1]], np.float32))  # commit
        seconds = time.perf_counter() - start
        grown = max(_rss_bytes() - before, 0)
        return scene, mesh, seconds, grown

    if field.stored(key) is None:
        scene, mesh, seconds, grown = build()
        field.store(key, (scene, mesh), {"seconds": seconds, "bytes": int(grown),
                                         "robust": robust,
                                         "bytes_note": "resident-memory growth during the build"})
    return field.stored(key)[0]


def far_bounds(field, origins, directions):
    """Per ray, the parameter after which no first hit can lie: where the ray leaves the
    box [0, cols-1] x [0, rows-1] x (-inf, hmax], or reaches the lowest height going
    down (from there on it is inside the solid). Widened by a hair for float32."""
    o, d = np.asarray(origins, float), np.asarray(directions, float)
    rows, cols = field.shape
    hmin, hmax = field.hmin, field.hmax
    far = np.full(len(o), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k, top in ((0, cols - 1.0), (1, rows - 1.0)):
            exit_ = np.where(d[:, k] > 0, (top - o[:, k]) / d[:, k],
                             np.where(d[:, k] < 0, -o[:, k] / d[:, k], np.inf))
            far = np.minimum(far, exit_)
        far = np.minimum(far, np.where(d[:, 2] < 0, (hmin - o[:, 2]) / d[:, 2],
                                       np.where(d[:, 2] > 0, (hmax - o[:, 2]) / d[:, 2], np.inf)))
    far = np.where(np.isfinite(far), np.maximum(far, 0) * (1 + 1e-5) + 1e-4, 1e37)
    return far.astype(np.float32)


def embree_timed(field, origins, directions, threads=1):
    """(run, t) for benchmarks: each ``run()`` traces every ray once with the fastest
    query and returns the elapsed ns of embreex's loop alone (with ``threads`` > 1, the
    wall time of a thread pool over ray ranges sharing the committed scene; embreex
    releases the GIL in its loop); ``t()`` gives the latest first-hit parameters (inf on
    a miss)."""
    scene = embree_scene(field)
    o32 = np.ascontiguousarray(origins, dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    far = far_bounds(field, origins, directions)
    tfar = np.empty_like(far)
    scene.run(o32[:1], d32[:1], dists=tfar[:1].copy(), query="DISTANCE")  # warm, untimed

    def part(a, b):
        scene.run(o32[a:b], d32[a:b], dists=tfar[a:b], query="DISTANCE")

    def run():
        np.copyto(tfar, far)
        start = time.perf_counter_ns()
        run_ranges(len(o32), threads, part)
        return time.perf_counter_ns() - start

    def t():
        out = tfar.astype(np.float64)
        return np.where(tfar < far, out, np.inf)

    return run, t


def embree_hits(field, origins, directions, tmin, tmax, threads=1):
    """(t, cell, normal, elapsed_ns) of the first hits in Embree's robust mode (ground
    truth: ``algos.intersect("embree", ...)`` and the tests); misses have t = inf."""
    scene = embree_scene(field, robust=True)
    n = len(origins)
    lo = np.zeros(n) if tmin is None else tmin
    start_points = origins + lo[:, None] * directions
    o32 = np.ascontiguousarray(start_points, dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    start = time.perf_counter_ns()
    parts = run_ranges(n, threads, lambda a, b: scene.run(o32[a:b], d32[a:b], output=1))
    elapsed = time.perf_counter_ns() - start
    result = {k: np.concatenate([p[k] for p in parts]) for k in ("primID", "tfar", "Ng")}
    prim = result["primID"].astype(np.int64)
    t = result["tfar"].astype(np.float64) + lo
    hit = prim >= 0
    if tmax is not None:
        hit &= t <= tmax
    t = np.where(hit, t, np.inf)
    nx = field.cols - 1
    cell_index = np.where(hit, prim // 2, -1)
    cell = np.stack([np.where(hit, cell_index % nx, -1), np.where(hit, cell_index // nx, -1)],
                    axis=1).astype(np.int32)
    normal = result["Ng"].astype(np.float64)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(length > 0, normal / np.where(length > 0, length, 1), np.nan)
    normal *= np.where(normal[:, 2:3] < 0, -1.0, 1.0)  # the side that faces up
    normal[~hit] = np.nan
    return t, cell, normal, elapsed


class EmbreeHorizon:
    """HORAYZON-style horizons (Steger et al. 2022, GMD): Embree occlusion rays from each
    vertex, with a bisection over the elevation angle until the bracket is narrower than
    ``tolerance`` radians. The scene holds the same two triangles per cell, in float32.
    Every ray starts ``offset`` cells above its vertex, as HORAYZON's ``ray_org_elev``
    (0.1 m there) does, so that the vertex's own triangles do not occlude it; this biases
    the angle to the nearest breakpoints by about offset / distance."""

    def __init__(self, heights, offset=1e-3):
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        self.heights = np.asarray(heights, dtype=np.float64)
        vertices, indices = triangles(self.heights)
        self.scene = rtcs.EmbreeScene()
        self._mesh = TriangleMesh(self.scene, vertices, indices)
        self.offset = float(offset)

    def tangents(self, dx, dy, max_distance=np.inf, tolerance=1e-4, vertices=None, threads=1):
        """Horizon tangents along the unit direction (dx, dy) for the vertex indices given
        (C order; default all), -inf where the ray has no point in the footprint."""
        h = self.heights
        rows, cols = h.shape
        idx = np.arange(h.size) if vertices is None else np.asarray(vertices, dtype=np.int64)
        j, i = np.divmod(idx, cols)
        with np.errstate(divide="ignore", invalid="ignore"):
            ex = np.where(dx > 0, (cols - 1 - i) / dx, np.where(dx < 0, -i / dx if dx else 0, np.inf))
            ey = np.where(dy > 0, (rows - 1 - j) / dy, np.where(dy < 0, -j / dy if dy else 0, np.inf))
        reach = np.minimum(np.minimum(ex, ey), max_distance)
        lo = np.full(len(idx), -np.pi / 2)
        hi = np.full(len(idx), np.pi / 2)
        z = h.ravel()[idx]
        steps = max(1, int(np.ceil(np.log2(np.pi / tolerance))))
        origin = np.empty((len(idx), 3), np.float32)
        direction = np.empty((len(idx), 3), np.float32)
        for _ in range(steps):
            mid = (lo + hi) / 2
            c, s = np.cos(mid), np.sin(mid)
            direction[:, 0], direction[:, 1], direction[:, 2] = c * dx, c * dy, s
            origin[:, 0], origin[:, 1], origin[:, 2] = i, j, z + self.offset
            # the ray's horizontal reach ends at the footprint edge or max_distance
            far = np.minimum(reach / np.maximum(c, 1e-12), 1e30).astype(np.float32)
            hit = np.concatenate(run_ranges(len(idx), threads, lambda a, b: self.scene.run(
                origin[a:b], direction[a:b], dists=far[a:b], query="OCCLUDED"))) == 0
            lo = np.where(hit, mid, lo)
            hi = np.where(hit, hi, mid)
        out = np.tan((lo + hi) / 2)
        out[reach <= 0] = -np.inf
        return out


_HORIZON_SCENES: dict = {}


def embree_horizon(heights) -> EmbreeHorizon:
    """The EmbreeHorizon of these heights, built once and kept (one field at a time)."""
    h = np.ascontiguousarray(heights, dtype=np.float64)
    import hashlib

    key = (h.shape, hashlib.sha256(h.tobytes()).hexdigest())
    if key not in _HORIZON_SCENES:
        _HORIZON_SCENES.clear()
        _HORIZON_SCENES[key] = EmbreeHorizon(h)
    return _HORIZON_SCENES[key]


def embree_horizon_tangents(heights, dx, dy, max_distance=np.inf, tolerance=1e-4, vertices=None,
                            threads=1):
    """:meth:`EmbreeHorizon.tangents` (the scene is kept between calls on one field);
    shaped (rows, cols) for all vertices."""
    peer = embree_horizon(heights)
    out = peer.tangents(dx, dy, max_distance, tolerance, vertices, threads)
    return out.reshape(np.shape(heights)) if vertices is None else out
