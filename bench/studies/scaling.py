"""``hftrace scale``: how the kernels scale up (threads), grow (grid side) and fit (a
16384^2 field). Writes ``reports/scaling/``:

* ``threads.md/.csv``: every C kernel (traversals on the ``visit`` workload, first-hit
  intersectors on fbm 2048^2) and Embree, 1 thread against every core, on the same rays
  in one process, interleaved (so the ratio is measured side by side); plus the work
  split (one static range per thread against ``CHUNKS_PER_THREAD`` ranges on a queue)
  and the best exact kernel against Embree with both on every core.
* ``split.md``: ranges per thread against speedup, for even (random) and uneven (camera)
  ray costs: how the default split was chosen.
* ``growth.md/.csv/.png``: ns per ray and per visited cell against the grid side, 256^2
  to 16384^2, every intersector and Embree, at a fixed run length (r = 25) and
  elevation (10 degrees), one thread pinned to one CPU, with the machine's L2 and L3
  sizes marked where the heights alone fill them.
* ``big.md/.json``: a 16384^2 fbm field (1 GiB of float32 heights): generation time,
  every structure's build time and bytes, first hits (the lean ``runs_maxmip`` layout
  and the default one), a render and a horizon, each in its own process so that its
  peak resident memory is its own.

Every part appends rows as it measures them and skips what its CSV already holds
(``--resume``), so an interrupted run loses nothing.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time

import numpy as np

import algos
from algos import parallel
from algos.embree_peer import _rss_bytes
from algos.intersect import prepare_timed_intersect
from datasets_gen import fields
from datasets_gen import rays as raysets

from .report import RowWriter
from .sweep import _rays2, first_hit_rays, read_rows
from .timing import cache_sizes, environment, interleaved, median_ci, ratio_ci, write_json

__all__ = ["run", "run_threads", "run_split", "run_growth", "run_big"]

SIDES = (256, 512, 1024, 2048, 4096, 8192, 16384)
GROWTH_R = 25
GROWTH_ELEVATION = 10.0
#: Embree's scene for a 8192^2 field is about 134 M triangles (some 10 GB measured at
#: 2048^2 x 16); the growth study stops it at this side by default
EMBREE_MAX_SIDE = 4096


def _field(side, seed=1):
    return algos.Field(fields.generate("fbm", side, seed=seed))


# ---- threads ---------------------------------------------------------------------------
THREAD_COLUMNS = ["part", "kernel", "threads", "rays", "ns_per_ray", "ns_per_ray_1",
                  "speedup", "speedup_ci_low", "speedup_ci_high", "repeats", "note"]


def _with_chunks(run, chunks):
    """The same job with ``chunks`` ranges per thread (the work-split comparison)."""
    def job():
        saved = parallel.CHUNKS_PER_THREAD
        parallel.CHUNKS_PER_THREAD = chunks
        try:
            return run()
        finally:
            parallel.CHUNKS_PER_THREAD = saved
    return job


#: the work splits compared: ranges per thread
SPLITS = (1, 32)


def run_threads(out_dir, side=2048, n=100_000, repeats=7, threads=None, echo=print, resume=False):
    """Scaling from 1 thread to ``threads`` (default: every core) for every kernel."""
    nthreads = parallel.resolve_threads(threads)
    csv_path = os.path.join(out_dir, "threads.csv")
    done = {(r["part"], r["kernel"]) for r in read_rows(csv_path)} if resume else set()
    field = _field(side)
    o, d = first_hit_rays(field, GROWTH_R, n, 11)
    shape = (side - 1, side - 1)
    o2, d2 = _rays2(shape, GROWTH_R, n, 11)
    with RowWriter(csv_path, THREAD_COLUMNS, append=resume) as writer:
        def measure(part, kernel, make, note=""):
            if (part, kernel) in done:
                return
            jobs = {1: make(1), nthreads: make(nthreads)}
            if part in ("first_hit", "visit") and kernel in ("dda", "runs", "runs_maxmip", "embree"):
                for chunks in SPLITS:
                    jobs[f"split{chunks}"] = _with_chunks(make(nthreads), chunks)
            times = interleaved(jobs, repeats)
            speed, lo, hi = ratio_ci(times[1], times[nthreads])
            row = dict(part=part, kernel=kernel, threads=nthreads, rays=n,
                       ns_per_ray=round(float(np.median(times[nthreads])) / n, 2),
                       ns_per_ray_1=round(float(np.median(times[1])) / n, 2),
                       speedup=round(speed, 3), speedup_ci_low=round(lo, 3),
                       speedup_ci_high=round(hi, 3), repeats=repeats, note=note)
            writer.write(row)
            echo(f"{part} {kernel}: {row['ns_per_ray_1']} -> {row['ns_per_ray']} ns/ray, "
                 f"{speed:.2f}x on {nthreads} threads")
            for chunks in SPLITS:
                key = f"split{chunks}"
                if key not in jobs:
                    continue
                s, slo, shi = ratio_ci(times[1], times[key])
                writer.write(dict(row, part=f"{part}, split {chunks}", ns_per_ray=round(
                    float(np.median(times[key])) / n, 2), speedup=round(s, 3),
                    speedup_ci_low=round(slo, 3), speedup_ci_high=round(shi, 3),
                    note=f"{chunks} range(s) per thread instead of {parallel.CHUNKS_PER_THREAD}"))
                echo(f"  {chunks} ranges per thread: {s:.2f}x")

        for name in algos.TRAVERSALS:
            measure("visit", name, lambda t, name=name: algos.prepare_timed(
                name, o2, d2, shape, "visit", threads=t)[0])
        for name in algos.INTERSECTORS:
            if name == "embree" and side > EMBREE_MAX_SIDE:
                continue
            measure("first_hit", name, lambda t, name=name: prepare_timed_intersect(
                name, field, o, d, threads=t)[0])
        # the terrain products (their own vertex ranges; algos.terrain)
        small = algos.Field(fields.generate("fbm", 1024, seed=2))
        h64 = small.heights.astype(np.float64)
        az = algos.rational_azimuths(4)

        def product(call):
            def make(t):
                def job():
                    start = time.perf_counter_ns()
                    call(t)
                    return time.perf_counter_ns() - start
                return job
            return make

        vertices = h64.size
        for algo in ("sweep", "pattern", "dda_maxmip"):
            md = None if algo == "sweep" else 200.0
            measure("horizon", algo, product(lambda t, a=algo, md=md: algos.horizon(
                h64, az, md, algorithm=a, threads=t)), note=f"fbm 1024, 4 azimuths, "
                f"{vertices} vertices per azimuth; ns per vertex-azimuth x {n / vertices / 4:.3g}")
        measure("viewshed", "dda_maxmip", product(lambda t: algos.viewshed(
            h64, (511.5, 511.5), algorithm="dda_maxmip", threads=t)),
            note="fbm 1024, one observer; ns per target x {:.3g}".format(n / vertices))
    rows = read_rows(csv_path)
    _threads_md(rows, out_dir, nthreads, side, n)
    return rows


def _threads_md(rows, out_dir, nthreads, side, n):
    env = environment()
    lines = [f"# Threads: 1 against {nthreads} (`hftrace scale --part threads`)", "",
             f"fbm {side}^2, {n} rays at run length {GROWTH_R} (first hits: 5-20 degrees below "
             "the horizon from one cell above the field; traversals: the `visit` workload), "
             "interleaved in one process, not pinned. Speedup = time on 1 thread / time on "
             f"{nthreads} (median, paired bootstrap 95 % CI). CPU: {env['cpu']}, "
             f"{parallel.available_cores()} cores in the affinity.", "",
             "| part | kernel | ns/ray, 1 thread | ns/ray, all | speedup [95 % CI] | note |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['part']} | {r['kernel']} | {r['ns_per_ray_1']} | {r['ns_per_ray']} | "
                     f"{float(r['speedup']):.2f}x [{float(r['speedup_ci_low']):.2f}, "
                     f"{float(r['speedup_ci_high']):.2f}] | {r['note']} |")
    by = {(r["part"], r["kernel"]): r for r in rows}
    exact = [k for p, k in by if p == "first_hit" and algos.INTERSECTOR_REGISTRY[k].accuracy == "exact"]
    if ("first_hit", "embree") in by and exact:
        best = min(exact, key=lambda k: float(by[("first_hit", k)]["ns_per_ray"]))
        ratio = float(by[("first_hit", "embree")]["ns_per_ray"]) / float(by[("first_hit", best)]["ns_per_ray"])
        lines += ["", f"Best exact kernel on all cores: `{best}`, {by[('first_hit', best)]['ns_per_ray']} "
                  f"ns/ray against Embree's {by[('first_hit', 'embree')]['ns_per_ray']} on all cores: "
                  f"**{ratio:.2f}x** Embree's rays/s."]
    c_rows = [r for r in rows if r["part"] in ("visit", "first_hit") and r["kernel"] != "embree"]
    if c_rows:
        worst = min(c_rows, key=lambda r: float(r["speedup"]))
        lines += ["", f"Smallest C-kernel scaling: `{worst['kernel']}` ({worst['part']}) "
                  f"{float(worst['speedup']):.2f}x; median over the C kernels "
                  f"{np.median([float(r['speedup']) for r in c_rows]):.2f}x."]
    with open(os.path.join(out_dir, "threads.md"), "w") as f:
        f.write("\n".join(lines) + "\n")


def run_split(out_dir, side=2048, repeats=11, echo=print):
    """The work split, measured: ranges per thread against speedup on 2+ threads, for
    random rays (even cost) and a pinhole camera (sky rays leave at once: uneven)."""
    from .render import default_camera

    nthreads = parallel.resolve_threads(None)
    field = _field(side)
    o, d = first_hit_rays(field, GROWTH_R, 100_000, 11)
    cam, centre = default_camera(field.heights)
    ph = raysets.pinhole(cam, centre, 60.0, 400, 250)
    choices = (1, 2, 4, 8, 32)
    lines = ["# Work split (`hftrace scale --part split`)", "",
             f"Speedup on {nthreads} threads over 1 (median of {repeats} interleaved repeats) "
             f"against the number of ray ranges per thread, fbm {side}^2. The default is "
             f"{parallel.CHUNKS_PER_THREAD}: one static range per thread loses up to a third "
             "on a camera's rays, where the sky rows cost nothing. On these VMs a run's "
             "medians move by about 0.1x between runs (an earlier run showed 1.0x for every "
             "split on the camera's rays, which re-measuring did not confirm).", "",
             "| rays | kernel | " + " | ".join(f"{c} per thread" for c in choices) + " |",
             "|---|---|" + "---|" * len(choices)]
    for label, (oo, dd) in (("random (100,000)", (o, d)),
                            ("pinhole 400x250", (ph.origins, ph.directions))):
        for name in ("runs", "runs_maxmip"):
            jobs = {"one": prepare_timed_intersect(name, field, oo, dd, threads=1)[0]}
            many = prepare_timed_intersect(name, field, oo, dd, threads=nthreads)[0]
            for c in choices:
                jobs[c] = _with_chunks(many, c)
            t = interleaved(jobs, repeats)
            base = float(np.median(t["one"]))
            cells = [f"{base / float(np.median(t[c])):.2f}x" for c in choices]
            lines.append(f"| {label} | {name} | " + " | ".join(cells) + " |")
            echo(lines[-1])
    with open(os.path.join(out_dir, "split.md"), "w") as f:
        f.write("\n".join(lines) + "\n")


# ---- growth ----------------------------------------------------------------------------
GROWTH_COLUMNS = ["side", "kernel", "rays", "cells_per_ray", "ns_per_ray", "ns_per_ray_ci_low",
                  "ns_per_ray_ci_high", "ns_per_cell", "heights_bytes", "structure_bytes",
                  "build_seconds", "repeats"]


def growth_rays(field, n, seed):
    """Rays at run length GROWTH_R falling at GROWTH_ELEVATION degrees from one cell above
    the highest point, origins uniform over the field."""
    rows, cols = field.rows, field.cols
    rs = raysets.by_run_length(GROWTH_R, n, (cols - 1, rows - 1), seed, origins="inside",
                               elevation=GROWTH_ELEVATION, height=field.hmax + 1.0)
    return rs.origins, rs.directions


def run_growth(out_dir, sides=SIDES, n=20_000, repeats=5, names=None, embree_max=EMBREE_MAX_SIDE,
               echo=print, resume=False):
    """ns/ray and ns/cell against the grid side, one thread, one run per side."""
    from .intersect_bench import pin_to_one_cpu

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
                field = _field(side)
                echo(f"growth {side}^2: field in {time.perf_counter() - start:.1f} s")
                o, d = growth_rays(field, n, 5)
                ref = algos.intersect("runs", field, o, d, outputs=("t", "stats"), threads=1)
                cells = float(ref.stats["cells_visited"].mean())
                jobs = {}
                use = [x for x in names if x != "embree" or side <= embree_max]
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


# ---- a field of 16384^2 ----------------------------------------------------------------
def _peak_rss_bytes() -> int:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def big_item(item, side, path):
    """One item of the big-field study, in this process; returns a dict (JSON)."""
    out = dict(item=item, side=side, rss_before_bytes=_rss_bytes())
    start = time.perf_counter()
    if item == "generate_4096":  # the generator target at 4096^2
        h = fields.generate("fbm", 4096, seed=1)
        out["seconds"] = time.perf_counter() - start
        out["heights_bytes"] = h.nbytes
        out["threads"] = parallel.available_cores()
    elif item == "generate":
        h = fields.generate("fbm", side, seed=1)
        out["seconds"] = time.perf_counter() - start
        np.save(path, h)
        out["heights_bytes"] = h.nbytes
    else:
        heights = np.load(path, mmap_mode="r")
        out["heights_bytes"] = heights.nbytes
        if item in ("first_hits_lean", "first_hits_runs", "first_hits_dda_maxmip"):
            name = {"first_hits_lean": "runs_maxmip", "first_hits_runs": "runs",
                    "first_hits_dda_maxmip": "dda_maxmip"}[item]
            field = algos.Field(heights, lean=item == "first_hits_lean")
            o, d = growth_rays(field, 100_000, 3)
            built = time.perf_counter()
            run, _ = prepare_timed_intersect(name, field, o, d, threads=None)
            # the wall time of every build (build_stats times nest: row_max builds cellmax)
            out["build_seconds"] = time.perf_counter() - built
            out["structure_bytes"] = sum(s["bytes"] for s in field.build_stats.values())
            out["structures"] = field.build_stats
            out["ns_per_ray"] = run() / len(o)
            out["ns_per_ray"] = min(out["ns_per_ray"], run() / len(o))
            out["kernel"] = name
        elif item == "render":
            from .render import render

            prefix = os.path.join(os.path.dirname(path), f"render{side}")
            render(str(path), algorithm="runs_maxmip", width=960, height=540, out=prefix,
                   echo=lambda *a: None)
            out["files"] = [prefix + ".png", prefix + ".exr"]
        elif item == "dask_horizon":
            # the file (1 GiB) is bigger than the 2 x 480 MiB the workers may use
            import datasets_gen

            from .terrain_dask import run_product

            prefix = os.path.join(os.path.dirname(path), f"dask{side}")
            hf = datasets_gen.open_lazy(path, chunks=1536)
            run_product("horizon", hf, prefix, "local:2", max_distance=500.0, azimuths=[135.0],
                        worker_memory="480MiB", echo=lambda *a: None)
            out.update(workers=2, worker_memory_bytes=480 << 20, max_distance=500.0,
                       tile=1536, png=prefix + ".png")
            os.remove(prefix + ".tif")  # 1 GiB; the preview stays
        elif item == "horizon":
            az = algos.rational_azimuths(1)
            angles = algos.horizon(heights, az, None)
            out["azimuths"] = [float(a) for a in az]
            out["mean_degrees"] = float(np.degrees(angles).mean())
            from algos import terrain

            out["algorithm"] = terrain.LAST_STATS.algorithm
        out["seconds"] = time.perf_counter() - start
    out["peak_rss_bytes"] = _peak_rss_bytes()
    out["rss_growth_bytes"] = out["peak_rss_bytes"] - out["rss_before_bytes"]
    return out


BIG_ITEMS = ("generate_4096", "generate", "first_hits_lean", "first_hits_runs", "first_hits_dda_maxmip",
             "render", "horizon", "dask_horizon")


def run_big(out_dir, side=16384, echo=print, resume=False, items=BIG_ITEMS):
    """Each item in a child process (its own peak RSS); results in big.json and big.md."""
    json_path = os.path.join(out_dir, "big.json")
    results = json.load(open(json_path)) if resume and os.path.exists(json_path) else {}
    path = os.path.join(out_dir, f"fbm{side}.npy")
    for item in items:
        if item in results and "error" not in results[item] and (
                item != "generate" or os.path.exists(path)):
            continue
        code = ("import json, sys; from bench.scale import big_item; "
                f"print(json.dumps(big_item({item!r}, {side}, {path!r}), default=str))")
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        if done.returncode != 0:
            results[item] = {"item": item, "error": done.stderr[-2000:]}
        else:
            results[item] = json.loads(done.stdout.strip().splitlines()[-1])
        echo(f"big {item}: " + ", ".join(f"{k} {v}" for k, v in results[item].items()
                                          if k in ("seconds", "peak_rss_bytes", "structure_bytes",
                                                   "ns_per_ray", "error")))
        with open(json_path, "w") as f:
            json.dump(results, f, indent=1, default=str)
    _big_md(results, out_dir, side)
    if os.path.exists(path):
        os.remove(path)  # 1 GiB: the study regenerates it
    return results


def _big_md(results, out_dir, side):
    gib = 1 << 30
    lines = [f"# A {side}^2 field (`hftrace scale --part big`)", "",
             f"fbm {side}^2 seed 1: {side * side * 4 / gib:.2f} GiB of float32 heights, saved "
             "as .npy and memory-mapped by every later item (each in its own process, so its "
             "peak resident memory, which counts the mapped heights it touched, is its own; "
             "RSS growth is the peak less the resident memory after the imports). "
             "First hits: 100,000 rays at r = 25 falling at 10 degrees, on every core.", "",
             "| item | seconds | builds (s) | peak RSS (GiB) | RSS growth (GiB) | structures (GiB) | "
             "extra / heights | ns/ray |",
             "|---|---|---|---|---|---|---|---|"]
    order = [k for k in BIG_ITEMS if k in results] + [k for k in results if k not in BIG_ITEMS]
    for item in order:
        r = results[item]
        if "error" in r:
            lines.append(f"| {item} | failed: {r['error'][-200:]!r} | | | | | | |")
            continue
        sb = r.get("structure_bytes")
        name = f"{item} ({r['kernel']})" if "kernel" in r else item
        gb = "" if sb is None else f"{sb / gib:.3f}"
        extra = "" if sb is None else f"{sb / r['heights_bytes']:.3f}x"
        ns = "" if "ns_per_ray" not in r else f"{float(r['ns_per_ray']):.0f}"
        build = f"{float(r['build_seconds']):.1f}" if "build_seconds" in r else ""
        lines.append(f"| {name} | {float(r['seconds']):.1f} | {build} | "
                     f"{r['peak_rss_bytes'] / gib:.2f} | {r['rss_growth_bytes'] / gib:.2f} | "
                     f"{gb} | {extra} | {ns} |")
    dask = results.get("dask_horizon", {})
    if "workers" in dask:
        lines += ["", f"dask_horizon: `hftrace horizon fbm{side}.npy --dask local:{dask['workers']} "
                  f"--max-distance {dask['max_distance']:g} --chunk {dask['tile']} --worker-memory "
                  f"{dask['worker_memory_bytes'] >> 20}MiB --azimuths 135` (through "
                  "`bench.terrain_dask.run_product`): the 1 GiB file is more than the "
                  f"{dask['workers']} x {dask['worker_memory_bytes'] >> 20} MiB the workers may "
                  "hold. Dask's nanny restarts a worker that passes 95 % of its limit, and a "
                  "task that kills three workers fails the run; a first attempt with 2048 "
                  "tiles and 400 MiB per worker failed that way. The peak RSS above is the "
                  f"driver's (it maps the output GeoTIFF). Preview: ![dask](dask{side}.png)"]
    lines += ["", "Structures per item are in big.json (build seconds and bytes of each).",
              f"![render](render{side}.png)"]
    with open(os.path.join(out_dir, "big.md"), "w") as f:
        f.write("\n".join(lines) + "\n")


def run(out_dir="reports/scaling", parts=("threads", "split", "growth", "big"), resume=False, echo=print,
        quick=False):
    os.makedirs(out_dir, exist_ok=True)
    write_json(os.path.join(out_dir, "env.json"), dict(environment(), caches=cache_sizes(),
                                                         cores=parallel.available_cores()))
    if "threads" in parts:
        run_threads(out_dir, side=512 if quick else 2048, n=20_000 if quick else 100_000,
                    repeats=3 if quick else 7, echo=echo, resume=resume)
    if "split" in parts:
        run_split(out_dir, side=512 if quick else 2048, repeats=3 if quick else 11, echo=echo)
    if "growth" in parts:
        run_growth(out_dir, sides=SIDES[:3] if quick else SIDES, n=2000 if quick else 20_000,
                   repeats=3 if quick else 5, echo=echo, resume=resume)
    if "big" in parts:
        run_big(out_dir, side=1024 if quick else 16384, echo=echo, resume=resume)
