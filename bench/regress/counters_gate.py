"""``hftrace regress --metric counters``: the exact algorithmic counters of every
first-hit kernel (cells visited, cells tested, runs visited, runs culled, tiles skipped;
``algos.STATS``) on the gate's fixed inputs, summed over the rays.

They depend on the algorithm and the inputs only, not on the compiler or the machine, so
the gate needs no tolerance and no valgrind: a work counter
(:data:`bench.regress.workload.WORK_COUNTERS`) that grows at all fails, any other change
is reported. The baseline records the input hashes; on a mismatch the gate counts the
baseline's commit built here instead (:mod:`bench.regress.baseline`).
"""
from __future__ import annotations

import os

from .instructions_gate import gate_inputs
from .workload import counter_changes, counters, intersector_names

#: The committed baseline of the counters (``hftrace regress --metric counters --update``)
BASELINE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "counters_baseline.json")


def cases(pkg=None) -> list[tuple[str, str]]:
    """Every (surface, kernel) counted: each C first-hit kernel of ``pkg`` (default the
    installed ``algos``) on each surface it supports."""
    if pkg is None:
        import algos as pkg
    out = []
    for name in intersector_names(pkg):
        for surface in pkg.SURFACES:
            if surface in pkg.INTERSECTOR_REGISTRY[name].surfaces:
                out.append((surface, name))
    return out


def compare(base: dict, measured: dict) -> tuple[list[dict], list[dict]]:
    """(failures, changes): a case missing or with a work counter grown fails; a case
    whose other counters moved is a change."""
    failures, changes = [], []
    for name, b in sorted(base.items()):
        got = measured.get(name)
        if got is None:
            failures.append(dict(case=name, reason="not measured"))
            continue
        grew, changed = counter_changes(b, got)
        if grew:
            failures.append(dict(case=name, reason="; ".join(grew + changed)))
        elif changed:
            changes.append(dict(case=name, reason="; ".join(changed)))
    return failures, changes


def run(baseline_path, tolerance=None, update=False, echo=print) -> int:
    """Count every case and compare with the baseline (or write it, from a clean tree,
    with ``update``). Exit status 0, 1 when a work counter grew or a case is missing, 2
    on an error. ``tolerance`` is refused: the counters are exact."""
    from . import baseline as bl
    from .revisions import load, toolchain

    if tolerance not in (None, 0, 0.0):
        echo(f"hftrace: error: tolerance: the counters are exact, none applies (got {tolerance})")
        return 2
    import algos

    try:
        inputs = gate_inputs()
        if update:
            commit = bl.provenance()
            measured = counters(algos, inputs, cases())
            bl.write(baseline_path, "counters", measured, inputs, toolchain(), commit, 0,
                     "algorithmic counters summed over the rays; see bench/regress/counters_gate.py")
            echo(f"wrote {len(measured)} cases counted at {commit[:10]} to {baseline_path}")
            return 0
        base = bl.read(baseline_path, "counters")
        base_cases = base["cases"]
        differ = bl.mismatches(base, inputs, toolchain(), ())
        if differ:
            echo("regress: the baseline was counted on other inputs (" + "; ".join(differ) + "): "
                 f"counting its commit {str(base.get('commit'))[:10]} here instead of the snapshot")
            pkg = load(bl.rebuilt_base(base, baseline_path, echo), "baseline")
            todo = [c for c in cases(pkg) if f"first_hit/{c[0]}/{c[1]}" in base_cases]
            base_cases = counters(pkg, inputs, todo)
        measured = counters(algos, inputs, cases())
    except (RuntimeError, OSError) as exc:
        echo(f"hftrace: error: {exc}")
        return 2
    failures, changes = compare(base_cases, measured)
    bad = {f["case"] for f in failures}
    echo(f"{'case':40s} {'cells/ray':>10s} {'tested/ray':>11s} {'runs/ray':>9s}  (before -> after)")
    for name in sorted(base_cases):
        b, m = base_cases[name], measured.get(name, {})

        def pair(k, b=b, m=m):
            rays = max(b.get("rays", 1), 1)
            return f"{b.get(k, 0) / rays:.2f}->{m.get(k, float('nan')) / rays:.2f}"

        flag = "  REGRESSED" if name in bad else ""
        echo(f"{name:40s} {pair('cells_visited'):>10s} {pair('cells_tested'):>11s} "
             f"{pair('runs_visited'):>9s}{flag}")
    for c in changes:
        echo(f"  changed (not a regression): {c['case']}: {c['reason']}")
    unbaselined = sorted(set(measured) - set(base_cases))
    if unbaselined:
        echo(f"  not in the baseline, so not gated (refresh it with --update): {', '.join(unbaselined)}")
    if failures:
        echo(f"{len(failures)} case(s) do more work than the baseline:")
        for f in failures:
            echo(f"  {f['case']}: {f['reason']}")
        return 1
    echo(f"all {len(base_cases)} cases do no more work than the baseline (exact counters)")
    return 0
