"""``hftrace profile``: instruction and branch counts of one kernel (``bench.profile``)."""
from __future__ import annotations

import math
import sys

import algos

from .args import positive_int


def _options(items) -> dict:
    """``KEY=VALUE`` intersector options: ints, or true/false."""
    options = {}
    for item in items:
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
    return options


def _run_length(text: str):
    """``--r``: ``"random"``, or a finite number >= 1 (an int when written as one). "nan",
    "inf" and "abc" raised int()'s "invalid literal for int() with base 10", naming no
    option."""
    if text == "random":
        return text
    try:
        r = int(text)
    except ValueError:
        try:
            r = float(text)
        except ValueError:
            r = math.nan
    if not (math.isfinite(r) and r >= 1):
        raise ValueError(f"--r: expected a number >= 1 or 'random', got {text!r}")
    return r


def profile_command(args):
    """Check the arguments, count one kernel under callgrind and print the report; 2 when
    valgrind is missing or fails."""
    from .. import profile as prof

    if args.workload == "first_hit":
        algos.get_intersector(args.kernel)
    else:
        algos.get_traversal(args.kernel)
    if args.surface not in algos.SURFACES:
        raise ValueError(f"--surface: unknown surface {args.surface!r}; valid: {', '.join(algos.SURFACES)}")
    r = _run_length(args.r)
    try:
        result = prof.profile(args.kernel, dataset=args.dataset, size=args.size, r=r,
                              rays=args.rays, surface=args.surface, workload=args.workload,
                              seed=args.seed, cache_sim=args.cache_sim,
                              options=_options(args.option), parallel=args.parallel)
    except RuntimeError as exc:
        print(f"hftrace: error: {exc}", file=sys.stderr)
        return 2
    print(prof.format_profile(result))
    return 0


def register(sub):
    """Add ``profile`` to the sub-parsers ``sub``."""
    p = sub.add_parser("profile", help="instruction and branch counts of one kernel (callgrind)")
    p.add_argument("kernel", help="an intersector (first_hit) or traversal (visit, runs)")
    p.add_argument("--workload", default="first_hit", choices=("first_hit", "visit", "runs"))
    p.add_argument("--dataset", default="fbm")
    p.add_argument("--size", type=positive_int, default=1024, help="field side in samples")
    p.add_argument("--r", default="25", help="mean run length, or 'random'")
    p.add_argument("--rays", type=positive_int, default=1000)
    p.add_argument("--surface", default="triangles")
    p.add_argument("--seed", type=int, default=2008)
    p.add_argument("--cache-sim", action="store_true",
                   help="also simulate the caches (D1 and last-level misses; slower)")
    p.add_argument("--parallel", action="store_true",
                   help="first hits: one batch of parallel rays of slope 1/r (orthographic)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="an intersector option, e.g. fine_level=2 or cull_runs=false (repeatable)")
    p.set_defaults(func=profile_command)
