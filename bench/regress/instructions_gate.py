"""``hftrace regress --metric instructions``: a regression gate that cannot flake.

Every C kernel runs once per (workload, surface) on a small fixed input (fBm 256^2,
seed 1; 200 first-hit rays or 400 traversal rays at r = 25) in one child Python under
``valgrind --tool=callgrind --branch-sim=yes``. ``--dump-before`` and ``--dump-after`` on
the C batch entries (:data:`BATCH_ENTRIES`) cut the run into one profile per batch, and
only instructions executed in the extension's own code (the ``algos._kernels`` object)
are counted, so NumPy, the interpreter and the set-up between batches never enter. The
counts are exact for one build on one input: two runs give identical numbers (tested), so
the default tolerance is 1 %. The gate is on each case's instructions and branches per ray in
total; the per-function counts recorded beside them only name the functions that grew,
since the split between functions moves whenever the compiler inlines differently.

The counts belong to one toolchain: the baseline records its commit, compiler, valgrind
and inputs, and on any mismatch the gate counts that commit built here instead
(:mod:`bench.regress.baseline`).
"""
from __future__ import annotations

import glob
import json
import os
import subprocess
import sys
import tempfile

from ..profile import callgrind_available

#: The committed baseline of the counts (``hftrace regress --metric instructions --update``)
BASELINE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "instructions_baseline.json")

DEFAULT_TOLERANCE = 0.01
#: The C batch entries, one profile each: the dispatcher's two, and pitched_maxmip's
#: (above the dispatcher, called by the binding)
BATCH_ENTRIES = ("hf_intersect_batch", "hf_walk_batch", "hf_pitched_batch")
SIZE = 256
FIRST_HIT_RAYS = 200
TRAVERSAL_RAYS = 400
R = 25
SEED = 2008

_CHILD = r"""
import json, sys
import numpy as np
import algos
spec = json.loads(sys.argv[1])
arrays = np.load(spec["inputs"])
heights, o3, d3, o2, d2 = (arrays[k] for k in ("heights", "o3", "d3", "o2", "d2"))
shape = (heights.shape[1] - 1, heights.shape[0] - 1)
prepare_hit = getattr(algos, "prepare_timed_intersect", None)
if prepare_hit is None:
    from algos.intersect import prepare_timed_intersect as prepare_hit
field = algos.Field(heights)
runs = []
for workload, surface, kernel in spec["cases"]:
    if workload == "first_hit":
        run, _ = prepare_hit(kernel, field, o3, d3, surface=surface)
    else:
        run, _ = algos.prepare_timed(kernel, o2, d2, shape, workload)
    runs.append(run)
# one throwaway batch first: its profile takes whatever the extension ran before the
# batches (a structure built in C, such as the cone_relaxed slopes), and is dropped
algos.intersect("dda", field, [[0.5, 0.5, 1e9]], [[1.0, 0.0, -1.0]])
for run in runs:
    run()
"""


def gate_inputs():
    """The gate's fixed field and rays (:func:`bench.regress.workload.make_inputs`)."""
    from .workload import make_inputs

    return make_inputs(size=SIZE, first_hit_rays=FIRST_HIT_RAYS, traversal_rays=TRAVERSAL_RAYS,
                       r=R, seed=SEED)


def cases():
    """Every (workload, surface, kernel) the gate counts: each C intersector on each
    surface, each traversal on both 2D workloads."""
    import algos

    out = []
    for name in algos.INTERSECTORS:
        # the peer and plugins run outside hftrace's C entry, which callgrind counts
        if algos.INTERSECTOR_REGISTRY[name].kind == "peer" or algos.INTERSECTOR_REGISTRY[name].plugin is not None:
            continue
        for surface in algos.SURFACES:
            out.append(("first_hit", surface, name))
    for name in algos.TRAVERSAL_REGISTRY:
        if algos.TRAVERSAL_REGISTRY[name].plugin is not None:
            continue
        for workload in ("visit", "runs"):
            out.append((workload, "-", name))
    return out


def key(workload, surface, kernel) -> str:
    """The name of one case in a baseline: ``workload/surface/kernel``."""
    return f"{workload}/{surface}/{kernel}"


def _parse_dump(path: str, object_part: str) -> tuple[str, dict, dict]:
    """(trigger, totals by event, self instructions by function) of one callgrind dump,
    counting only functions whose object path contains ``object_part``."""
    events, trigger = [], ""
    obs, fns, fls = {}, {}, {}
    current_ob = current_fn = None
    in_call = False
    totals: dict = {}
    per_fn: dict = {}

    def name(table, text):
        text = text.strip()
        if text.startswith("("):
            close = text.index(")")
            ident, rest = text[1:close], text[close + 1:].strip()
            if rest:
                table[ident] = rest
            return table.get(ident, rest)
        return text

    with open(path) as f:
        for line in f:
            if line.startswith("events:"):
                events = line.split()[1:]
            elif line.startswith("desc: Trigger:"):
                trigger = line.split("Trigger:", 1)[1].strip()
            elif line.startswith("ob="):
                current_ob = name(obs, line[3:])
            elif line.startswith(("fl=", "fi=", "fe=")):
                name(fls, line[3:])
            elif line.startswith("fn="):
                current_fn = name(fns, line[3:])
            elif line.startswith("cob="):
                name(obs, line[4:])
            elif line.startswith(("cfi=", "cfl=")):
                name(fls, line[4:])
            elif line.startswith("cfn="):
                name(fns, line[4:])
            elif line.startswith("calls="):
                in_call = True
            elif line[:1].isdigit() or line[:1] in "+-*":
                if in_call:  # the inclusive cost of a call, not the caller's own
                    in_call = False
                    continue
                if current_ob is None or object_part not in current_ob:
                    continue
                values = [int(v) for v in line.split()[1:]]
                for ev, v in zip(events, values):
                    totals[ev] = totals.get(ev, 0) + v
                if values:
                    per_fn[current_fn] = per_fn.get(current_fn, 0) + values[0]
    return trigger, totals, per_fn


def measure(echo=print, only=None, root=None, inputs=None, todo=None) -> dict:
    """Counts of every case (or of the cases in ``only``, or of the explicit list ``todo``
    of (workload, surface, kernel)), now: {key: {instructions_per_ray, branches_per_ray,
    functions}}. ``root``: the directory whose ``algos`` package (and built extension)
    is counted, default this checkout; ``inputs``: the field and rays
    (:func:`gate_inputs` by default)."""
    if not callgrind_available():
        raise RuntimeError("regress --metric instructions needs valgrind (apt-get install "
                           "valgrind); it is not on PATH")
    import numpy as np

    import algos

    inputs = inputs if inputs is not None else gate_inputs()
    if todo is None:
        todo = [c for c in cases() if only is None or key(*c) in only]
    todo = [list(c) for c in todo]
    object_part = os.path.basename(algos._kernels.__file__)
    if root is None:
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    with tempfile.TemporaryDirectory() as tmp:
        arrays = os.path.join(tmp, "inputs.npz")
        np.savez(arrays, heights=inputs.heights, o3=inputs.o3, d3=inputs.d3, o2=inputs.o2,
                 d2=inputs.d2)
        spec = dict(inputs=arrays, cases=todo)
        out = os.path.join(tmp, "cg.out")
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
               "--branch-sim=yes", *(f"--dump-{when}={entry}" for when in ("before", "after")
                                     for entry in BATCH_ENTRIES),
               sys.executable, "-c", _CHILD, json.dumps(spec)]
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
                   PYTHONHASHSEED="0")
        env.pop("LD_PRELOAD", None)
        # the counted tree first, alone: another checkout's algos must not shadow it
        env["PYTHONPATH"] = root
        echo(f"regress: counting {len(todo)} batches under callgrind ...")
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp)
        if proc.returncode != 0:
            raise RuntimeError(f"regress: valgrind failed ({proc.returncode}):\n"
                               f"{proc.stderr[-2000:]}")
        dumps = sorted(glob.glob(out + ".*"), key=lambda p: int(p.rsplit(".", 1)[1]))
        parsed = [_parse_dump(p, object_part) for p in dumps]
    batches = [(t, f) for trigger, t, f in parsed if trigger.startswith("--dump-after")][1:]
    if len(batches) != len(todo):
        raise RuntimeError(f"regress: expected {len(todo)} batch profiles, got {len(batches)}")
    result = {}
    for (workload, surface, kernel), (totals, per_fn) in zip(todo, batches):
        rays = len(inputs.o3) if workload == "first_hit" else len(inputs.o2)
        instructions = totals.get("Ir", 0)
        branches = totals.get("Bc", 0) + totals.get("Bi", 0)
        top = {fn: v for fn, v in sorted(per_fn.items(), key=lambda kv: -kv[1])
               if v >= 0.005 * max(instructions, 1)}
        result[key(workload, surface, kernel)] = dict(
            instructions_per_ray=round(instructions / rays, 3),
            branches_per_ray=round(branches / rays, 3), functions=top)
    return result


def compare(baseline: dict, measured: dict, tolerance: float) -> list[dict]:
    """Cases whose instructions or branches per ray grew by more than ``tolerance``, or
    that were not measured; each with the functions whose counts grew."""
    if not 0 <= tolerance < 1:
        raise ValueError(f"tolerance: expected a fraction in [0, 1), got {tolerance}")
    failures = []
    for name, base in sorted(baseline.items()):
        got = measured.get(name)
        if got is None:
            failures.append(dict(case=name, reason="not measured", grew=[]))
            continue
        reasons = []
        for metric in ("instructions_per_ray", "branches_per_ray"):
            b, m = base[metric], got[metric]
            if m > b * (1 + tolerance):
                reasons.append(f"{metric.replace('_per_ray', '')} per ray {b:,.1f} -> {m:,.1f} "
                               f"(+{100 * (m / b - 1):.2f} %)")
        if reasons:
            rays = FIRST_HIT_RAYS if name.startswith("first_hit") else TRAVERSAL_RAYS
            grew = []
            for fn in set(base.get("functions", {})) | set(got.get("functions", {})):
                before = base.get("functions", {}).get(fn, 0)
                after = got.get("functions", {}).get(fn, 0)
                if after > before:
                    grew.append((fn, before / rays, after / rays))
            grew.sort(key=lambda g: g[1] - g[2])
            failures.append(dict(case=name, reason="; ".join(reasons), grew=grew[:5]))
    return failures


#: What instruction counts depend on besides the code and the inputs
TOOLCHAIN_KEYS = ("compiler", "valgrind", "python", "numpy", "machine", "switches")


def print_table(base_cases: dict, measured: dict, failures, echo=print) -> None:
    """The per-case table: instructions and branches per ray, before and after."""
    echo(f"{'case':40s} {'instr/ray before':>17s} {'after':>12s} {'branches before':>16s} {'after':>10s}")
    for name, b in sorted(base_cases.items()):
        m = measured.get(name, {})
        flag = "  REGRESSED" if any(f["case"] == name for f in failures) else ""
        echo(f"{name:40s} {b['instructions_per_ray']:17,.1f} "
             f"{m.get('instructions_per_ray', float('nan')):12,.1f} "
             f"{b['branches_per_ray']:16,.1f} {m.get('branches_per_ray', float('nan')):10,.1f}{flag}")


def run(baseline_path, tolerance=None, update=False, echo=print) -> int:
    """Count every case and compare with the baseline at ``baseline_path`` (or, with
    ``update``, write it from a clean tree). When the baseline was counted with another
    toolchain or on other inputs, its commit is rebuilt and counted here instead
    (:mod:`bench.regress.baseline`). The gate is on each case's totals per ray, never on
    the split between functions, which moves when the compiler inlines differently.
    Exit status: 0 when every case is within ``tolerance`` (default the baseline's, else
    1 %), 1 when any grew or is missing, 2 on an error (no valgrind, an unreadable
    baseline, a dirty tree for ``update``, a base that cannot be rebuilt)."""
    from . import baseline as bl
    from .revisions import toolchain

    if not callgrind_available():
        echo("hftrace: error: regress --metric instructions needs valgrind (apt-get install "
             "valgrind); it is not on PATH")
        return 2
    try:
        tc = toolchain()
        inputs = gate_inputs()
        if update:
            commit = bl.provenance()
            measured = measure(echo, inputs=inputs)
            bl.write(baseline_path, "instructions", measured, inputs, tc, commit,
                     tolerance if tolerance is not None else DEFAULT_TOLERANCE,
                     "callgrind counts per ray; see bench/regress/instructions_gate.py")
            echo(f"wrote {len(measured)} cases counted at {commit[:10]} to {baseline_path}")
            return 0
        base = bl.read(baseline_path, "instructions")
        base_cases = base["cases"]
        differ = bl.mismatches(base, inputs, tc, TOOLCHAIN_KEYS)
        if differ:
            echo("regress: the baseline was counted elsewhere (" + "; ".join(differ) + "): "
                 f"counting its commit {str(base.get('commit'))[:10]} here instead of the snapshot")
            built = bl.rebuilt_base(base, baseline_path, echo)
            base_cases = measure(echo, inputs=inputs, root=built.root,
                                 todo=[c for c in cases() if key(*c) in base_cases])
        measured = measure(echo, inputs=inputs)
    except (RuntimeError, OSError) as exc:
        echo(f"hftrace: error: {exc}")
        return 2
    tol = tolerance if tolerance is not None else base.get("tolerance", DEFAULT_TOLERANCE)
    failures = compare(base_cases, measured, tol)
    print_table(base_cases, measured, failures, echo)
    unbaselined = sorted(set(measured) - set(base_cases))
    if unbaselined:
        echo(f"  not in the baseline, so not gated (refresh it with --update): {', '.join(unbaselined)}")
    if failures:
        echo(f"{len(failures)} case(s) grew by more than {100 * tol:g} %:")
        for f in failures:
            echo(f"  {f['case']}: {f['reason']}")
            for fn, before, after in f["grew"]:
                echo(f"      {fn}: {before:,.1f} -> {after:,.1f} instructions per ray "
                     "(attribution only: inlining moves it)")
        return 1
    echo(f"all {len(base_cases)} cases within {100 * tol:g} % of the baseline")
    return 0
