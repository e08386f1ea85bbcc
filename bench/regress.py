"""``hftrace regress``: CI performance regression on speedup ratios.

Absolute times move with the machine; ratios measured side by side in one process
(algorithm over ``dda`` on the same rays, interleaved) hold up on noisy runners. The check
re-measures a fixed set of ratios and fails when any falls more than ``tolerance``
(default 15 %) below the committed baseline. Higher ratios never fail; refresh the
baseline with ``--update`` after an intended speedup.
"""
from __future__ import annotations

import json
import os

import numpy as np

import algos
import datasets_gen

from .sweep import measure_group
from .timing import environment, write_json

#: What is measured: (workload, surface, run length, algorithms, rays). Field: fBm 512^2,
#: seed 1. Ray counts make every batch last several milliseconds: shorter batches are at
#: the mercy of the scheduler.
CHECKS = (
    ("visit", "-", 1, ("midpoint", "runs"), 20000),
    ("visit", "-", 25, ("midpoint", "runs"), 20000),
    ("runs", "-", 25, ("midpoint", "runs"), 60000),
    ("first_hit", "triangles", 1, ("midpoint", "runs", "dda_maxmip", "runs_maxmip"), 10000),
    ("first_hit", "triangles", 25, ("midpoint", "runs", "dda_maxmip", "runs_maxmip"), 10000),
    ("first_hit", "bilinear", 25, ("runs",), 10000),
)
DEFAULT_TOLERANCE = 0.15


def key(workload, surface, r, name) -> str:
    return f"{workload}/{surface}/r={r}/{name}"


def measure(repeats=15, seed=7, rounds=3) -> dict[str, float]:
    """The ratios of CHECKS, measured now: the median over ``rounds`` rounds, each with a
    freshly allocated field and fresh rays, so that one unlucky memory placement (which
    interleaving inside a round cannot cancel) does not decide a ratio."""
    samples: dict[str, list] = {}
    for round_ in range(rounds):
        heights = datasets_gen.load("fbm", size=512, seed=1).heights.copy()
        field = algos.Field(heights)
        for workload, surface, r, names, rays in CHECKS:
            rows = measure_group(field, "fbm512", workload, surface, r, ["dda", *names], rays,
                                 repeats, seed + round_)
            for row in rows:
                if row["algorithm"] != "dda":
                    samples.setdefault(key(workload, surface, r, row["algorithm"]), []).append(
                        float(row["speedup"]))
    return {k: float(np.median(v)) for k, v in samples.items()}


def compare(baseline: dict, measured: dict, tolerance: float) -> list[dict]:
    """Every ratio of ``baseline`` that ``measured`` lacks or that fell more than
    ``tolerance`` (a fraction) below it."""
    if not 0 <= tolerance < 1:
        raise ValueError(f"tolerance: expected a fraction in [0, 1), got {tolerance}")
    failures = []
    for name, base in sorted(baseline.items()):
        floor = base * (1 - tolerance)
        got = measured.get(name)
        if got is None:
            failures.append(dict(ratio=name, baseline=base, measured=None, floor=floor,
                                 reason="not measured"))
        elif got < floor:
            failures.append(dict(ratio=name, baseline=base, measured=got, floor=floor,
                                 reason=f"{100 * (1 - got / base):.1f} % below the baseline"))
    return failures


def load_baseline(path) -> dict:
    if not os.path.isfile(path):
        raise ValueError(f"baseline: {path} does not exist (create it with --update)")
    with open(path) as f:
        data = json.load(f)
    if not isinstance(data.get("ratios"), dict) or not data["ratios"]:
        raise ValueError(f"baseline: {path} has no 'ratios' table")
    return data


def run(baseline_path, tolerance=None, update=False, echo=print) -> int:
    """Exit status: 0 when every ratio holds, 1 when any regressed."""
    from .intersect_bench import pin_to_one_cpu

    pin_to_one_cpu()
    measured = measure()
    if update:
        write_json(baseline_path, {"ratios": measured, "tolerance": tolerance or DEFAULT_TOLERANCE,
                                   "env": environment(),
                                   "note": "speedup ratios over dda; see bench/regress.py"})
        echo(f"wrote {len(measured)} ratios to {baseline_path}")
        return 0
    base = load_baseline(baseline_path)
    tol = tolerance if tolerance is not None else base.get("tolerance", DEFAULT_TOLERANCE)
    failures = compare(base["ratios"], measured, tol)
    echo(f"{'ratio':45s} {'baseline':>9s} {'measured':>9s}")
    for name, b in sorted(base["ratios"].items()):
        m = measured.get(name)
        flag = "  REGRESSED" if any(f["ratio"] == name for f in failures) else ""
        echo(f"{name:45s} {b:9.3f} {m if m is not None else float('nan'):9.3f}{flag}")
    if failures:
        echo(f"{len(failures)} ratio(s) fell more than {100 * tol:.0f} % below the baseline:")
        for f in failures:
            echo(f"  {f['ratio']}: {f['reason']} (floor {f['floor']:.3f})")
        return 1
    echo(f"all {len(base['ratios'])} ratios within {100 * tol:.0f} % of the baseline")
    return 0
