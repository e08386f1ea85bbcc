"""Argument types and shared options of the ``hftrace`` commands."""
from __future__ import annotations

import argparse
import os

import algos

__all__ = ["add_plugin", "load_plugins", "positive_int", "run_lengths", "param", "vector", "names", "results_dir",
           "add_out", "add_bench_arguments"]

#: Where commands write by default: ``results/<command>/`` under the current directory
#: (untracked; ``/results/`` is in .gitignore)
RESULTS = "results"


def positive_int(text):
    """An int >= 1 (argparse type)."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text}")
    return value


def run_lengths(text):
    """Comma-separated mean run lengths >= 1, ints where written without a point."""
    try:
        values = tuple(float(v) if "." in v else int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}")
    if any(v < 1 for v in values):
        raise argparse.ArgumentTypeError("run lengths must be >= 1")
    return values


def param(text):
    """``NAME=VALUE`` as (name, value), the value an int or float where it parses as one."""
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    name, value = text.split("=", 1)
    for cast in (int, float):
        try:
            return name, cast(value)
        except ValueError:
            pass
    return name, value


def vector(text):
    """``x,y,z`` as a list of three floats."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected x,y,z, got {text!r}") from None
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected x,y,z, got {text!r}")
    return values


def names(text, lookup, option="--algorithms"):
    """A comma-separated list of algorithm names, each checked by ``lookup`` (e.g.
    ``algos.get_traversal``, which raises ValueError naming an unknown one); None for
    an empty text. Empty items (``dda,,runs``, a trailing comma) are skipped. The
    lookup's error is raised again naming the command-line ``option`` it came from."""
    if not text:
        return None
    chosen = [n.strip() for n in text.split(",") if n.strip()]
    if not chosen:
        raise ValueError(f"{option}: expected comma-separated names, got {text!r}")
    for name in chosen:
        try:
            lookup(name)
        except ValueError as exc:
            message = str(exc)
            if message.startswith("name: "):
                message = message[len("name: "):]
            if not message.startswith(option):
                message = f"{option}: {message}"
            raise ValueError(message) from None
    return chosen


def results_dir(command: str) -> str:
    """The default output directory of ``command``: ``results/<command>``."""
    return os.path.join(RESULTS, command)


def add_out(p, command, what="output directory"):
    """``--out``, defaulting to :func:`results_dir` of ``command``."""
    p.add_argument("--out", default=results_dir(command),
                   help=f"{what} (default {results_dir(command)})")


def add_bench_arguments(p, command):
    """The options bench-traverse and bench-intersect share."""
    p.add_argument("--rays", type=positive_int, default=2000, help="rays per run length")
    p.add_argument("--grid", type=positive_int, default=1024, help="grid side in cells")
    p.add_argument("--repeats", type=positive_int, default=9, help="interleaved repeats")
    p.add_argument("--seed", type=int, default=2004)
    p.add_argument("--run-lengths", type=run_lengths, default=(1, 2, 5, 25, 100),
                   help="comma-separated mean run lengths r")
    kinds = algos.INTERSECTORS if command == "bench-intersect" else algos.TRAVERSALS
    p.add_argument("--algorithms", default=None,
                   help=f"comma-separated subset of {', '.join(kinds)} (default: all)")
    add_out(p, command)


def add_plugin(p):
    """``--plugin SPEC`` (repeatable): a C plugin's library or ``module:callable``."""
    p.add_argument("--plugin", action="append", default=None, metavar="LIB.so|module:callable",
                   help="register a kernel first (repeatable; docs/plugins.md)")


def load_plugins(args):
    """Register the kernels of every ``--plugin``; ValueError names a bad one."""
    from algos.plugins import load_plugin_spec

    for spec in getattr(args, "plugin", None) or []:
        load_plugin_spec(spec)
