"""``hftrace sweep`` (a custom sweep from a TOML config) and ``hftrace plot`` (tables and
plots of a results.csv)."""
from __future__ import annotations

import os

from .args import add_plugin, load_plugins, results_dir


def run_sweep(args):
    """``hftrace sweep``: bench.sweep on one pinned CPU, or on a Dask cluster with --dask;
    then the reports and the speedup tables."""
    from .. import analysis
    from .. import sweep as engine
    from ..timing import pin_to_one_cpu

    load_plugins(args)
    cfg = engine.load_config(args.config)  # fails before any work, naming the key
    out_dir = args.out or os.path.join(results_dir("sweep"), cfg.name)
    if args.dask:
        # each group on one single-threaded worker process (pinning is the workers' own)
        from ..sweep_dask import run_sweep_dask

        rows = run_sweep_dask(cfg, out_dir, args.dask, resume=args.resume,
                              progress=not args.no_progress)
    else:
        pin_to_one_cpu()
        rows = engine.run_sweep(cfg, out_dir, resume=args.resume, progress=not args.no_progress,
                                isolate=args.isolate)
    paths = analysis.write_reports(os.path.join(out_dir, "results.csv"), out_dir,
                                   title=f"hftrace sweep {cfg.name}", all_kernels=args.all_kernels)
    df = analysis.load(os.path.join(out_dir, "results.csv"), echo=None)  # (said above)
    for (workload, surface), _ in df.groupby(["workload", "surface"], sort=False):
        label = workload if surface == "-" else f"{workload}, {surface}"
        print(f"\n{label}: speedup over dda (geometric mean over datasets)")
        print(analysis.pivot_ci(df, workload, surface).to_string())
    print(f"\n{len(rows)} rows in {out_dir}/results.csv; tables in {paths['speedup']}")
    errors = df[df["error"] != ""]
    if args.dask:  # the local engine printed each error as its run ended; Dask's does not
        for _, row in errors.iterrows():
            print(f"error: {row['algorithm']} ({row['dataset']} {row['workload']} "
                  f"r={row['run_length']}): {row['error']}")
    elif not errors.empty:
        print(f"{len(errors)} row(s) with a kernel error: the Kernel errors table of "
              f"{paths['speedup']}")
    return 1 if not errors.empty else 0


def plot(args):
    """``hftrace plot``: bench.analysis.write_reports of one run of a results.csv."""
    from .. import analysis

    load_plugins(args)
    paths = analysis.write_reports(args.results, args.out, all_kernels=args.all_kernels,
                                   run=args.run, echo=print)
    for label, path in paths.items():
        print(f"{label:8s} {path}")
    return 0


def register(sub):
    """Add ``sweep`` and ``plot`` to the sub-parsers ``sub``."""
    p = sub.add_parser("sweep", help="a custom sweep from a TOML config")
    p.add_argument("config", help="the TOML config (docs/sweeps.md; examples/*.toml)")
    p.add_argument("--out", default=None,
                   help=f"output directory (default {results_dir('sweep')}/<name>)")
    p.add_argument("--resume", action="store_true", help="skip rows already in results.csv")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--dask", default=None, metavar="ADDRESS",
                   help="run each group as a task on a Dask cluster: a scheduler address, or "
                        "local:N for a LocalCluster of N single-threaded workers")
    p.add_argument("--isolate", action="store_true",
                   help="measure each group's plugin kernels in a child process, so a crash "
                        "takes only their rows")
    p.add_argument("--all-kernels", action="store_true",
                   help="plot every kernel (default: a readable subset and every plugin)")
    add_plugin(p)
    p.set_defaults(func=run_sweep)

    p = sub.add_parser("plot", help="tables and plots from a results.csv")
    p.add_argument("results", help="a results.csv of reproduce or sweep")
    p.add_argument("--out", default=None, help="output directory (default: beside the CSV)")
    p.add_argument("--all-kernels", action="store_true",
                   help="plot every kernel (default: a readable subset and every plugin)")
    p.add_argument("--run", default=None, metavar="ID",
                   help="the run to plot when the file holds several (a prefix of its run_id; "
                        "of its commit for files without run identifiers); runs are never "
                        "blended")
    add_plugin(p)
    p.set_defaults(func=plot)
