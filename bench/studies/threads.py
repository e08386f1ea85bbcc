"""``hftrace scale --part threads`` and ``--part split``: every C kernel (traversals on the
``visit`` workload, first-hit intersectors on fbm 2048^2) and Embree, 1 thread against
every core, on the same rays in one process, interleaved (so the ratio is measured side
by side); plus the work split (one static range per thread against
``CHUNKS_PER_THREAD`` ranges on a queue) and the best exact kernel against Embree with
both on every core. Writes ``threads.md``, ``threads.csv`` and ``split.md``.
"""
from __future__ import annotations

import os
import time

import numpy as np

import algos
from algos import parallel
from algos.intersect import prepare_timed_intersect
from algos.render import default_camera
from datasets_gen import fields
from datasets_gen import rays as raysets
from datasets_gen.rays import first_hit_rays, traversal_rays

from ..report import RowWriter
from ..sweep import read_rows
from ..timing import environment, interleaved, ratio_ci
from .scaling_workload import EMBREE_MAX_SIDE, GROWTH_R, fbm_field

__all__ = ["run_threads", "run_split"]

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
    field = fbm_field(side)
    o, d = first_hit_rays(field, GROWTH_R, n, 11)
    shape = (side - 1, side - 1)
    o2, d2 = traversal_rays(shape, GROWTH_R, n, 11)
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
            if name in ("embree", "embree3") and side > EMBREE_MAX_SIDE:
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
    nthreads = parallel.resolve_threads(None)
    field = fbm_field(side)
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


