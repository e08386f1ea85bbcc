"""``hftrace raster-vs-trace``: when does rasterising the cells beat tracing the pixels?

Rasterising costs grow with the cells in view, tracing costs with the pixels
and their path lengths; the crossover is read over *image pixels per visible cell*.

Axes (each a declared list; ``quick`` is the small tier, the default):

* ``images``: image sizes, width x height;
* ``fields``: fbm fields of side ``n`` (``datasets_gen.load("fbm", size=n, seed=1)``);
* ``views``: ``overview`` (above the north-west corner, the whole field in view, as
  ``hftrace render`` frames it) and ``grazing`` (a level camera near the ground at the
  south edge, looking north across the field).

Renderers: the rasterisers of :mod:`algos.raster` (the zbuffer, the reverse painter,
Watkins' scanline, Warnock's area subdivision, the floating horizon) and the best tracers
(:data:`TRACERS`), each on one thread, plus ``runs_maxmip`` and ``zbuffer`` on every core
as the threaded runs. Each case times every renderer interleaved
(:func:`bench.timing.interleaved`, caches flushed, the median of ``repeats``), on the
C loop's own clock; the field's acceleration structures are built once per field, before
timing, and not counted.

Definitions: ``visible_cells`` is the number of distinct cells that own a pixel of the
exact image (``zbuffer``); ``ratio`` is (median time of the best single-thread tracer) /
(median time of the best exact single-thread rasteriser, one of
``algos.raster.EXACT_RASTERISERS``): above 1 rasterising wins; the table also lists
``watkins`` and ``warnock`` on their own, and every row of the CSV carries
``ns_per_pixel`` (median time over the image's pixels). ``floating_horizon`` is
approximate; its time and its disagreement with the exact image (fraction of pixels whose
cell differs) are listed beside, its place on the accuracy Pareto.

The cost model sits next to the times: cells looked at, culled and rasterised,
triangles, fragments and pixels written by the rasterisers; cells and runs visited and
tiles skipped by the tracers; and, with ``counts=True`` and valgrind installed, the
instructions per pixel of each renderer on the smallest case (callgrind, collecting only
inside ``hf_raster_render`` / ``hf_intersect_batch``).

Outputs in ``out_dir``: ``raster_vs_trace.csv`` (one row per case and renderer),
``raster_vs_trace.md`` (the crossover table), ``raster_vs_trace.png`` (the ratio over
pixels per visible cell), ``instructions.csv`` (when counted) and ``env.json``.
"""
from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np

import algos
import datasets_gen
from algos import raster
from bench.timing import environment, interleaved, write_json

__all__ = ["QUICK", "FULL", "TRACERS", "VIEWS", "view_camera", "run"]

#: the small tier: runs in about a minute
QUICK = dict(
    images=[(320, 180), (640, 360)],   # image sizes, width x height
    fields=[256, 512],                 # fbm field sides (samples)
    repeats=3,                         # timed runs per renderer and case
)
#: the issue's tier: 320x180 to 3840x2160 images, 256^2 to 8192^2 fields (hours)
FULL = dict(
    images=[(320, 180), (640, 360), (1280, 720), (1920, 1080), (3840, 2160)],
    fields=[256, 1024, 2048, 4096, 8192],
    repeats=5,
)
#: the best tracers (exact, triangles surface): the baseline cell walk and the culling ones
TRACERS = ("dda", "runs", "dda_maxmip", "runs_maxmip")
#: the threaded runs: a tracer and a rasteriser on every core (or ``threads``)
THREADED = "runs_maxmip"
THREADED_RASTERISER = "zbuffer"
VIEWS = ("overview", "grazing")
EXACT_RASTERISERS = raster.EXACT_RASTERISERS
#: the visibility algorithms listed in their own columns of the table
LISTED = ("watkins", "warnock")
FOV = 60.0


def view_camera(view: str, heights: np.ndarray):
    """``(position, look_at)`` of a view of ``heights`` (cell units).

    ``overview``: 15 % of the field outside its north-west corner and high above it,
    looking at the centre (the framing of ``hftrace render``). ``grazing``: at the
    middle of the south edge, 2 % of the field's side above the highest sample within
    two cells, looking level towards the north edge."""
    rows, cols = heights.shape
    hmin, hmax = float(heights.min()), float(heights.max())
    if view == "overview":
        span = hmax - hmin
        centre = ((cols - 1) / 2, (rows - 1) / 2, float(np.mean(heights)))
        position = (-0.15 * cols, -0.15 * rows, hmax + 0.15 * max(rows, cols) + span)
        return position, centre
    if view == "grazing":
        x, y = (cols - 1) / 2, 1.0
        local = float(heights[: 3, int(x) - 2:int(x) + 3].max())
        z = local + 0.02 * max(rows, cols)
        return (x, y, z), (x, rows - 1.0, z)
    raise ValueError(f"view: expected one of {', '.join(VIEWS)}, got {view!r}")


def _available_tracers():
    return tuple(t for t in TRACERS if t in algos.INTERSECTORS)


def _case(field, view, width, height, repeats, threads):
    """Time every renderer on one case; returns rows (one per renderer)."""
    heights = field.heights
    position, look_at = view_camera(view, heights)
    images = {}

    def image_job(draw, name, n_threads=1):
        """A timed job drawing the view with ``draw`` (``raster.render`` or
        ``raster.trace``); its image is kept for the comparisons."""
        key = name if n_threads == 1 else f"{name}@threads"

        def job():
            images[key] = draw(name, field, position, look_at, FOV, width, height,
                               threads=n_threads)
            return images[key].elapsed_ns
        return job

    jobs = {name: image_job(raster.render, name) for name in raster.RASTERISERS}
    for name in _available_tracers():
        jobs[name] = image_job(raster.trace, name, 1)
    if threads != 1 and THREADED in algos.INTERSECTORS:
        jobs[f"{THREADED}@threads"] = image_job(raster.trace, THREADED, threads)
    if threads != 1:
        jobs[f"{THREADED_RASTERISER}@threads"] = image_job(raster.render, THREADED_RASTERISER, threads)
    times = interleaved(jobs, repeats)
    exact = images["zbuffer"]
    cells = exact.cell[np.isfinite(exact.t)]
    visible = int(len(np.unique(cells[:, 1].astype(np.int64) * field.cols + cells[:, 0])))
    rows = []
    for name, samples in times.items():
        image = images[name]
        agreement = raster.diff_images(image, exact)
        rows.append(dict(
            field=field.rows, view=view, width=width, height=height, pixels=width * height,
            visible_cells=visible, renderer=name,
            kind="rasteriser" if name.split("@")[0] in raster.RASTERISERS else "tracer",
            threads=(threads if name.endswith("@threads") else 1),
            median_ms=float(np.median(samples)) / 1e6,
            ns_per_pixel=float(np.median(samples)) / (width * height),
            cell_differs=agreement["cell_differs"],
            counts=json.dumps(image.counts, sort_keys=True)))
    return rows


def _summaries(rows):
    """One summary per case: the best tracer, the best exact rasteriser and their ratio."""
    cases = {}
    for row in rows:
        cases.setdefault((row["field"], row["view"], row["width"], row["height"]), []).append(row)
    out = []
    for (size, view, width, height), group in sorted(cases.items()):
        tracers = [r for r in group if r["kind"] == "tracer" and r["threads"] == 1]
        rasters = [r for r in group if r["renderer"] in EXACT_RASTERISERS]
        best_t = min(tracers, key=lambda r: r["median_ms"])
        best_r = min(rasters, key=lambda r: r["median_ms"])
        fh = next(r for r in group if r["renderer"] == "floating_horizon")
        threaded = {r["renderer"]: r["median_ms"] for r in group if r["renderer"].endswith("@threads")}
        listed = {r["renderer"]: r["median_ms"] for r in group if r["renderer"] in LISTED}
        out.append(dict(
            field=size, view=view, width=width, height=height, pixels=width * height,
            visible_cells=group[0]["visible_cells"],
            pixels_per_visible_cell=width * height / max(group[0]["visible_cells"], 1),
            best_tracer=best_t["renderer"], tracer_ms=best_t["median_ms"],
            best_rasteriser=best_r["renderer"], rasteriser_ms=best_r["median_ms"],
            ratio=best_t["median_ms"] / best_r["median_ms"],
            floating_horizon_ms=fh["median_ms"], floating_horizon_cell_differs=fh["cell_differs"],
            **{f"{name}_ms": listed.get(name, float("nan")) for name in LISTED},
            threaded_tracer_ms=threaded.get(f"{THREADED}@threads", float("nan")),
            threaded_rasteriser_ms=threaded.get(f"{THREADED_RASTERISER}@threads", float("nan"))))
    return out


def _write_table(path, summaries, env, tier, instructions):
    lines = [
        "# Rasterising against tracing",
        "",
        f"Tier `{tier}`; every renderer on one thread (the threaded columns: "
        f"`{THREADED}` and `{THREADED_RASTERISER}` on {env.get('threads_used')} threads); "
        "median of the C loop's time (of the pool's wall time when threaded). "
        "ratio = best tracer / best exact rasteriser: above 1 rasterising wins. "
        "`fh` = floating_horizon (approximate): time and fraction of pixels whose cell "
        "differs from the exact image. `watkins` and `warnock` (exact) are listed on their own.",
        "",
        "| field | view | image | visible cells | pixels / visible cell | best tracer | ms "
        "| best rasteriser | ms | ratio | watkins ms | warnock ms | fh ms | fh cells differ "
        "| threaded tracer ms | threaded zbuffer ms |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in summaries:
        lines.append(
            f"| {s['field']}^2 | {s['view']} | {s['width']}x{s['height']} | {s['visible_cells']} "
            f"| {s['pixels_per_visible_cell']:.3g} | {s['best_tracer']} | {s['tracer_ms']:.1f} "
            f"| {s['best_rasteriser']} | {s['rasteriser_ms']:.1f} | {s['ratio']:.2f} "
            f"| {s['watkins_ms']:.1f} | {s['warnock_ms']:.1f} "
            f"| {s['floating_horizon_ms']:.1f} | {s['floating_horizon_cell_differs']:.3f} "
            f"| {s['threaded_tracer_ms']:.1f} | {s['threaded_rasteriser_ms']:.1f} |")
    if instructions:
        lines += ["", "Instructions per pixel (callgrind, smallest case):", "",
                  "| renderer | instructions | per pixel |", "|---|---|---|"]
        for row in instructions:
            lines.append(f"| {row['renderer']} | {row['instructions']} "
                         f"| {row['instructions_per_pixel']:.1f} |")
    lines += ["", f"Environment: {env.get('cpu')}, commit {env.get('git_commit')}; "
              "see env.json.", ""]
    with open(path, "w") as f:
        f.write("\n".join(lines))


def _plot(path, summaries):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=110)
    for view, marker in zip(VIEWS, "os"):
        pts = [s for s in summaries if s["view"] == view]
        if not pts:
            continue
        ax.scatter([s["pixels_per_visible_cell"] for s in pts], [s["ratio"] for s in pts],
                   marker=marker, label=view)
        for s in pts:
            ax.annotate(f"{s['field']}², {s['width']}x{s['height']}",
                        (s["pixels_per_visible_cell"], s["ratio"]), fontsize=6,
                        xytext=(3, 3), textcoords="offset points")
    ax.axhline(1.0, color="grey", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("image pixels per visible cell")
    ax.set_ylabel("time: best tracer / best rasteriser")
    ax.set_title("above 1: rasterising wins")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


_CHILD = r"""
import json, sys
import numpy as np, datasets_gen, algos
from algos import raster
from bench.studies.raster_vs_trace import view_camera, FOV
spec = json.loads(sys.argv[1])
field = algos.Field(datasets_gen.load("fbm", size=spec["size"], seed=1).heights)
position, look_at = view_camera(spec["view"], field.heights)
if spec["renderer"] in raster.RASTERISERS:
    raster.render(spec["renderer"], field, position, look_at, FOV, spec["width"], spec["height"])
else:
    raster.trace(spec["renderer"], field, position, look_at, FOV, spec["width"], spec["height"],
                 threads=1)
"""


def instructions(renderer, size, view, width, height):
    """Instructions executed inside the renderer's C entry (callgrind), or None without
    valgrind."""
    if shutil.which("valgrind") is None:
        return None
    entry = "hf_raster_render" if renderer in raster.RASTERISERS else "hf_intersect_batch"
    spec = dict(renderer=renderer, size=size, view=view, width=width, height=height)
    # warm the dataset cache natively (the generator is slow under valgrind)
    datasets_gen.load("fbm", size=size, seed=1)
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
               f"--toggle-collect={entry}", sys.executable, "-c", _CHILD, json.dumps(spec)]
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
                   PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
        env.pop("LD_PRELOAD", None)
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            raise RuntimeError(f"instructions: valgrind failed ({proc.returncode}):\n"
                               f"{proc.stderr[-2000:]}")
        with open(out) as f:
            for line in f:
                if line.startswith(("summary:", "totals:")):
                    return int(line.split()[1])
    return None


def run(out_dir, quick=True, threads=None, counts=True, echo=print, tier=None) -> dict:
    """Run the study; write its files into ``out_dir`` and return their paths.

    ``quick``: the small tier :data:`QUICK` (else :data:`FULL`, hours: do not run it on a
    shared machine). ``threads``: the threaded runs' thread count (None: every core).
    ``counts``: instruction counts of every renderer on the smallest case, when valgrind
    is installed. ``tier``: a dict like :data:`QUICK` that replaces the tier (tests)."""
    tier = tier or (QUICK if quick else FULL)
    os.makedirs(out_dir, exist_ok=True)
    n_threads = threads if threads is not None else len(os.sched_getaffinity(0))
    rows = []
    for size in tier["fields"]:
        field = algos.Field(datasets_gen.load("fbm", size=size, seed=1).heights)
        for view in VIEWS:
            for width, height in tier["images"]:
                case = _case(field, view, width, height, tier["repeats"], n_threads)
                rows += case
                best = min((r for r in case if r["kind"] == "tracer" and r["threads"] == 1),
                           key=lambda r: r["median_ms"])
                z = next(r for r in case if r["renderer"] == "zbuffer")
                echo(f"raster-vs-trace: {size}^2 {view} {width}x{height}: zbuffer "
                     f"{z['median_ms']:.1f} ms, best tracer {best['renderer']} "
                     f"{best['median_ms']:.1f} ms")
    summaries = _summaries(rows)
    env = environment()
    env.update(threads_used=n_threads, tier="quick" if quick else "full",
               note="every renderer on 1 thread; runs_maxmip and zbuffer also threaded")
    paths = {}
    paths["csv"] = os.path.join(out_dir, "raster_vs_trace.csv")
    with open(paths["csv"], "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    instruction_rows = []
    if counts and shutil.which("valgrind") is not None:
        size, (width, height), view = tier["fields"][0], tier["images"][0], VIEWS[0]
        for name in raster.RASTERISERS + _available_tracers():
            total = instructions(name, size, view, width, height)
            instruction_rows.append(dict(renderer=name, field=size, view=view, width=width,
                                         height=height, instructions=total,
                                         instructions_per_pixel=total / (width * height)))
        paths["instructions"] = os.path.join(out_dir, "instructions.csv")
        with open(paths["instructions"], "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(instruction_rows[0]))
            writer.writeheader()
            writer.writerows(instruction_rows)
    elif counts:
        echo("raster-vs-trace: valgrind not found; no instruction counts")
    paths["md"] = os.path.join(out_dir, "raster_vs_trace.md")
    _write_table(paths["md"], summaries, env, "quick" if quick else "full", instruction_rows)
    paths["png"] = os.path.join(out_dir, "raster_vs_trace.png")
    _plot(paths["png"], summaries)
    paths["env"] = os.path.join(out_dir, "env.json")
    write_json(paths["env"], env)
    return paths
