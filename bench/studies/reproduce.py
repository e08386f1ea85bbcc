"""``hftrace reproduce``: the speedup-by-run-length study of Henning & Stephenson (2004),
measured here, next to every registered algorithm (plugins included) and Embree.

Presets (all seeded; every field is generated or loaded from the embedded data):

* headline (default, <= 3 minutes on 2 cores; the kernels of :data:`HEADLINE_KERNELS`
  and every plugin): the paper's measure only, first hit on two triangles per cell by
  mean run length, on fBm, terraces and uniform random at 1024^2 and the Jacksboro DEM
  upsampled to 2048 samples on its longer side; r in {1, 2, 5, 25, 100} plus uniformly
  random azimuths: 24 groups. Each group is measured in sequential paired rounds
  (``bench.timing.paired_rounds``) until every ratio is within ``precision`` (default
  ±2 %) or the group's :data:`GROUP_BUDGET` seconds are spent, on calls of at least
  1000 rays lasting :data:`CALL_MS` ms. Writes the headline table (at most eight kernel
  columns) and the full one, the run-length plot with every shown kernel's intervals,
  and the cost model with instruction counts of the kernels it shows.
* standard (``--preset standard``, the former quick preset): the same fields and run
  lengths with the workloads visit, runs and first_hit on all four surfaces (144
  groups), every registered kernel, the same sequential design, then the "parallel
  rays" part (``bench.studies.parallel_rays``:
  ``parallel.md``, ``parallel.csv``, ``products.png``).
* full (``--full`` or ``--preset full``): adds fBm 2048^2; r in
  {1, 1.5, 2, 3, 5, 8, 13, 25, 50, 100} plus random; 3000 rays, 9 repeats (about 330
  groups), then the parallel rays part and the quick tier of the rasterising-against-
  tracing study (``bench.studies.raster_vs_trace``, into ``raster_vs_trace/``) and the
  coherent-batch study (``bench.studies.packets``, into ``packets/``).

Each dataset's structures and Embree scene are built once and kept on its Field for
every group; each group's rays are drawn once; the instruction counts run after the
timings, two callgrind processes at a time (nothing is timed then).
"""
from __future__ import annotations

import os
import time

from .. import analysis
from ..sweep import SweepConfig, groups, run_sweep
from ..timing import pin_to_one_cpu

#: The repository's root: ``publish`` writes its ``reports/``
REPOSITORY = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

PRESETS = ("headline", "standard", "full")
#: Where each preset writes: results/<name> by default, reports/<published> with --publish
#: (the standard preset keeps the committed reports/reproduce of the former quick preset).
OUT_NAMES = {"headline": "reproduce", "standard": "reproduce-standard", "full": "reproduce-full"}
PUBLISHED = {"headline": "reproduce-headline", "standard": "reproduce", "full": "reproduce-full"}
#: Seconds a group may spend in timed rounds (``bench.sweep.SweepConfig.group_budget``),
#: and the shortest baseline call (``call_ms``) a group's rays are sized for.
GROUP_BUDGET = {"headline": 6.0, "standard": 3.0, "full": 4.0}
CALL_MS = 0.5
#: The work a timed call is sized to, in cell steps of the baseline (``bench.sweep.work_per_ray``,
#: ``rays_for_cells``): 0.2-0.4 ms here on every dataset and run length, so a kernel's
#: working set stays near the per-core cache and a group affords some hundred pairs.
CALL_CELLS = 100000
#: The cache state of a timed call (``bench.timing.FLUSH_MODES``; docs/METHOD.md, "Cache
#: regimes compared"): warm, each visit's timed calls follow an untimed call of the same
#: kernel on the same rays, so they find the lines the kernel itself left, whichever
#: kernel ran before. A flushed call's time is mostly the first touch of the field from
#: memory that other machines share, and a paired log-ratio of two such calls spreads by
#: 10-35 % on this VM against 1-5 % warm: the flushed regime cannot reach ±2 % in the
#: run's minutes. ``--flush call`` still measures it.
FLUSH = "warm"
#: The fewest paired rounds of every kernel (``repeats``).
MIN_ROUNDS = 10
#: Seconds of a group's set-up beside its budget (rays, reference, calibration, agreement),
#: for the first line's estimate (:func:`estimate_seconds`).
SECONDS_GROUP_SETUP = 0.6
#: Seconds of the parallel rays part and of the instruction counts (two at a time).
SECONDS_PARALLEL = {"headline": 0, "standard": 240, "full": 420}
SECONDS_PER_COUNT = 5.0

DATASETS_QUICK = [
    {"name": "fbm", "size": 1024, "seed": 1},
    {"name": "terraces", "size": 1024, "seed": 1},
    {"name": "uniform", "size": 1024, "seed": 1},
    {"name": "jacksboro", "size": 2048},
]
RUN_LENGTHS = [1, 2, 5, 25, 100, "random"]
#: Intersectors the headline preset measures (plugins join them): the baseline, the cell
#: walks of the fair baseline, the paper's run walk, the max-mipmap walks, the cone
#: walk, one marcher and Embree. The other kernels (bit-identical to dda_maxmip, the
#: other marchers, the run walk's float and periodic variants, the C Embree peer) are in
#: the standard and full presets, bench-intersect and hftrace targets.
HEADLINE_KERNELS = ("dda", "dda_f32", "midpoint", "runs", "dda_maxmip", "runs_maxmip", "cone",
                    "march_linear", "embree")
#: Among those left out: bit-identical to dda_maxmip, or the optional C Embree peer.
HEADLINE_LEAVES_OUT = ("packet_maxmip", "dda_compact", "embree3")


def _check_precision(precision):
    if isinstance(precision, bool) or not isinstance(precision, (int, float)) or \
            not 0 < precision < 1:
        raise ValueError(f"--precision: expected a fraction in (0, 1) (0.02 is ±2 %), got "
                         f"{precision!r}")


def preset(full=False, name=None, kernels=None, precision=0.02, flush=FLUSH) -> SweepConfig:
    """The sweep of a preset (module docstring): ``name`` one of :data:`PRESETS` (default
    headline; ``full=True`` means "full"); ``kernels`` restricts the algorithms (dda, the
    baseline, is always measured); ``precision`` the half-width, as a fraction of the
    speedup, at which a ratio's rounds stop (docs/METHOD.md, "Paired rounds")."""
    name = "full" if full else (name or "headline")
    if name not in PRESETS:
        raise ValueError(f"--preset: unknown preset {name!r}; valid: {', '.join(PRESETS)}")
    _check_precision(precision)
    out = OUT_NAMES[name]
    design = dict(precision=float(precision), group_budget=GROUP_BUDGET[name], call_ms=CALL_MS,
                  flush=flush, call_cells=CALL_CELLS)
    if name == "full":
        return SweepConfig(
            name=out, rays=3000, repeats=MIN_ROUNDS, seed=2004, **design,
            workloads=["visit", "runs", "first_hit"],
            surfaces=["flat", "plane3", "triangles", "bilinear"],
            run_lengths=[1, 1.5, 2, 3, 5, 8, 13, 25, 50, 100, "random"],
            datasets=DATASETS_QUICK + [{"name": "fbm", "size": 2048, "seed": 1}],
            algorithms=kernels)
    if name == "standard":
        return SweepConfig(
            name=out, rays=1000, repeats=MIN_ROUNDS, seed=2004, **design,
            workloads=["visit", "runs", "first_hit"],
            surfaces=["flat", "plane3", "triangles", "bilinear"],
            run_lengths=list(RUN_LENGTHS), datasets=list(DATASETS_QUICK), algorithms=kernels)
    if kernels is None:
        # the headline keeps its three minutes by measuring the kernels its table shows
        from algos import INTERSECTOR_REGISTRY

        kernels = [n for n, a in INTERSECTOR_REGISTRY.items()
                   if n in HEADLINE_KERNELS or a.plugin is not None]
    return SweepConfig(name=out, rays=1000, repeats=MIN_ROUNDS, seed=2004, **design,
                       workloads=["first_hit"],
                       surfaces=["triangles"], run_lengths=list(RUN_LENGTHS),
                       datasets=list(DATASETS_QUICK), algorithms=kernels)


def estimate_seconds(cfg, name, counts=True) -> float:
    """The run's wall time on a quiet 2-core machine here when every group spends its
    whole budget, in seconds: an upper estimate. Each group of ``cfg`` (``bench.sweep.groups``)
    takes ``cfg.group_budget`` and its set-up (:data:`SECONDS_GROUP_SETUP`), then come the
    instruction counts of the kernels it measures (``counts``; two at a time, Embree not
    counted) and the preset's parallel rays part (:data:`SECONDS_PARALLEL`; the full
    preset's raster-vs-trace and packets studies are not included). A group stops
    sooner when every ratio reaches ``cfg.precision``: with fewer kernels or a looser
    precision the run takes less."""
    todo = groups(cfg)
    kernels = {k for *_, names in todo for k in names if k != "embree"}
    count_s = SECONDS_PER_COUNT * len(kernels) / 2 if counts else 0
    return len(todo) * (cfg.group_budget + SECONDS_GROUP_SETUP) + SECONDS_PARALLEL[name] + \
        count_s + 15


def _plural(n, word) -> str:
    return f"{n} {word}{'s' if n != 1 else ''}"


def start_line(cfg, name, counts, out_dir) -> str:
    """The run's first line: the preset, its groups, datasets and kernels, at most how long
    it takes (:func:`estimate_seconds`, rounded to minutes) and on what that depends, its
    phases and where it writes."""
    todo = groups(cfg)
    kernels = {k for *_, names in todo for k in names}
    minutes = max(1, round(estimate_seconds(cfg, name, counts) / 60))
    until = "" if cfg.precision is None else f"every ratio is within ±{100 * cfg.precision:g} % or "
    return (f"hftrace reproduce ({name} preset): {_plural(len(todo), 'group')} on "
            f"{_plural(len(cfg.datasets), 'dataset')}, {_plural(len(kernels), 'kernel')}; at "
            f"most about {minutes} min on a quiet 2-core machine (each group until {until}its "
            f"{cfg.group_budget:g} s budget is spent; longer while other processes run) "
            f"(phases: measure{', counts' if counts else ''}"
            f"{', parallel rays' if name != 'headline' else ''}"
            f"{', raster vs trace and packets (not in the estimate)' if name == 'full' else ''}"
            f", reports) -> {out_dir}")


def run(full=False, out_dir=None, resume=False, progress=True, echo=print, counts=True,
        publish=False, preset_name=None, kernels=None, isolate=False, all_kernels=False,
        precision=0.02, flush=FLUSH):
    """Run the study and write its reports; returns the paths of ``analysis.write_reports``
    and ``"all_contended"``: True when every group ran while other processes used the
    machine (``--strict`` then exits non-zero).

    ``out_dir`` defaults to ``results/<name>`` under the current directory (untracked,
    :data:`OUT_NAMES`); ``publish`` writes to the committed reference,
    ``reports/<name>`` of the repository (:data:`PUBLISHED`), instead. ``counts``: also
    the instruction counts (callgrind, when valgrind exists); ``resume``: keep the rows
    already measured; ``kernels``: a subset of algorithms; ``isolate``: plugins in a
    child process (``bench.sweep.run_sweep``); ``flush``: the cache state of a timed call
    (:data:`FLUSH`)."""
    name = "full" if full else (preset_name or "headline")
    _check_precision(precision)
    cfg = preset(name=name, kernels=kernels, flush=flush)
    if cfg.precision is not None:
        cfg.precision = float(precision)
    if publish and out_dir is not None:
        raise ValueError("out_dir: give either an output directory or publish, not both")
    if out_dir is not None and not str(out_dir).strip():
        raise ValueError("--out: an empty path; give a directory")
    if publish:
        # the committed reference is replaced on purpose (git keeps the former one)
        out_dir = os.path.join(REPOSITORY, "reports", PUBLISHED[name])
        if not resume:
            for old in ("results.csv", "counts.csv", "parallel.csv"):
                if os.path.exists(os.path.join(out_dir, old)):
                    os.remove(os.path.join(out_dir, old))
    if out_dir is None:
        # the default directory is never overwritten: a rerun writes a new run directory,
        # and --resume continues the latest one
        base = os.path.join("results", cfg.name)
        runs = [base] + [f"{base}.{k}" for k in range(2, 1000)]
        used = [d for d in runs if os.path.exists(os.path.join(d, "results.csv"))]
        if resume:
            out_dir = used[-1] if used else base
        else:
            out_dir = next(d for d in runs if not os.path.exists(os.path.join(d, "results.csv")))
            if out_dir != base:
                echo(f"{base} holds an earlier run (kept); writing {out_dir} "
                     f"(`--resume` continues the latest run directory)")
    wall0 = time.perf_counter()
    echo(start_line(cfg, name, counts, out_dir))
    affinity = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    pin_to_one_cpu()
    measure0 = time.perf_counter()
    run_sweep(cfg, out_dir, resume=resume, progress=progress, echo=echo, isolate=isolate)
    measure_s = time.perf_counter() - measure0
    counts0 = time.perf_counter()
    if affinity is not None:  # nothing is timed from here on: every core may count
        os.sched_setaffinity(0, affinity)
    if counts:
        # the cost model's instruction counts (callgrind) of the kernels the table shows
        from ..counts import write_counts

        df = analysis.load(os.path.join(out_dir, "results.csv"))
        shown = list(dict.fromkeys(df.loc[df["workload"] == "first_hit", "algorithm"]))
        write_counts(os.path.join(out_dir, "counts.csv"), shown, resume=resume, echo=echo,
                     workers=len(affinity or [1]), progress=progress)
    if name != "headline":
        # parallel rays at work: horizons and orthographic first hits at slopes 1/r, with
        # every method and the peers (bench/studies/parallel_rays.py)
        from .parallel_rays import run_parallel

        pin_to_one_cpu()
        run_parallel(out_dir=out_dir, resume=resume, echo=echo,
                     repeats=7 if name == "full" else 5, sample=40000 if name == "full" else 20000)
    if name == "full":
        # the other road: rasterising the cells against tracing the pixels, its
        # quick tier (`hftrace raster-vs-trace --full` is the full one, hours)
        from . import raster_vs_trace

        raster_vs_trace.run(os.path.join(out_dir, "raster_vs_trace"), quick=True, counts=counts,
                            echo=echo)
        # the coherence axis: packets against the per-ray walk (bench.studies.packets)
        from . import packets

        packets.run(os.path.join(out_dir, "packets"), quick=False, counts=counts, echo=echo)
    reports0 = time.perf_counter()
    other_phases_s = reports0 - counts0  # counts, and the parallel rays part beyond headline
    paths = analysis.write_reports(os.path.join(out_dir, "results.csv"), out_dir,
                                   title=f"hftrace reproduce ({name} preset)",
                                   all_kernels=all_kernels)
    import json

    from ..timing import write_json

    env_path = os.path.join(out_dir, "env.json")
    env = json.load(open(env_path))
    total = time.perf_counter() - wall0
    # this session's (a resumed run's "run" adds up every session: bench.sweep.merge_sessions)
    session = (env.get("run") or {}).get("last_session") or env.get("run") or {}
    timed = session.get("timed_s") or 0.0
    # the sweep's phases: preparing (fields, their structures, Embree's scenes), then
    # measuring (noise calibration, the groups' set-up, their timed and untimed calls)
    prepare_s = session.get("prepare_s") or 0.0
    measure_s -= prepare_s
    env["reproduce"] = {"preset": name, "wall_s": round(total, 1), "measure_s": round(measure_s, 1),
                        "prepare_s": round(prepare_s, 1),
                        "after_measure_s": round(other_phases_s, 1),
                        "reports_s": round(time.perf_counter() - reports0, 1),
                        "timed_share_of_total": round(timed / total, 4) if total else None,
                        "precision": cfg.precision}
    # timed seconds over the measure phase (the sweep, noise calibration included)
    env["timed_share_of_measure"] = round(timed / measure_s, 4) if measure_s else None
    write_json(env_path, env)
    df = analysis.load(os.path.join(out_dir, "results.csv"))
    groups_ = df.drop_duplicates(["dataset", "workload", "surface", "run_length"])
    paths["all_contended"] = bool(len(groups_)) and bool(groups_["contended"].all())
    with open(paths["speedup"]) as f:
        text = f.read()
    echo(text[: text.find("## Workload")] if "## Workload" in text else text)
    if paths["all_contended"]:
        echo("every group ran while other processes used the machine: no cell is a finding")
    echo(f"wrote {out_dir}/results.csv, speedup.md, speedup_full.md, run_length_vs_speedup.png, "
         f"ns_per_ray_vs_cells.png, env.json; {time.perf_counter() - wall0:.0f} s in all")
    return paths
