"""``hftrace scale --part growth``: ns per ray and per visited cell against the grid side,
256^2 to 16384^2, every intersector and Embree, at a fixed run length (r = 25) and
elevation (10 degrees), one thread pinned to one CPU, with the machine's L2 and L3 sizes
marked where the heights alone fill them. Writes ``growth.md``, ``growth.csv`` and
``growth.png``.
"""
from __future__ import annotations

import math
import os
import time

import algos
from algos.intersect import prepare_timed_intersect

from ..report import RowWriter
from ..sweep import read_rows
from ..timing import cache_sizes, interleaved, median_ci, pin_to_one_cpu
from .scaling_workload import EMBREE_MAX_SIDE, GROWTH_ELEVATION, GROWTH_R, SIDES, fbm_field, growth_rays

__all__ = ["run_growth"]

# ---- growth ----------------------------------------------------------------------------
GROWTH_COLUMNS = ["side", "kernel", "rays", "cells_per_ray", "ns_per_ray", "ns_per_ray_ci_low",
                  "ns_per_ray_ci_high", "ns_per_cell", "heights_bytes", "structure_bytes",
                  "build_seconds", "repeats"]



def run_growth(out_dir, sides=SIDES, n=20_000, repeats=5, names=None, embree_max=EMBREE_MAX_SIDE,
               echo=print, resume=False):
    """ns/ray and ns/cell against the grid side, one thread, one run per side."""
    csv_path = os.path.join(out_dir, "growth.csv")
    done = {int(r["side"]) for r in read_rows(csv_path)} if resume else set()
    names = list(names or algos.INTERSECTORS)
    saved = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    pin_to_one_cpu()
    try:
        with RowWriter(csv_path, GROWTH_COLUMNS, append=resume) as writer:
            for side in sides:
                if side in done:
                    continue
                start = time.perf_counter()
                field = fbm_field(side)
                echo(f"growth {side}^2: field in {time.perf_counter() - start:.1f} s")
                o, d = growth_rays(field, n, 5)
                ref = algos.intersect("runs", field, o, d, outputs=("t", "stats"), threads=1)
                cells = float(ref.stats["cells_visited"].mean())
                jobs = {}
                use = [x for x in names if x not in ("embree", "embree3") or side <= embree_max]
                for name in use:
                    jobs[name] = prepare_timed_intersect(name, field, o, d, threads=1)[0]
                times = interleaved(jobs, repeats)
                built = field.build_stats
                for name in use:
                    keys = _structures_of(name, built)
                    med, lo, hi = median_ci(times[name] / n)
                    writer.write(dict(
                        side=side, kernel=name, rays=n, cells_per_ray=round(cells, 2),
                        ns_per_ray=round(med, 2), ns_per_ray_ci_low=round(lo, 2),
                        ns_per_ray_ci_high=round(hi, 2), ns_per_cell=round(med / cells, 4),
                        heights_bytes=field.heights.nbytes,
                        structure_bytes=sum(built[k]["bytes"] for k in keys),
                        build_seconds=round(sum(built[k]["seconds"] for k in keys), 3),
                        repeats=repeats))
                echo(f"growth {side}^2: {len(use)} kernels, {cells:.0f} cells/ray, "
                     f"{time.perf_counter() - start:.1f} s")
                del field, jobs
    finally:
        if saved is not None:
            os.sched_setaffinity(0, saved)
    rows = read_rows(csv_path)
    _growth_report(rows, out_dir)
    return rows


def _structures_of(name, built):
    uses = {"embree": ("embree",)}.get(name)
    if uses is None:
        algorithm = algos.INTERSECTOR_REGISTRY[name]
        uses = ("cellmax",) + tuple(algorithm.structures)
        if algorithm.traversal in ("runs", "runs_f64", "runs_periodic") and \
                algorithm.options.get("cull_runs"):
            uses += ("row_max", "col_max")
    return [k for k in built if k in uses]


def _growth_report(rows, out_dir):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    caches = cache_sizes()
    kernels = list(dict.fromkeys(r["kernel"] for r in rows))
    sides = sorted({int(r["side"]) for r in rows})
    by = {(int(r["side"]), r["kernel"]): r for r in rows}
    fig, axes = plt.subplots(1, 2, figsize=(13, 5))
    colours = plt.get_cmap("tab20").colors
    for ax, key, label in ((axes[0], "ns_per_ray", "ns per ray"),
                           (axes[1], "ns_per_cell", "ns per visited cell")):
        for n_k, k in enumerate(kernels):
            xs = [s for s in sides if (s, k) in by]
            ax.plot(xs, [float(by[(s, k)][key]) for s in xs], marker="o",
                    color="black" if k == "embree" else colours[(2 * n_k) % 20 + (n_k >= 10)],
                    linestyle="--" if k == "embree" else "-", label=k)
        for level, size in caches.items():
            if level == "L1d":
                continue
            side = math.sqrt(size / 4)  # heights alone fill the cache
            ax.axvline(side, color="grey", lw=0.8, ls=":")
            ax.text(side, 0.98, f" {level} {size / (1 << 20):g} MiB",
                    transform=ax.get_xaxis_transform(), va="top", fontsize=8, color="grey")
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("grid side (samples)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"Cost against grid side: fbm, r = {GROWTH_R}, elevation {GROWTH_ELEVATION:g} "
                 "degrees, one thread (dotted: the side whose float32 heights fill each cache)")
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "growth.png"), dpi=110)
    plt.close(fig)
    lines = ["# Cost against grid side (`hftrace scale --part growth`)", "",
             f"fbm, {rows[0]['rays'] if rows else ''} rays per side at run length {GROWTH_R}, "
             f"falling at {GROWTH_ELEVATION:g} degrees from one cell above the highest point, "
             "one thread pinned to one CPU, every kernel interleaved on the same rays in one "
             "run per side. Caches of this machine: "
             + ", ".join(f"{k} {v >> 10} KiB" for k, v in caches.items()) + ".", "",
             "ns per ray (ns per visited cell):", "",
             "| kernel | " + " | ".join(f"{s}^2" for s in sides) + " |",
             "|---|" + "---|" * len(sides)]
    for k in kernels:
        cells = [f"{float(by[(s, k)]['ns_per_ray']):.0f} ({float(by[(s, k)]['ns_per_cell']):.2f})"
                 if (s, k) in by else "-" for s in sides]
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    lines += ["", "cells per ray: " + ", ".join(
        f"{s}^2 {float(by[(s, kernels[0])]['cells_per_ray']):.0f}" for s in sides if (s, kernels[0]) in by),
        "", f"Embree is measured up to {EMBREE_MAX_SIDE}^2 by default: its scene for 8192^2 "
        "would be about 134 M triangles.", "", "![growth](growth.png)"]
    with open(os.path.join(out_dir, "growth.md"), "w") as f:
        f.write("\n".join(lines) + "\n")


