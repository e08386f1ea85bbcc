"""The cost model of a report directory: ns per ray, cell and run next to instructions and
branches per cell, for every (workload, algorithm) in its ``results.csv``.

Times are the medians over the report's groups; counts come from callgrind
(:mod:`bench.profile`) on fixed rays (fbm 1024^2, r = 25, 300 rays; first hits on
triangles), written to ``counts.csv`` in the same directory, one row per kernel as it is
counted (``--resume`` keeps them). The section replaces any earlier one at the end of the
report's markdown file.

    python -m bench.cost_report results/bench-intersect [--markdown tables.md] [--resume]
"""
from __future__ import annotations

import argparse
import csv
import os

import pandas as pd

from .profile import callgrind_available, profile

FIELDS = ["workload", "kernel", "dataset", "size", "r", "rays", "instructions_per_cell",
          "branches_per_cell", "instructions_per_ray"]
HEADING = "## Cost model"


def cost_model(df, counts=None) -> list:
    """The cost model's table: ns per ray, cell and run (medians over the first-hit
    groups on triangles), with instructions and branches per cell from ``counts.csv``
    (:mod:`bench.counts`) where they were counted."""
    cost = df[(df["workload"] == "first_hit") & (df["surface"] == "triangles")]
    if cost.empty:
        return []
    c = cost.groupby("algorithm", sort=False)[["ns_per_ray", "ns_per_cell", "ns_per_run"]].median()
    counts = counts or {}
    lines = ["## Cost model (first hit, triangles; medians over groups)", ""]
    if counts:
        any_row = next(iter(counts.values()))
        lines += [f"Instructions and branches per cell: callgrind, {any_row['dataset']} "
                  f"{any_row['size']}^2, r = {any_row['r']}, {any_row['rays']} rays "
                  "(`hftrace profile KERNEL`; per cell of the `runs` walk up to its hit, "
                  "each ray's setup included).", ""]
    else:
        lines += ["No instruction counts here (valgrind was not available, or "
                  "`--no-counts`); `hftrace profile KERNEL` gives them.", ""]
    lines += ["| algorithm | ns/ray | ns/cell | ns/run | instr/cell | branches/cell |",
              "|---|---|---|---|---|---|"]
    for a, r in c.iterrows():
        k = counts.get(a, {})
        lines.append(f"| {a} | {r.ns_per_ray:.0f} | {r.ns_per_cell:.2f} | {r.ns_per_run:.2f} | "
                     f"{k.get('instructions_per_cell', '')} | {k.get('branches_per_cell', '')} |")
    lines.append("")
    return lines


def _read(path):
    if not os.path.exists(path):
        return {}
    with open(path, newline="") as f:
        return {(row["workload"], row["kernel"]): row for row in csv.DictReader(f)}


def count(report_dir, pairs, resume=False, rays=300, echo=print) -> dict:
    """Counts of every (workload, kernel) pair into report_dir/counts.csv."""
    path = os.path.join(report_dir, "counts.csv")
    done = _read(path) if resume else {}
    if not callgrind_available():
        echo("cost_report: valgrind not found; times only")
        return done
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS)
        writer.writeheader()
        for row in done.values():
            writer.writerow({k: row.get(k, "") for k in FIELDS})
        for workload, kernel in pairs:
            if kernel in ("embree", "embree3") or (workload, kernel) in done:
                continue
            p = profile(kernel, size=1024, r=25, rays=rays, workload=workload)
            row = dict(workload=workload, kernel=kernel, dataset="fbm", size=1024, r=25,
                       rays=rays, instructions_per_cell=round(p["instructions_per_cell"], 2),
                       branches_per_cell=round(p["branches_per_cell"], 2),
                       instructions_per_ray=round(p["instructions_per_ray"], 1))
            writer.writerow(row)
            f.flush()
            done[(workload, kernel)] = row
            echo(f"cost_report: {workload} {kernel} {row['instructions_per_cell']} instructions/cell")
    return done


def section(df, counts) -> str:
    """The cost-model section (Markdown): per (workload, algorithm) the median ns per
    ray, cell and run of ``df`` next to ``counts``' instructions and branches per cell."""
    lines = [HEADING, "",
             "Medians over this report's groups (ns) and callgrind counts per cell (fbm "
             "1024^2, r = 25, 300 rays; first hits on triangles; each ray's setup included; "
             "`hftrace profile KERNEL --workload W`). Cells and runs are those of the exact "
             "walk (first hits: up to the hit).", "",
             "| workload | algorithm | ns/ray | ns/cell | ns/run | instr/cell | branches/cell |",
             "|---|---|---|---|---|---|---|"]
    med = df.groupby(["workload", "algorithm"], sort=False)[
        ["ns_per_ray", "ns_per_cell", "ns_per_run"]].median()
    for (workload, algorithm), r in med.iterrows():
        c = counts.get((workload, algorithm), {})
        lines.append(f"| {workload} | {algorithm} | {r.ns_per_ray:.0f} | {r.ns_per_cell:.2f} | "
                     f"{r.ns_per_run:.2f} | {c.get('instructions_per_cell', '')} | "
                     f"{c.get('branches_per_cell', '')} |")
    return "\n".join(lines) + "\n"


def write(report_dir, markdown="tables.md", resume=False, echo=print):
    """Count every (workload, kernel) of ``report_dir``/results.csv and put the cost
    section at the end of ``report_dir``/``markdown``, replacing an earlier one; returns
    the Markdown path."""
    df = pd.read_csv(os.path.join(report_dir, "results.csv"))
    if "workload" not in df:
        df["workload"] = "first_hit"
    pairs = list(dict.fromkeys(zip(df["workload"], df["algorithm"])))
    pairs = [(w, k) for w, k in pairs if not str(k).startswith("march")] + \
            [(w, k) for w, k in pairs if str(k).startswith("march")]
    counts = count(report_dir, pairs, resume=resume, echo=echo)
    path = os.path.join(report_dir, markdown)
    text = open(path).read() if os.path.exists(path) else ""
    if HEADING in text:
        text = text[: text.index(HEADING)].rstrip() + "\n"
    with open(path, "w") as f:
        f.write(text + ("\n" if text else "") + section(df, counts))
    return path


def main(argv=None):
    """``python -m bench.cost_report REPORT_DIR``: :func:`write`; exit status 0."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report_dir")
    parser.add_argument("--markdown", default="tables.md")
    parser.add_argument("--resume", action="store_true")
    args = parser.parse_args(argv)
    print(write(args.report_dir, args.markdown, args.resume))


if __name__ == "__main__":
    main()
