"""The ``hftrace`` command line."""
from __future__ import annotations

import argparse
import sys

import algos


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


def _list(args):
    for t in algos.TRAVERSAL_REGISTRY.values():
        exact = "exact" if t.exact else (f"exact when {t.exact_when}" if t.exact_when else t.precision)
        print(f"{t.name:14s} {t.family:4s} {exact:50s} {t.summary} ({t.citation})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hftrace",
        description="Benchmark harness for ray traversal of height fields.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="list the registered algorithms")
    p.set_defaults(func=_list)

    p = sub.add_parser("bench-traverse",
                       help="time the visit and runs workloads of every kernel relative to dda")
    _add_bench_arguments(p, "reports/bench_traverse")
    p.set_defaults(func=_bench_traverse)

    p = sub.add_parser(
        "reproduce",
        help="the main study; until the first-hit study lands this runs bench-traverse")
    _add_bench_arguments(p, "reports/reproduce")
    p.set_defaults(func=_bench_traverse)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, TypeError) as exc:
        print(f"hftrace: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
