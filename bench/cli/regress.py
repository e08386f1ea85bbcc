"""``hftrace regress``: the CI gates (``bench.regress``) against their committed
baselines, which sit next to them."""
from __future__ import annotations


def regress(args):
    """Run the instruction-count, counter or time gate; its exit status. ``--plugin``
    kernels join the time gate's checks of their workload; the exact gates count
    hftrace's own C kernels only, so ``--plugin`` with them is refused rather than
    passed over (a CI job would pass without ever gating the plugin)."""
    from .args import load_plugins

    if args.plugin and args.metric != "time":
        raise ValueError(f"--plugin: --metric {args.metric} gates hftrace's own C kernels "
                         "only and would pass without looking at "
                         f"{', '.join(args.plugin)}; gate a plugin with --metric time, or "
                         "count a C plugin with valgrind --tool=callgrind "
                         "--toggle-collect=hftrace_first_hit (or hftrace_traverse) "
                         "(docs/plugins.md, \"Regression gates and instruction counts\")")
    load_plugins(args)
    if args.metric == "instructions":
        from ..regress import instructions_gate as gate
    elif args.metric == "counters":
        from ..regress import counters_gate as gate
    else:
        from ..regress import time_gate as gate
    if args.only is not None:
        if args.metric != "time":
            raise ValueError(f"--only: selects the time gate's kernels; --metric "
                             f"{args.metric} counts every kernel in a few minutes")
        return gate.run(args.baseline or gate.BASELINE, tolerance=args.tolerance,
                        update=args.update, only=gate.check_only(args.only))
    return gate.run(args.baseline or gate.BASELINE, tolerance=args.tolerance,
                    update=args.update)


def register(sub):
    """Add ``regress`` to the sub-parsers ``sub``."""
    p = sub.add_parser("regress", help="CI check: instruction counts or speedup ratios against "
                                       "a baseline")
    p.add_argument("--metric", choices=("time", "instructions", "counters"), default="time",
                   help="time: speedup ratios (noisy machines; statistics); instructions: "
                        "callgrind counts per ray (exact; needs valgrind); counters: cells, "
                        "runs and tiles per ray (exact; any compiler)")
    p.add_argument("--baseline", default=None,
                   help="default bench/regress/<metric>_baseline.json")
    p.add_argument("--tolerance", type=float, default=None,
                   help="allowed fractional change (default: the baseline's; 0.01 for "
                        "instructions)")
    p.add_argument("--only", default=None, metavar="KERNEL[,KERNEL]",
                   help="time gate: measure and judge these kernels' ratios alone (a plugin's, "
                        "in a fraction of the time); with --update, write them into the "
                        "baseline and keep its others")
    p.add_argument("--update", action="store_true",
                   help="write a new baseline instead (instructions, counters: from a clean "
                        "tree, whose commit it records)")
    from .args import add_plugin

    add_plugin(p)
    p.set_defaults(func=regress)
    # the same measures between two git revisions built here: compare and bisect
    from . import compare

    compare.register(sub)
