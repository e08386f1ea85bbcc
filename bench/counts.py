"""Instruction and branch counts next to the timings: ``counts.csv`` of a report.

Each first-hit kernel runs once under callgrind (:func:`bench.profile.profile`) on fixed
rays (fbm 1024^2, r = 25, 300 rays, triangles); the rows are appended one kernel at a
time, so an interrupted run keeps what it counted and ``resume`` skips those kernels.
Counts are exact for one build and input, which is what the cost model needs on a VM
whose timings are noisy. Without valgrind nothing is written and the report says so.
"""
from __future__ import annotations

import csv
import os

from .profile import callgrind_available

FIELDS = ["kernel", "dataset", "size", "r", "rays", "surface", "instructions_per_ray",
          "instructions_per_cell", "branches_per_cell", "mispredicts_per_cell"]


def read_counts(path: str) -> dict:
    """kernel -> row of a counts.csv (empty when the file does not exist)."""
    if not os.path.exists(path):
        return {}
    with open(path, newline="") as f:
        return {row["kernel"]: row for row in csv.DictReader(f)}


def write_counts(path: str, kernels, dataset="fbm", size=1024, r=25, rays=300,
                 surface="triangles", resume=False, echo=print, workers=1,
                 progress=False) -> bool:
    """Count every kernel in ``kernels`` (the peer and plugins excluded: callgrind counts
    only inside hftrace's own C batch entry) into ``path``; False when valgrind is
    missing. ``workers`` callgrind processes run at once (run them only when nothing is
    being timed); rows are appended as each kernel finishes."""
    if not callgrind_available():
        echo("counts: valgrind not found; no instruction counts (apt-get install valgrind)")
        return False
    import algos

    done = read_counts(path) if resume else {}
    if not resume and os.path.exists(path):
        os.remove(path)
    todo = [k for k in kernels if k not in ("embree", "embree3") and k not in done and
            k in algos.INTERSECTOR_REGISTRY and algos.INTERSECTOR_REGISTRY[k].plugin is None]
    skipped = [k for k in kernels if k in algos.INTERSECTOR_REGISTRY and
               algos.INTERSECTOR_REGISTRY[k].plugin is not None]
    if skipped and echo:
        echo(f"counts: no instruction counts for plugins ({', '.join(skipped)}): callgrind "
             "collects inside hftrace's C entry only; `valgrind --tool=callgrind` on your own "
             "library gives them")
    new = not os.path.exists(path)
    from concurrent.futures import ThreadPoolExecutor, as_completed

    from .profile import profile_many

    # one callgrind run per worker, each counting its share of the kernels in turn (one
    # interpreter start under valgrind per worker instead of one per kernel)
    chunks = [todo[k::max(1, workers)] for k in range(max(1, workers))]
    chunks = [c for c in chunks if c]
    bar = None
    if progress and todo:
        from tqdm import tqdm

        bar = tqdm(total=len(chunks), unit="callgrind run", desc="counts (callgrind)",
                   dynamic_ncols=True)
    with open(path, "a", newline="") as f, ThreadPoolExecutor(max(1, len(chunks))) as pool:
        writer = csv.DictWriter(f, fieldnames=FIELDS)
        if new:
            writer.writeheader()
        futures = [pool.submit(profile_many, chunk, dataset=dataset, size=size, r=r, rays=rays,
                               surface=surface) for chunk in chunks]
        for future in as_completed(futures):
            for kernel, p in future.result().items():
                writer.writerow(dict(kernel=kernel, dataset=dataset, size=size, r=r, rays=rays,
                                     surface=surface,
                                     instructions_per_ray=round(p["instructions_per_ray"], 1),
                                     instructions_per_cell=round(p["instructions_per_cell"], 2),
                                     branches_per_cell=round(p["branches_per_cell"], 2),
                                     mispredicts_per_cell=round(p["mispredicts_per_cell"], 3)))
                if echo and bar is None:
                    echo(f"counts: {kernel} {p['instructions_per_cell']:.1f} instructions/cell")
            f.flush()
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    return True
