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

from .profile import callgrind_available, profile

FIELDS = ["kernel", "dataset", "size", "r", "rays", "surface", "instructions_per_ray",
          "instructions_per_cell", "branches_per_cell", "mispredicts_per_cell"]


def read_counts(path: str) -> dict:
    """kernel -> row of a counts.csv (empty when the file does not exist)."""
    if not os.path.exists(path):
        return {}
    with open(path, newline="") as f:
        return {row["kernel"]: row for row in csv.DictReader(f)}


def write_counts(path: str, kernels, dataset="fbm", size=1024, r=25, rays=300,
                 surface="triangles", resume=False, echo=print) -> bool:
    """Count every kernel in ``kernels`` (the peer excluded) into ``path``; False when
    valgrind is missing."""
    if not callgrind_available():
        echo("counts: valgrind not found; no instruction counts (apt-get install valgrind)")
        return False
    done = read_counts(path) if resume else {}
    if not resume and os.path.exists(path):
        os.remove(path)
    new = not os.path.exists(path)
    with open(path, "a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS)
        if new:
            writer.writeheader()
        for kernel in kernels:
            if kernel == "embree" or kernel in done:
                continue
            p = profile(kernel, dataset=dataset, size=size, r=r, rays=rays, surface=surface)
            writer.writerow(dict(kernel=kernel, dataset=dataset, size=size, r=r, rays=rays,
                                 surface=surface,
                                 instructions_per_ray=round(p["instructions_per_ray"], 1),
                                 instructions_per_cell=round(p["instructions_per_cell"], 2),
                                 branches_per_cell=round(p["branches_per_cell"], 2),
                                 mispredicts_per_cell=round(p["mispredicts_per_cell"], 3)))
            f.flush()
            echo(f"counts: {kernel} {p['instructions_per_cell']:.1f} instructions/cell")
    return True
