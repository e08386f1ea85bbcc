"""``hftrace scale``: how the kernels scale up (threads), grow (grid side) and fit (a
16384^2 field). :func:`run` runs the parts, each a study of its own, into one folder
(default ``results/scale/``; the committed reference is ``reports/scaling/``):

* ``bench.studies.threads``: ``threads.md/.csv`` (every kernel on 1 thread against every
  core) and ``split.md`` (ranges per thread against speedup);
* ``bench.studies.growth``: ``growth.md/.csv/.png``, ns per ray and per visited cell
  against the grid side, 256^2 to 16384^2;
* ``bench.studies.big``: ``big.md/.json``, a 16384^2 fbm field (1 GiB of float32 heights)
  item by item, each in its own process.

This module holds what they share: the field and ray set of the studies, and their
constants. Every part appends rows as it measures them and skips what its CSV already
holds (``--resume``), so an interrupted run loses nothing.
"""
from __future__ import annotations

import os

import algos
from algos import parallel
from datasets_gen import fields
from datasets_gen import rays as raysets

from ..timing import cache_sizes, environment, write_json

__all__ = ["run", "fbm_field", "growth_rays", "SIDES", "GROWTH_R", "GROWTH_ELEVATION",
           "EMBREE_MAX_SIDE"]

SIDES = (256, 512, 1024, 2048, 4096, 8192, 16384)
GROWTH_R = 25
GROWTH_ELEVATION = 10.0
#: Embree's scene for a 8192^2 field is about 134 M triangles (some 10 GB measured at
#: 2048^2 x 16); the growth study stops it at this side by default
EMBREE_MAX_SIDE = 4096


def fbm_field(side, seed=1) -> algos.Field:
    """The studies' field: fBm of ``side`` x ``side`` samples (``datasets_gen.fields``)."""
    return algos.Field(fields.generate("fbm", side, seed=seed))


def growth_rays(field, n, seed):
    """Rays at run length GROWTH_R falling at GROWTH_ELEVATION degrees from one cell above
    the highest point, origins uniform over the field."""
    rows, cols = field.rows, field.cols
    rs = raysets.by_run_length(GROWTH_R, n, (cols - 1, rows - 1), seed, origins="inside",
                               elevation=GROWTH_ELEVATION, height=field.hmax + 1.0)
    return rs.origins, rs.directions



def run(out_dir="results/scale", parts=("threads", "split", "growth", "big"), resume=False,
        echo=print, quick=False):
    """Run the ``parts`` (any of threads, split, growth, big) into ``out_dir`` with env.json;
    ``quick``: small sizes (a check that it runs); ``resume``: skip what the CSVs hold."""
    from .big import run_big
    from .growth import run_growth
    from .threads import run_split, run_threads

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

