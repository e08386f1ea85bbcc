"""Coherent batches: ``packet_maxmip`` against the per-ray ``dda_maxmip`` on the same rays.

The coherence axis (:data:`COHERENCE`), one seeded batch each:

* ``random``: the sweep's first-hit rays (``datasets_gen.rays.first_hit_rays``, r = 25):
  origins uniform over the field, neighbours in the batch unrelated;
* ``camera``: ``algos.render``'s primary rays (``datasets_gen.rays.pinhole``, default
  camera, row-major: neighbours in a packet are neighbouring pixels of one row);
* ``parallel``: an orthographic camera: a regular grid of origins above the field in scan
  order, one direction falling at 20 degrees;
* ``sun``: sun-shadow rays: from every vertex (scan order, lifted 1e-3 above it) towards
  a sun at azimuth 315 and elevation 20 degrees (rising rays, neighbours one cell apart).

Two measures, both on the same rays:

* instructions per ray under ``valgrind --tool=callgrind`` (exact and independent of the
  machine's load; only the extension's own code between the entry and exit of
  ``hf_intersect_batch`` is counted, as in ``bench.regress.instructions_gate``), on a
  row sample of the batch (every ``row_step``-th row of the image, whole rows, so packets
  keep their neighbours);
* ns per ray, median of interleaved repeats on one pinned CPU, with the load average
  printed beside it (the machine may be shared: then only the counts are firm).

``ratio`` = dda_maxmip / packet_maxmip (instructions, or ns): above 1, packets pay.
Every batch is also checked bit for bit (t and cell) between the two kernels.
"""
from __future__ import annotations

import glob
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

import algos
import datasets_gen
from datasets_gen import rays as raysets

from ..profile import callgrind_available
from ..report import RowWriter
from ..timing import environment, interleaved, pin_to_one_cpu, write_json

#: the rays' coherence (module docstring)
COHERENCE = ("random", "camera", "parallel", "sun")
#: the per-ray kernel, and the packet kernel at each packet width
PER_RAY = "dda_maxmip"
PACKET = "packet_maxmip"
WIDTHS = (4, 8)
#: (dataset, side): the issue's fields (Jacksboro 2048 and fBm; 8192^2 in the full tier)
QUICK_DATASETS = (("jacksboro", 2048), ("fbm", 2048))
FULL_DATASETS = (("jacksboro", 2048), ("fbm", 2048), ("fbm", 8192))
IMAGE = (1280, 720)
COLUMNS = ("dataset", "coherence", "surface", "algorithm", "packet_width", "rays",
           "counted_rays", "instructions_per_ray", "branches_per_ray", "ns_per_ray",
           "ratio_instructions", "ratio_ns", "load_1min", "identical")


def batch(field, coherence, seed=2008, image=IMAGE):
    """(origins, directions, row_length) of one coherent (or random) batch of about
    ``image[0] * image[1]`` rays on ``field``; ``row_length``: rays per image row (the unit
    a row sample keeps whole)."""
    h = field.heights
    rows, cols = h.shape
    width, height = image
    top = float(h.max())
    if coherence == "camera":
        pos, look = _default_camera(h)
        rs = raysets.pinhole(pos, look, 60.0, width, height)
        return rs.origins, rs.directions, width
    if coherence == "parallel":
        # an orthographic camera over the footprint, looking north-east and down
        u = np.linspace(0, cols - 1, width) + 0.0137
        v = np.linspace(0, rows - 1, height) + 0.0291
        uu, vv = np.meshgrid(u, v)
        n = uu.size
        o = np.column_stack([uu.ravel() - 0.25 * cols, vv.ravel() - 0.25 * rows,
                             np.full(n, top + 1.0)])
        d = np.tile([math.cos(math.radians(37.0)), math.sin(math.radians(37.0)),
                     -math.tan(math.radians(20.0))], (n, 1))
        return o, d, width
    if coherence == "sun":
        # shadow rays from a width x height sample of vertices, in scan order
        i = np.linspace(0, cols - 1, width).round()
        j = np.linspace(0, rows - 1, height).round()
        ii, jj = np.meshgrid(i, j)
        z = h[jj.astype(int), ii.astype(int)].astype(float) + 1e-3
        az, el = math.radians(315.0), math.radians(20.0)
        # azimuth clockwise from north, north is -y (docs/CONVENTIONS.md)
        d = np.tile([math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el), math.sin(el)],
                    (ii.size, 1))
        return np.column_stack([ii.ravel(), jj.ravel(), z.ravel()]), d, width
    if coherence == "random":
        from datasets_gen.rays import first_hit_rays

        o, d = first_hit_rays(field, 25, width * height, seed)
        return o, d, width
    raise ValueError(f"coherence: unknown {coherence!r}; valid: {', '.join(COHERENCE)}")


def _default_camera(h):
    from algos.render import default_camera

    return default_camera(h)


def _row_sample(o, d, row_length, row_step):
    """Every row_step-th row of the batch (whole rows)."""
    n_rows = len(o) // row_length
    keep = np.concatenate([np.arange(r * row_length, (r + 1) * row_length)
                           for r in range(0, n_rows, row_step)])
    return o[keep], d[keep]


_CHILD = r"""
import json, sys
import numpy as np
import algos
from algos.intersect import prepare_timed_intersect
spec = json.loads(sys.argv[1])
field = algos.Field(np.load(spec["heights"]))
o = np.load(spec["origins"]); d = np.load(spec["directions"])
runs = [prepare_timed_intersect(k, field, o, d, surface=spec["surface"], **opts)[0]
        for k, opts in spec["kernels"]]
algos.intersect("dda", field, [[0.5, 0.5, 1e9]], [[1.0, 0.0, -1.0]])  # a throwaway batch
for run in runs:
    run()
"""


def count_instructions(heights, o, d, kernels, surface="triangles"):
    """Instructions and branches per ray of each (name, options) in ``kernels`` on the
    same rays, in one callgrind run: a list of (instructions_per_ray, branches_per_ray)."""
    from ..regress.instructions_gate import _parse_dump

    if not callgrind_available():
        raise RuntimeError("packets: counting needs valgrind (apt-get install valgrind)")
    with tempfile.TemporaryDirectory() as tmp:
        paths = {k: os.path.join(tmp, f"{k}.npy") for k in ("heights", "origins", "directions")}
        np.save(paths["heights"], heights)
        np.save(paths["origins"], o)
        np.save(paths["directions"], d)
        spec = dict(paths, surface=surface, kernels=[list(k) for k in kernels])
        out = os.path.join(tmp, "cg.out")
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", "--branch-sim=yes",
               "--dump-before=hf_intersect_batch", "--dump-after=hf_intersect_batch",
               sys.executable, "-c", _CHILD, json.dumps(spec)]
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
                   PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
        env.pop("LD_PRELOAD", None)
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            raise RuntimeError(f"packets: valgrind failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
        dumps = sorted(glob.glob(out + ".*"), key=lambda p: int(p.rsplit(".", 1)[1]))
        object_part = os.path.basename(algos._kernels.__file__)
        parsed = [_parse_dump(p, object_part) for p in dumps]
    batches = [t for trigger, t, _ in parsed if trigger.startswith("--dump-after")][1:]
    if len(batches) != len(kernels):
        raise RuntimeError(f"packets: expected {len(kernels)} batch profiles, got {len(batches)}")
    return [(t.get("Ir", 0) / len(o), (t.get("Bc", 0) + t.get("Bi", 0)) / len(o))
            for t in batches]


def _load_1min() -> float:
    return os.getloadavg()[0]


def measure(label, field, coherence, surface="triangles", repeats=5, row_step=8, counts=True,
            time_it=True, seed=2008, image=IMAGE):
    """Rows for one (field, coherence): dda_maxmip and packet_maxmip at each width."""
    o, d, row_length = batch(field, coherence, seed, image)
    kernels = [(PER_RAY, {})] + [(PACKET, {"packet_width": w}) for w in WIDTHS]
    ref = algos.intersect(PER_RAY, field, o, d, surface=surface, threads=1)
    identical = []
    for _, opts in kernels[1:]:
        got = algos.intersect(PACKET, field, o, d, surface=surface, threads=1, **opts)
        identical.append(bool(np.array_equal(ref.t.view(np.int64), got.t.view(np.int64))
                              and np.array_equal(ref.cell, got.cell)))
    counted = [(math.nan, math.nan)] * len(kernels)
    n_counted = 0
    if counts and callgrind_available():
        oc, dc = _row_sample(o, d, row_length, row_step)
        n_counted = len(oc)
        counted = count_instructions(field.heights, oc, dc, kernels, surface)
    ns = [math.nan] * len(kernels)
    load = _load_1min()
    if time_it:
        from algos.intersect import prepare_timed_intersect

        jobs = {}
        for k, (name, opts) in enumerate(kernels):
            jobs[k] = prepare_timed_intersect(name, field, o, d, surface=surface, **opts)[0]
        times = interleaved(jobs, repeats, flush=False)
        ns = [float(np.median(times[k])) / len(o) for k in range(len(kernels))]
        load = max(load, _load_1min())
    rows = []
    for k, (name, opts) in enumerate(kernels):
        rows.append(dict(
            dataset=label, coherence=coherence, surface=surface, algorithm=name,
            packet_width=opts.get("packet_width", 1), rays=len(o), counted_rays=n_counted,
            instructions_per_ray=round(counted[k][0], 1), branches_per_ray=round(counted[k][1], 1),
            ns_per_ray=round(ns[k], 1),
            ratio_instructions=round(counted[0][0] / counted[k][0], 3) if counted[k][0] else math.nan,
            ratio_ns=round(ns[0] / ns[k], 3) if ns[k] else math.nan,
            load_1min=round(load, 2), identical=True if k == 0 else identical[k - 1]))
    return rows


def table(rows) -> str:
    """The markdown table of :func:`run`'s rows."""
    lines = ["| field | coherence | kernel | width | instr/ray | ratio (instr) | ns/ray | "
             "ratio (ns) | load | bit-identical |", "|---|---|---|---|---|---|---|---|---|---|"]
    for x in rows:
        lines.append(f"| {x['dataset']} | {x['coherence']} | {x['algorithm']} | "
                     f"{x['packet_width']} | {x['instructions_per_ray']} | "
                     f"{x['ratio_instructions']} | {x['ns_per_ray']} | {x['ratio_ns']} | "
                     f"{x['load_1min']} | {x['identical']} |")
    return "\n".join(lines)


def run(out_dir="results/packets", quick=True, counts=True, time_it=True, repeats=5,
        datasets=None, coherences=COHERENCE, surface="triangles", row_step=8, image=IMAGE,
        echo=print):
    """Measure every (field, coherence): results.csv, tables.md and env.json in
    ``out_dir``; returns the rows. Pins this process to one CPU."""
    os.makedirs(out_dir, exist_ok=True)
    cpu = pin_to_one_cpu()
    env = dict(environment(), pinned_cpu=cpu)
    write_json(os.path.join(out_dir, "env.json"), env)
    datasets = datasets or (QUICK_DATASETS if quick else FULL_DATASETS)
    rows = []
    with RowWriter(os.path.join(out_dir, "results.csv"), COLUMNS) as writer:
        for dataset, side in datasets:
            heights = datasets_gen.load(dataset, size=side, seed=1).heights
            label = f"{dataset}{side}"
            field = algos.Field(heights)
            for coherence in coherences:
                for row in measure(label, field, coherence, surface, repeats, row_step, counts,
                                   time_it, image=image):
                    writer.write(row)
                    rows.append(row)
                echo(f"  packets: {label} {coherence} done")
    text = ["# Coherent batches: packet_maxmip vs the per-ray dda_maxmip", "",
            f"{image[0]} x {image[1]} rays per batch, surface {surface}; instructions counted "
            f"by callgrind on every {row_step}-th row; ns/ray: median of {repeats} interleaved "
            f"repeats on one pinned CPU, with the 1-minute load average (a shared machine "
            f"makes ns/ray unreliable; the counts are exact). ratio = dda_maxmip / kernel. "
            f"Machine: {env['cpu']}, commit {env['git_commit']}.", "", table(rows), ""]
    with open(os.path.join(out_dir, "tables.md"), "w") as f:
        f.write("\n".join(text))
    echo("\n".join(text))
    return rows
