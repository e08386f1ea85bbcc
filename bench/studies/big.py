"""``hftrace scale --part big``: a 16384^2 fbm field (1 GiB of float32 heights):
generation time, every structure's build time and bytes, first hits (the lean
``runs_maxmip`` layout and the default one), a render and a horizon, each in its own
process so that its peak resident memory is its own. Writes ``big.md`` and ``big.json``.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np

import algos
from algos import parallel
from algos.intersect import prepare_timed_intersect
from datasets_gen import fields

from ..timing import resident_bytes
from .scaling_workload import growth_rays

__all__ = ["run_big", "big_item", "BIG_ITEMS"]

#: The repository root (the child processes import ``bench`` from there)
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# ---- a field of 16384^2 ----------------------------------------------------------------
def _peak_rss_bytes() -> int:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def big_item(item, side, path, commands=None):
    """One item of the big-field study, in this process; returns a dict (JSON).

    ``commands``: the two commands the "render" and "dask_horizon" items measure,
    ``{"render_files": bench.cli.render.render_files, "run_product":
    bench.cli.terrain_dask.run_product}``, handed in by the child's entry point
    (``python -m bench.cli.big_item``), so this study imports nothing of the CLI above it.
    """
    commands = commands or {}
    out = dict(item=item, side=side, rss_before_bytes=resident_bytes())
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
            render_files = commands["render_files"]
            prefix = os.path.join(os.path.dirname(path), f"render{side}")
            render_files(str(path), algorithm="runs_maxmip", width=960, height=540, out=prefix,
                   echo=lambda *a: None)
            out["files"] = [prefix + ".png", prefix + ".exr"]
        elif item == "dask_horizon":
            # the file (1 GiB) is bigger than the 2 x 480 MiB the workers may use
            import datasets_gen

            run_product = commands["run_product"]
            prefix = os.path.join(os.path.dirname(path), f"dask{side}")
            hf = datasets_gen.open_lazy(path, chunks=1536)
            run_product("horizon", hf, prefix, "local:2", max_distance=500.0, azimuths=[135.0],
                        worker_memory="480MiB", echo=lambda *a: None)
            out.update(workers=2, worker_memory_bytes=480 << 20, max_distance=500.0,
                       tile=1536, png=prefix + ".png")
            os.remove(prefix + ".tif")  # 1 GiB; the preview stays
        elif item == "horizon":
            az = algos.rational_azimuths(1)
            angles, stats = algos.horizon(heights, az, None, return_stats=True)
            out["azimuths"] = [float(a) for a in az]
            out["mean_degrees"] = float(np.degrees(angles).mean())
            out["algorithm"] = stats.algorithm
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
        # the child is the command-line entry of one item (bench/cli/big_item.py), which
        # hands the measured commands to big_item
        done = subprocess.run([sys.executable, "-m", "bench.cli.big_item", item, str(side), path],
                              capture_output=True, text=True, cwd=ROOT)
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
                  "`bench.cli.terrain_dask.run_product`): the 1 GiB file is more than the "
                  f"{dask['workers']} x {dask['worker_memory_bytes'] >> 20} MiB the workers may "
                  "hold. Dask's nanny restarts a worker that passes 95 % of its limit, and a "
                  "task that kills three workers fails the run; a first attempt with 2048 "
                  "tiles and 400 MiB per worker failed that way. The peak RSS above is the "
                  f"driver's (it maps the output GeoTIFF). Its preview is `dask{side}.png`."]
    lines += ["", "Structures per item are in big.json (build seconds and bytes of each).", "",
              f"The images `render{side}.png`, `render{side}.exr` and `dask{side}.png` are "
              "written next to this file by `hftrace scale --part big` and are not committed "
              "(one-off, several MB each): run it to see them."]
    with open(os.path.join(out_dir, "big.md"), "w") as f:
        f.write("\n".join(lines) + "\n")


