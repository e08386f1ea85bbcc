"""The floor level of the max-mipmap walks, chosen by measurement.

``dda_maxmip`` walks the tiles of its floor level (2^floor cells wide) cell by cell,
``runs_maxmip`` run by run; above the floor both skip or descend. This times every floor
from 0 to 5 for both, next to ``dda`` and the fair Embree peer, on the rays of
bench-intersect (interleaved repeats in one process, caches flushed before each timed
run, one pinned CPU), and counts
instructions per ray with callgrind (fbm 1024^2, r = 25).

    python -m bench.studies.maxmip_floor [--out results/maxmip_floor] [--no-counts]

(the committed reference: ``--out reports/tuning``, ``make reports``)
"""
from __future__ import annotations

import argparse
import csv
import os

import numpy as np

import algos
import datasets_gen
from algos.intersect import prepare_timed_intersect
from datasets_gen.rays import first_hit_rays

from ..timing import interleaved, pin_to_one_cpu

FLOORS = range(6)
FIELDS = (("fbm", 1024), ("fbm", 2048))
RUN_LENGTHS = (1, 25, "random")


def configs():
    """(kernel, options) of every configuration timed: ``dda``, both max-mipmap kernels at
    every floor of :data:`FLOORS`, and Embree."""
    yield "dda", {}
    for k in ("dda_maxmip", "runs_maxmip"):
        for f in FLOORS:
            yield k, {"fine_level": f}
    yield "embree", {}


def label(kernel, opts):
    """The table label of one configuration, e.g. ``runs_maxmip floor 3``."""
    return kernel + (f" floor {opts['fine_level']}" if "fine_level" in opts else "")


def measure(rays=4000, repeats=7, seed=2008):
    """Rows of ns per ray and speedup over ``dda`` for every configuration, field and run
    length, all configurations interleaved on the same first-hit rays."""
    rows = []
    for name, side in FIELDS:
        field = algos.Field(datasets_gen.load(name, size=side, seed=1).heights)
        for r in RUN_LENGTHS:
            o, d = first_hit_rays(field, r, rays, seed)
            runs = [(k, opts, prepare_timed_intersect(k, field, o, d, **opts)[0])
                    for k, opts in configs()]
            got = interleaved({slot: run for slot, (_, _, run) in enumerate(runs)}, repeats)
            times = [got[slot] for slot in range(len(runs))]
            dda = np.median(times[0]) / rays
            for (k, opts, _), t in zip(runs, times):
                ns = np.median(t) / rays
                rows.append(dict(dataset=f"{name}{side}", r=r, kernel=k,
                                 floor=opts.get("fine_level", ""), ns_per_ray=round(ns, 1),
                                 speedup_vs_dda=round(dda / ns, 3)))
                print(rows[-1], flush=True)
    return rows


def counts(rows, rays=300):
    """Add callgrind's instructions and branches per ray to the fbm1024, r = 25 rows
    (in place; Embree excluded)."""
    from ..profile import profile

    for row in rows:
        if row["dataset"] != "fbm1024" or row["r"] != 25 or row["kernel"] == "embree":
            continue
        opts = {"fine_level": row["floor"]} if row["floor"] != "" else {}
        p = profile(row["kernel"], size=1024, r=25, rays=rays, options=opts)
        row["instructions_per_ray"] = round(p["instructions_per_ray"], 1)
        row["branches_per_ray"] = round(p["branches_per_ray"], 1)
        print(row, flush=True)


def write(rows, out):
    """maxmip_floor.csv and maxmip_floor.md of ``rows`` into ``out``."""
    os.makedirs(out, exist_ok=True)
    keys = ["dataset", "r", "kernel", "floor", "ns_per_ray", "speedup_vs_dda",
            "instructions_per_ray", "branches_per_ray"]
    with open(os.path.join(out, "maxmip_floor.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    lines = ["# Max-mipmap floor level", "",
             "Written by `python -m bench.studies.maxmip_floor`. ns per ray (median of interleaved "
             "repeats, caches flushed before each, one pinned CPU), speedup over `dda` in the same process; "
             "instructions per ray from callgrind (fbm 1024^2, r = 25, 300 rays).", ""]
    groups = [(d, r) for d in dict.fromkeys(x["dataset"] for x in rows)
              for r in dict.fromkeys(x["r"] for x in rows)]
    lines.append("| kernel | " + " | ".join(f"{d} r={r}" for d, r in groups) + " | instr/ray |")
    lines.append("|---" * (len(groups) + 2) + "|")
    for k, opts in configs():
        cells = []
        instr = ""
        for d, r in groups:
            for x in rows:
                if (x["dataset"], x["r"], x["kernel"]) == (d, r, k) and \
                        x["floor"] == opts.get("fine_level", ""):
                    cells.append(f"{x['ns_per_ray']:.0f} ({x['speedup_vs_dda']:.2f}x)")
                    instr = x.get("instructions_per_ray", instr)
        lines.append(f"| {label(k, opts)} | " + " | ".join(cells) + f" | {instr} |")
    with open(os.path.join(out, "maxmip_floor.md"), "w") as f:
        f.write("\n".join(lines) + "\n")


def main(argv=None):
    """``python -m bench.studies.maxmip_floor``: measure on one pinned CPU, count, write."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results/maxmip_floor")
    parser.add_argument("--rays", type=int, default=4000)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--no-counts", action="store_true")
    args = parser.parse_args(argv)
    pin_to_one_cpu()
    rows = measure(args.rays, args.repeats)
    if not args.no_counts:
        counts(rows)
    write(rows, args.out)


if __name__ == "__main__":
    main()
