"""``hftrace scale``: how the kernels scale up (threads), grow (grid side) and fit (a
16384^2 field). :func:`run` runs the parts, each a study of its own, into one folder
(default ``results/scale/``; the committed reference is ``reports/scaling/``):

* ``bench.studies.threads``: ``threads.md/.csv`` (every kernel on 1 thread against every
  core) and ``split.md`` (ranges per thread against speedup);
* ``bench.studies.growth``: ``growth.md/.csv/.png``, ns per ray and per visited cell
  against the grid side, 256^2 to 16384^2;
* ``bench.studies.big``: ``big.md/.json``, a 16384^2 fbm field (1 GiB of float32 heights)
  item by item, each in its own process.

What they share (the field, the ray set and the constants) is in
``bench.studies.scaling_workload``. Every part appends rows as it measures them and skips what its CSV already
holds (``--resume``), so an interrupted run loses nothing.
"""
from __future__ import annotations

import os

from algos import parallel

from ..timing import cache_sizes, environment, write_json
from .big import run_big
from .growth import run_growth
from .scaling_workload import SIDES
from .threads import run_split, run_threads

__all__ = ["run"]


def run(out_dir="results/scale", parts=("threads", "split", "growth", "big"), resume=False,
        echo=print, quick=False):
    """Run the ``parts`` (any of threads, split, growth, big) into ``out_dir`` with env.json;
    ``quick``: small sizes (a check that it runs); ``resume``: skip what the CSVs hold."""
    os.makedirs(out_dir, exist_ok=True)
    write_json(os.path.join(out_dir, "env.json"), dict(environment(), caches=cache_sizes(),
                                                         cores=parallel.available_cores()))
    if "threads" in parts:
        run_threads(out_dir, side=512 if quick else 2048, n=20_000 if quick else 100_000,
                    repeats=3 if quick else 7, echo=echo, resume=resume)
    if "split" in parts:
        run_split(out_dir, side=512 if quick else 2048, repeats=3 if quick else 11, echo=echo)
    if "growth" in parts:
        run_growth(out_dir, sides=SIDES[:3] if quick else SIDES, n=2000 if quick else 20_000,
                   repeats=3 if quick else 5, echo=echo, resume=resume)
    if "big" in parts:
        run_big(out_dir, side=1024 if quick else 16384, echo=echo, resume=resume)

