"""``hftrace regress`` (``--metric time``): CI performance regression on speedup ratios.

Absolute times move with the machine; ratios measured side by side in one process
(algorithm over ``dda`` on the same rays, interleaved) hold up on noisy runners. The check
re-measures a fixed set of ratios, keeping every paired per-repeat ratio (15 repeats in
each of 3 rounds with fresh data), and compares them with the baseline's samples by a
bootstrap of the relative change of the medians. A ratio regresses only when the change
is significant *and* large: the one-sided upper confidence bound (default 99 %) of the
change lies below ``-tolerance`` (default 5 %). For each ratio it prints the smallest
drop this run could have flagged, which the noise sets, and a ratio whose noise alone
exceeds the tolerance is ``inconclusive`` (exit status 3 when nothing regressed: the run
could not have seen a drop of the tolerance's size). Higher ratios never fail; refresh
the baseline with ``--update`` after an intended speedup. Exact, load-independent counts
are the other mode: ``bench.regress.instructions_gate``.

The committed baseline is ``time_baseline.json`` next to this module (:data:`BASELINE`).
"""
from __future__ import annotations

import json
import os

import numpy as np

import algos
import datasets_gen
from algos.plugins import PluginError

from ..sweep import measure_group
from ..timing import environment, pin_to_one_cpu, write_json

#: The committed baseline of the ratios (``hftrace regress --update`` rewrites it)
BASELINE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "time_baseline.json")

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
DEFAULT_TOLERANCE = 0.05
DEFAULT_CONFIDENCE = 0.99


def key(workload, surface, r, name) -> str:
    """The name of one ratio in a baseline: ``workload/surface/r=R/algorithm``."""
    return f"{workload}/{surface}/r={r}/{name}"


def checks(only=None):
    """:data:`CHECKS` with every registered plugin (``algos.plugins``) added to the checks
    of its workload: traversals to the visit checks, intersectors to the first-hit checks
    of the surfaces they declared (gated on time; callgrind counts only hftrace's own C).
    ``only`` (kernel names): keep those kernels alone, and the checks that hold one."""
    out = []
    for workload, surface, r, names, rays in CHECKS:
        if workload == "first_hit":
            extra = [n for n, a in algos.INTERSECTOR_REGISTRY.items()
                     if a.plugin is not None and surface in a.surfaces]
        elif workload == "visit":
            extra = [n for n, t in algos.TRAVERSAL_REGISTRY.items() if t.plugin is not None]
        else:
            extra = []
        names = tuple(names) + tuple(extra)
        if only is not None:
            names = tuple(n for n in names if n in only)
        if names:
            out.append((workload, surface, r, names, rays))
    return tuple(out)


def check_only(only) -> list | None:
    """``--only`` as a list of kernel names, each measured by some check (a plugin once
    registered); ValueError naming the first that none measures."""
    if only is None:
        return None
    names = [n.strip() for n in str(only).split(",") if n.strip()]
    if not names:
        raise ValueError(f"--only: expected kernel names separated by commas, got {only!r}")
    measured = {n for c in checks() for n in c[3]}
    for name in names:
        if name not in measured:
            raise ValueError(f"--only: {name!r} is in no check of the time gate; it gates "
                             f"{', '.join(sorted(measured))} (a plugin once loaded with "
                             "--plugin)")
    return names


def measure(repeats=15, seed=7, rounds=3, only=None) -> dict[str, list]:
    """The paired per-repeat ratios of CHECKS, measured now, over ``rounds`` rounds, each
    with a freshly allocated field and fresh rays, so that one unlucky memory placement
    (which interleaving inside a round cannot cancel) does not decide a ratio. ``only``:
    the ratios of those kernels alone (:func:`checks`)."""
    samples: dict[str, list] = {}
    for round_ in range(rounds):
        heights = datasets_gen.load("fbm", size=512, seed=1).heights.copy()
        field = algos.Field(heights)
        for workload, surface, r, names, rays in checks(only):
            rows = measure_group(field, "fbm512", workload, surface, r, ["dda", *names], rays,
                                 repeats, seed + round_, keep_samples=True)
            for row in rows:
                if row.get("error"):
                    # a kernel that fails (a plugin that raises, or whose exactness claim
                    # fails) has no ratio to gate: one line naming the ratio and why
                    raise PluginError(f"time gate: {key(workload, surface, r, row['algorithm'])}: "
                                      f"kernel {row['algorithm']!r} failed, so its ratio cannot "
                                      f"be gated: {' '.join(str(row['error']).split())}")
                if row["algorithm"] != "dda":
                    samples.setdefault(key(workload, surface, r, row["algorithm"]), []).extend(
                        round(float(v), 5) for v in row["ratio_samples"])
    return samples


def assess(base: list, now: list, tolerance: float, confidence=DEFAULT_CONFIDENCE,
           n_boot=4000, seed=0) -> dict:
    """The relative change of the median ratio (now against base), its one-sided upper
    confidence bound by a bootstrap of both sample sets, whether that bound lies below
    ``-tolerance`` (a regression), and the smallest drop this comparison could flag."""
    base, now = np.asarray(base, float), np.asarray(now, float)
    change = float(np.median(now) / np.median(base) - 1)
    rng = np.random.Generator(np.random.PCG64(seed))
    boot = np.median(now[rng.integers(0, len(now), (n_boot, len(now)))], axis=1) / \
        np.median(base[rng.integers(0, len(base), (n_boot, len(base)))], axis=1) - 1
    upper = float(np.quantile(boot, confidence))
    return dict(change=change, upper=upper, regressed=upper < -tolerance,
                detectable=tolerance + (upper - change))


def compare(baseline: dict, measured: dict, tolerance: float,
            confidence=DEFAULT_CONFIDENCE) -> list[dict]:
    """Every ratio of ``baseline`` (name -> samples) that ``measured`` lacks (marked
    ``missing``, with why: a kernel not registered in this run, such as a plugin not
    loaded) or that regressed by :func:`assess`."""
    if not 0 <= tolerance < 1:
        raise ValueError(f"tolerance: expected a fraction in [0, 1), got {tolerance}")
    if not 0.5 <= confidence < 1:
        raise ValueError(f"confidence: expected a fraction in [0.5, 1), got {confidence}")
    failures = []
    for name, base in sorted(baseline.items()):
        got = measured.get(name)
        if got is None:
            failures.append(dict(ratio=name, missing=True, reason=_missing_reason(name)))
            continue
        a = assess(base, got, tolerance, confidence)
        if a["regressed"]:
            failures.append(dict(ratio=name, **a, reason=(
                f"{-100 * a['change']:.1f} % below the baseline (at {100 * confidence:g} % "
                f"confidence at least {-100 * a['upper']:.1f} %)")))
    return failures


def _missing_reason(name) -> str:
    """Why the ratio ``workload/surface/r=R/algorithm`` was not measured."""
    kernel = name.rsplit("/", 1)[-1]
    if kernel not in algos.TRAVERSAL_REGISTRY and kernel not in algos.INTERSECTOR_REGISTRY:
        return (f"not measured: kernel {kernel!r} is not registered in this run (a plugin? "
                "load it with --plugin, or drop it from the baseline with --update)")
    return "not measured: this run's checks do not include it"


def load_baseline(path) -> dict:
    """The baseline JSON at ``path``; ValueError (naming the path) when it is missing or
    holds no per-repeat ``samples``."""
    if not os.path.isfile(path):
        raise ValueError(f"baseline: {path} does not exist (create it with --update)")
    with open(path) as f:
        data = json.load(f)
    if not isinstance(data.get("samples"), dict) or not data["samples"]:
        raise ValueError(f"baseline: {path} has no 'samples' table (an old baseline: "
                         "refresh it with --update)")
    return data


#: Exit status of a run that showed no regression but could not show one of the
#: tolerance's size for some ratio (its noise alone exceeds the tolerance)
INCONCLUSIVE = 3


def inconclusive(a: dict, tolerance: float) -> bool:
    """Whether :func:`assess`'s comparison could not have flagged a drop of twice the
    tolerance: the upper bound lies more than ``tolerance`` above the change (the rule of
    ``hftrace compare``: the interval's side wider than the tolerance)."""
    return a["upper"] - a["change"] > tolerance


def run(baseline_path, tolerance=None, update=False, echo=print,
        confidence=DEFAULT_CONFIDENCE, only=None) -> int:
    """Exit status: 1 when any ratio regressed; else :data:`INCONCLUSIVE` (3) when some
    ratio's noise was too wide to show a drop of the tolerance's size ("holds" would then
    claim what the run cannot see); else 0, every ratio holds. The other processes' CPU
    time over the measurement is printed, and a contended run is labelled so.

    ``only`` (a list of kernel names, as :func:`check_only` returns it): measure and judge the ratios of those
    kernels alone (each against ``dda``, as always); with ``update``, those ratios are
    written into the baseline and its others kept."""
    import sys

    from ..load import contention, snapshot, snapshot_after

    pin_to_one_cpu()
    n_ratios = sum(len(c[3]) for c in checks(only))
    echo(f"measuring {n_ratios} speedup ratios over dda, 3 rounds of 15 interleaved repeats "
         "(a few minutes) ...")
    sys.stdout.flush()
    before = snapshot()
    measured = measure() if only is None else measure(only=only)
    load = contention(before, snapshot_after(before))
    other = "unknown" if load["other_cpu"] is None else f"{load['other_cpu']:.2f} cores"
    echo(f"other processes during the measurement: {other}, load average "
         f"{load['load_before']} -> {load['load_after']}"
         + (" - CONTENDED: the ratios below are not findings" if load["contended"] else ""))
    if update:
        samples = dict(measured)
        if only is not None and os.path.exists(baseline_path):
            # the other kernels' ratios stay as they were measured
            samples = {**load_baseline(baseline_path)["samples"], **measured}
        write_json(baseline_path, {
            "ratios": {k: round(float(np.median(v)), 4) for k, v in samples.items()},
            "samples": samples, "tolerance": tolerance or DEFAULT_TOLERANCE,
            "confidence": confidence, "env": environment(),
            "note": "paired per-repeat speedup ratios over dda; see bench/regress/time_gate.py"})
        echo(f"wrote {len(measured)} ratios to {baseline_path}"
             + (f" ({len(samples)} in all)" if len(samples) != len(measured) else ""))
        return 0
    base = load_baseline(baseline_path)
    if only is not None:  # judge the kernels asked for, against their own baseline ratios
        kept = {k: v for k, v in base["samples"].items() if k.rsplit("/", 1)[1] in only}
        if not kept:
            raise ValueError(f"--only: {', '.join(only)} has no ratio in {baseline_path} "
                             "(measure it first with --update)")
        base = dict(base, samples=kept)
    tol = tolerance if tolerance is not None else base.get("tolerance", DEFAULT_TOLERANCE)
    failures = compare(base["samples"], measured, tol, confidence)
    echo(f"{'ratio':45s} {'baseline':>9s} {'measured':>9s} {'change':>8s} {'detectable':>11s}")
    worst = 0.0
    unsure = []
    for name, b in sorted(base["samples"].items()):
        m = measured.get(name)
        if m is None:
            echo(f"{name:45s} {np.median(b):9.3f} {'-':>9s}  MISSING")
            continue
        a = assess(b, m, tol, confidence)
        worst = max(worst, a["detectable"])
        flag = "  REGRESSED" if any(f["ratio"] == name for f in failures) else (
            "  inconclusive" if inconclusive(a, tol) else "")
        if flag == "  inconclusive":
            unsure.append(name)
        echo(f"{name:45s} {np.median(b):9.3f} {np.median(m):9.3f} {100 * a['change']:+7.1f}% "
             f"{100 * a['detectable']:10.1f}%{flag}")
    for name in sorted(set(measured) - set(base["samples"])):
        echo(f"{name:45s} {'-':>9s} {np.median(measured[name]):9.3f}  not in the baseline "
             "(--update, or --baseline FILE of your own)")
    echo(f"smallest drop this run could flag, at {100 * confidence:g} % confidence and "
         f"tolerance {100 * tol:g} %: {100 * worst:.1f} % (the noisiest ratio)")
    missing = [f for f in failures if f.get("missing")]
    regressed = [f for f in failures if not f.get("missing")]
    if missing:
        echo(f"{len(missing)} ratio(s) missing (not measured, so not judged):")
        for f in missing:
            echo(f"  {f['ratio']}: {f['reason']}")
    if regressed:
        echo(f"{len(regressed)} ratio(s) regressed:")
        for f in regressed:
            echo(f"  {f['ratio']}: {f['reason']}")
    if failures:
        return 1
    if unsure:
        echo(f"no regression shown, but {len(unsure)} of {len(base['samples'])} ratio(s) "
             f"inconclusive: their noise alone exceeds the {100 * tol:g} % tolerance, so a "
             "drop of that size could not have been seen (rerun on a quiet machine, or use "
             "--metric instructions, which is exact for hftrace's own C kernels; plugins are "
             "gated on time only)")
        return INCONCLUSIVE
    echo(f"all {len(base['samples'])} ratios hold"
         + (" (on a contended machine)" if load["contended"] else ""))
    return 0


def validate(baseline_path, runs=10, out="results/regress/validation.md", echo=print) -> int:
    """False-alarm check of the time mode: ``runs`` consecutive measurements of an
    unchanged build against the baseline, each judged as ``hftrace regress`` would; writes
    the count of false alarms and the detectable drop of each run to ``out`` (the
    committed one: ``reports/regress_validation.md``)."""
    pin_to_one_cpu()
    base = load_baseline(baseline_path)
    tol = base.get("tolerance", DEFAULT_TOLERANCE)
    conf = base.get("confidence", DEFAULT_CONFIDENCE)
    lines = ["# Time-mode regression check: false alarms on an unchanged build", "",
             f"Written by `python -m bench.regress.time_gate --validate {runs}` against `{baseline_path}` "
             f"(tolerance {100 * tol:g} %, confidence {100 * conf:g} %). Each run re-measures "
             "all ratios in a fresh process state, exactly as `hftrace regress` does.", "",
             "| run | ratios flagged | largest drop measured | smallest detectable drop (worst ratio) |",
             "|---|---|---|---|"]
    alarms = 0
    for k in range(1, runs + 1):
        measured = measure()
        failures = compare(base["samples"], measured, tol, conf)
        results = [assess(base["samples"][n], measured[n], tol, conf)
                   for n in base["samples"] if n in measured]
        alarms += bool(failures)
        worst_drop = min(a["change"] for a in results)
        detectable = max(a["detectable"] for a in results)
        lines.append(f"| {k} | {len(failures)} | {100 * worst_drop:+.1f} % | {100 * detectable:.1f} % |")
        echo(lines[-1])
    lines += ["", f"False alarms: {alarms} of {runs} runs."]
    os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    return 1 if alarms else 0


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description="time-mode regression check utilities")
    parser.add_argument("--validate", type=int, metavar="RUNS", required=True)
    parser.add_argument("--baseline", default=BASELINE)
    parser.add_argument("--out", default="results/regress/validation.md")
    args = parser.parse_args()
    raise SystemExit(validate(args.baseline, args.validate, args.out))
