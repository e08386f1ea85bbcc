"""Before/after figures of a kernel change: ns/ray, ns/cell and callgrind counts of every
first-hit kernel on the rays of bench-intersect, measured by the tree this module is
imported from. Run it once per tree (e.g. a git worktree of the old commit) and join the
CSVs; times come from separate processes (medians of interleaved repeats within each),
instruction counts are exact.

    python -m bench.studies.before_after OUT.csv [--label after] [--counts]
"""
from __future__ import annotations

import argparse
import csv

import algos
import datasets_gen

from ..sweep import measure_group
from ..timing import pin_to_one_cpu

KERNELS = ("dda", "dda_f32", "midpoint", "runs", "runs_f64", "runs_periodic", "dda_maxmip",
           "runs_maxmip", "embree")
FIELDS = (("fbm", 1024), ("fbm", 2048))
RUN_LENGTHS = (1, 25, "random")


def main(argv=None):
    """``python -m bench.studies.before_after OUT.csv``: every kernel's rows on the fields
    and run lengths above (``--counts``: with callgrind counts) into OUT.csv."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("--label", default="after")
    parser.add_argument("--rays", type=int, default=4000)
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--counts", action="store_true", help="also callgrind counts (slow)")
    parser.add_argument("--count-rays", type=int, default=300)
    args = parser.parse_args(argv)
    pin_to_one_cpu()
    rows = []
    for name, side in FIELDS:
        field = algos.Field(datasets_gen.load(name, size=side, seed=1).heights)
        for r in RUN_LENGTHS:
            for row in measure_group(field, f"{name}{side}", "first_hit", "triangles", r,
                                     list(KERNELS), args.rays, args.repeats, 2008):
                rows.append(dict(label=args.label, dataset=row["dataset"], r=r,
                                 kernel=row["algorithm"], ns_per_ray=row["ns_per_ray"],
                                 ns_per_cell=row["ns_per_cell"], cells_per_ray=row["cells_per_ray"],
                                 speedup_vs_dda=row["speedup"]))
                print(rows[-1], flush=True)
    if args.counts:
        from ..profile import profile

        for row in rows:
            if row["kernel"] == "embree" or row["r"] != 25:
                continue
            p = profile(row["kernel"], size=int(row["dataset"][3:]), r=25, rays=args.count_rays)
            row["instructions_per_cell"] = round(p["instructions_per_cell"], 2)
            row["branches_per_cell"] = round(p["branches_per_cell"], 2)
            print(row, flush=True)
    keys = sorted({k for row in rows for k in row}, key=lambda k: list(rows[0]).index(k)
                  if k in rows[0] else 99)
    with open(args.out, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main()
