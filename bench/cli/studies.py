"""The studies' commands: ``bench-traverse``, ``bench-intersect``, ``reproduce``, ``scale``,
``terrain-bench``, ``accuracy``, ``stress``, ``raster-vs-trace``, ``targets`` and ``compact``. Each calls its module in
``bench.studies`` and writes under ``results/<command>/`` unless ``--out`` says otherwise.
"""
from __future__ import annotations

import algos

from .args import add_bench_arguments, add_out, add_plugin, load_plugins, names, positive_int


def bench_traverse(args):
    """``hftrace bench-traverse``: bench.studies.traverse.run."""
    from ..studies import traverse

    traverse.run(out_dir=args.out, n=args.rays, side=args.grid, repeats=args.repeats,
                 seed=args.seed, run_lengths=args.run_lengths,
                 names=names(args.algorithms, algos.get_traversal))
    return 0


def bench_intersect(args):
    """``hftrace bench-intersect``: bench.studies.intersect.run."""
    from ..studies import intersect

    chosen = names(args.algorithms, algos.get_intersector)
    datasets = []
    for item in args.datasets.split(","):
        name, _, side = item.strip().partition(":")
        datasets.append((name, int(side or 1024)))
    surfaces = tuple(s.strip() for s in args.surfaces.split(","))
    for surface in surfaces:
        if surface not in algos.SURFACES:
            raise ValueError(f"--surfaces: unknown surface {surface!r}; valid: {', '.join(algos.SURFACES)}")
    regimes = tuple(s.strip() for s in args.regimes.split(","))
    for regime in regimes:
        if regime not in intersect.REGIMES:
            raise ValueError(f"--regimes: unknown regime {regime!r}; valid: {', '.join(intersect.REGIMES)}")
    coherences = tuple(s.strip() for s in args.coherence.split(","))
    for coherence in coherences:
        if coherence not in intersect.COHERENCES:
            raise ValueError(f"--coherence: unknown ray batch {coherence!r}; valid: "
                             f"{', '.join(intersect.COHERENCES)}")
    intersect.run(out_dir=args.out, n=args.rays, repeats=args.repeats, seed=args.seed,
                  datasets=datasets, run_lengths=args.run_lengths, surfaces=surfaces,
                  names=chosen, regimes=regimes, coherences=coherences)
    return 0


def reproduce(args):
    """``hftrace reproduce``: bench.studies.reproduce.run."""
    from ..studies import reproduce as study
    from ..sweep import BASELINE

    load_plugins(args)
    if args.full and args.preset not in (None, "full"):
        raise ValueError(f"--full: contradicts --preset {args.preset}")
    preset_name = "full" if args.full else (args.preset or "headline")
    kernels = names(args.kernels, lambda name: _reproduce_kernel(name, preset_name), "--kernels")
    if kernels is not None and set(kernels) <= {BASELINE}:
        # every cell is a speedup over the baseline: a run of the baseline alone has none
        raise ValueError(f"--kernels: name at least one kernel besides {BASELINE}, the baseline "
                         f"every speedup is measured against (it always runs); got {args.kernels!r}")
    if not 0 < args.precision < 100:
        raise ValueError(f"--precision: expected a percentage in (0, 100), got {args.precision}")
    paths = study.run(full=args.full, out_dir=args.out, resume=args.resume,
                      progress=not args.no_progress, counts=not args.no_counts,
                      publish=args.publish, preset_name=args.preset, kernels=kernels,
                      isolate=args.isolate, all_kernels=args.all_kernels,
                      precision=args.precision / 100, flush=args.flush)
    return 1 if args.strict and paths.get("all_contended") else 0


def _reproduce_kernel(name, preset_name):
    """Check one ``--kernels`` name: an intersector, or a 2D traversal (a plugin among
    them) where the preset measures the visit workload; ValueError naming what it lacks."""
    if name in algos.INTERSECTOR_REGISTRY:
        return
    if name in algos.TRAVERSAL_REGISTRY:
        if preset_name == "headline":
            raise ValueError(f"--kernels: {name!r} is a 2D traversal (the visit workload) "
                             "with no first-hit kernel, and the headline preset measures "
                             "first hits only; add --preset standard (or --full) to measure "
                             "its visit workload")
        return
    algos.get_intersector(name)  # unknown: the error lists the valid names


def scale(args):
    """``hftrace scale``: bench.studies.scaling.run."""
    from ..studies import scaling

    scaling.run(out_dir=args.out, parts=tuple(args.part or ("threads", "split", "growth", "big")),
                resume=args.resume, quick=args.quick)
    return 0


def terrain_bench(args):
    """``hftrace terrain-bench``: bench.studies.terrain_targets.run_targets, pinned."""
    from ..studies import terrain_targets
    from ..timing import pin_to_one_cpu

    pin_to_one_cpu()
    terrain_targets.run_targets(out_dir=args.out, size=args.size, repeats=args.repeats,
                                quick=args.quick)
    return 0


def accuracy(args):
    """``hftrace accuracy``: bench.studies.accuracy.run."""
    from ..studies import accuracy as study

    study.run(out_dir=args.out, full=args.full)
    return 0


def stress(args):
    """``hftrace stress``: bench.studies.stress.run."""
    from ..studies import stress as study

    study.run(out_dir=args.out, full=args.full)
    return 0


def raster_vs_trace(args):
    """``hftrace raster-vs-trace``: bench.studies.raster_vs_trace.run."""
    from ..studies import raster_vs_trace as study

    study.run(args.out, quick=not args.full, threads=args.threads, counts=not args.no_counts)
    return 0


def targets(args):
    """``hftrace targets``: bench.studies.targets.run; exit status 1 when a row failed."""
    from ..studies import targets as study

    if args.full and args.tier not in (None, "full"):
        raise ValueError(f"--full: contradicts --tier {args.tier}")
    tier = "full" if args.full else args.tier or ("medium" if args.publish else "quick")
    if args.publish and tier == "quick":
        raise ValueError("--publish: the quick tier judges nothing and is not published; "
                         "use --tier medium (the default with --publish) or full")
    only = None
    if args.only is not None:
        only = [key.strip() for key in args.only.split(",") if key.strip()]
        keys = [row.key for row in study.ROWS]
        if not only:
            raise ValueError(f"--only: expected one or more rows, got {args.only!r}; valid: "
                             f"{', '.join(keys)}")
        for key in only:
            if key not in keys:
                raise ValueError(f"--only: unknown row {key!r}; valid: {', '.join(keys)}")
    out = args.out or (study.PUBLISH_OUT if args.publish else study.DEFAULT_OUT)
    record = study.run(out_dir=out, tier=tier, processes=args.processes, seed=args.seed,
                       counts=not args.no_counts, resume=args.resume, only=only)
    return 1 if any("error" in row for row in record["rows"].values()) else 0


def compact(args):
    """``hftrace compact``: bench.studies.compact.run."""
    from ..studies import compact as study

    tier = dict(study.FULL if args.full else study.QUICK)
    if args.sizes:
        tier["sizes"] = tuple(positive_int(s) for s in args.sizes.split(","))
    if args.rays:
        tier["rays"] = args.rays
    out = "reports/compact" if args.publish else args.out
    study.run(out, tier, counts=not args.no_counts, timing=not args.no_timing,
              resume=args.resume)
    return 0


def register(sub):
    """Add the studies' commands to the sub-parsers ``sub``."""
    p = sub.add_parser("bench-traverse",
                       help="time the visit and runs workloads of every kernel relative to dda")
    add_bench_arguments(p, "bench-traverse")
    p.set_defaults(func=bench_traverse)

    p = sub.add_parser("bench-intersect",
                       help="time first hits of every intersector relative to dda, and Embree")
    add_bench_arguments(p, "bench-intersect")
    p.set_defaults(rays=1000, repeats=7, seed=2008)
    p.add_argument("--datasets", default="fbm:1024,fbm:2048,uniform:1024",
                   help="comma-separated NAME:SIDE fields")
    p.add_argument("--surfaces", default="triangles", help="comma-separated surfaces")
    p.add_argument("--regimes", default="flushed,warm",
                   help="comma-separated cache regimes: flushed (caches evicted before every "
                        "timed run), warm (each kernel warmed on its own rays)")
    p.add_argument("--coherence", default="random,parallel,camera",
                   help="comma-separated ray batches: random, parallel (slope 1/r), camera "
                        "(render's pinhole rays)")
    p.set_defaults(func=bench_intersect)

    p = sub.add_parser("reproduce", help="the speedup-by-run-length study (headline preset, "
                       "<= 3 min; --preset standard; --full)")
    p.add_argument("--full", action="store_true", help="the paper-scale sweep (--preset full)")
    p.add_argument("--preset", choices=("headline", "standard", "full"), default=None,
                   help="headline (default): first hit on triangles by run length, the "
                        "paper's measure; standard: every workload and surface plus the "
                        "parallel rays part; full: the paper-scale sweep")
    p.add_argument("--kernels", default=None,
                   help="comma-separated kernels to measure (dda always; plugins by name; "
                        "2D traversals with --preset standard or full)")
    p.add_argument("--isolate", action="store_true",
                   help="measure plugin kernels in a child process (a crash is contained)")
    p.add_argument("--all-kernels", action="store_true", help="plot every kernel")
    p.add_argument("--precision", type=float, default=2.0,
                   help="percent: a kernel's paired rounds stop once its speedup's 95 %% "
                        "interval is within this on either side (default 2)")
    p.add_argument("--strict", action="store_true",
                   help="exit with status 1 when every group ran while other processes used "
                        "the machine (no cell is then a finding)")
    p.add_argument("--flush", choices=("warm", "call", "round", "none"), default="warm",
                   help="the cache state of a timed call: warm (default; an untimed call of "
                        "the same kernel first), flushed before every call, once per cycle "
                        "of calls, or never (docs/METHOD.md, \"Cache regimes compared\")")
    add_plugin(p)
    where = p.add_mutually_exclusive_group()
    where.add_argument("--out", default=None, help="output directory (default "
                       "results/reproduce; results/reproduce-standard or results/reproduce-full "
                       "for the other presets)")
    where.add_argument("--publish", action="store_true",
                       help="write the committed reference instead: reports/reproduce-headline, "
                            "reports/reproduce (standard) or reports/reproduce-full")
    p.add_argument("--resume", action="store_true", help="keep the rows already measured")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-counts", action="store_true",
                   help="skip the instruction counts (callgrind, run after the timings)")
    p.set_defaults(func=reproduce)

    p = sub.add_parser("scale", help="threads, growth with the grid side, and a 16384^2 field")
    p.add_argument("--part", action="append", choices=("threads", "split", "growth", "big"),
                   default=None, help="repeatable; default all four")
    add_out(p, "scale")
    p.add_argument("--resume", action="store_true", help="skip what the CSVs already hold")
    p.add_argument("--quick", action="store_true", help="small sizes (a check that it runs)")
    p.set_defaults(func=scale)

    p = sub.add_parser("terrain-bench", help="the terrain products' targets against the peers")
    p.add_argument("--size", type=positive_int, default=2048)
    p.add_argument("--repeats", type=positive_int, default=3)
    p.add_argument("--quick", action="store_true",
                   help="only the every-azimuth section, on small fields (a check that it runs)")
    add_out(p, "terrain-bench")
    p.set_defaults(func=terrain_bench)

    p = sub.add_parser("accuracy", help="run time against error for every algorithm")
    p.add_argument("--full", action="store_true")
    add_out(p, "accuracy")
    p.set_defaults(func=accuracy)

    p = sub.add_parser("stress", help="adversarial and very long rays: the drift table")
    p.add_argument("--full", action="store_true")
    add_out(p, "stress")
    p.set_defaults(func=stress)

    p = sub.add_parser("raster-vs-trace",
                       help="rasterising the cells (z-buffer, painter, Watkins, Warnock, "
                            "floating horizon) against tracing the pixels: the crossover")
    p.add_argument("--full", action="store_true",
                   help="the full tier (images to 3840x2160, fields to 8192^2: hours)")
    p.add_argument("--threads", type=positive_int, default=None,
                   help="threads of the threaded runs (default: every core)")
    p.add_argument("--no-counts", action="store_true", help="skip the callgrind counts")
    add_out(p, "raster-vs-trace")
    p.set_defaults(func=raster_vs_trace)

    p = sub.add_parser("targets", help="the round's targets table: our best exact kernel "
                       "against embreex and the C Embree 3 peer (random rays, level and "
                       "pitched cameras, flushed and warm) and the 16-azimuth horizon; one "
                       "process per row, one pinned CPU")
    p.add_argument("--tier", choices=("quick", "medium", "full"), default=None,
                   help="quick (tiny fields: checks that every row runs; the default), "
                        "medium (the targets' sizes but 8192^2: about 25 minutes on a quiet "
                        "machine; the default with --publish) or full (8192^2 too)")
    p.add_argument("--full", action="store_true", help="the same as --tier full")
    p.add_argument("--processes", type=positive_int, default=None,
                   help="processes measuring the 2048^2 random rays, whose ratios' spread is "
                        "reported (default: 2 quick, 3 medium, 5 full)")
    p.add_argument("--only", default=None,
                   help="comma-separated rows to measure: random2048, random4096, "
                        "random8192, level, pitched, horizon16 (default: the tier's)")
    p.add_argument("--seed", type=int, default=2008, help="seed of the random rays")
    p.add_argument("--no-counts", action="store_true",
                   help="skip the callgrind counts (instructions, last-level misses)")
    p.add_argument("--resume", action="store_true",
                   help="keep the rows the output's targets.json already holds (same tier, "
                        "--seed and --processes, or it is refused)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--out", default=None, help="output directory (default results/targets)")
    where.add_argument("--publish", action="store_true", help="write reports/targets instead")
    p.set_defaults(func=targets)

    p = sub.add_parser("compact",
                       help="the cache-compact maximum tree (dda_compact) against dda_maxmip: "
                            "callgrind cache misses per ray by field side")
    p.add_argument("--full", action="store_true",
                   help="sides 256 to 8192, 2000 rays (callgrind: an hour or more)")
    p.add_argument("--sizes", default=None, help="comma-separated field sides")
    p.add_argument("--rays", type=positive_int, default=None, help="rays per side")
    p.add_argument("--no-counts", action="store_true", help="skip the callgrind counts")
    p.add_argument("--no-timing", action="store_true", help="skip the ns per ray")
    p.add_argument("--resume", action="store_true",
                   help="keep the sides the output's compact.csv already holds")
    where = p.add_mutually_exclusive_group()
    add_out(where, "compact")
    where.add_argument("--publish", action="store_true", help="write reports/compact instead")
    p.set_defaults(func=compact)
