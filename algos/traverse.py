"""``algos.traverse``: the public entry to the C traversal kernels.

This module validates and converts every input; the C layer trusts what it is given.
"""
from __future__ import annotations

import numbers
import time
from dataclasses import dataclass

import numpy as np

from . import _kernels, plugin_calls
from .field import HeightField
from .lattice import quantize
from .parallel import resolve_threads, run_ranges, split
from .reference import runs_from_cells
from .registry import Traversal, get_traversal
from .validate import check_rays, check_shape, check_t

__all__ = [
    "CellPaths", "RunPaths", "PathCounts", "traverse", "walk_timed", "prepare_timed",
    "DEFAULT_MAX_DENOMINATOR", "MAX_DENOMINATOR", "OUTPUTS", "WORKLOADS",
]

#: Default Q of runs_periodic: slopes p/q with q <= 2**16 are replayed exactly.
DEFAULT_MAX_DENOMINATOR = _kernels.DEFAULT_MAX_DENOMINATOR
#: Largest Q accepted (the pattern workspace holds Q + 1 int32).
MAX_DENOMINATOR = _kernels.MAX_DENOMINATOR

_MODE = {"count": 0, "cells": 1, "runs": 2, "visit": 3, "runfold": 4}
#: Output modes of :func:`traverse`.
OUTPUTS = ("cells", "runs", "count")
#: Timed workloads of :func:`walk_timed` (docs/CONVENTIONS.md, "Workloads").
WORKLOADS = {"visit": "visit", "runs": "runfold"}


@dataclass(frozen=True)
class CellPaths:
    """Visited cells of N rays, concatenated.

    ``cells[offsets[k]:offsets[k+1]]`` (also ``paths[k]``) is ray k's ``(n_k, 2)`` array
    of ``(i, j)`` in visiting order.
    """

    offsets: np.ndarray  # (N + 1,) int64
    cells: np.ndarray  # (M, 2) int32
    algorithm: str

    def __len__(self) -> int:
        return len(self.offsets) - 1

    def __getitem__(self, k: int) -> np.ndarray:
        k = range(len(self))[k]
        return self.cells[self.offsets[k]:self.offsets[k + 1]]

    def __iter__(self):
        return (self[k] for k in range(len(self)))

    @property
    def counts(self) -> np.ndarray:
        """Cells per ray."""
        return np.diff(self.offsets)


@dataclass(frozen=True)
class RunPaths:
    """Runs of N rays, concatenated: ``runs[offsets[k]:offsets[k+1]]`` (``paths[k]``)
    holds ray k's runs ``(minor, first, last)``; ``first`` and ``last`` are major-axis
    indices in travel order, and ``major[k]`` is 0 when x is ray k's major axis."""

    offsets: np.ndarray  # (N + 1,) int64
    runs: np.ndarray  # (M, 3) int32
    major: np.ndarray  # (N,) int8
    algorithm: str

    def __len__(self) -> int:
        return len(self.offsets) - 1

    def __getitem__(self, k: int) -> np.ndarray:
        k = range(len(self))[k]
        return self.runs[self.offsets[k]:self.offsets[k + 1]]

    def __iter__(self):
        return (self[k] for k in range(len(self)))


@dataclass(frozen=True)
class PathCounts:
    """Number of cells and of runs per ray."""

    cells: np.ndarray  # (N,) int64
    runs: np.ndarray  # (N,) int64
    algorithm: str


# ---- validation (the shared validators live in algos.validate) ---------------------
def _check_max_denominator(value, algorithm: Traversal) -> int:
    if value is None:
        return DEFAULT_MAX_DENOMINATOR if algorithm.shared_direction else 0
    if not algorithm.shared_direction:
        raise ValueError(f"max_denominator: only runs_periodic takes it, not {algorithm.name}")
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"max_denominator: expected an integer, got {value!r}")
    if not 1 <= int(value) <= MAX_DENOMINATOR:
        raise ValueError(f"max_denominator: {value} outside [1, 2**24]")
    return int(value)


#: The largest |direction component| a float walk can step by, per precision: beyond,
#: 1/d (or the float32 copy of d) leaves the number range and the walk stops early
FLOAT_DIRECTION_RANGE = {"float64": (2.0**-1000, 2.0**1000), "float32": (2.0**-100, 2.0**100)}


def _check_float_range(algorithm: Traversal, directions: np.ndarray) -> None:
    """ValueError naming the first non-zero direction whose largest component a float
    walk cannot step by (the exact walks rescale d on their lattice and take any)."""
    bounds = FLOAT_DIRECTION_RANGE.get(algorithm.precision)
    if bounds is None or algorithm.plugin is not None or not len(directions):
        return
    largest = np.max(np.abs(directions), axis=1)
    bad = (largest > 0) & ((largest < bounds[0]) | (largest > bounds[1]))
    if bad.any():
        k = int(np.argmax(bad))
        low, high = (int(np.log2(b)) for b in bounds)
        raise ValueError(
            f"directions: ray {k} has a largest component {float(largest[k])!r}, outside "
            f"[2**{low}, 2**{high}], where {algorithm.name} walks in {algorithm.precision} "
            "(1/d would leave the range); scale the direction (no cell changes) or use an "
            "exact kernel")


class _Batch:
    """Validated inputs of one call, ready for the C kernels."""

    def __init__(self, name, origins, directions, shape, tmin, tmax, max_denominator):
        self.algorithm = get_traversal(name)
        self.origins, self.directions = check_rays(origins, directions, 2)
        _check_float_range(self.algorithm, self.directions)
        self.n = len(self.origins)
        if isinstance(shape, HeightField):  # its grid of cells
            shape = (shape.cols - 1, shape.rows - 1)
        self.nx, self.ny = check_shape(shape)
        self.tmin = check_t(tmin, "tmin", self.n)
        self.tmax = check_t(tmax, "tmax", self.n)
        self.max_denominator = _check_max_denominator(max_denominator, self.algorithm)
        self.pattern = (
            np.zeros(self.max_denominator + 1, dtype=np.int32)
            if self.algorithm.shared_direction else None
        )

    def run(self, mode: str, n_cells=None, n_runs=None, offsets=None, out=None, checksums=None,
            threads=1):
        """Run the batch in C, split over ``threads`` (bit-identical for every count).
        Returns the elapsed ns: the C clock with one range, else the wall time of the
        whole pool."""

        def part(a, b):
            def cut(x):  # a per-ray array's range; a scalar or None as it is
                return None if x is None or np.ndim(x) == 0 else x[a:b]

            pattern = None if self.pattern is None else np.zeros_like(self.pattern)
            try:
                return _kernels.walk(
                    self.algorithm.kernel_id, _MODE[mode], self.origins[a:b],
                    self.directions[a:b], cut(self.tmin), cut(self.tmax), self.nx, self.ny,
                    self.max_denominator, pattern, cut(n_cells), cut(n_runs),
                    None if offsets is None else offsets[a:b + 1], out, cut(checksums))
            except RuntimeError as exc:
                raise RuntimeError(f"{exc} (ray index counted from ray {a})") from None

        ranges = split(self.n, threads)
        if len(ranges) == 1:
            return part(*ranges[0])
        start = time.perf_counter_ns()
        run_ranges(self.n, threads, part)
        return time.perf_counter_ns() - start

    def counts(self, threads=1):
        n_cells = np.zeros(self.n, dtype=np.int64)
        n_runs = np.zeros(self.n, dtype=np.int64)
        self.run("count", n_cells=n_cells, n_runs=n_runs, threads=threads)
        return n_cells, n_runs

    def major(self) -> np.ndarray:
        """Each ray's major axis by the rule its kernel applies."""
        d = self.directions
        if self.algorithm.exact:
            d = quantize(self.origins, d)[1]
        elif self.algorithm.precision == "float32":
            d = d.astype(np.float32)
        return (np.abs(d[:, 1]) > np.abs(d[:, 0])).astype(np.int8)


def _offsets(counts: np.ndarray) -> np.ndarray:
    offsets = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return offsets


def traverse(name, origins, directions, shape, tmin=None, tmax=None, *, output="cells",
             max_denominator=None, threads=None):
    """Walk N rays across a 2D grid with one registered kernel.

    Parameters
    ----------
    name : str
        A name in ``algos.TRAVERSALS``.
    origins, directions : array_like, shape (N, 2)
        Rays ``o + t d`` in (x, y); any real dtype, byte order or layout (converted to
        float64). Components must be finite, ``|origins| <= 2**30`` and
        ``|directions| <= 2**1000``; the float walks also need a non-zero direction's
        largest component within :data:`FLOAT_DIRECTION_RANGE` (float64: ``2**-1000`` to
        ``2**1000``, float32: ``2**-100`` to ``2**100``). A zero direction
        is a vertical ray and visits at most the cell under the origin.
    shape : (nx, ny) or HeightField
        Grid size in cells, (x, y) order; each side in ``[1, 2**24]``. A
        :class:`algos.HeightField` gives its grid of cells, ``(cols - 1, rows - 1)``.
    tmin, tmax : None, float or array_like of shape (N,)
        Parameter range ``[tmin, tmax)``; default ``[0, inf)``; ``+-inf`` allowed.
    output : {"cells", "runs", "count"}
        What to return, so that a caller pays only for what it needs.
    max_denominator : int, optional
        ``runs_periodic`` only: Q, the largest slope denominator (default ``2**16``). The
        reduced slope ``|minor/major|`` of the lattice-rounded ray is replaced by its best
        rational approximation p/q with q <= Q (ties to the smaller q, as
        ``Fraction.limit_denominator``); the walk is the exact one of the ray with that
        slope through the same origin, moving along the major axis at the same speed.
        So the result equals the exact kernels' whenever the slope already is p/q with
        q <= Q, and is approximate otherwise.
    threads : None or int
        Threads to split the rays over (``None``: every core in the process's affinity).
        The result is bit-identical for every value.

    Returns
    -------
    CellPaths, RunPaths or PathCounts
        Exact kernels (``registry.TRAVERSAL_REGISTRY[name].exact``) return exactly
        ``reference_cells`` of the ray rounded by :func:`algos.lattice.quantize`, for any
        ``tmin``/``tmax``; float kernels are measured against it (the accuracy study).

    Raises
    ------
    ValueError, TypeError
        Bad input, with a message naming the argument and the offending ray; a plugin
        kernel (``algos.plugins``) that cannot serve the call (a Python kernel given a
        ray range, a C library without ``hftrace_traverse_cells``), naming the kernel and
        what it lacks.
    algos.plugins.PluginError (defined in algos.plugin_calls)
        A plugin kernel failed or returned cells that are not inside the grid.

    Notes
    -----
    A registered plugin runs on the calling thread (``threads`` is not passed to it);
    its runs are grouped from its cells, with each ray's major axis the larger ``|d|``
    of the ray as given (x on a tie).
    """
    batch = _Batch(name, origins, directions, shape, tmin, tmax, max_denominator)
    if output not in OUTPUTS:
        raise ValueError(f"output: expected one of {OUTPUTS}, got {output!r}")
    nthreads = resolve_threads(threads)
    if batch.algorithm.plugin is not None:
        return _plugin_paths(batch, output)
    n_cells, n_runs = batch.counts(nthreads)
    if output == "count":
        return PathCounts(n_cells, n_runs, batch.algorithm.name)
    if output == "cells":
        offsets = _offsets(n_cells)
        cells = np.empty((int(offsets[-1]), 2), dtype=np.int32)
        batch.run("cells", offsets=offsets, out=cells, threads=nthreads)
        return CellPaths(offsets, cells, batch.algorithm.name)
    offsets = _offsets(n_runs)
    runs = np.empty((int(offsets[-1]), 3), dtype=np.int32)
    batch.run("runs", offsets=offsets, out=runs, threads=nthreads)
    return RunPaths(offsets, runs, batch.major(), batch.algorithm.name)


def _plugin_paths(batch, output):
    """``traverse``'s result for a registered plugin: its cells (``algos.plugins``), and
    the runs and counts grouped from them."""
    name = batch.algorithm.name
    offsets, cells = plugin_calls.traversal_cells(name, batch.origins, batch.directions,
                                             (batch.nx, batch.ny), batch.tmin, batch.tmax)
    if output == "cells":
        return CellPaths(offsets, cells, name)
    d = batch.directions
    major = (np.abs(d[:, 1]) > np.abs(d[:, 0])).astype(np.int8)
    per_ray = [runs_from_cells(cells[offsets[k]:offsets[k + 1]].tolist(), int(major[k]))
               for k in range(batch.n)]
    n_runs = np.array([len(r) for r in per_ray], dtype=np.int64)
    if output == "count":
        return PathCounts(np.diff(offsets), n_runs, name)
    run_offsets = _offsets(n_runs)
    runs = np.array([run for r in per_ray for run in r], dtype=np.int32).reshape(-1, 3)
    return RunPaths(run_offsets, runs, major, name)


def prepare_timed(name, origins, directions, shape, workload="visit", tmin=None,
                  tmax=None, *, max_denominator=None, threads=1):
    """Validate once and return ``(run, checksums)``: each ``run()`` call walks the whole
    batch again in C and returns its elapsed nanoseconds, filling ``checksums``.

    ``visit`` folds every visited cell into a per-ray checksum; ``runs`` folds every
    run. The clock (CLOCK_MONOTONIC) wraps the C loop and nothing else. Checksums are
    identical across kernels that visit the same cells (or runs) in the same order.
    With ``threads`` > 1 the batch is split over a thread pool and ``run()`` returns the
    pool's wall time (timing studies state their thread count; default 1).
    """
    if workload not in WORKLOADS:
        raise ValueError(f"workload: expected one of {tuple(WORKLOADS)}, got {workload!r}")
    batch = _Batch(name, origins, directions, shape, tmin, tmax, max_denominator)
    checksums = np.zeros(batch.n, dtype=np.uint64)
    plugin = batch.algorithm.plugin
    if plugin is not None:
        if workload != "visit":
            raise ValueError(f"workload: kernel {plugin.describe(name)} folds visited cells "
                             f"(the visit workload); it has no {workload!r} fold")
        if plugin.language == "python" and (batch.tmin is not None or batch.tmax is not None):
            raise ValueError(f"tmin: kernel {plugin.describe(name)} takes no ray range")
        run_plugin, sums = plugin_calls.prepare_timed_traversal(name, batch.origins,
                                                           batch.directions, (batch.nx, batch.ny))

        def run_and_fold() -> int:
            elapsed = run_plugin()
            checksums[:] = sums()  # folded after the clock stopped
            return elapsed

        return run_and_fold, checksums
    mode = WORKLOADS[workload]

    nthreads = resolve_threads(threads)

    def run() -> int:
        return batch.run(mode, checksums=checksums, threads=nthreads)

    return run, checksums


def walk_timed(name, origins, directions, shape, workload="visit", tmin=None, tmax=None,
               *, max_denominator=None):
    """Time one workload of one kernel over a batch once (see :func:`prepare_timed`).

    Returns
    -------
    elapsed_ns : int
    checksums : ndarray of uint64, shape (N,)
    """
    run, checksums = prepare_timed(name, origins, directions, shape, workload, tmin, tmax,
                                   max_denominator=max_denominator)
    return run(), checksums
