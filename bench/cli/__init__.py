"""The ``hftrace`` command line."""
from __future__ import annotations

import os

# Benchmarks pin themselves to one CPU; idle BLAS worker threads spinning on that CPU
# would steal time from the timed loops. hftrace uses no BLAS: keep one thread. (Set
# before NumPy is first imported.)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402

import algos  # noqa: E402


def _positive_int(text):
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text}")
    return value


def _run_lengths(text):
    try:
        values = tuple(float(v) if "." in v else int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}")
    if any(v < 1 for v in values):
        raise argparse.ArgumentTypeError("run lengths must be >= 1")
    return values


def _add_bench_arguments(p, out_dir):
    p.add_argument("--rays", type=_positive_int, default=2000, help="rays per run length")
    p.add_argument("--grid", type=_positive_int, default=1024, help="grid side in cells")
    p.add_argument("--repeats", type=_positive_int, default=9, help="interleaved repeats")
    p.add_argument("--seed", type=int, default=2004)
    p.add_argument("--run-lengths", type=_run_lengths, default=(1, 2, 5, 25, 100),
                   help="comma-separated mean run lengths r")
    p.add_argument("--algorithms", default=None,
                   help=f"comma-separated subset of {', '.join(algos.TRAVERSALS)}")
    p.add_argument("--out", default=out_dir, help="output directory")


def _bench_traverse(args):
    from . import traverse_bench

    names = None
    if args.algorithms:
        names = [n.strip() for n in args.algorithms.split(",")]
        for name in names:
            algos.get_traversal(name)
    traverse_bench.run(out_dir=args.out, n=args.rays, side=args.grid, repeats=args.repeats,
                       seed=args.seed, run_lengths=args.run_lengths, names=names)
    return 0


def _bench_intersect(args):
    from . import intersect_bench

    names = None
    if args.algorithms:
        names = [n.strip() for n in args.algorithms.split(",")]
        for name in names:
            algos.get_intersector(name)
    datasets = []
    for item in args.datasets.split(","):
        name, _, side = item.strip().partition(":")
        datasets.append((name, int(side or 1024)))
    surfaces = tuple(s.strip() for s in args.surfaces.split(","))
    for surface in surfaces:
        if surface not in algos.SURFACES:
            raise ValueError(f"--surfaces: unknown surface {surface!r}; valid: {', '.join(algos.SURFACES)}")
    intersect_bench.run(out_dir=args.out, n=args.rays, repeats=args.repeats, seed=args.seed,
                        datasets=datasets, run_lengths=args.run_lengths, surfaces=surfaces,
                        names=names)
    return 0


def _reproduce(args):
    from . import reproduce

    reproduce.run(full=args.full, out_dir=args.out, resume=args.resume,
                  progress=not args.no_progress, counts=not args.no_counts)
    return 0


def _load_terrain(args):
    """A HeightField from a dataset name or a file (GeoTIFF, PNG, EXR, .npy)."""
    import datasets_gen

    source = args.source
    if os.path.exists(source):
        return datasets_gen.load_file(source)
    params = dict(args.param or [])
    return datasets_gen.load(source, size=args.size, seed=args.seed, **params)


def _terrain_product_dask(args):
    from . import terrain_dask

    hf = terrain_dask.open_source(args.source, args.chunk, size=args.size, seed=args.seed,
                                  params=dict(args.param or []))
    kind = args.command
    options = dict(max_distance=args.max_distance, algorithm=args.algorithm,
                   worker_memory=args.worker_memory)
    if kind == "horizon":
        options["azimuths"] = [float(v) for v in (args.azimuths or "0").split(",")]
    elif kind == "svf":
        options.update(n_azimuths=args.n_azimuths, rational=args.rational)
    elif kind == "shadows":
        options.update(azimuth=args.azimuth, elevation=args.elevation)
    else:
        options.update(observers=[tuple(float(v) for v in o.split(",")) for o in args.observer],
                       observer_height=args.observer_height, target_height=args.target_height,
                       curvature=args.curvature, refraction=args.refraction)
    terrain_dask.run_product(kind, hf, args.out, args.dask, **options)
    return 0


def _terrain_product(args):
    import numpy as np
    from tqdm import tqdm

    from . import terrain_bench

    if args.dask:
        return _terrain_product_dask(args)

    hf = _load_terrain(args)
    kind = args.command
    common = dict(algorithm=args.algorithm, threads=args.threads)
    spacing = hf.spacing if hf.unit != "cell" else None
    md = args.max_distance
    progress = not args.no_progress
    if kind in ("horizon", "svf"):
        if args.azimuths:
            az = np.array([float(v) for v in args.azimuths.split(",")])
        elif kind == "svf":
            az = (algos.rational_azimuths(args.n_azimuths) if args.rational
                  else np.arange(args.n_azimuths) * (360.0 / args.n_azimuths))
        else:
            az = np.array([0.0])
        layers = []
        for a in tqdm(az, desc=f"{kind} {hf.name}", unit="azimuth", disable=not progress):
            layers.append(algos.horizon(hf, [a], md, **common)[0])
        angles = np.stack(layers)
        if kind == "svf":
            result = 1.0 - np.mean(np.sin(np.maximum(angles, 0.0)), axis=0)
            outputs = {"svf": (result, "cividis", 0.0, 1.0)}
        else:
            outputs = {f"horizon_az{a:g}": (np.degrees(angles[k]), "magma", None, None)
                       for k, a in enumerate(az)}
    elif kind == "shadows":
        result = algos.shadows(hf, args.azimuth, args.elevation, max_distance=md, **common)
        outputs = {"shadows": (result.astype(np.float32), "gray_r", 0.0, 1.0)}
    else:
        observers = [tuple(float(v) for v in o.split(",")) for o in args.observer] or \
            [((hf.shape[1] - 1) / 2, (hf.shape[0] - 1) / 2)]
        count = np.zeros(hf.shape, dtype=np.uint16)
        for o in tqdm(observers, desc=f"viewshed {hf.name}", unit="observer",
                      disable=not progress or len(observers) == 1):
            count += algos.viewshed(hf, o, args.observer_height, args.target_height, md,
                                    curvature=args.curvature, refraction=args.refraction,
                                    **common)
        outputs = {"viewshed": (count.astype(np.float32), "Greens", 0.0,
                                float(max(len(observers), 1)))}
    flip = (hf.params or {}).get("north") == "+y"
    for name, (array, cmap, lo, hi) in outputs.items():
        shown = array[::-1] if flip else array  # files are written north-up
        prefix = args.out if len(outputs) == 1 else f"{args.out}_{name}"
        paths = terrain_bench.write_product(prefix, shown, spacing=spacing,
                                            cmap=cmap, vmin=lo, vmax=hi)
        finite = array[np.isfinite(array)]
        print(f"{name}: {hf.name} {hf.shape[0]}x{hf.shape[1]}, min {finite.min():.4g}, "
              f"mean {finite.mean():.4g}, max {finite.max():.4g} -> {', '.join(paths)}")
    return 0


def _scale(args):
    from . import scale

    scale.run(out_dir=args.out, parts=tuple(args.part or ("threads", "split", "growth", "big")),
              resume=args.resume, quick=args.quick)
    return 0


def _terrain_bench(args):
    from . import terrain_bench
    from .intersect_bench import pin_to_one_cpu

    pin_to_one_cpu()
    terrain_bench.run_targets(out_dir=args.out, size=args.size, repeats=args.repeats)
    return 0


def _sweep(args):
    import os

    from . import analysis, sweep
    from .intersect_bench import pin_to_one_cpu

    cfg = sweep.load_config(args.config)  # fails before any work, naming the key
    out_dir = args.out or os.path.join("reports", cfg.name)
    if args.dask:
        # each group on one single-threaded worker process (pinning is the workers' own)
        rows = sweep.run_sweep_dask(cfg, out_dir, args.dask, resume=args.resume,
                                    progress=not args.no_progress)
    else:
        pin_to_one_cpu()
        rows = sweep.run_sweep(cfg, out_dir, resume=args.resume, progress=not args.no_progress)
    paths = analysis.write_reports(os.path.join(out_dir, "results.csv"), out_dir,
                                   title=f"hftrace sweep {cfg.name}")
    df = analysis.load(os.path.join(out_dir, "results.csv"))
    for (workload, surface), _ in df.groupby(["workload", "surface"], sort=False):
        label = workload if surface == "-" else f"{workload}, {surface}"
        print(f"\n{label}: speedup over dda (geometric mean over datasets)")
        print(analysis.pivot(df, workload, surface).round(2).to_string())
    print(f"\n{len(rows)} rows in {out_dir}/results.csv; tables in {paths['speedup']}")
    return 0


def _plot(args):
    from . import analysis

    paths = analysis.write_reports(args.results, args.out)
    for label, path in paths.items():
        print(f"{label:8s} {path}")
    return 0


def _regress(args):
    if args.metric == "instructions":
        from . import regress_counts

        return regress_counts.run(args.baseline or "reports/instructions_baseline.json",
                                  tolerance=args.tolerance, update=args.update)
    from . import regress

    return regress.run(args.baseline or "reports/baseline.json", tolerance=args.tolerance,
                       update=args.update)


def _vector(text):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected x,y,z, got {text!r}") from None
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected x,y,z, got {text!r}")
    return values


def _render(args):
    from . import render

    algos.get_intersector(args.algorithm)
    if args.diff:
        for name in args.diff:
            algos.get_intersector(name)
    render.render(dataset=args.dataset, size=args.size, seed=args.seed, algorithm=args.algorithm,
                  surface=args.surface, width=args.width, height=args.height,
                  position=args.camera, look_at=args.look_at, fov=args.fov, fog=args.fog,
                  out=args.out, diff=args.diff, params=dict(args.param or []),
                  threads=args.threads)
    return 0


def _accuracy(args):
    from . import accuracy

    accuracy.run(out_dir=args.out, full=args.full)
    return 0


def _stress(args):
    from . import stress

    stress.run(out_dir=args.out, full=args.full)
    return 0


def _list(args):
    print("traversals (algos.traverse):")
    for t in algos.TRAVERSAL_REGISTRY.values():
        exact = "exact" if t.exact else (f"exact when {t.exact_when}" if t.exact_when else t.precision)
        print(f"  {t.name:14s} {t.family:4s} {exact:50s} {t.summary} ({t.citation})")
    print("intersectors (algos.intersect):")
    for a in algos.INTERSECTOR_REGISTRY.values():
        print(f"  {a.name:14s} {a.kind:9s} {a.accuracy:13s} {a.summary}")
    return 0


def _param(text):
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    name, value = text.split("=", 1)
    for cast in (int, float):
        try:
            return name, cast(value)
        except ValueError:
            pass
    return name, value


def _datasets_list(args):
    import datasets_gen

    for row in datasets_gen.catalogue():
        params = ", ".join(f"{k}={v}" for k, v in row["params"].items())
        print(f"{row['name']:15s} {row['kind']:9s} {row['summary']}")
        print(f"{'':25s} params: {params}")
    return 0


def _datasets_show(args):
    import datasets_gen
    from datasets_gen.preview import write_png

    params = dict(args.param or [])
    field = datasets_gen.load(args.name, size=args.size, seed=args.seed,
                              use_cache=not args.no_cache, cache_dir=args.cache_dir, **params)
    h = field.heights
    print(f"name      {field.name}")
    print(f"shape     {h.shape[0]} rows x {h.shape[1]} cols ({h.shape[1] - 1} x {h.shape[0] - 1} cells)")
    print(f"heights   [{float(h.min()):.4f}, {float(h.max()):.4f}] cells, mean {float(h.mean()):.4f}")
    print(f"spacing   1 cell = {field.spacing:g} {field.unit}")
    print(f"sha256    {field.checksum}")
    if args.png:
        write_png(args.png, h)
        print(f"preview   {args.png}")
    return 0


def _profile(args):
    from . import profile as prof

    if args.workload == "first_hit":
        algos.get_intersector(args.kernel)
    else:
        algos.get_traversal(args.kernel)
    if args.surface not in algos.SURFACES:
        raise ValueError(f"--surface: unknown surface {args.surface!r}; valid: {', '.join(algos.SURFACES)}")
    r = args.r if args.r == "random" else float(args.r) if "." in args.r else int(args.r)
    if r != "random" and r < 1:
        raise ValueError(f"--r: expected a number >= 1 or 'random', got {args.r!r}")
    options = {}
    for item in args.option:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ValueError(f"--option: expected KEY=VALUE, got {item!r}")
        if value.lower() in ("true", "false"):
            options[key] = value.lower() == "true"
            continue
        try:
            options[key] = int(value)
        except ValueError:
            raise ValueError(f"--option {key}: expected an integer, true or false, "
                             f"got {value!r}") from None
    try:
        result = prof.profile(args.kernel, dataset=args.dataset, size=args.size, r=r,
                              rays=args.rays, surface=args.surface, workload=args.workload,
                              seed=args.seed, cache_sim=args.cache_sim, options=options,
                              parallel=args.parallel)
    except RuntimeError as exc:
        print(f"hftrace: error: {exc}", file=sys.stderr)
        return 2
    print(prof.format_profile(result))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hftrace",
        description="Benchmark harness for ray traversal of height fields.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="list the registered algorithms")
    p.set_defaults(func=_list)

    p = sub.add_parser("datasets", help="the catalogue of height fields")
    dsub = p.add_subparsers(dest="datasets_command", required=True)
    q = dsub.add_parser("list", help="every generator and embedded field with its parameters")
    q.set_defaults(func=_datasets_list)
    q = dsub.add_parser("show", help="shape, range, spacing and checksum of one field")
    q.add_argument("name")
    q.add_argument("--size", type=_positive_int, default=None,
                   help="side in samples (generators: default 256; jacksboro: longer side)")
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--param", type=_param, action="append", metavar="NAME=VALUE",
                   help="a generator parameter (repeatable)")
    q.add_argument("--png", default=None, help="write a hillshaded preview here")
    q.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    q.add_argument("--cache-dir", default=None, help="cache location (default: $HFTRACE_CACHE "
                   "or ~/.cache/hftrace)")
    q.set_defaults(func=_datasets_show)

    p = sub.add_parser("bench-traverse",
                       help="time the visit and runs workloads of every kernel relative to dda")
    _add_bench_arguments(p, "reports/bench_traverse")
    p.set_defaults(func=_bench_traverse)

    p = sub.add_parser("bench-intersect",
                       help="time first hits of every intersector relative to dda, and Embree")
    _add_bench_arguments(p, "reports/bench_intersect")
    p.set_defaults(rays=1000, repeats=7, seed=2008)
    p.add_argument("--datasets", default="fbm:1024,fbm:2048,uniform:1024",
                   help="comma-separated NAME:SIDE fields")
    p.add_argument("--surfaces", default="triangles", help="comma-separated surfaces")
    p.set_defaults(func=_bench_intersect)

    p = sub.add_parser("reproduce", help="the speedup-by-run-length study (quick preset; --full)")
    p.add_argument("--full", action="store_true", help="the paper-scale sweep")
    p.add_argument("--out", default=None, help="output directory (default reports/reproduce)")
    p.add_argument("--resume", action="store_true", help="keep the rows already measured")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-counts", action="store_true",
                   help="skip the instruction counts (callgrind, about 4 minutes)")
    p.set_defaults(func=_reproduce)

    for kind, text in (("horizon", "horizon angles (degrees) along azimuths"),
                       ("shadows", "cast shadows for a sun azimuth and elevation"),
                       ("svf", "sky-view factor (Zaksek et al. 2011)"),
                       ("viewshed", "what one or more observers see")):
        p = sub.add_parser(kind, help=f"{text}: GeoTIFF, EXR and PNG")
        p.add_argument("source", nargs="?", default="jacksboro",
                       help="a dataset name (hftrace datasets list) or a file (default jacksboro)")
        p.add_argument("--size", type=_positive_int, default=None)
        p.add_argument("--seed", type=int, default=1)
        p.add_argument("--param", type=_param, action="append", metavar="NAME=VALUE")
        p.add_argument("--algorithm", default=None, help="default: chosen by measurement")
        p.add_argument("--threads", type=_positive_int, default=None,
                       help="default: every core in the affinity")
        p.add_argument("--max-distance", type=float, default=None,
                       help="in the field's unit (metres for jacksboro)")
        p.add_argument("--out", default=kind, help="output path prefix")
        p.add_argument("--no-progress", action="store_true")
        p.add_argument("--dask", default=None, metavar="ADDRESS",
                       help="tile by tile on a Dask cluster (a scheduler address, or local:N "
                            "for N single-threaded local workers); needs --max-distance; "
                            "files are read window by window, so they may exceed memory")
        p.add_argument("--chunk", type=_positive_int, default=2048,
                       help="--dask: tile side in samples (default 2048)")
        p.add_argument("--worker-memory", default=None, metavar="BYTES",
                       help="--dask local:N: memory limit per worker, e.g. 600MiB")
        if kind == "horizon":
            p.add_argument("--azimuths", default=None, help="comma-separated degrees (default 0)")
        if kind == "svf":
            p.add_argument("--n-azimuths", type=_positive_int, default=16)
            p.add_argument("--azimuths", default=None, help="comma-separated degrees")
            p.add_argument("--rational", action="store_true",
                           help="nearest rational azimuths: the exact sweep applies")
        if kind == "shadows":
            p.add_argument("--azimuth", type=float, default=315.0)
            p.add_argument("--elevation", type=float, default=30.0)
        if kind == "viewshed":
            p.add_argument("--observer", action="append", default=[], metavar="X,Y",
                           help="grid coordinates (repeatable; default the centre)")
            p.add_argument("--observer-height", type=float, default=1.75)
            p.add_argument("--target-height", type=float, default=0.0)
            p.add_argument("--curvature", action="store_true")
            p.add_argument("--refraction", type=float, default=0.13)
        p.set_defaults(func=_terrain_product, command=kind)

    p = sub.add_parser("scale", help="threads, growth with the grid side, and a 16384^2 field "
                                     "(reports/scaling)")
    p.add_argument("--part", action="append", choices=("threads", "split", "growth", "big"),
                   default=None, help="repeatable; default all four")
    p.add_argument("--out", default="reports/scaling")
    p.add_argument("--resume", action="store_true", help="skip what the CSVs already hold")
    p.add_argument("--quick", action="store_true", help="small sizes (a check that it runs)")
    p.set_defaults(func=_scale)

    p = sub.add_parser("terrain-bench", help="the terrain products' targets against the peers")
    p.add_argument("--size", type=_positive_int, default=2048)
    p.add_argument("--repeats", type=_positive_int, default=3)
    p.add_argument("--out", default="reports/terrain")
    p.set_defaults(func=_terrain_bench)

    p = sub.add_parser("sweep", help="a custom sweep from a TOML config")
    p.add_argument("config", help="the TOML config (see bench/sweep.py)")
    p.add_argument("--out", default=None, help="output directory (default reports/<name>)")
    p.add_argument("--resume", action="store_true", help="skip rows already in results.csv")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--dask", default=None, metavar="ADDRESS",
                   help="run each group as a task on a Dask cluster: a scheduler address, or "
                        "local:N for a LocalCluster of N single-threaded workers")
    p.set_defaults(func=_sweep)

    p = sub.add_parser("regress", help="CI check: instruction counts or speedup ratios against "
                                       "a baseline")
    p.add_argument("--metric", choices=("time", "instructions"), default="time",
                   help="time: speedup ratios (noisy machines; statistics); instructions: "
                        "callgrind counts per ray (exact; needs valgrind)")
    p.add_argument("--baseline", default=None,
                   help="default reports/baseline.json (time) or "
                        "reports/instructions_baseline.json (instructions)")
    p.add_argument("--tolerance", type=float, default=None,
                   help="allowed fractional change (default: the baseline's; 0.01 for "
                        "instructions)")
    p.add_argument("--update", action="store_true", help="write a new baseline instead")
    p.set_defaults(func=_regress)

    p = sub.add_parser("render", help="a pinhole image (OpenEXR + PNG) with any intersector")
    p.add_argument("dataset", help="a generator or embedded field (hftrace datasets list), or "
                                   "a file (.npy is memory-mapped)")
    p.add_argument("--size", type=_positive_int, default=None)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--param", type=_param, action="append", metavar="NAME=VALUE")
    p.add_argument("--algorithm", default="runs", help="an intersector name")
    p.add_argument("--surface", default="triangles", choices=algos.SURFACES)
    p.add_argument("--width", type=_positive_int, default=640)
    p.add_argument("--height", type=_positive_int, default=360)
    p.add_argument("--camera", type=_vector, default=None, help="x,y,z (default: above a corner)")
    p.add_argument("--look-at", type=_vector, default=None, help="x,y,z (default: the centre)")
    p.add_argument("--fov", type=float, default=60.0, help="horizontal field of view, degrees")
    p.add_argument("--fog", type=float, default=0.0,
                   help="height-fog density sigma0 per cell at the lowest point (0: none)")
    p.add_argument("--diff", nargs=2, metavar=("A", "B"), default=None,
                   help="also write the depth difference and step ratio of two intersectors")
    p.add_argument("--out", default="render", help="output path prefix")
    p.add_argument("--threads", type=_positive_int, default=None,
                   help="default: every core in the affinity (the image is the same)")
    p.set_defaults(func=_render)

    p = sub.add_parser("accuracy", help="run time against error for every algorithm")
    p.add_argument("--full", action="store_true")
    p.add_argument("--out", default="reports/accuracy")
    p.set_defaults(func=_accuracy)

    p = sub.add_parser("stress", help="adversarial and very long rays: the drift table")
    p.add_argument("--full", action="store_true")
    p.add_argument("--out", default="reports/stress")
    p.set_defaults(func=_stress)

    p = sub.add_parser("profile", help="instruction and branch counts of one kernel (callgrind)")
    p.add_argument("kernel", help="an intersector (first_hit) or traversal (visit, runs)")
    p.add_argument("--workload", default="first_hit", choices=("first_hit", "visit", "runs"))
    p.add_argument("--dataset", default="fbm")
    p.add_argument("--size", type=_positive_int, default=1024, help="field side in samples")
    p.add_argument("--r", default="25", help="mean run length, or 'random'")
    p.add_argument("--rays", type=_positive_int, default=1000)
    p.add_argument("--surface", default="triangles")
    p.add_argument("--seed", type=int, default=2008)
    p.add_argument("--cache-sim", action="store_true",
                   help="also simulate the caches (D1 and last-level misses; slower)")
    p.add_argument("--parallel", action="store_true",
                   help="first hits: one batch of parallel rays of slope 1/r (orthographic)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="an intersector option, e.g. fine_level=2 or cull_runs=false (repeatable)")
    p.set_defaults(func=_profile)

    p = sub.add_parser("plot", help="tables and plots from a results.csv")
    p.add_argument("results", help="a results.csv of reproduce or sweep")
    p.add_argument("--out", default=None, help="output directory (default: beside the CSV)")
    p.set_defaults(func=_plot)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, TypeError) as exc:
        print(f"hftrace: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. `hftrace datasets list | head`
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    sys.exit(main())
