"""``hftrace compare`` and ``hftrace bisect``: two git revisions of the kernels built here
and measured side by side in one process (``bench.compare``)."""
from __future__ import annotations

import os
import sys
import tempfile


def _setup(args):
    from ..compare import METRICS, Setup

    metrics = METRICS if args.metric == "all" else tuple(m.strip() for m in args.metric.split(",") if m.strip())
    kernels = None
    if args.kernels is not None:
        kernels = tuple(k.strip() for k in args.kernels.split(",") if k.strip())
        if not kernels:  # an unset variable in a script: not the default set by surprise
            raise ValueError(f"--kernels: {args.kernels!r} names no kernel (give comma-separated "
                             "first-hit kernels, or leave --kernels out for the default set)")
    setup = Setup(metrics=metrics, kernels=kernels, surface=args.surface, tolerance=args.tolerance,
                  repeats=args.repeats, budget=args.budget)
    setup.check()
    return setup


def _fail(text) -> int:
    print(f"hftrace: error: {text}", file=sys.stderr)
    return 2


def compare(args):
    """Compare BASE with HEAD; exit 0 (no kernel slower), 1 (one slower), 2 (error)."""
    from ..compare import compare, publish

    try:
        setup = _setup(args)
        _check_json(args.json)
        report = compare(args.repo, args.base, args.head, setup, echo=_note)
    except (RuntimeError, ValueError) as exc:  # CompareError, RevisionError, valgrind's failure
        return _fail(exc)
    publish(report, args.json)
    return report["status"]


def bisect(args):
    """Find the first commit from GOOD to BAD whose kernels are slower than GOOD's."""
    from ..compare import bisect, bisect_lines

    try:
        setup = _setup(args)
        result = bisect(args.repo, args.good, args.bad, setup, echo=_note)
    except (RuntimeError, ValueError) as exc:
        return _fail(exc)
    for line in bisect_lines(result, args.good, args.bad):
        print(line)
    return 0


def _check_json(path):
    """``ValueError`` naming ``--json`` when its folder does not exist or takes no new
    file (a trial file is created and removed: access() passes /proc or a read-only bind
    mount for root): said before anything is built or measured, not after."""
    if not path:
        return
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        raise ValueError(f"--json: {path} is a directory; give a file name")
    if not os.path.isdir(folder):
        raise ValueError(f"--json: the folder {folder} does not exist")
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".hftrace-json-", suffix=".tmp"):
            pass
    except OSError as exc:
        raise ValueError(f"--json: cannot create a file in {folder} "
                         f"({exc.strerror or exc})") from None


def _note(text):
    print(text, file=sys.stderr)


def _common(p, default_metric):
    from ..compare import DEFAULT_BUDGET, DEFAULT_KERNELS, DEFAULT_REPEATS, DEFAULT_TOLERANCE

    p.add_argument("--repo", default=os.curdir, help="the git repository (default: the current directory)")
    p.add_argument("--metric", default=default_metric,
                   help="comma-separated: time, instructions (callgrind; needs valgrind), counters "
                        f"(cells, runs, tiles per ray), or all (default {default_metric})")
    p.add_argument("--kernels", default=None,
                   help=f"comma-separated first-hit kernels (default {','.join(DEFAULT_KERNELS)})")
    p.add_argument("--surface", default="triangles", help="the cell surface (default triangles)")
    p.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE,
                   help=f"time change below which kernels are the same (default {DEFAULT_TOLERANCE})")
    p.add_argument("--repeats", type=int, default=DEFAULT_REPEATS,
                   help=f"the fewest timed pairs per kernel (default {DEFAULT_REPEATS})")
    p.add_argument("--budget", type=float, default=DEFAULT_BUDGET,
                   help="seconds a kernel's timed pairs may take; they stop earlier once the "
                        f"interval is within a third of the tolerance (default {DEFAULT_BUDGET:g})")


def register(sub):
    """Add ``compare`` and ``bisect`` to the sub-parsers ``sub``."""
    p = sub.add_parser("compare", help="two git revisions built here, measured side by side: "
                                       "a verdict per kernel (exit 1 when one is slower)",
                       epilog="exit status: 0 when no kernel is slower (same, faster or "
                              "inconclusive), 1 when at least one is slower beyond the "
                              "tolerance, 2 on an error (one line: a revision that does not "
                              "exist or does not build, a bad option, no valgrind)")
    p.add_argument("base", help="the base revision (a commit, branch or tag)")
    p.add_argument("head", nargs="?", default=None,
                   help="the head revision (default: the working tree)")
    _common(p, "time,counters")
    p.add_argument("--json", default=None, help="also write the verdicts to this JSON file")
    p.set_defaults(func=compare)
    p = sub.add_parser("bisect", help="the first commit between GOOD and BAD whose kernels are "
                                      "slower than GOOD's",
                       epilog="exit status: 0 when the search ran (it prints `first bad commit: "
                              "SHA`, or that BAD is not slower than GOOD), 2 on an error (one "
                              "line: a revision that does not exist or does not build on the "
                              "path, a bad option)")
    p.add_argument("good", help="a revision without the regression")
    p.add_argument("bad", help="a later revision with it")
    _common(p, "counters")
    p.set_defaults(func=bisect)
