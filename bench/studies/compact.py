"""``hftrace compact``: the cache-compact maximum tree (``dda_compact``) against today's
maximum mipmap (``dda_maxmip``), by the cache lines a ray touches.

For each field side (fBm, the growth curve from 256^2 up), on the same random-azimuth
first-hit rays as bench-intersect (``datasets_gen.rays.first_hit_rays``, r = "random"), two-triangle
surface, one thread:

* **callgrind's cache simulation** (``valgrind --tool=callgrind --cache-sim=yes``, counted
  only inside the C batch entry ``hf_intersect_batch``; whatever the machine's load,
  instructions and data accesses are exact for one build and input, and misses move by
  about 1 % with where the arrays land in memory), with a fixed cache model :data:`CACHE` (32 KiB 8-way D1,
  8 MiB 16-way LL, 64-byte lines) so the counts do not depend on the host: instructions,
  data reads and writes, D1 misses (the lines a ray touches: a ray's own lines stay in
  D1, and random rays share almost none) and LL misses (data), per ray. Both kernels run
  in one child process, each after a write over 64 MiB that evicts the simulated caches.
* **natively**: the cells visited, cells tested and tiles skipped per ray (the batch's
  statistics), ns per ray (``bench.timing.interleaved``, caches flushed before every run:
  indicative only on a shared machine; the report prints ``uptime``), and each
  structure's build time and bytes per height sample.

    python -m bench.studies.compact [--full] [--sizes 256,2048,8192] [--rays 2000]
                                    [--out results/compact | --publish]

``--publish`` writes ``reports/compact/``. The quick tier (the default) is small and is
what the tests run.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

import algos
import algos.accel.compact
import datasets_gen

__all__ = ["KERNELS", "STRUCTURES", "CACHE", "QUICK", "FULL", "callgrind_cache_counts",
           "native_counts", "run", "main"]

#: the compared kernels: today's hierarchy first
KERNELS = ("dda_maxmip", "dda_compact")
#: the structures each kernel builds (Field.build_stats keys): the tree is built from
#: the cell maxima
STRUCTURES = {"dda_maxmip": ("cellmax", "mip"), "dda_compact": ("cellmax", "compact")}
#: the structures each kernel's walk reads besides the heights (dda_compact reads the cell
#: maxima only in the fallback walk of rays lying on a grid line)
READS = {"dda_maxmip": ("cellmax", "mip"), "dda_compact": ("compact",)}
#: the simulated caches: (bytes, ways, line bytes)
CACHE = {"I1": (32768, 8, 64), "D1": (32768, 8, 64), "LL": (8 << 20, 16, 64)}
#: the tiers: field sides, rays per side, timing repeats
QUICK = dict(sizes=(256, 512), rays=200, repeats=3)
FULL = dict(sizes=(256, 1024, 2048, 4096, 8192), rays=2000, repeats=5)
DATASET, SEED, RUN_LENGTH, SURFACE = "fbm", 2008, "random", "triangles"
#: the report's target: LL misses per ray of dda_compact over dda_maxmip's, at 8192^2
TARGET_RATIO, TARGET_SIZE = 0.5, 8192

_CHILD = r"""
import json, sys
import numpy as np
from bench.studies.compact import _prepared
spec = json.loads(sys.argv[1])
runs = _prepared(spec)
for kernel in spec["kernels"]:
    scratch = np.ones(64 << 17)   # 64 MiB written: the simulated caches start cold
    scratch += 1.0
    runs[kernel]()
"""

#: callgrind_cache_counts(regimes=True): per kernel, a flush, the rays twice (flushed,
#: warm), then a flush, the other rays (not counted) and the rays again (other-warmed)
_CHILD_REGIMES = r"""
import json, sys
import numpy as np
from bench.studies.compact import _prepared
spec = json.loads(sys.argv[1])
runs = _prepared(dict(spec, other=True))
for kernel in spec["kernels"]:
    for calls in ((kernel, kernel), (kernel + "/other", kernel)):
        scratch = np.ones(64 << 17)   # 64 MiB written: the simulated caches start cold
        scratch += 1.0
        for name in calls:
            runs[name]()
"""
#: the dumps of one kernel under _CHILD_REGIMES, and which of them each regime counts
REGIME_DUMPS, REGIMES = 4, {"flushed": 0, "warm": 1, "other_warmed": 3}


def _field(size):
    return algos.Field(datasets_gen.load(DATASET, size=size, seed=1).heights)


def _save_case(size, rays, seed, directory, other=False) -> None:
    """Build the field's structures and the rays natively and save them as .npy files in
    ``directory``: the child under valgrind maps them instead of building them (which
    would take it most of an hour at 8192^2). ``other``: as many other rays too (seed + 1),
    which warm the caches before the counted rays in the other-warmed regime."""
    from datasets_gen.rays import first_hit_rays

    field = _field(size)
    o, d = first_hit_rays(field, RUN_LENGTH, rays, seed)
    mip = field.mip_for()
    arrays = dict(heights=field.cell_heights, cellmax=field.cellmax_for(), compact=
                  algos.accel.compact.compact_for(field), origins=o, directions=d,
                  **{f"mip{k}": level for k, level in enumerate(mip) if k > 0})
    if other:
        arrays["origins_other"], arrays["directions_other"] = first_hit_rays(
            field, RUN_LENGTH, rays, seed + 1)
    for name, a in arrays.items():
        np.save(os.path.join(directory, f"{name}.npy"), a)
    with open(os.path.join(directory, "case.json"), "w") as f:
        json.dump(dict(levels=len(mip)), f)


def _prepared(spec: dict) -> dict:
    """kernel -> a prepared batch (calling it runs the C loop once) on the rays saved by
    :func:`_save_case` in ``spec["directory"]``, every structure memory-mapped; with
    ``spec["other"]`` also kernel + "/other" -> the batch of its other rays, on the same
    mappings (a second mapping of a file would be other addresses to the caches)."""
    from algos.intersect import prepare_timed_intersect

    directory = spec["directory"]

    def load(name):
        return np.load(os.path.join(directory, f"{name}.npy"), mmap_mode="r")

    with open(os.path.join(directory, "case.json")) as f:
        levels = json.load(f)["levels"]
    field = algos.Field(load("heights"))
    cellmax = load("cellmax")
    field.store("cellmax", cellmax, {"seconds": 0.0, "bytes": cellmax.nbytes})
    field.store("mip", [cellmax] + [load(f"mip{k}") for k in range(1, levels)],
                {"seconds": 0.0, "bytes": 0})
    field.store("compact", load("compact"), {"seconds": 0.0, "bytes": 0})
    rays = {"": (load("origins"), load("directions"))}
    if spec.get("other"):
        rays["/other"] = (load("origins_other"), load("directions_other"))
    return {k + tail: prepare_timed_intersect(k, field, np.array(o), np.array(d),
                                              surface=spec["surface"])[0]
            for tail, (o, d) in rays.items() for k in spec["kernels"]}


def callgrind_cache_counts(size, rays, seed=SEED, kernels=KERNELS,
                           regimes=False) -> dict | None:
    """kernel -> per-ray callgrind counts (``instructions``, ``data_accesses``,
    ``d1_misses``, ``ll_misses``) on ``rays`` first-hit rays of fBm ``size``^2, or None
    without valgrind. One child process; each kernel's batch is one dump, after a flush.
    ``regimes``: kernel -> regime -> those counts, for the regimes of :data:`REGIMES`:
    ``flushed`` (after a flush), ``warm`` (the same rays again, right after) and
    ``other_warmed`` (after a flush and a batch of as many other rays)."""
    from ..profile import _parse, callgrind_available

    if not callgrind_available():
        return None
    entry = "hf_intersect_batch"
    cache = [f"--{name}={','.join(str(v) for v in CACHE[name])}" for name in ("I1", "D1", "LL")]
    with tempfile.TemporaryDirectory() as tmp:
        _save_case(size, rays, seed, tmp, other=regimes)
        spec = dict(directory=tmp, surface=SURFACE, kernels=list(kernels))
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", "--cache-sim=yes", *cache,
               f"--callgrind-out-file={out}", f"--toggle-collect={entry}",
               f"--dump-after={entry}", sys.executable, "-c",
               _CHILD_REGIMES if regimes else _CHILD, json.dumps(spec)]
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
                   PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
        env.pop("LD_PRELOAD", None)
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            raise RuntimeError(f"compact: valgrind failed ({proc.returncode}):\n"
                               f"{proc.stderr[-2000:]}")
        dumps = sorted((f for f in os.listdir(tmp) if f.startswith("callgrind.out.")
                        and f.rsplit(".", 1)[1].isdigit()), key=lambda f: int(f.rsplit(".", 1)[1]))
        per_kernel = REGIME_DUMPS if regimes else 1
        if len(dumps) < per_kernel * len(kernels):
            raise RuntimeError(f"compact: expected {per_kernel * len(kernels)} dumps, "
                               f"got {len(dumps)}")

        def counts(name):
            t = _parse(os.path.join(tmp, name))["totals"]
            return {"instructions": t.get("Ir", 0) / rays,
                    "data_accesses": (t.get("Dr", 0) + t.get("Dw", 0)) / rays,
                    "d1_misses": (t.get("D1mr", 0) + t.get("D1mw", 0)) / rays,
                    "ll_misses": (t.get("DLmr", 0) + t.get("DLmw", 0)) / rays}

        result = {}
        for k, kernel in enumerate(kernels):
            mine = dumps[k * per_kernel:(k + 1) * per_kernel]
            result[kernel] = ({regime: counts(mine[n]) for regime, n in REGIMES.items()}
                              if regimes else counts(mine[0]))
    return result


#: the structure a source line of the kernels reads, by what the line indexes (the floor
#: walk, cext/hierarchies/maxmip.h, reads the leaf's codes and the row-major cell maxima
#: on lines of their own; the compiler charges a code's load to the decode's line,
#: hf_leaf_bound in cext/hierarchies/maxmip.h)
SOURCES = (("heights[", "heights"), ("leaf->code[", "tree leaves"),
           ("(double)code * step", "tree leaves"), ("node->", "tree nodes"), ("mip[", "mipmap"),
           ("cellmax[", "cell maxima"), ("maxima[", "cell maxima"))


def _classify(path: str, line: int, cache: dict) -> str:
    """The structure read at ``path:line`` (:data:`SOURCES`), else ``other``."""
    if path not in cache:
        try:
            with open(path) as f:
                cache[path] = f.read().splitlines()
        except OSError:
            cache[path] = []
    text = cache[path][line - 1] if 0 < line <= len(cache[path]) else ""
    for needle, name in SOURCES:
        if needle in text:
            return name
    return "other"


def _misses_by_source(path: str) -> dict:
    """structure -> (D1 misses, LL misses) of a callgrind file written with
    ``--compress-strings=no --compress-pos=no``, by the source line of each cost."""
    events, fl, fi, out, cache, skip = [], None, None, {}, {}, False
    with open(path) as f:
        for row in f:
            if row.startswith("calls="):
                skip = True  # the next cost line is the call's inclusive cost
            elif row.startswith("events:"):
                events = row.split()[1:]
            elif row.startswith("fl="):
                fl = fi = row[3:].strip()
            elif row.startswith(("fi=", "fe=")):
                fi = row[3:].strip()
            elif row.startswith("fn="):
                fi = fl
            elif row[:1].isdigit() and events:
                if skip:
                    skip = False
                    continue
                parts = row.split()
                values = dict(zip(events, (int(v) for v in parts[1:])))
                d1 = values.get("D1mr", 0) + values.get("D1mw", 0)
                ll = values.get("DLmr", 0) + values.get("DLmw", 0)
                if d1 or ll:
                    name = _classify(fi or "", int(parts[0]), cache)
                    a, b = out.get(name, (0, 0))
                    out[name] = (a + d1, b + ll)
    return out


def miss_sources(size, rays, seed=SEED, kernels=KERNELS) -> dict | None:
    """kernel -> structure -> per-ray (D1 misses, LL misses), from callgrind's cache
    simulation with the misses attributed to the kernels' source lines (the heights, the
    tree's leaves and nodes, the mipmap, the row-major cell maxima, other); None without
    valgrind. The costs of calls (the cell test inlined or not) count where they run."""
    from ..profile import callgrind_available

    if not callgrind_available():
        return None
    entry = "hf_intersect_batch"
    cache = [f"--{name}={','.join(str(v) for v in CACHE[name])}" for name in ("I1", "D1", "LL")]
    with tempfile.TemporaryDirectory() as tmp:
        _save_case(size, rays, seed, tmp)
        spec = dict(directory=tmp, surface=SURFACE, kernels=list(kernels))
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", "--cache-sim=yes", *cache,
               "--compress-strings=no", "--compress-pos=no",
               f"--callgrind-out-file={out}", f"--toggle-collect={entry}",
               f"--dump-after={entry}", sys.executable, "-c", _CHILD, json.dumps(spec)]
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
                   PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
        env.pop("LD_PRELOAD", None)
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            raise RuntimeError(f"compact: valgrind failed ({proc.returncode}):\n"
                               f"{proc.stderr[-2000:]}")
        dumps = sorted((f for f in os.listdir(tmp) if f.startswith("callgrind.out.")
                        and f.rsplit(".", 1)[1].isdigit()), key=lambda f: int(f.rsplit(".", 1)[1]))
        return {k: {name: (d1 / rays, ll / rays) for name, (d1, ll) in
                    _misses_by_source(os.path.join(tmp, f)).items()}
                for k, f in zip(kernels, dumps)}


def native_counts(size, rays, repeats, seed=SEED, kernels=KERNELS, timing=True) -> dict:
    """kernel -> per-ray walk statistics, ns per ray (None without ``timing``), and the
    structures' build seconds and bytes per height sample, on fBm ``size``^2."""
    from algos.intersect import prepare_timed_intersect
    from datasets_gen.rays import first_hit_rays

    from ..timing import interleaved

    field = _field(size)
    o, d = first_hit_rays(field, RUN_LENGTH, rays, seed)
    result, runs = {}, {}
    for k in kernels:
        hits = algos.intersect(k, field, o, d, surface=SURFACE, outputs=("t", "stats"))
        runs[k] = prepare_timed_intersect(k, field, o, d, surface=SURFACE)[0]
        stats = field.build_stats
        result[k] = {
            "hits": int(np.isfinite(hits.t).sum()),
            "t": hits.t,
            **{f"{s}_per_ray": float(hits.stats[s].mean())
               for s in ("cells_visited", "cells_tested", "tiles_skipped")},
            "build_seconds": sum(stats[s]["seconds"] for s in STRUCTURES[k]),
            "bytes_per_sample": sum(stats[s]["bytes"] for s in READS[k]) / field.heights.size,
            "structure_bytes_per_sample": {s: stats[s]["bytes"] / field.heights.size
                                           for s in STRUCTURES[k]}}
    if timing:
        times = interleaved(runs, repeats)
        for k in kernels:
            result[k]["ns_per_ray"] = float(np.median(times[k])) / rays
    return result


FIELDS = ["kernel", "size", "rays", "hits", "instructions_per_ray", "data_accesses_per_ray",
          "d1_misses_per_ray", "ll_misses_per_ray", "cells_visited_per_ray",
          "cells_tested_per_ray", "tiles_skipped_per_ray", "ns_per_ray", "build_seconds",
          "bytes_per_sample", "uptime"]


def _uptime() -> str:
    """The load averages (1, 5, 15 min), read in-process: a child ``uptime`` would inherit
    a sanitizer run's preloaded runtime and can hang there."""
    try:
        return "load average: " + ", ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "unknown"


def _fmt(v, digits=1):
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "n/a"
    return f"{v:.{digits}f}"


def _table(rows) -> list[str]:
    """The markdown tables: per kernel and size, and the ratios compact / maxmip."""
    by = {(r["kernel"], r["size"]): r for r in rows}
    sizes = sorted({r["size"] for r in rows})
    lines = ["| side | kernel | LL misses/ray | D1 misses (lines touched)/ray | "
             "instructions/ray | data accesses/ray | cells visited/ray | tiles skipped/ray | "
             "ns/ray | build s | bytes/sample |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in sizes:
        for k in KERNELS:
            r = by.get((k, s))
            if r is None:
                continue
            lines.append(
                f"| {s} | `{k}` | {_fmt(r['ll_misses_per_ray'], 2)} | "
                f"{_fmt(r['d1_misses_per_ray'])} | {_fmt(r['instructions_per_ray'], 0)} | "
                f"{_fmt(r['data_accesses_per_ray'], 0)} | {_fmt(r['cells_visited_per_ray'])} | "
                f"{_fmt(r['tiles_skipped_per_ray'])} | {_fmt(r['ns_per_ray'], 0)} | "
                f"{_fmt(r['build_seconds'], 3)} | {_fmt(r['bytes_per_sample'], 2)} |")
    lines += ["", "Ratios `dda_compact` / `dda_maxmip` (below 1: the compact tree does less):", "",
              "| side | LL misses | D1 misses | instructions | ns |", "|---|---|---|---|---|"]
    for s in sizes:
        a, b = by.get(("dda_maxmip", s)), by.get(("dda_compact", s))
        if a is None or b is None:
            continue

        def ratio(key):
            x, y = a.get(key), b.get(key)
            return _fmt(y / x, 2) if x and y is not None and x == x and y == y else "n/a"

        lines.append(f"| {s} | {ratio('ll_misses_per_ray')} | {ratio('d1_misses_per_ray')} | "
                     f"{ratio('instructions_per_ray')} | {ratio('ns_per_ray')} |")
    return lines


def _plot(rows, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = (("ll_misses_per_ray", "LL misses per ray (callgrind)"),
              ("d1_misses_per_ray", "D1 misses per ray: lines touched (callgrind)"),
              ("instructions_per_ray", "instructions per ray (callgrind)"),
              ("ns_per_ray", "ns per ray (indicative: shared machine)"))
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.6))
    for ax, (key, title) in zip(axes, panels):
        for k, style in zip(KERNELS, ("o-", "s-")):
            pts = sorted((r["size"], r[key]) for r in rows
                         if r["kernel"] == k and r.get(key) is not None and r[key] == r[key])
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], style, label=k)
        ax.set_xscale("log", base=2)
        ax.set_xlabel("field side (cells)")
        ax.set_title(title, fontsize=9)
        ax.grid(True, alpha=0.3)
    for ax in axes:
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
            break
    fig.suptitle(f"{DATASET}, random azimuths, first hit on {SURFACE}, one thread", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _read_rows(path) -> list[dict]:
    """The rows of an existing compact.csv, numbers parsed (empty cells: None)."""
    if not os.path.exists(path):
        return []
    rows = []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            for key, value in row.items():
                if key in ("kernel", "uptime"):
                    continue
                row[key] = None if value in ("", "None") else (
                    int(value) if key in ("size", "rays", "hits") else float(value))
            rows.append(row)
    return rows


def run(out_dir, tier=None, counts=True, timing=True, echo=print, resume=False) -> dict:
    """Measure every side of ``tier`` (default :data:`QUICK`), write ``compact.csv``,
    ``compact.md``, ``compact.json`` and ``compact.png`` into ``out_dir`` (rewritten after
    each side); return their paths. ``counts``: the callgrind counts (skipped without
    valgrind, and said so); ``timing``: the ns per ray; ``resume``: keep the sides the
    CSV already holds (each row carries the ``uptime`` it was measured at)."""
    tier = dict(QUICK, **(tier or {}))
    os.makedirs(out_dir, exist_ok=True)
    paths = {name: os.path.join(out_dir, f"compact.{name}") for name in ("csv", "md", "json", "png")}
    rows = [r for r in _read_rows(paths["csv"]) if r["rays"] == tier["rays"]] if resume else []
    done = {r["size"] for r in rows}
    for size in tier["sizes"]:
        if size in done:
            continue
        uptime = _uptime()
        echo(f"compact: {size}^2: {uptime}")
        native = native_counts(size, tier["rays"], tier["repeats"], timing=timing)
        ref_t = native[KERNELS[0]]["t"]
        for k in KERNELS[1:]:
            # the same first hits, bit for bit, on the measured rays
            if not np.array_equal(native[k]["t"].view(np.uint64), ref_t.view(np.uint64)):
                raise AssertionError(f"compact: {k} and {KERNELS[0]} differ on fbm {size}")
        cg = callgrind_cache_counts(size, tier["rays"]) if counts else None
        for k in KERNELS:
            n, c = native[k], (cg or {}).get(k, {})
            rows.append(dict(
                kernel=k, size=size, rays=tier["rays"], hits=n["hits"],
                instructions_per_ray=c.get("instructions"),
                data_accesses_per_ray=c.get("data_accesses"),
                d1_misses_per_ray=c.get("d1_misses"), ll_misses_per_ray=c.get("ll_misses"),
                cells_visited_per_ray=n["cells_visited_per_ray"],
                cells_tested_per_ray=n["cells_tested_per_ray"],
                tiles_skipped_per_ray=n["tiles_skipped_per_ray"],
                ns_per_ray=n.get("ns_per_ray"), build_seconds=n["build_seconds"],
                bytes_per_sample=n["bytes_per_sample"], uptime=uptime))
            echo(f"compact: {size}^2 {k}: LL {_fmt(rows[-1]['ll_misses_per_ray'], 2)}/ray, "
                 f"D1 {_fmt(rows[-1]['d1_misses_per_ray'])}/ray, "
                 f"{_fmt(rows[-1]['instructions_per_ray'], 0)} instr/ray, "
                 f"{_fmt(rows[-1]['ns_per_ray'], 0)} ns/ray")
        rows.sort(key=lambda r: (r["size"], KERNELS.index(r["kernel"])))
        _write(paths, rows, tier)
    _write(paths, rows, tier)
    return paths


def _write(paths, rows, tier) -> None:
    """The CSV, the environment, the table and the plot of ``rows``."""
    from ..timing import environment

    uptime = "; ".join(f"{s}^2: {u}" for s, u in sorted({(r["size"], r["uptime"]) for r in rows}))
    with open(paths["csv"], "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    env = environment()
    with open(paths["json"], "w") as f:
        json.dump(dict(tier=tier, cache=CACHE, environment=env, uptime=uptime,
                       dataset=DATASET, seed=SEED, run_length=RUN_LENGTH, surface=SURFACE),
                  f, indent=2, sort_keys=True, default=str)
        f.write("\n")
    lines = ["# The cache-compact maximum tree against the maximum mipmap", "",
             f"`dda_compact` (`algos.accel.compact`, `cext/hierarchies/compact.c`) against `dda_maxmip`: {DATASET} "
             f"fields seed 1, {tier['rays']} first-hit rays per side at random azimuths "
             f"(`datasets_gen.rays.first_hit_rays`, seed {SEED}), {SURFACE}, one thread. Both "
             "kernels give the same t bit for bit on these rays (checked while measuring).", "",
             "Counts: callgrind's cache simulation inside `hf_intersect_batch`, independent "
             "of the machine's load (instructions and data accesses exact; misses move by "
             "about 1 % with where the arrays land in memory), with a fixed cache model (D1 "
             f"{CACHE['D1'][0] >> 10} KiB {CACHE['D1'][1]}-way, LL {CACHE['LL'][0] >> 20} MiB "
             f"{CACHE['LL'][1]}-way, {CACHE['LL'][2]}-byte lines); each kernel starts with "
             "evicted caches. D1 misses count the lines a ray touches. ns/ray: "
             "`bench.timing.interleaved`, caches flushed, median of "
             f"{tier['repeats']} runs; **indicative only**: measured on a shared machine "
             f"(`uptime`: {uptime}). build s: the structures each kernel needs, the cell maxima "
             "included (the tree is built from them). bytes/sample: the structures each "
             "walk reads besides the heights (`dda_compact` reads the row-major cell maxima "
             "only in the fallback walk of rays lying on a grid line).", "",
             *_table(rows), "",
             f"Environment: {env.get('cpu')}, {env.get('compiler')}, commit "
             f"{env.get('git_commit')}.", "", "![growth](compact.png)", ""]
    with open(paths["md"], "w") as f:
        f.write("\n".join(lines))
    _plot(rows, paths["png"])


def main(argv=None) -> int:
    """``python -m bench.studies.compact``: :func:`run` with the command line's tier and
    output directory; returns the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true",
                        help=f"sides {FULL['sizes']}, {FULL['rays']} rays (an hour or more)")
    parser.add_argument("--sizes", default=None, help="comma-separated field sides")
    parser.add_argument("--rays", type=int, default=None)
    parser.add_argument("--repeats", type=int, default=None)
    parser.add_argument("--no-counts", action="store_true", help="skip callgrind")
    parser.add_argument("--no-timing", action="store_true", help="skip the ns per ray")
    parser.add_argument("--resume", action="store_true",
                        help="keep the sides the output's compact.csv already holds")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--out", default=os.path.join("results", "compact"))
    where.add_argument("--publish", action="store_true", help="write reports/compact/")
    args = parser.parse_args(argv)
    tier = dict(FULL if args.full else QUICK)
    if args.sizes:
        tier["sizes"] = tuple(int(s) for s in args.sizes.split(","))
    if args.rays:
        tier["rays"] = args.rays
    if args.repeats:
        tier["repeats"] = args.repeats
    out = os.path.join("reports", "compact") if args.publish else args.out
    paths = run(out, tier, counts=not args.no_counts, timing=not args.no_timing,
                resume=args.resume)
    print(f"compact: wrote {', '.join(paths.values())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
