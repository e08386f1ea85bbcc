"""``hftrace terrain-bench``: the terrain products' targets on Jacksboro at 2048 samples and
fBm 2048^2: horizons at 16 azimuths, one-observer viewsheds against xarray-spatial (and
GDAL when ``osgeo`` imports), and ``runs_periodic`` against ``runs`` on parallel batches.
Writes ``targets.md``, ``targets.csv`` and ``env.json``. Method: ``bench.studies.terrain``.
"""
from __future__ import annotations

import csv
import os
import time

import numpy as np

import algos
import algos.terrain as T
import datasets_gen

from ..timing import environment, write_json
from .terrain import (
    HORIZON_METHODS,
    PARALLEL_COLUMNS,
    RUN_LENGTHS,
    azimuth_for_run_length,
    gdal_viewshed,
    hit_group,
    horizon_group,
    los_margins,
    observer_up,
    xrspatial_viewshed,
)
from .terrain_graph import dask_graph_sizes

__all__ = ["run_targets"]

# ---- the targets ---------------------------------------------------------------------------

def _fields(size):
    fbm = datasets_gen.load("fbm", size=size, seed=1)
    jb = datasets_gen.load("jacksboro", size=size)
    return [(f"jacksboro{size}", jb), (f"fbm{size}", fbm)]


def run_targets(out_dir="results/terrain-bench", size=2048, repeats=3, sample=16384, rays=4000,
                seed=2004, echo=print, quick=False):
    """The issue's targets table (module docstring), then the "every azimuth fast" section
    (:mod:`bench.studies.terrain_azimuths`). ``quick``: that section only, on small fields
    (Jacksboro at 128 samples, SVF on 96^2 at radii 4 and 20), one repeat: a check that
    it runs."""
    from .terrain_azimuths import run_azimuths

    os.makedirs(out_dir, exist_ok=True)
    env = environment()
    write_json(os.path.join(out_dir, "env.json"), env)
    lines = [f"# Terrain products: the targets ({'quick tier' if quick else f'{size} samples'})",
             "",
             f"Machine: {env['cpu']}; commit {env['git_commit']}. Single thread, pinned CPU. "
             "Command: `hftrace terrain-bench`.", ""]
    csv_rows = []
    azimuths = T.rational_azimuths(16)
    for label, hf in ([] if quick else _fields(size)):
        h = np.ascontiguousarray(hf.heights, dtype=np.float64)
        echo(f"  {label}: horizons at 16 azimuths")
        totals = {name: 0.0 for name in HORIZON_METHODS}
        errs = {name: 0.0 for name in HORIZON_METHODS}
        p99s = {name: 0.0 for name in HORIZON_METHODS}
        agree = {name: [] for name in HORIZON_METHODS}
        start = time.perf_counter()
        for az in azimuths:
            for row in horizon_group(h, az, HORIZON_METHODS, sample, repeats,
                                     embree_sample=4096):
                totals[row["algorithm"]] += row["field_seconds"]
                errs[row["algorithm"]] = max(errs[row["algorithm"]], row["max_err_deg"])
                p99s[row["algorithm"]] = max(p99s[row["algorithm"]], row["p99_err_deg"])
                agree[row["algorithm"]].append(row["agree_1e9"])
                csv_rows.append(dict(row, workload="horizon16", dataset=label, azimuth=az))
            echo(f"    az {az:7.3f} done ({time.perf_counter() - start:6.1f} s)")
        t0 = time.perf_counter()
        _, ran = T.horizon(hf, azimuths, threads=1, return_stats=True)
        wall = time.perf_counter() - t0
        lines += [f"## {label}: horizon, 16 rational azimuths (`rational_azimuths(16)`), "
                  "every vertex, unlimited distance", "",
                  f"`algos.horizon(field, rational_azimuths(16), threads=1)` (default "
                  f"algorithm `{ran.algorithm}`): **{wall:.2f} s** wall-clock, "
                  "frames and output included.", "",
                  "| method | seconds for the field (16 az.) | sweep's speedup | max error (deg) "
                  "| 99th percentile error (deg) | vertices within 1e-9 rad |",
                  "|---|---|---|---|---|---|"]
        for name in HORIZON_METHODS:
            note = "" if name == "sweep" else " (scaled from a sample)"
            lines.append(f"| `{name}`{note} | {totals[name]:.2f} | "
                         f"{totals[name] / totals['sweep']:.1f}x | {errs[name]:.2g} | "
                         f"{p99s[name]:.2g} | {100 * np.mean(agree[name]):.2f} % |")
        lines.append("")
        # viewshed
        rows_, cols_ = h.shape
        observer = (cols_ // 2, rows_ // 2)
        oh = 1.75 / hf.spacing if hf.unit != "cell" else 1.75
        times, ours = [], None
        for _ in range(repeats):
            t0 = time.perf_counter()
            ours, ran = T.viewshed(hf, observer, observer_height=1.75, threads=1,
                                   return_stats=True)
            times.append(time.perf_counter() - t0)
        stats = dict(ran.__dict__)
        ours_up = ours[::-1] if hf.north == "+y" else ours
        up_obs = observer_up(hf, observer)
        hu = h[::-1] if hf.north == "+y" else h
        lines += [f"## {label}: viewshed from one observer at the centre, 1.75 m", "",
                  f"- hftrace `{stats['algorithm']}`: {np.median(times):.2f} s (median of "
                  f"{repeats}); {100 * ours.mean():.2f} % visible; "
                  f"{stats['exact_resolved']} near-ties decided exactly."]
        for peer_name, peer_fn in (("xarray-spatial", xrspatial_viewshed), ("GDAL", gdal_viewshed)):
            if peer_fn(np.zeros((4, 4)), (1, 1), 1.0) is None:
                lines.append(f"- {peer_name}: not importable here; skipped.")
                continue
            ptimes, peer = [], None
            for _ in range(repeats):
                t0 = time.perf_counter()
                peer = peer_fn(hu, up_obs, oh)
                ptimes.append(time.perf_counter() - t0)
            differ = np.flatnonzero((peer != ours_up).ravel())
            z0 = float(hu[up_obs[1], up_obs[0]]) + oh
            margins, cell_ranges = los_margins(hu, up_obs, z0, differ)
            explained = np.abs(margins) <= cell_ranges + 1e-9
            lines.append(
                f"- {peer_name}: {np.median(ptimes):.2f} s; hftrace is "
                f"**{np.median(ptimes) / np.median(times):.1f}x** faster; agreement "
                f"{100 * (1 - len(differ) / h.size):.3f} % of vertices ({len(differ)} differ; "
                f"{100 * peer.mean():.2f} % visible). Of the differences, "
                f"{int(explained.sum())} ({100 * explained.mean() if len(differ) else 100:.1f} %) "
                f"are decided by a margin smaller than the height range of the cell that decides "
                f"them, where a cell-centre model and the two triangles put the surface at "
                f"different heights; the largest such margin is "
                f"{(np.abs(margins).max() if len(differ) else 0):.3g} cells.")
            csv_rows.append(dict(workload="viewshed", dataset=label, algorithm=peer_name,
                                 vertices=h.size, ns_per_vertex=np.median(ptimes) * 1e9 / h.size,
                                 field_seconds=np.median(ptimes), speedup_vs_dda=float("nan"),
                                 max_err_deg=float("nan"),
                                 agree_1e9=1 - len(differ) / h.size, azimuth=float("nan")))
        csv_rows.append(dict(workload="viewshed", dataset=label, algorithm=stats["algorithm"],
                             vertices=h.size, ns_per_vertex=np.median(times) * 1e9 / h.size,
                             field_seconds=np.median(times), speedup_vs_dda=float("nan"),
                             max_err_deg=float("nan"), agree_1e9=1.0, azimuth=float("nan")))
        lines.append("")
        # runs_periodic on parallel batches
        field = algos.Field(hf.heights)
        lines += [f"## {label}: orthographic first hits ({rays} parallel rays)", "",
                  "| r | `runs_periodic` / `runs` speed | `runs` ns/ray | `runs_periodic` ns/ray |",
                  "|---|---|---|---|"]
        for r in RUN_LENGTHS:
            group = {g["algorithm"]: g for g in hit_group(field, r, ("dda", "runs", "runs_periodic"),
                                                            rays, max(repeats, 5), seed)}
            a, b = group["runs"]["ns_per_vertex"], group["runs_periodic"]["ns_per_vertex"]
            lines.append(f"| {r} | {a / b:.2f}x | {a:.0f} | {b:.0f} |")
            for g in group.values():
                csv_rows.append(dict(g, workload="ortho_first_hit", dataset=label, run_length=r,
                                     azimuth=azimuth_for_run_length(r)))
        lines.append("")
    if quick:
        az_lines, az_rows = run_azimuths(size=128, svf_size=96, radii=(4, 20), repeats=1,
                                         baseline=True, echo=echo)
    else:
        az_lines, az_rows = run_azimuths(size=size, repeats=repeats, echo=echo)
    lines += [""] + ["#" + line if line.startswith("#") else line for line in az_lines]
    csv_rows += az_rows
    lines += dask_graph_sizes(out_dir, echo=echo)
    with open(os.path.join(out_dir, "targets.md"), "w") as f:
        f.write("\n".join(lines))
    with open(os.path.join(out_dir, "targets.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, PARALLEL_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for row in csv_rows:
            writer.writerow({k: row.get(k, "") for k in PARALLEL_COLUMNS})
    echo("\n".join(lines))
    return lines


