"""``hftrace sweep`` (a custom sweep from a TOML config) and ``hftrace plot`` (tables and
plots of a results.csv)."""
from __future__ import annotations

import os

from .args import results_dir


def run_sweep(args):
    """``hftrace sweep``: bench.sweep on one pinned CPU, or on a Dask cluster with --dask;
    then the reports and the speedup tables."""
    from .. import analysis
    from .. import sweep as engine
    from ..timing import pin_to_one_cpu

    cfg = engine.load_config(args.config)  # fails before any work, naming the key
    out_dir = args.out or os.path.join(results_dir("sweep"), cfg.name)
    if args.dask:
        # each group on one single-threaded worker process (pinning is the workers' own)
        rows = engine.run_sweep_dask(cfg, out_dir, args.dask, resume=args.resume,
                                     progress=not args.no_progress)
    else:
        pin_to_one_cpu()
        rows = engine.run_sweep(cfg, out_dir, resume=args.resume, progress=not args.no_progress)
    paths = analysis.write_reports(os.path.join(out_dir, "results.csv"), out_dir,
                                   title=f"hftrace sweep {cfg.name}")
    df = analysis.load(os.path.join(out_dir, "results.csv"))
    for (workload, surface), _ in df.groupby(["workload", "surface"], sort=False):
        label = workload if surface == "-" else f"{workload}, {surface}"
        print(f"\n{label}: speedup over dda (geometric mean over datasets)")
        print(analysis.pivot(df, workload, surface).round(2).to_string())
    print(f"\n{len(rows)} rows in {out_dir}/results.csv; tables in {paths['speedup']}")
    return 0


def plot(args):
    """``hftrace plot``: bench.analysis.write_reports of one results.csv."""
    from .. import analysis

    paths = analysis.write_reports(args.results, args.out)
    for label, path in paths.items():
        print(f"{label:8s} {path}")
    return 0


def register(sub):
    """Add ``sweep`` and ``plot`` to the sub-parsers ``sub``."""
    p = sub.add_parser("sweep", help="a custom sweep from a TOML config")
    p.add_argument("config", help="the TOML config (see bench/sweep.py)")
    p.add_argument("--out", default=None,
                   help=f"output directory (default {results_dir('sweep')}/<name>)")
    p.add_argument("--resume", action="store_true", help="skip rows already in results.csv")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--dask", default=None, metavar="ADDRESS",
                   help="run each group as a task on a Dask cluster: a scheduler address, or "
                        "local:N for a LocalCluster of N single-threaded workers")
    p.set_defaults(func=run_sweep)

    p = sub.add_parser("plot", help="tables and plots from a results.csv")
    p.add_argument("results", help="a results.csv of reproduce or sweep")
    p.add_argument("--out", default=None, help="output directory (default: beside the CSV)")
    p.set_defaults(func=plot)
