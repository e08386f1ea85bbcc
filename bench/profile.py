"""``hftrace profile``: exact instruction and branch counts of one kernel, from callgrind.

Timing on a shared VM is noisy and these VMs expose no hardware counters, so the cost
model of every report also carries counts: the kernel runs once in a child Python under
``valgrind --tool=callgrind --branch-sim=yes``, collecting only inside the C batch entry
(``--toggle-collect``), so NumPy, the field generator and the interpreter are not
counted. The same batch, run natively, gives the cells and runs it visits, and the
counts are divided by them. Counts are deterministic for one build on one input.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

__all__ = ["profile", "profile_many", "format_profile", "prepared_batch", "ENTRY", "callgrind_available"]

#: The C entry each workload's batch runs in; only it is counted.
ENTRY = {"first_hit": "hf_intersect_batch", "visit": "hf_walk_batch", "runs": "hf_walk_batch"}

_CHILD = r"""
import json, sys
from bench.profile import prepared_batch
spec = json.loads(sys.argv[1])
run = prepared_batch(spec)
run()
"""


_CHILD_MANY = r"""
import json, sys
from bench.profile import prepared_batch
for spec in json.loads(sys.argv[1]):
    run = prepared_batch(spec)
    run()
"""


def profile_many(kernels, dataset="fbm", size=1024, r=25, rays=300, surface="triangles",
                 seed=2008) -> dict:
    """First-hit counts of several kernels in one callgrind run (one interpreter start
    instead of one per kernel): each exit of the C entry dumps its counts
    (``--dump-after``), the i-th dump being the i-th kernel's. Returns kernel -> the
    per-ray and per-cell values of :func:`profile`."""
    if not callgrind_available():
        raise RuntimeError("profile: valgrind is not installed (apt-get install valgrind)")
    specs = [dict(kernel=k, dataset=dataset, size=size, r=r, rays=rays, surface=surface,
                  workload="first_hit", seed=seed, options={}, parallel=False) for k in kernels]
    if not specs:
        return {}
    cells, runs = _visited(specs[0])
    entry = ENTRY["first_hit"]
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
               f"--toggle-collect={entry}", f"--dump-after={entry}", "--branch-sim=yes",
               sys.executable, "-c", _CHILD_MANY, json.dumps(specs)]
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
        env.pop("LD_PRELOAD", None)
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            raise RuntimeError(f"profile: valgrind failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
        dumps = sorted((f for f in os.listdir(tmp) if re.fullmatch(r"callgrind\.out\.\d+", f)),
                       key=lambda f: int(f.rsplit(".", 1)[1]))
        if len(dumps) < len(specs):
            raise RuntimeError(f"profile: expected {len(specs)} dumps, callgrind wrote {len(dumps)}")
        parsed = [_parse(os.path.join(tmp, f)) for f in dumps[: len(specs)]]
    result = {}
    for spec, p in zip(specs, parsed):
        t = p["totals"]
        instructions = t.get("Ir", 0)
        branches = t.get("Bc", 0) + t.get("Bi", 0)
        mispredicts = t.get("Bcm", 0) + t.get("Bim", 0)
        result[spec["kernel"]] = {
            "instructions_per_ray": instructions / rays,
            "instructions_per_cell": instructions / cells if cells else float("nan"),
            "branches_per_cell": branches / cells if cells else float("nan"),
            "mispredicts_per_cell": mispredicts / cells if cells else float("nan")}
    return result


def callgrind_available() -> bool:
    """Whether ``valgrind`` is on PATH (callgrind comes with it)."""
    return shutil.which("valgrind") is not None


def _first_hit_rays(field, spec):
    """The spec's first-hit rays: the sweep's random-origin rays at run length r, or with
    ``parallel`` one batch of parallel rays of slope 1/r (orthographic, falling at 10
    degrees), the workload runs_periodic is built for."""
    from datasets_gen.rays import first_hit_rays, orthographic_rays

    if spec.get("parallel"):
        h = field.heights
        return orthographic_rays((h.shape[1] - 1, h.shape[0] - 1), int(spec["r"]),
                                 spec["rays"], spec["seed"], top=field.hmax)
    return first_hit_rays(field, spec["r"], spec["rays"], spec["seed"])


def prepared_batch(spec: dict):
    """The prepared batch of ``spec`` (dataset, size, seed, r, rays, workload, surface,
    kernel); calling it runs the C loop once."""
    import algos
    import datasets_gen
    from algos.intersect import prepare_timed_intersect
    from datasets_gen.rays import traversal_rays

    heights = datasets_gen.load(spec["dataset"], size=spec["size"], seed=1).heights
    workload = spec["workload"]
    if workload == "first_hit":
        field = algos.Field(heights)
        o, d = _first_hit_rays(field, spec)
        run, _ = prepare_timed_intersect(
            spec["kernel"], field, o, d, surface=spec["surface"], **spec.get("options", {}))
        return run
    rows, cols = heights.shape
    shape = (cols - 1, rows - 1)
    o, d = traversal_rays(shape, spec["r"], spec["rays"], spec["seed"])
    run, _ = algos.prepare_timed(spec["kernel"], o, d, shape,
                                 "visit" if workload == "visit" else "runs")
    return run


def _visited(spec: dict) -> tuple[float, float]:
    """Total cells and runs the batch visits (a native run of the same rays)."""
    import algos
    import datasets_gen
    from datasets_gen.rays import traversal_rays

    heights = datasets_gen.load(spec["dataset"], size=spec["size"], seed=1).heights
    if spec["workload"] == "first_hit":
        field = algos.Field(heights)
        o, d = _first_hit_rays(field, spec)
        ref = algos.intersect("runs", field, o, d, surface=spec["surface"], outputs=("stats",))
        # cells along the ray up to the hit (the same for every exact walk): the cost
        # model divides by the work every kernel must account for, not by what it skipped
        return float(ref.stats["cells_visited"].sum()), float(ref.stats["runs_visited"].sum())
    rows, cols = heights.shape
    o, d = traversal_rays((cols - 1, rows - 1), spec["r"], spec["rays"], spec["seed"])
    counts = algos.traverse("midpoint", o, d, (cols - 1, rows - 1), output="count")
    return float(counts.cells.sum()), float(counts.runs.sum())


def _parse(path: str) -> dict:
    """Event totals and per-function self counts of a callgrind output file. A cost line
    right after ``calls=`` is the inclusive cost of that call, not the caller's own."""
    events, totals, functions, names = [], None, {}, {}
    current, skip_next = None, False
    with open(path) as f:
        for line in f:
            if line.startswith("events:"):
                events = line.split()[1:]
            elif line.startswith(("summary:", "totals:")):
                totals = [int(v) for v in line.split()[1:]]
            elif line.startswith("fn="):
                current = _name(line[3:].strip(), names)
                functions.setdefault(current, [0] * len(events))
            elif line.startswith("cfn="):
                _name(line[4:].strip(), names)
            elif line.startswith("calls="):
                skip_next = True
            elif line[:1].isdigit() or line[:1] in "+-*":
                if skip_next:
                    skip_next = False
                    continue
                if current is not None:
                    vals = functions[current]
                    for k, v in enumerate(line.split()[1:][: len(events)]):
                        vals[k] += int(v)
    if totals is None:
        totals = [sum(v[k] for v in functions.values()) for k in range(len(events))]
    return {"events": events, "totals": dict(zip(events, totals)),
            "functions": {fn: dict(zip(events, v)) for fn, v in functions.items()}}


def _name(text: str, names: dict) -> str:
    """callgrind's name compression: '(12) name' defines, '(12)' refers."""
    m = re.match(r"\((\d+)\)(?:\s+(.*))?$", text)
    if not m:
        return text
    if m.group(2):
        names[m.group(1)] = m.group(2)
    return names.get(m.group(1), text)


def profile(kernel: str, dataset="fbm", size=1024, r=25, rays=1000, surface="triangles",
            workload="first_hit", seed=2008, cache_sim=False, options=None,
            parallel=False) -> dict:
    """Run one kernel's batch under callgrind; counts per ray, per cell and per run.

    Returns a dict with ``instructions``, ``branches`` (conditional + indirect
    executed), ``mispredicts`` (callgrind's simple predictor), their per-ray, per-cell
    and per-run values, the ``functions`` with the most instructions, and, with
    ``cache_sim``, ``d1_misses`` and ``ll_misses`` (simulated caches). ``options`` are
    the intersector's options (first hits only), e.g. ``{"fine_level": 2}``.
    ``parallel``: one batch of parallel rays of slope 1/r instead (first hits only).
    """
    if not callgrind_available():
        raise RuntimeError("profile: valgrind is not installed (apt-get install valgrind); "
                           "the instruction counts need callgrind")
    if workload not in ENTRY:
        raise ValueError(f"workload: expected one of {', '.join(ENTRY)}, got {workload!r}")
    if kernel in ("embree", "embree3"):
        raise ValueError(f"kernel: {kernel} runs outside our C entry; profile counts our kernels")
    spec = dict(kernel=kernel, dataset=dataset, size=size, r=r, rays=rays, surface=surface,
                workload=workload, seed=seed, options=dict(options or {}),
                parallel=bool(parallel))
    if parallel and (workload != "first_hit" or r == "random"):
        raise ValueError("parallel: one batch of parallel first-hit rays needs a numeric r")
    if spec["options"] and workload != "first_hit":
        raise ValueError("options: only first-hit intersectors take options")
    # warm the dataset cache natively: under valgrind a generator is ~50x slower
    cells, runs = _visited(spec)
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
               f"--toggle-collect={ENTRY[workload]}", "--branch-sim=yes",
               f"--cache-sim={'yes' if cache_sim else 'no'}",
               sys.executable, "-c", _CHILD, json.dumps(spec)]
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
        env.pop("LD_PRELOAD", None)  # a sanitizer runtime preloaded here cannot run under valgrind
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            raise RuntimeError(f"profile: valgrind failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
        parsed = _parse(out)
    t = parsed["totals"]
    instructions = t.get("Ir", 0)
    branches = t.get("Bc", 0) + t.get("Bi", 0)
    mispredicts = t.get("Bcm", 0) + t.get("Bim", 0)
    result = dict(spec, instructions=instructions, branches=branches, mispredicts=mispredicts,
                  cells=cells, runs=runs)
    for what, value in (("instructions", instructions), ("branches", branches),
                        ("mispredicts", mispredicts)):
        result[f"{what}_per_ray"] = value / rays
        result[f"{what}_per_cell"] = value / cells if cells else float("nan")
        result[f"{what}_per_run"] = value / runs if runs else float("nan")
    if cache_sim:
        result["d1_misses"] = t.get("D1mr", 0) + t.get("D1mw", 0)
        result["ll_misses"] = t.get("DLmr", 0) + t.get("DLmw", 0)
        result["d1_misses_per_cell"] = result["d1_misses"] / cells if cells else float("nan")
        result["ll_misses_per_cell"] = result["ll_misses"] / cells if cells else float("nan")
    top = sorted(parsed["functions"].items(), key=lambda kv: -kv[1].get("Ir", 0))[:8]
    result["functions"] = [(fn, v.get("Ir", 0)) for fn, v in top if v.get("Ir", 0) > 0]
    return result


def format_profile(p: dict) -> str:
    """The text report of one :func:`profile` result: totals and per-ray, per-cell and
    per-run counts, and the functions with the most instructions."""
    opts = "".join(f" {k}={v}" for k, v in p.get("options", {}).items())
    lines = [f"{p['kernel']}{opts} on {p['dataset']} {p['size']}^2, {p['workload']}"
             + (f" {p['surface']}" if p["workload"] == "first_hit" else "")
             + f", r = {p['r']}, {p['rays']} rays "
             f"({p['cells'] / p['rays']:.1f} cells, {p['runs'] / p['rays']:.1f} runs per ray)",
             f"  instructions: {p['instructions']:>14,}  {p['instructions_per_ray']:10.1f}/ray "
             f"{p['instructions_per_cell']:8.2f}/cell {p['instructions_per_run']:8.2f}/run",
             f"  branches:     {p['branches']:>14,}  {p['branches_per_ray']:10.1f}/ray "
             f"{p['branches_per_cell']:8.2f}/cell {p['branches_per_run']:8.2f}/run",
             f"  mispredicted: {p['mispredicts']:>14,}  {p['mispredicts_per_ray']:10.1f}/ray "
             f"{p['mispredicts_per_cell']:8.2f}/cell"]
    if "d1_misses" in p:
        lines.append(f"  D1 misses:    {p['d1_misses']:>14,}  {p['d1_misses_per_cell']:8.3f}/cell;"
                     f"  LL misses {p['ll_misses']:,} ({p['ll_misses_per_cell']:.3f}/cell)")
    lines.append("  most instructions in: " + ", ".join(f"{fn} {ir:,}" for fn, ir in p["functions"][:4]))
    return "\n".join(lines)
