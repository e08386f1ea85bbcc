"""Threads for the C kernels: every call releases the GIL around its C loop, so a batch
split into contiguous ray ranges runs on several cores from plain Python threads.

Work split (measured in ``reports/scaling``): rays are cut into ``CHUNKS_PER_THREAD``
ranges per thread and handed to a pool whose threads take the next range as they finish
(a shared queue, the Python form of an atomic ray counter). Ray costs vary by orders of
magnitude (a ray that hits at once against one that crosses the field), so one static
range per thread leaves a core idle at the end; more, smaller ranges balance the load at
a cost of one C call (about a microsecond) each. ``MIN_RAYS_PER_CHUNK`` keeps that cost
below 0.1 % of the work.

Every kernel computes each ray from that ray's inputs alone (the per-batch scratch, the
run pattern of ``runs_periodic``, is allocated per range), so results are bit-identical
for every thread count and split; the tests check it.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

__all__ = ["resolve_threads", "split", "run_ranges", "available_cores",
           "CHUNKS_PER_THREAD", "MIN_RAYS_PER_CHUNK"]

CHUNKS_PER_THREAD = 8
MIN_RAYS_PER_CHUNK = 1024


def available_cores() -> int:
    """Cores this process may run on (its affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def resolve_threads(threads) -> int:
    """``None`` -> every core in the affinity; else a positive int, checked."""
    if threads is None:
        return available_cores()
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ValueError(f"threads: expected None or a positive int, got {threads!r}")
    return int(threads)


def split(n: int, threads: int, chunks_per_thread: int | None = None,
          min_chunk: int = MIN_RAYS_PER_CHUNK) -> list[tuple[int, int]]:
    """Contiguous ranges covering ``[0, n)``: ``threads * chunks_per_thread`` of them
    (default ``CHUNKS_PER_THREAD``, read at call time), none shorter than ``min_chunk``
    (except a lone one), in order."""
    if chunks_per_thread is None:
        chunks_per_thread = CHUNKS_PER_THREAD
    if n <= 0:
        return [(0, 0)]
    if threads <= 1:  # one range (the timed calls of one thread take this path)
        return [(0, int(n))]
    pieces = max(1, min(threads * chunks_per_thread, n // max(min_chunk, 1)))
    bounds = np.linspace(0, n, pieces + 1).astype(np.int64)
    return [(int(bounds[k]), int(bounds[k + 1])) for k in range(pieces)]


def run_ranges(n: int, threads: int, call, chunks_per_thread: int | None = None,
               min_chunk: int = MIN_RAYS_PER_CHUNK) -> list:
    """``call(start, stop)`` over the ranges of :func:`split`; results in range order.

    With one range the call runs on the caller's thread. An exception from any range is
    raised after the pool has finished (the first in range order)."""
    ranges = split(n, threads, chunks_per_thread, min_chunk)
    if len(ranges) == 1 or threads <= 1:
        return [call(a, b) for a, b in ranges]
    with ThreadPoolExecutor(min(threads, len(ranges))) as pool:
        futures = [pool.submit(call, a, b) for a, b in ranges]
        return [f.result() for f in futures]
