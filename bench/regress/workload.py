"""The fixed inputs of the gates and of ``hftrace compare``, and the exact counters.

Every gate and every compare runs the kernels on one field and one ray set, made here
by the current checkout (never by the revision under test, so two revisions always see
the same bytes). Their SHA-256 prefixes are recorded in baselines: a baseline counted on
other inputs is a workload mismatch, never compared as if it were the same.

The algorithmic counters are the per-ray statistics the first-hit kernels return
(``algos.STATS``: cells visited, cells given the surface test, runs visited, runs culled,
mip tiles skipped). They depend on the algorithm and the inputs only: any compiler gives
the same integers, so they are gated exactly.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

#: Counters whose growth means more work per ray (the others count work avoided)
WORK_COUNTERS = ("cells_visited", "cells_tested", "runs_visited")


@dataclass
class Inputs:
    """One field (``heights``, float64 (rows, cols)) and its ray sets: first-hit rays
    ``o3``/``d3`` (N, 3) and traversal rays ``o2``/``d2`` (M, 2), float64; ``spec`` says
    how they were made, ``hashes`` their SHA-256 prefixes."""

    heights: np.ndarray
    o3: np.ndarray
    d3: np.ndarray
    o2: np.ndarray
    d2: np.ndarray
    spec: dict

    @property
    def shape(self) -> tuple[int, int]:
        """The traversal grid (nx, ny) of the field's cells."""
        return self.heights.shape[1] - 1, self.heights.shape[0] - 1

    @property
    def hashes(self) -> dict:
        """``field`` and ``rays`` SHA-256 prefixes (16 hex digits) of the arrays' bytes."""
        return dict(field=array_hash(self.heights),
                    rays=array_hash(self.o3, self.d3, self.o2, self.d2))


def array_hash(*arrays) -> str:
    """SHA-256 prefix (16 hex digits) of the arrays' dtypes, shapes and C-order bytes."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def make_inputs(size=256, first_hit_rays=200, traversal_rays=400, r=25, seed=2008) -> Inputs:
    """fBm ``size``^2 (seed 1) and rays of mean run length ``r`` (seed ``seed``), as the
    sweeps draw them (``datasets_gen.rays.first_hit_rays`` and ``traversal_rays``)."""
    import algos
    import datasets_gen
    from datasets_gen import rays as raysets

    heights = np.ascontiguousarray(datasets_gen.load("fbm", size=size, seed=1).heights,
                                   dtype=np.float64)
    o3, d3 = raysets.first_hit_rays(algos.Field(heights), r, first_hit_rays, seed)
    o2, d2 = raysets.traversal_rays((heights.shape[1] - 1, heights.shape[0] - 1), r, traversal_rays, seed)
    spec = dict(dataset="fbm", size=size, field_seed=1, r=r, seed=seed,
                first_hit_rays=first_hit_rays, traversal_rays=traversal_rays)
    return Inputs(heights, *(np.ascontiguousarray(a, dtype=np.float64) for a in (o3, d3, o2, d2)),
                  spec=spec)


def intersector_names(pkg) -> list[str]:
    """The first-hit kernels of package ``pkg`` (a revision's ``algos``) that run in its
    own C extension: not the peers, not plugins."""
    reg = pkg.INTERSECTOR_REGISTRY
    return [n for n, a in reg.items()
            if a.kind != "peer" and getattr(a, "plugin", None) is None]


def counters(pkg, inputs: Inputs, cases) -> dict:
    """The counters of each first-hit case ``(surface, kernel)`` run by package ``pkg``:
    ``{"first_hit/<surface>/<kernel>": {counter: total over the rays (int)}}``, with
    ``rays`` (the ray count) beside them."""
    out = {}
    n = len(inputs.o3)
    for surface, kernel in cases:
        hits = pkg.intersect(kernel, inputs.heights, inputs.o3, inputs.d3, surface=surface,
                             outputs=("t", "stats"))
        totals = {k: int(np.asarray(v, dtype=np.int64).sum()) for k, v in hits.stats.items()}
        out[f"first_hit/{surface}/{kernel}"] = dict(totals, rays=n)
    return out


def counter_changes(base: dict, head: dict) -> tuple[list[str], list[str]]:
    """(regressions, other changes) between two counter records of one case, as text:
    a work counter (:data:`WORK_COUNTERS`) that grew is a regression, any other
    difference a change."""
    grew, changed = [], []
    rays = max(int(head.get("rays", base.get("rays", 1))), 1)
    for name in sorted(set(base) | set(head)):
        if name == "rays":
            continue
        b, h = base.get(name), head.get(name)
        if b == h:
            continue
        text = f"{name} per ray {_per_ray(b, rays)} -> {_per_ray(h, rays)}"
        if name in WORK_COUNTERS and b is not None and h is not None and h > b:
            grew.append(text + f" (+{100 * (h / max(b, 1) - 1):.2f} %)")
        else:
            changed.append(text)
    return grew, changed


def _per_ray(total, rays) -> str:
    return "absent" if total is None else f"{total / rays:,.3f}"
