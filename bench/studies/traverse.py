"""``hftrace bench-traverse``: the 2D workloads of every traversal kernel, relative to dda.

For each mean run length r, one seeded ray set (``datasets_gen.rays.by_run_length``:
azimuth atan(1/r) mirrored over the 8 octants, origins uniform inside the grid, rays
grouped by direction so parallel rays are consecutive) is walked by every kernel in the
registry, in one process, interleaved, on one thread, timed in C around the whole batch.

Columns: ns_per_ray is the median over repeats of (batch time / rays); speedup is
median(dda) / median(algorithm) from the same repeats, with a paired bootstrap 95 %
interval; agree is the fraction of rays whose checksum equals the exact ``midpoint``'s
(1.0 for every exact kernel; float kernels and approximate slopes may differ).
"""
from __future__ import annotations

import os
import time

import numpy as np

import algos
from datasets_gen.rays import traversal_rays

from ..report import RowWriter, speedup_table
from ..timing import environment, interleaved, median_ci, ratio_ci, write_json

RUN_LENGTHS = (1, 2, 5, 25, 100)
BASELINE = "dda"
REFERENCE_KERNEL = "midpoint"  # exact: the checksums every kernel is compared with

COLUMNS = ["workload", "run_length", "algorithm", "baseline", "grid", "rays",
           "cells_per_ray", "runs_per_ray", "ns_per_ray", "ns_per_ray_ci_low",
           "ns_per_ray_ci_high", "ns_per_cell", "ns_per_run", "speedup", "speedup_ci_low",
           "speedup_ci_high", "agree", "repeats"]


def measure(r, workload, n, side, repeats, seed, names=None):
    """Rows for one (r, workload): every kernel on the same rays."""
    names = list(names or algos.TRAVERSALS)
    if BASELINE not in names:
        names.insert(0, BASELINE)
    o, d = traversal_rays((side, side), r, n, seed)
    shape = (side, side)
    counts = algos.traverse(REFERENCE_KERNEL, o, d, shape, output="count")
    jobs, checksums = {}, {}
    for name in names:
        jobs[name], checksums[name] = algos.prepare_timed(name, o, d, shape, workload)
    reference_run, reference_sums = algos.prepare_timed(REFERENCE_KERNEL, o, d, shape, workload)
    reference_run()
    times = interleaved(jobs, repeats)
    cells_per_ray = float(counts.cells.mean())
    runs_per_ray = float(counts.runs.mean())
    rows = []
    for name in names:
        per_ray = times[name] / n
        median, low, high = median_ci(per_ray, seed=seed)
        speedup, s_low, s_high = ratio_ci(times[BASELINE], times[name], seed=seed)
        rows.append(dict(
            workload=workload, run_length=r, algorithm=name, baseline=BASELINE,
            grid=f"{side}x{side}", rays=n, cells_per_ray=round(cells_per_ray, 2),
            runs_per_ray=round(runs_per_ray, 2), ns_per_ray=round(median, 2),
            ns_per_ray_ci_low=round(low, 2), ns_per_ray_ci_high=round(high, 2),
            ns_per_cell=round(median / cells_per_ray, 4) if cells_per_ray else float("nan"),
            ns_per_run=round(median / runs_per_ray, 4) if runs_per_ray else float("nan"),
            speedup=round(speedup, 4), speedup_ci_low=round(s_low, 4),
            speedup_ci_high=round(s_high, 4),
            agree=round(float(np.mean(checksums[name] == reference_sums)), 6),
            repeats=repeats,
        ))
    return rows


def format_table(rows, workload) -> str:
    """A Markdown table: one row per algorithm, one column per run length."""
    rows = [row for row in rows if row["workload"] == workload]

    def counts(columns, lookup, names):
        return "| cells / runs per ray | " + " | ".join(
            f"{lookup[(names[0], r)]['cells_per_ray']:.0f} / {lookup[(names[0], r)]['runs_per_ray']:.0f}"
            for r in columns) + " |"

    return speedup_table(rows, footer=counts)


def run(out_dir="results/bench-traverse", n=2000, side=1024, repeats=9, seed=2004,
        run_lengths=RUN_LENGTHS, names=None, echo=print):
    """Measure every (workload, r), print the tables and write results.csv, tables.md
    and env.json to ``out_dir``. Rows are appended and flushed as they are measured."""
    os.makedirs(out_dir, exist_ok=True)
    env = environment()
    write_json(os.path.join(out_dir, "env.json"), env)
    rows = []
    start = time.perf_counter()
    with RowWriter(os.path.join(out_dir, "results.csv"), COLUMNS) as writer:
        for workload in algos.WORKLOADS:
            for r in run_lengths:
                for row in measure(r, workload, n, side, repeats, seed, names):
                    writer.write(row)
                    rows.append(row)
                echo(f"  {workload:5s} r={r:<4} done ({time.perf_counter() - start:5.1f} s)")
    text = [f"# bench-traverse: speedup over `{BASELINE}` (median ratio [95 % CI], ns/ray)",
            "",
            f"{n} rays per run length on a {side}x{side} grid, origins inside, "
            f"{repeats} interleaved repeats, one thread. Machine: {env['cpu']}, "
            f"commit {env['git_commit']}.",
            "Speedup = median time of dda / median time of the algorithm, same rays, same "
            "process. `agree` < 100 % marks rays whose cells differ from the exact walk.",
            ""]
    for workload in algos.WORKLOADS:
        text += [f"## workload `{workload}`", "", format_table(rows, workload), ""]
    with open(os.path.join(out_dir, "tables.md"), "w") as f:
        f.write("\n".join(text))
    echo("\n".join(text))
    return rows
