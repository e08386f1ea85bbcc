"""The dask viewshed's graph size: tasks and build time of ``algos.viewshed`` on a lazy
array, against the number of chunks (``hftrace terrain-bench`` calls
:func:`dask_graph_sizes`; the graph is built by ``algos.terrain.tiled.tiled_viewshed``).

Method: the input is ``dask.array.zeros`` (float64) with square chunks, nothing is
computed. "Build" is the ``algos.viewshed`` call; "graph" is materialising the low-level
graph (``dict(result.__dask_graph__())``), which a scheduler does before any work, and its
length is the task count (the input's chunks included). The largest case is
xarray-spatial's own lazy test: a 100000^2 field of 1000^2 chunks, one observer at the
centre, ``max_distance`` 10 cells. Times are wall-clock on whatever else the machine runs.
"""
from __future__ import annotations

import csv
import os
import time

__all__ = ["GRAPH_CASES", "GRAPH_COLUMNS", "dask_graph_sizes"]

#: (side in samples, chunk side, observers per side of an even grid, max_distance in cells;
#: None: unlimited)
GRAPH_CASES = (
    (10000, 1000, 1, 500.0),
    (10000, 1000, 4, 500.0),
    (10000, 1000, 1, None),
    (20000, 1000, 1, 500.0),
    (20000, 1000, 4, 500.0),
    (100000, 1000, 1, 10.0),
)
GRAPH_COLUMNS = ["side", "chunk", "chunks", "observers", "max_distance", "tasks",
                 "tasks_per_chunk", "build_seconds", "graph_seconds"]


def _observers(side, per_side):
    """``per_side``^2 observers on an even grid (one: the centre), in grid coordinates."""
    if per_side == 1:
        return (side / 2, side / 2)
    step = side / per_side
    return [((i + 0.5) * step, (j + 0.5) * step)
            for j in range(per_side) for i in range(per_side)]


def dask_graph_sizes(out_dir=None, cases=GRAPH_CASES, echo=print):
    """Tasks and build times of the dask viewshed's graph for each of ``cases`` (see
    :data:`GRAPH_CASES`). Returns markdown lines; with ``out_dir``, also writes
    ``dask_graph.csv`` there (:data:`GRAPH_COLUMNS`). Without dask: one line saying so."""
    try:
        import dask.array as da
    except ImportError:
        return ["## Dask viewshed graph", "", "dask is not importable here; skipped.", ""]
    import algos

    rows = []
    for side, chunk, per_side, max_distance in cases:
        lazy = da.zeros((side, side), chunks=chunk)
        observer = _observers(side, per_side)
        t0 = time.perf_counter()
        seen = algos.viewshed(lazy, observer, max_distance=max_distance)
        build = time.perf_counter() - t0
        t0 = time.perf_counter()
        tasks = len(dict(seen.__dask_graph__()))
        graph = time.perf_counter() - t0
        chunks = lazy.npartitions
        rows.append(dict(side=side, chunk=chunk, chunks=chunks, observers=per_side ** 2,
                         max_distance="unlimited" if max_distance is None else max_distance,
                         tasks=tasks, tasks_per_chunk=round(tasks / chunks, 3),
                         build_seconds=round(build, 4), graph_seconds=round(graph, 4)))
        echo(f"  dask viewshed graph {side}^2 / {chunk}^2 chunks, {per_side ** 2} observer(s), "
             f"max_distance {rows[-1]['max_distance']}: {tasks} tasks, built in {build:.3f} s "
             f"+ {graph:.3f} s")
    if out_dir is not None:
        with open(os.path.join(out_dir, "dask_graph.csv"), "w", newline="") as f:
            writer = csv.DictWriter(f, GRAPH_COLUMNS)
            writer.writeheader()
            writer.writerows(rows)
    lines = ["## Dask viewshed graph", "",
             "`algos.viewshed` on `dask.array.zeros((side, side), chunks=chunk)`, nothing "
             "computed: tasks (the input's included) and seconds to build the call and to "
             "materialise the graph (`bench.studies.terrain_graph`).", "",
             "| side | chunk | chunks | observers | max_distance (cells) | tasks "
             "| tasks per chunk | build (s) | graph (s) |",
             "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['side']} | {r['chunk']} | {r['chunks']} | {r['observers']} | "
              f"{r['max_distance']} | {r['tasks']} | {r['tasks_per_chunk']:g} | "
              f"{r['build_seconds']:.3f} | {r['graph_seconds']:.3f} |" for r in rows]
    return lines + [""]
