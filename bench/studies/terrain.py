"""Parallel rays at work: terrain products timed against each other and against the peers.

Two entry points:

* :func:`run_parallel` (part of ``hftrace reproduce``): per-azimuth horizon (and so shadow)
  workloads and orthographic first hits at octant slopes 1/r, r in {1, 2, 5, 25, 100},
  with every method, on the embedded Jacksboro DEM. Writes ``parallel.csv`` (a row as
  each group finishes; ``resume`` keeps them), ``parallel.md`` and ``products.png``.
* :func:`run_targets` (``hftrace terrain-bench``): the issue's targets on Jacksboro at
  2048 samples and fBm 2048^2: horizons at 16 azimuths, one-observer viewsheds against
  xarray-spatial (and GDAL when ``osgeo`` imports), and ``runs_periodic`` against
  ``runs`` on parallel batches. Writes ``reports/terrain/targets.md`` and ``targets.csv``.

Method: single thread, pinned CPU, interleaved repeats with flushed caches
(``bench.timing.interleaved``), C clocks around the kernels. Per-vertex methods too slow for
every vertex of a big field run on a sample of evenly spread row bands. Their time is
reported per vertex and scaled to the field, and this is stated next to each figure. The
sweep always does every vertex.
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

from .report import RowWriter
from .timing import environment, interleaved, write_json

RUN_LENGTHS = (1, 2, 5, 25, 100)
HORIZON_METHODS = ("sweep", "pattern", "dda", "dda_maxmip", "march", "embree")
HIT_METHODS = ("dda", "runs", "runs_periodic", "dda_maxmip", "runs_maxmip", "embree")
PARALLEL_COLUMNS = ["workload", "dataset", "run_length", "azimuth", "algorithm", "vertices",
                    "ns_per_vertex", "field_seconds", "speedup_vs_dda", "max_err_deg",
                    "p99_err_deg", "agree_1e9"]


def azimuth_for_run_length(r) -> float:
    """The azimuth whose octant slope is exactly 1/r (east-south-east; rational (r, 1))."""
    return 90.0 + math.degrees(math.atan2(1, r))


def sample_ranges(rows, cols, n_vertices, bands=32):
    """About n_vertices in ``bands`` contiguous pieces of rows spread evenly down the field,
    each centred in its row (whole rows when a band needs more), as C-order ranges."""
    per = max(1, int(n_vertices) // bands)
    out = []
    for row in np.linspace(0, rows - 1, bands).astype(int):
        length = min(per, (rows - row) * cols)
        start = row * cols + max(0, (cols - length) // 2)
        if out and start < out[-1][1]:
            start = out[-1][1]
        stop = min(start + length, rows * cols)
        if stop > start:
            out.append((start, stop))
    return out


def _err(values, exact):
    ok = np.isfinite(exact) & ~np.isnan(values)
    both_empty = ok & (exact == -np.inf) & (values == -np.inf)
    valid = ok & np.isfinite(values) & np.isfinite(exact)
    a, b = np.arctan(values[valid]), np.arctan(exact[valid])
    diff = np.abs(a - b)
    n = int(ok.sum())
    agree = (np.sum(diff <= 1e-9) + np.sum(both_empty)) / max(n, 1)
    mismatch = int(np.sum(ok & (np.isinf(values) != np.isinf(exact))))
    worst = np.inf if mismatch else (float(np.degrees(diff.max())) if len(diff) else 0.0)
    p99 = float(np.degrees(np.percentile(diff, 99))) if len(diff) else 0.0
    return worst, float(agree), p99


def horizon_group(h, azimuth, methods, sample, repeats, embree_sample=2048):
    """Time every method on one azimuth; rows with ns per vertex and error against the
    sweep (or the plain walk when the azimuth is not rational)."""
    rows, cols = h.shape
    ranges = sample_ranges(rows, cols, sample) if sample and sample < h.size else None
    e_ranges = sample_ranges(rows, cols, embree_sample)
    jobs, values, counts = {}, {}, {}
    for name in methods:
        use = e_ranges if name == "embree" else ranges
        run, vals, n = T.prepare_horizon_timed(h, azimuth, name, ranges=use)
        jobs[name], values[name], counts[name] = run, vals, n
    times = interleaved(jobs, repeats)
    exact_name = "sweep" if "sweep" in methods else "dda"
    exact = values[exact_name]()
    per = {name: float(np.median(times[name])) / counts[name] for name in methods}
    out = []
    for name in methods:
        err, agree, p99 = _err(values[name](), exact)
        out.append(dict(algorithm=name, vertices=counts[name], ns_per_vertex=per[name],
                        field_seconds=per[name] * h.size / 1e9,
                        speedup_vs_dda=per.get("dda", float("nan")) / per[name],
                        max_err_deg=err, p99_err_deg=p99, agree_1e9=agree))
    return out


def orthographic_rays(shape, r, n, seed, elevation_deg=10.0, top=None):
    """n parallel rays of octant slope 1/r (direction (r, 1) scaled), falling at
    elevation_deg, origins spread over the field one cell above ``top``."""
    rays = datasets_gen.rays.parallel(n, shape, seed, rational=(1, r))
    d2 = rays.directions
    norm = np.hypot(d2[:, 0], d2[:, 1])
    d = np.column_stack([d2, -norm * math.tan(math.radians(elevation_deg))])
    o = np.column_stack([rays.origins, np.full(len(d), float(top) + 1.0)])
    return o, d


def hit_group(field, r, methods, n, repeats, seed):
    from algos.intersect import prepare_timed_intersect

    h = field.heights
    o, d = orthographic_rays((h.shape[1] - 1, h.shape[0] - 1), r, n, seed, top=field.hmax)
    jobs, hits = {}, {}
    for name in methods:
        jobs[name], hits[name] = prepare_timed_intersect(name, field, o, d, surface="triangles")
    times = interleaved(jobs, repeats)
    ref = hits["runs"]()
    per = {name: float(np.median(times[name])) / n for name in methods}
    out = []
    for name in methods:
        t = hits[name]()
        with np.errstate(invalid="ignore"):
            same = (np.isinf(t) & np.isinf(ref)) | (np.abs(t - ref) <= 1e-4 * (1 + np.abs(ref)))
        out.append(dict(algorithm=name, vertices=n, ns_per_vertex=per[name],
                        field_seconds=float("nan"), speedup_vs_dda=per["dda"] / per[name],
                        max_err_deg=float("nan"), p99_err_deg=float("nan"),
                        agree_1e9=float(np.mean(same))))
    return out


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


def run_parallel(out_dir="reports/reproduce", size=None, run_lengths=RUN_LENGTHS, repeats=5,
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
    text += ["## What the periodic patterns buy", ""]
    for r in sorted({int(x["run_length"]) for x in rows}):
        def ns(workload, name):
            m = [float(x["ns_per_vertex"]) for x in rows if x["workload"] == workload and
                 int(x["run_length"]) == r and x["algorithm"] == name]
            return m[0] if m else float("nan")
        text.append(f"- r = {r}: `runs_periodic` {ns('first_hit', 'runs') / ns('first_hit', 'runs_periodic'):.2f}x "
                    f"`runs` on orthographic first hits; the shared pattern "
                    f"{ns('horizon', 'dda') / ns('horizon', 'pattern'):.2f}x and the sweep "
                    f"{ns('horizon', 'dda') / ns('horizon', 'sweep'):.2f}x the per-vertex walk "
                    f"on horizons.")
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
    north_up = (lambda a: a[::-1]) if (hf.params or {}).get("north") == "+y" else (lambda a: a)
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
    fig.savefig(path, dpi=110)
    plt.close(fig)
    echo(f"wrote {path}")


def observer_up(hf, observer):
    """The observer's (x, y) in the north-up array (rows flipped when north is +y)."""
    if (hf.params or {}).get("north") == "+y":
        return observer[0], hf.shape[0] - 1 - observer[1]
    return observer


# ---- peers -------------------------------------------------------------------------------

def xrspatial_viewshed(h, observer, observer_height, target_height=0.0):
    """xarray-spatial's viewshed on the same grid (x = column, y = row, unit spacing), as a
    bool array; None when xarray-spatial is not installed."""
    try:
        import xarray as xr
        from xrspatial import viewshed as xrs_viewshed
    except ImportError:
        return None
    rows, cols = h.shape
    da = xr.DataArray(np.asarray(h, dtype=np.float64), dims=("y", "x"),
                      coords={"y": np.arange(rows, dtype=float), "x": np.arange(cols, dtype=float)})
    out = xrs_viewshed(da, x=float(observer[0]), y=float(observer[1]),
                       observer_elev=float(observer_height), target_elev=float(target_height))
    return np.asarray(out.values) > -1


def gdal_viewshed(h, observer, observer_height, target_height=0.0):
    """GDAL's ViewshedGenerate on the same grid, or None when osgeo does not import."""
    try:
        from osgeo import gdal
    except ImportError:
        return None
    rows, cols = h.shape
    src = gdal.GetDriverByName("MEM").Create("", cols, rows, 1, gdal.GDT_Float64)
    src.SetGeoTransform((0.0, 1.0, 0.0, 0.0, 1.0, 1.0))  # pixel corners: x = col, y = row
    src.GetRasterBand(1).WriteArray(np.asarray(h, float))
    out = gdal.ViewshedGenerate(src.GetRasterBand(1), "MEM", "", [], observer[0] + 0.5,
                                observer[1] + 0.5, observer_height, target_height, 255, 0,
                                0, 0, 0, gdal.GVM_Edge, 0.0)
    return out.GetRasterBand(1).ReadAsArray() == 255


def los_margins(h, observer, z0, targets, target_height=0.0):
    """Float margins max(s - segment) over each target's breakpoints (positive: blocked),
    and the height range of the cell where that maximum is, for the agreement analysis."""
    rows, cols = h.shape
    ox, oy = observer
    margins, ranges = [], []
    for v in targets:
        j, i = divmod(int(v), cols)
        dx, dy = i - ox, j - oy
        ts = [np.arange(1, 1) * 1.0]
        for o, dd, n in ((ox, dx, cols), (oy, dy, rows)):
            if dd:
                k = np.arange(0, n)
                t = (k - o) / dd
                ts.append(t[(t > 0) & (t < 1)])
        if dx != dy:
            k = np.arange(-(rows - 1), cols)
            t = (k - (ox - oy)) / (dx - dy)
            ts.append(t[(t > 0) & (t < 1)])
        t = np.concatenate(ts)
        if len(t) == 0:
            margins.append(-np.inf)
            ranges.append(0.0)
            continue
        x, y = ox + t * dx, oy + t * dy
        ci = np.clip(np.floor(x).astype(int), 0, cols - 2)
        cj = np.clip(np.floor(y).astype(int), 0, rows - 2)
        u, w = x - ci, y - cj
        h00, h10 = h[cj, ci], h[cj, ci + 1]
        h01, h11 = h[cj + 1, ci], h[cj + 1, ci + 1]
        s = np.where(u >= w, h00 + (h10 - h00) * u + (h11 - h10) * w,
                     h00 + (h11 - h01) * u + (h01 - h00) * w)
        zt = h[j, i] + target_height
        m = s - (z0 + (zt - z0) * t)
        k = int(np.argmax(m))
        margins.append(float(m[k]))
        corners = (h00[k], h10[k], h01[k], h11[k])
        ranges.append(float(max(corners) - min(corners)))
    return np.array(margins), np.array(ranges)


# ---- the targets ---------------------------------------------------------------------------

def _fields(size):
    fbm = datasets_gen.load("fbm", size=size, seed=1)
    jb = datasets_gen.load("jacksboro", size=size)
    return [(f"jacksboro{size}", jb), (f"fbm{size}", fbm)]


def run_targets(out_dir="reports/terrain", size=2048, repeats=3, sample=16384, rays=4000,
                seed=2004, echo=print):
    """The issue's targets table (module docstring)."""
    os.makedirs(out_dir, exist_ok=True)
    env = environment()
    write_json(os.path.join(out_dir, "env.json"), env)
    lines = [f"# Terrain products: the targets ({size} samples)", "",
             f"Machine: {env['cpu']}; commit {env['git_commit']}. Single thread, pinned CPU. "
             "Command: `hftrace terrain-bench`.", ""]
    csv_rows = []
    azimuths = T.rational_azimuths(16)
    for label, hf in _fields(size):
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
        T.horizon(hf, azimuths, threads=1)
        wall = time.perf_counter() - t0
        lines += [f"## {label}: horizon, 16 rational azimuths (`rational_azimuths(16)`), "
                  "every vertex, unlimited distance", "",
                  f"`algos.horizon(field, rational_azimuths(16), threads=1)` (default "
                  f"algorithm `{T.LAST_STATS.algorithm}`): **{wall:.2f} s** wall-clock, "
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
            ours = T.viewshed(hf, observer, observer_height=1.75, threads=1)
            times.append(time.perf_counter() - t0)
        stats = dict(T.LAST_STATS.__dict__)
        ours_up = ours[::-1] if (hf.params or {}).get("north") == "+y" else ours
        up_obs = observer_up(hf, observer)
        hu = h[::-1] if (hf.params or {}).get("north") == "+y" else h
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
    with open(os.path.join(out_dir, "targets.md"), "w") as f:
        f.write("\n".join(lines))
    with open(os.path.join(out_dir, "targets.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, PARALLEL_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for row in csv_rows:
            writer.writerow({k: row.get(k, "") for k in PARALLEL_COLUMNS})
    echo("\n".join(lines))
    return lines


# ---- products on the command line ---------------------------------------------------------

def write_product(prefix, array, *, spacing=None, cmap="viridis", vmin=None, vmax=None,
                  title=""):
    """prefix.tif (GeoTIFF-style float32 with the pixel scale), prefix.exr and prefix.png
    (a colour map). Returns the three paths."""
    import tifffile
    from matplotlib import colormaps
    from PIL import Image

    from .render import write_exr

    data = np.asarray(array, dtype=np.float32)
    extratags = []
    if spacing:
        extratags.append((33550, "d", 3, (float(spacing), float(spacing), 0.0), False))
    tifffile.imwrite(prefix + ".tif", data, extratags=extratags)
    write_exr(prefix + ".exr", {"Y": data})
    lo = float(np.nanmin(data)) if vmin is None else vmin
    hi = float(np.nanmax(data)) if vmax is None else vmax
    norm = (data - lo) / (hi - lo) if hi > lo else np.zeros_like(data)
    rgba = colormaps[cmap](np.clip(norm, 0, 1))
    Image.fromarray(np.round(rgba[..., :3] * 255).astype(np.uint8)).save(prefix + ".png")
    return [prefix + ".tif", prefix + ".exr", prefix + ".png"]
