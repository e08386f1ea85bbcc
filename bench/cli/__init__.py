"""The ``hftrace`` command line: ``main`` and the parser, assembled from one module per
command group. Each module's ``register(subparsers)`` adds its commands and sets their
``func``; a command takes the parsed arguments and returns the exit status.

Every command that writes files writes them under ``results/<command>/`` of the current
directory by default (``--out`` to choose); the committed reference reports in
``reports/`` change only through ``hftrace reproduce --publish`` and ``make reports``.
"""
from __future__ import annotations

import os

# Benchmarks pin themselves to one CPU; idle BLAS worker threads spinning on that CPU
# would steal time from the timed loops. hftrace uses no BLAS: keep one thread. (Set
# before NumPy is first imported.)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402

from . import catalogue, profile, regress, render, studies, sweep, terrain  # noqa: E402

__all__ = ["main", "build_parser"]

#: The command groups, in the order of ``hftrace --help``
GROUPS = (catalogue, studies, terrain, sweep, regress, render, profile)


def build_parser() -> argparse.ArgumentParser:
    """The ``hftrace`` parser with every command group's sub-commands."""
    parser = argparse.ArgumentParser(
        prog="hftrace",
        description="Benchmark harness for ray traversal of height fields. Commands write "
                    "under results/<command>/ by default (--out to choose).")
    sub = parser.add_subparsers(dest="command", required=True)
    for group in GROUPS:
        group.register(sub)
    return parser


#: Options whose value may start with a minus sign (a western longitude, a negative
#: easting): argparse would take ``--observer -12345,4099535`` for two options
_SIGNED_VALUES = ("--observer", "--observer-pixel", "--camera", "--look-at", "--azimuths")


def _join_signed_values(argv):
    """``--observer -1,2`` as ``--observer=-1,2`` (see :data:`_SIGNED_VALUES`)."""
    out, k = [], 0
    while k < len(argv):
        if argv[k] in _SIGNED_VALUES and k + 1 < len(argv) and len(argv[k + 1]) > 1 \
                and argv[k + 1][0] == "-" and (argv[k + 1][1].isdigit() or argv[k + 1][1] == "."):
            out.append(f"{argv[k]}={argv[k + 1]}")
            k += 2
        else:
            out.append(argv[k])
            k += 1
    return out


def _warn(text):
    print(text, file=sys.stderr)


def main(argv=None) -> int:
    """Run one ``hftrace`` command; the exit status: 2 on a user error (a ValueError,
    TypeError, a plugin that fails to load or run, or an unreadable file, printed as one
    line ``hftrace: error: ...``, never a traceback), 130 on Ctrl-C (with how to resume).
    The kernels of installed packages' ``hftrace.kernels`` entry points are registered first (``algos.plugins``)."""
    from algos.plugins import PluginError, load_entry_points

    load_entry_points(warn=_warn)
    parser = build_parser()
    args = parser.parse_args(_join_signed_values(list(sys.argv[1:] if argv is None else argv)))
    try:
        return args.func(args)
    except (ValueError, TypeError, PluginError) as exc:
        print(f"hftrace: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # an unreadable input, an unwritable --out: the path and why
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"hftrace: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        resumable = "--resume" in {a.option_strings[0] for a in _actions(parser, args)}
        again = " ".join(sys.argv[1:] if argv is None else argv)
        hint = (f"; every finished group is kept: `hftrace {again} --resume` continues"
                if resumable and "--resume" not in again.split() else "")
        print(f"\nhftrace: interrupted{hint}", file=sys.stderr)
        return 130
    except MemoryError as exc:  # e.g. `rays = 10000000000` in a sweep config: one line
        detail = f" ({exc})" if str(exc) else ""
        print(f"hftrace: error: out of memory{detail}; ask for fewer rays or a smaller field",
              file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. `hftrace datasets list | head`
        sys.stderr.close()
        return 0


def _actions(parser, args):
    """The options of the sub-command that ran (to tell whether it can resume)."""
    for action in parser._subparsers._group_actions:
        sub = action.choices.get(args.command)
        if sub is not None:
            return [a for a in sub._actions if a.option_strings]
    return []


