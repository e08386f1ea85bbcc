"""The horizon walks of one direction over every vertex: the rational sweep, the shared
pattern (per vertex and row-vectorised), the chain walk, the cell walks and the
baselines; and the timing entry the benchmarks use."""
from __future__ import annotations

import math
import time

import numpy as np

from .. import _kernels
from ..accel.mipmap import terrain_mipmap
from ..parallel import run_ranges
from .algorithms import _pick_horizon_algorithm
from .directions import Direction, _from_frame, _to_frame, azimuth_direction
from .grid import _prepare, _run_ranges
from .patterns import PATTERN_STOP_EVERY, _pattern_arrays, _period_pattern, _shared_pattern
from .stats import TerrainStats

__all__ = ["chain_neighbours", "chain_strips", "prepare_horizon_timed", "CHAIN_BLOCK_ROWS",
           "CHAIN_MAX_DENOMINATOR", "CHAIN_MAX_NEIGHBOURS", "CHAIN_MAX_OFFSET", "CHAIN_STRIP_WIDTH",
           "CHAIN_STRIP_BIN"]


def _sweep(hf, d: Direction, out, threads=1):
    """The rational sweep over the whole octant-frame field hf into out, its lines split
    over threads (each line writes its own vertices); returns ns (summed over threads)."""
    q, p = d.rational
    T, xa, ya, xb, yb, w = _pattern_arrays(_period_pattern(q, p, d.anti))
    mx, my = np.maximum(xa, xb), np.maximum(ya, yb)
    n_lines = q * (hf.shape[0] - 1) + p * (hf.shape[1] - 1) + 1
    return sum(run_ranges(n_lines, threads, lambda a, b: _kernels.horizon_sweep(
        hf, q, p, T, xa, ya, xb, yb, w, mx, my, math.hypot(q, p), a, b, out)[0],
        chunks_per_thread=4, min_chunk=64))


def _pattern_walk(hf, pat, zmax, start, stop, out, kappa=0.0):
    """The shared-pattern walk of octant-frame vertices [start, stop); returns ns."""
    return _kernels.horizon_pattern(
        hf, pat["inv_t"], pat["xa"], pat["ya"], pat["xb"], pat["yb"], pat["w"],
        pat["limit_x"], pat["limit_y"], pat["end_k"], pat["end_f"], pat["end_inv"], zmax,
        PATTERN_STOP_EVERY, start, stop, out, kappa)[0]


#: Rows per block of the chain walk: a vertex borrows only from neighbours in its own
#: block, so that results do not depend on how blocks are shared among threads.
CHAIN_BLOCK_ROWS = 256
#: Largest denominator of the convergents the chain walk borrows along, and their largest
#: distance (cells) across the ray.
CHAIN_MAX_DENOMINATOR = 1024
CHAIN_MAX_OFFSET = 0.5
#: How many of them the walk borrows from: those of the smallest denominators (nearest
#: along the ray), and besides them a rational direction's own period, on the ray itself.
#: Each costs its bound's evaluation at every vertex, and beyond the first two they add
#: almost nothing: on Jacksboro 2048 at 22.5 and 112.5 degrees, all 9 (q <= 1024) leave
#: 9.95 cells evaluated per vertex, 3 10.06, 2 10.11, 1 11.01; by callgrind on a
#: 1024 x 1024 window at 22.5 degrees the walk takes 5.03, 4.72 and 4.63 G instructions
#: with 9, 3 and 2 (docs/terrain.md).
CHAIN_MAX_NEIGHBOURS = 2


def _rows_pattern(h, d: Direction, max_distance, threads):
    """The shared pattern of ``d`` in the grid's own frame, row by row, vectorised over each
    row's vertices (``hf_horizon_rows``): the octant-frame pattern's offsets mapped back
    to the grid, so no frame copy is made. Bit-identical to the pattern walk. Returns
    (tangents (rows, cols), ns)."""
    rows, cols = h.shape
    fr, fc = (cols, rows) if d.swap else (rows, cols)
    pat = _shared_pattern(d, fr, fc, max_distance)
    mx = np.maximum.accumulate(np.maximum(pat["xa"], pat["xb"])).astype(np.int64)
    my = np.maximum.accumulate(np.maximum(pat["ya"], pat["yb"])).astype(np.int64)
    xa, ya, xb, yb = pat["xa"], pat["ya"], pat["xb"], pat["yb"]
    rx, ry = mx, my
    if d.swap:  # the frame's x is the grid's y
        xa, ya, xb, yb, rx, ry = ya, xa, yb, xb, my, mx
    sx, sy = (-1 if d.sx < 0 else 1), (-1 if d.sy < 0 else 1)
    if pat["end_k"] >= 0:
        n_main = pat["end_k"] + 1
    else:  # no end between breakpoints: as many as any vertex can use (the pattern's limits)
        n_main = int(min(pat["limit_x"][-1], pat["limit_y"][-1]))
    out = np.empty(rows * cols)
    ns = sum(run_ranges(rows, threads, lambda a, b: _kernels.horizon_rows(
        h, pat["inv_t"], np.ascontiguousarray(sx * xa), np.ascontiguousarray(sy * ya),
        np.ascontiguousarray(sx * xb), np.ascontiguousarray(sy * yb), pat["w"], rx, ry, sx, sy,
        n_main, pat["end_k"], pat["end_f"], pat["end_inv"], a, b, out)[0],
        chunks_per_thread=4, min_chunk=8))
    return out.reshape(rows, cols), ns


def _convergents(x: float, max_denominator: int):
    """The continued-fraction convergents p/q of x >= 0 with q <= max_denominator, as
    (q, p) pairs in order of q."""
    out, (p0, q0, p1, q1) = [], (0, 1, 1, 0)
    for _ in range(64):
        a = math.floor(x)
        p0, q0, p1, q1 = p1, q1, a * p1 + p0, a * q1 + q0
        if q1 > max_denominator:
            break
        out.append((q1, p1))
        frac = x - a
        if frac <= 0.0:
            break
        x = 1.0 / frac
    return out


def chain_neighbours(d: Direction, max_denominator=CHAIN_MAX_DENOMINATOR,
                     max_offset=CHAIN_MAX_OFFSET, max_neighbours=CHAIN_MAX_NEIGHBOURS):
    """The offsets (gx, gy) and distances along ``d`` of the vertices the chain walk borrows
    lower bounds from: v + (gx, gy) for the ``max_neighbours`` convergents p/q of the
    octant slope of smallest q (q <= max_denominator) whose line passes within
    ``max_offset`` cells of v's ray (|q b - p a| for the octant direction (a, b)), and the
    direction's own period (q, p) when it is rational (on the ray itself, within
    max_denominator); nearest across first (the period first)."""
    found = []
    for q, p in _convergents(d.b / d.a, max_denominator):
        across = abs(q * d.b - p * d.a)
        if across > max_offset:
            continue
        fx, fy = (p, q) if d.swap else (q, p)
        gx, gy = (-fx if d.sx < 0 else fx), (-fy if d.sy < 0 else fy)
        found.append((across, gx, gy, q * d.a + p * d.b))
    period = [f for f in found[max_neighbours:] if f[0] < 1e-9]  # in order of q
    found = found[:max_neighbours] + period[-1:]
    found.sort()
    return (np.array([f[1] for f in found], dtype=np.int64),
            np.array([f[2] for f in found], dtype=np.int64),
            np.array([f[3] for f in found], dtype=np.float64))


#: The chain walk's strips (cells): their width across the direction, and the length
#: along it of a bin at the finest level (bins of 4 cells: fewer mispredicted branches,
#: no faster; docs/terrain.md).
CHAIN_STRIP_WIDTH = 1.0
CHAIN_STRIP_BIN = 2.0


def chain_strips(h, d: Direction, width=CHAIN_STRIP_WIDTH, bin_length=CHAIN_STRIP_BIN):
    """The strips of direction ``d`` over the heights ``h`` (cell units, (rows, cols)
    float64) that the chain walk skips along: ``(strips, ns)``, where ``strips`` is
    ``(data, offset, n_bins, width, bin_length)`` (``hf_hz_strips`` in
    cext/terrain/horizon_fast.h: strip k holds the lines at c = dx y - dy x in
    [c_min + k width, c_min + (k + 1) width); its bin b at level l, at
    ``data[offset[l] + b * n_strips + k]`` (float32, rounded up), the largest corner height
    of every cell those lines cross at a = dx x + dy y in [a_min + b bin 2^l, a_min + (b + 1) bin 2^l)) and
    ``ns`` the build's C time. ``bin_length`` must be a power of two."""
    rows, cols = h.shape
    _, _, n_strips, n_bins0 = _kernels.horizon_strips_frame(rows, cols, d.dx, d.dy, width,
                                                            bin_length)
    n_bins = [n_bins0]
    while n_bins[-1] > 1:
        n_bins.append((n_bins[-1] + 1) // 2)
    n_bins = np.array(n_bins, dtype=np.int64)
    offset = np.concatenate([[0], np.cumsum(n_strips * n_bins[:-1])]).astype(np.int64)
    data = np.empty(int(offset[-1]) + n_strips, dtype=np.float32)
    strips = (data, offset, n_bins, float(width), float(bin_length))
    ns = _kernels.horizon_strips(h, strips, d.dx, d.dy)
    return strips, ns


def _chain(h, d: Direction, max_distance, threads, stats):
    """The chain walk of every vertex (grid frame): the strips, then ``hf_horizon_chain``.
    Returns the tangents (rows, cols) and adds the walk's counts to ``stats``."""
    rows, cols = h.shape
    nb_x, nb_y, nb_d = chain_neighbours(d)
    strips, ns = chain_strips(h, d)
    stats.ns += ns
    out = np.empty(rows * cols)
    occ = np.full(rows * cols, np.nan)
    md = math.inf if max_distance is None else float(max_distance)
    n_blocks = -(-rows // CHAIN_BLOCK_ROWS)
    for ns, cells, skips, tests, bounded, cell_skips in run_ranges(
            n_blocks, threads, lambda a, b: _kernels.horizon_chain(
                h, strips, d.dx, d.dy, md, nb_x, nb_y, nb_d, CHAIN_BLOCK_ROWS, a, b, out, occ),
            chunks_per_thread=1, min_chunk=1):
        stats.ns += ns
        stats.cells += cells
        stats.skips += skips
        stats.tile_tests += tests
        stats.bounded += bounded
        stats.cell_skips += cell_skips
    return out.reshape(rows, cols)


def _horizon_one(h, d: Direction, algorithm, max_distance, threads, mip, stats, march_step,
                 embree_tolerance, kappa=0.0):
    rows, cols = h.shape
    if algorithm == "chain":
        return _chain(h, d, max_distance, threads, stats)
    if algorithm == "rows":
        out, ns = _rows_pattern(h, d, max_distance, threads)
        stats.ns += ns
        return out
    if algorithm in ("sweep", "pattern"):
        hf = np.ascontiguousarray(_to_frame(h, d))
        fr, fc = hf.shape
        out = np.empty(fr * fc)
        if algorithm == "sweep":
            stats.ns += _sweep(hf, d, out, threads)
        else:
            pat = _shared_pattern(d, fr, fc, max_distance)
            zmax = float(hf.max())
            stats.ns += sum(_run_ranges(fr * fc, threads,
                                        lambda a, b: _pattern_walk(hf, pat, zmax, a, b, out,
                                                                   kappa)))
        return _from_frame(out.reshape(fr, fc), d)
    out = np.empty(rows * cols)
    md = math.inf if max_distance is None else max_distance
    if algorithm in ("dda", "dda_maxmip"):
        def call(start, stop):
            return _kernels.horizon_walk(h, mip if algorithm == "dda_maxmip" else None,
                                         d.dx, d.dy, md, start, stop, out, kappa)
    elif algorithm == "march":
        zmax = float(h.max())

        def call(start, stop):
            return _kernels.horizon_march(h, d.dx, d.dy, march_step, md, zmax, start, stop, out,
                                          kappa)
    elif algorithm == "embree":
        from ..peers.embree import embree_horizon_tangents

        t0 = time.perf_counter_ns()
        out[:] = embree_horizon_tangents(h, d.dx, d.dy, md, tolerance=embree_tolerance,
                                        threads=threads).ravel()
        stats.ns += time.perf_counter_ns() - t0
        return out.reshape(rows, cols)
    else:  # pragma: no cover - checked by the caller
        raise AssertionError(algorithm)
    for ns, cells, skips in _run_ranges(rows * cols, threads, call):
        stats.ns += ns
        stats.cells += cells
        stats.skips += skips
    return out.reshape(rows, cols)


def prepare_horizon_timed(heights, azimuth, algorithm, ranges=None, max_distance=None,
                          march_step=1.0, embree_tolerance=1e-4):
    """Validate and build once; return ``(run, values, n_vertices)``. Each ``run()``
    computes the horizon tangents of one azimuth again, single-threaded, and returns the
    nanoseconds measured around the C loop (around embreex's queries and the bisection for
    the Embree peer). ``values()`` gives the tangents of the latest run, NaN outside the
    vertices computed. ``ranges``: [(start, stop), ...] of C-order vertex indices, a
    sample for the per-vertex methods; the sweep always covers every vertex (it is one
    pass over shared lines; so do ``rows``, one pass per row, and ``chain``, whose
    vertices borrow from each other), and n_vertices says how many were computed."""
    h = _prepare(heights, None).h
    d = azimuth_direction(azimuth)
    name = _pick_horizon_algorithm(algorithm, [d], max_distance)
    rows, cols = h.shape
    n_all = rows * cols
    if name in ("rows", "chain"):
        latest = [np.full((rows, cols), np.nan)]

        def run():
            stats = TerrainStats(name)
            latest[0] = _horizon_one(h, d, name, max_distance, 1, None, stats, march_step,
                                     embree_tolerance)
            return stats.ns
        return run, (lambda: latest[0].ravel().copy()), n_all
    ranges = [(0, n_all)] if ranges is None or name == "sweep" else \
        [(int(a), int(b)) for a, b in ranges]
    n_vertices = sum(b - a for a, b in ranges)
    md = math.inf if max_distance is None else float(max_distance)
    out = np.full(n_all, np.nan)
    if name in ("sweep", "pattern"):
        hf = np.ascontiguousarray(_to_frame(h, d))
        fr, fc = hf.shape
        frame_out = np.full(fr * fc, np.nan)
        # the sample's vertices, in the frame: ranges index the original C order
        if name == "sweep":
            def run():
                return _sweep(hf, d, frame_out)
        else:
            pat = _shared_pattern(d, fr, fc, max_distance)
            zmax = float(hf.max())
            index = _from_frame(np.arange(fr * fc).reshape(fr, fc), d).ravel()
            wanted = np.concatenate([index[a:b] for a, b in ranges])
            wanted.sort()
            # contiguous runs of frame indices
            breaks = np.flatnonzero(np.diff(wanted) != 1) + 1
            frame_ranges = [(int(s[0]), int(s[-1]) + 1) for s in np.split(wanted, breaks)]

            def run():
                return sum(_pattern_walk(hf, pat, zmax, a, b, frame_out) for a, b in frame_ranges)

        def values():
            full = _from_frame(frame_out.reshape(fr, fc), d).ravel()
            res = np.full(n_all, np.nan)
            for a, b in ranges:
                res[a:b] = full[a:b]
            return res
        return run, values, n_vertices
    if name in ("dda", "dda_maxmip", "march"):
        mip = terrain_mipmap(h) if name == "dda_maxmip" else None
        zmax = float(h.max())

        def run():
            total = 0
            for a, b in ranges:
                if name == "march":
                    total += _kernels.horizon_march(h, d.dx, d.dy, march_step, md, zmax, a, b, out)[0]
                else:
                    total += _kernels.horizon_walk(h, mip, d.dx, d.dy, md, a, b, out)[0]
            return total
        return run, (lambda: out.copy()), n_vertices
    from ..peers.embree import embree_horizon

    peer = embree_horizon(h)  # built once per field, outside the timed call
    vertices = np.concatenate([np.arange(a, b) for a, b in ranges])

    def run():
        start = time.perf_counter_ns()
        out[vertices] = peer.tangents(d.dx, d.dy, md, embree_tolerance, vertices)
        return time.perf_counter_ns() - start
    return run, (lambda: out.copy()), n_vertices
