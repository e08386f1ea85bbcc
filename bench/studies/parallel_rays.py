"""The "parallel rays" part of ``hftrace reproduce``: per-azimuth horizon (and so shadow)
workloads and orthographic first hits at octant slopes 1/r, r in {1, 2, 5, 25, 100},
with every method, on the embedded Jacksboro DEM. Writes ``parallel.csv`` (a row as
each group finishes; ``resume`` keeps them), ``parallel.md`` and ``products.png``.
Method: ``bench.studies.terrain``.
"""
from __future__ import annotations

import csv
import math
import os
import time

import numpy as np

import algos
import algos.terrain as T
import datasets_gen

from ..analysis import ratio_text
from ..report import RowWriter
from ..timing import log_ratio_interval
from .terrain import (
    HIT_METHODS,
    HORIZON_METHODS,
    PARALLEL_COLUMNS,
    RUN_LENGTHS,
    azimuth_for_run_length,
    hit_group,
    horizon_group,
    observer_up,
    xrspatial_viewshed,
)

__all__ = ["run_parallel", "products_figure"]

#: products.png is a 13 x 8.5 inch figure of six noisy raster panels: at 70 dpi it stays
#: well under 1 MB (at 110 dpi it was 1.7 MB)
PRODUCTS_DPI = 70

def _done(path):
    if not os.path.exists(path):
        return set()
    with open(path) as f:
        return {(r["workload"], r["dataset"], r["run_length"]) for r in csv.DictReader(f)}


def _read(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def _table(rows, workload, value, fmt, methods):
    rs = sorted({int(r["run_length"]) for r in rows if r["workload"] == workload})
    lines = ["| algorithm | " + " | ".join(f"r = {r}" for r in rs) + " |",
             "|---" * (len(rs) + 1) + "|"]
    for name in methods:
        cells = []
        for r in rs:
            m = [x for x in rows if x["workload"] == workload and int(x["run_length"]) == r
                 and x["algorithm"] == name]
            cells.append(fmt(float(m[0][value])) if m else "")
        if any(cells):
            lines.append(f"| `{name}` | " + " | ".join(cells) + " |")
    return "\n".join(lines)


#: The tables of parallel.md: (title, workload, column, format after the colon).
PARALLEL_TABLES = (
    ("Horizon: ns per vertex", "horizon", "ns_per_vertex", "0f"),
    ("Horizon: speedup over the per-vertex `dda` walk", "horizon", "speedup_vs_dda", "2f"),
    ("Horizon: largest angle error against the exact sweep (degrees)", "horizon",
     "max_err_deg", "2g"),
    ("Horizon: 99th percentile of the angle error (degrees)", "horizon", "p99_err_deg", "2g"),
    ("Orthographic first hits: speedup over `dda`", "first_hit", "speedup_vs_dda", "2f"),
    ("Orthographic first hits: ns per ray", "first_hit", "ns_per_vertex", "0f"),
)


def run_parallel(out_dir="results/reproduce", size=None, run_lengths=RUN_LENGTHS, repeats=5,
                 sample=20000, rays=2000, seed=2004, resume=False, echo=print, figure=True):
    """The "parallel rays" part of ``hftrace reproduce`` (module docstring)."""
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "parallel.csv")
    if not resume and os.path.exists(path):
        os.remove(path)
    done = _done(path)
    hf = datasets_gen.load("jacksboro", size=size)
    label = f"jacksboro{max(hf.shape)}"
    h = np.ascontiguousarray(hf.heights, dtype=np.float64)
    field = algos.Field(hf.heights)
    start = time.perf_counter()
    with RowWriter(path, PARALLEL_COLUMNS, append=bool(done)) as writer:
        for r in run_lengths:
            az = azimuth_for_run_length(r)
            for workload in ("horizon", "first_hit"):
                if (workload, label, str(r)) in done:
                    continue
                if workload == "horizon":
                    group = horizon_group(h, az, HORIZON_METHODS, sample, repeats)
                else:
                    group = hit_group(field, r, HIT_METHODS, rays, repeats, seed)
                for row in group:
                    writer.write(dict(row, workload=workload, dataset=label, run_length=r,
                                      azimuth=round(az, 6)))
                echo(f"  parallel rays {label} {workload} r={r:<4} done "
                     f"({time.perf_counter() - start:6.1f} s)")
    rows = _read(path)
    text = [f"# Parallel rays at work ({label})", "",
            "Every vertex's horizon along one azimuth of octant slope 1/r (so shadows at any "
            "sun elevation: a shadow is one comparison more), and orthographic first hits "
            f"({rays} parallel rays falling at 10 degrees, same slope), single thread, "
            f"{repeats} interleaved repeats with flushed caches. Per-vertex methods ran on "
            f"about {sample} vertices in evenly spread row bands (Embree on 2048), scaled to "
            "the field; the sweep does every vertex.", ""]
    for title, workload, column, digits in PARALLEL_TABLES:
        methods = HORIZON_METHODS if workload == "horizon" else HIT_METHODS
        text += [f"## {title}", "",
                 _table(rows, workload, column, lambda v, d=digits: f"{v:.{d}}", methods), ""]
    text += ["## What the periodic patterns buy", "",
             "Geometric means of the paired per-repeat ratios, ±the half-width of their 95 % "
             "interval (Student's t on the log-ratios); labelled as every table is "
             "(`bench.analysis.finding`, docs/METHOD.md): a ratio wider than ±2 % says why "
             "it is inconclusive, one whose interval contains 1 says `(same)`.", ""]
    for r in sorted({int(x["run_length"]) for x in rows}):
        def ratio(workload, num, den):
            a = [x for x in rows if x["workload"] == workload and int(x["run_length"]) == r
                 and x["algorithm"] in (num, den)]
            got = {x["algorithm"]: x.get("ns_samples") or "" for x in a}
            if not got.get(num) or not got.get(den):
                return "no interval (per-repeat times not recorded): inconclusive"
            top = np.array([float(v) for v in got[num].split(";")])
            bottom = np.array([float(v) for v in got[den].split(";")])
            text = ratio_text(*log_ratio_interval(top, bottom)).replace(" ", "x ", 1)
            return text or "no interval (fewer than two repeats): inconclusive"
        text.append(f"- r = {r}: `runs_periodic` {ratio('first_hit', 'runs', 'runs_periodic')} "
                    f"`runs` on orthographic first hits; the shared pattern "
                    f"{ratio('horizon', 'dda', 'pattern')} and the sweep "
                    f"{ratio('horizon', 'dda', 'sweep')} the per-vertex walk on horizons.")
    text.append("")
    with open(os.path.join(out_dir, "parallel.md"), "w") as f:
        f.write("\n".join(text))
    if figure:
        products_figure(hf, os.path.join(out_dir, "products.png"), echo=echo)
    echo("\n".join(text[:14]))
    return rows


# ---- figure ----------------------------------------------------------------------------

def products_figure(hf, path, sun=(135.0, 15.0), echo=print):
    """Shadows and sky-view factor on a field, ours next to the peers' (the r.horizon-style
    marcher, the RVT-style marcher over 16 equal azimuths) and the viewshed next to
    xarray-spatial's when it is installed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from datasets_gen.preview import hillshade

    h = hf.heights
    # display north up: fields whose rows run north (jacksboro) are flipped by the products
    north_up = (lambda a: a[::-1]) if hf.north == "+y" else (lambda a: a)
    ours_sh = T.shadows(hf, sun[0], sun[1])
    march_sh = T.horizon(hf, sun[0], algorithm="march")[0] > math.radians(sun[1])
    svf = T.sky_view_factor(hf, 16, rational=True)
    svf_rvt = T.sky_view_factor(hf, 16, algorithm="march")
    rows, cols = h.shape
    observer = (cols // 2, rows // 2)
    vs = T.viewshed(hf, observer, observer_height=1.75)
    peer = xrspatial_viewshed(north_up(np.asarray(h, float)), observer_up(hf, observer), 1.75 / hf.spacing
                              if hf.unit != "cell" else 1.75)
    fig, axes = plt.subplots(2, 3, figsize=(13, 8.5), constrained_layout=True)
    shade = north_up(hillshade(h))
    panels = [
        (north_up(ours_sh), f"shadows, exact (sun {sun[0]:.0f}/{sun[1]:.0f} deg)", "gray_r"),
        (north_up(march_sh), "shadows, r.horizon-style marcher", "gray_r"),
        (north_up(svf), "sky-view factor, exact sweep (16 rational az.)", "viridis"),
        (north_up(svf_rvt), "sky-view factor, RVT-style marcher (16 az.)", "viridis"),
        (north_up(vs), "viewshed, exact (observer 1.75 m)", "Greens"),
        (None if peer is None else peer, "viewshed, xarray-spatial" if peer is not None
         else "xarray-spatial not installed", "Greens"),
    ]
    for ax, (img, title, cmap) in zip(axes.ravel(), panels):
        ax.imshow(shade, cmap="gray", alpha=0.6)
        if img is not None:
            ax.imshow(img.astype(float), cmap=cmap, alpha=0.6,
                      vmin=0 if img.dtype == bool else None, vmax=1 if img.dtype == bool else None)
        ax.set_title(title, fontsize=9)
        ax.set_axis_off()
    fig.suptitle(f"{hf.name} {rows}x{cols}: products and their peers", fontsize=11)
    fig.savefig(path, dpi=PRODUCTS_DPI)
    plt.close(fig)
    echo(f"wrote {path}")


