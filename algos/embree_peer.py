"""Embree (through ``embreex``) on the same triangles: ground truth and the peer to beat.

Cell (i, j) becomes the triangles (i,j)(i+1,j)(i+1,j+1) and (i,j)(i+1,j+1)(i,j+1) with
vertex (i, j, H[j, i]) (CONVENTIONS.md), so primitive ``2 (j nx + i) + k`` is triangle
k of cell (i, j). Embree computes in float32. Its scene is built once per Field; the
build time and the process's resident-memory growth during the build (Embree does not
report its own bytes through embreex) are recorded in ``field.build_stats["embree"]``.
Rays are traced one at a time by embreex's loop, i.e. on one thread.
"""
from __future__ import annotations

import time

import numpy as np

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


def embree_scene(field):
    """The Embree scene of a Field, built on first use and kept on the Field."""
    def build():
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        vertices, indices = triangles(field.heights)
        before = _rss_bytes()
        start = time.perf_counter()
        scene = rtcs.EmbreeScene()
        mesh = TriangleMesh(scene, vertices, indices)
        scene.run(np.zeros((1, 3), np.float32), np.array([[0, 0, -1]], np.float32))  # commit
        seconds = time.perf_counter() - start
        grown = max(_rss_bytes() - before, 0)
        return scene, mesh, seconds, grown

    if "embree" not in field._cache:
        scene, mesh, seconds, grown = build()
        field._cache["embree"] = (scene, mesh)
        field.build_stats["embree"] = {"seconds": seconds, "bytes": int(grown),
                                       "bytes_note": "resident-memory growth during the build"}
    return field._cache["embree"][0]


def embree_hits(field, origins, directions, tmin, tmax):
    """(t, cell, normal, elapsed_ns) of the first hits; misses have t = inf."""
    scene = embree_scene(field)
    n = len(origins)
    lo = np.zeros(n) if tmin is None else tmin
    start_points = origins + lo[:, None] * directions
    o32 = np.ascontiguousarray(start_points, dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    start = time.perf_counter_ns()
    result = scene.run(o32, d32, output=1)
    elapsed = time.perf_counter_ns() - start
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
