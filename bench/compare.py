"""``hftrace compare`` and ``hftrace bisect``: two revisions of the C kernels, built here and
measured side by side in one process.

Each revision is built once into a cache (:mod:`bench.regress.revisions`) and its
``algos`` package imported under its own name, so base and head run in one process on
the same field and rays (:func:`bench.regress.workload.make_inputs`, made by this
checkout). Per first-hit kernel, three measures:

- ``time``: base and head in adjacent pairs (``bench.timing.paired_rounds``: cycles
  ``B H B H B``, each visit warm, one untimed call before its timed ones). Each head visit
  and the geometric mean of the base visits around it give one paired log-ratio
  log(head/base); their median and its distribution-free interval (``confidence``,
  default 99 %) give the ratio head/base and its interval. Pairs are added until the
  interval is within a third of the tolerance, or the kernel's ``budget`` is spent. The
  machine's noise hits both sides of a pair and cancels, and the ratio is absolute: a
  slower ``dda`` shows as slower.
- ``instructions``: callgrind instructions and branches per ray of each build
  (``bench.regress.instructions_gate``, on that gate's smaller inputs); exact, gated at 1 %.
- ``counters``: cells, runs and tiles per ray (``algos.STATS``); exact and
  compiler-independent; a work counter that grows is a regression.

One verdict per kernel: ``slower`` (some measure is significantly worse beyond its
tolerance), ``faster``, ``same``, or ``inconclusive`` (the time interval is wider than the
tolerance, so neither could be shown). ``detectable`` is the smallest slowdown this run
would have flagged: the tolerance plus the interval's half-width. How the design is
justified is in docs/METHOD.md.
"""
from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass, field

import numpy as np

from .regress import revisions
from .regress.workload import WORK_COUNTERS, counter_changes, counters, intersector_names, make_inputs

METRICS = ("time", "instructions", "counters")
DEFAULT_METRICS = ("time", "counters")
#: The first-hit kernels compared when ``--kernels`` is not given
DEFAULT_KERNELS = ("dda", "midpoint", "runs", "dda_maxmip", "runs_maxmip", "cone", "dda_compact")
DEFAULT_TOLERANCE = 0.03
INSTRUCTION_TOLERANCE = 0.01
#: The fewest pairs of a kernel, and the seconds its pairs may take
DEFAULT_REPEATS = 20
#: The most pairs a kernel's time is measured in (``paired_rounds``' ``max_rounds``)
MAX_PAIRS = 100000
DEFAULT_BUDGET = 10.0
DEFAULT_CONFIDENCE = 0.99
#: The compare's inputs: fBm 512^2, 4000 first-hit rays at r = 25 (batches of a few ms)
SIZE, RAYS, R, SEED = 512, 4000, 25, 2008


class CompareError(RuntimeError):
    """A user error of compare or bisect (exit status 2, one line)."""


@dataclass
class KernelResult:
    """One kernel's measures and verdict (see the module docstring)."""

    kernel: str
    verdict: str = "same"
    time: dict | None = None
    instructions: dict | None = None
    counters: dict | None = None
    reasons: list = field(default_factory=list)


def time_verdict(log_ratios, tolerance, confidence=DEFAULT_CONFIDENCE) -> dict:
    """The ratio head/base of paired log-ratios ``log(head/base)`` (one per pair): its
    point value (exp of the median), its distribution-free interval (the binomial order
    statistics of ``bench.timing.median_interval`` at ``confidence``), the
    ``detectable`` slowdown (tolerance plus the interval's wider side) and the verdict:
    ``slower`` when the interval lies above ``1 + tolerance``, ``faster`` when below
    ``1/(1 + tolerance)``, ``inconclusive`` when its wider side exceeds the tolerance,
    else ``same``."""
    try:
        from scipy import stats  # noqa: F401 - the interval's binomial ranks
    except ImportError as exc:
        raise CompareError("metric: time needs SciPy for its intervals "
                           "(pip install 'hftrace[regress]')") from exc
    from .timing import median_interval

    x = np.asarray(log_ratios, dtype=float)
    x = x[np.isfinite(x)]
    if x.size < 3:
        raise ValueError(f"log_ratios: need at least 3 pairs, got {x.size}")
    mid, low, high = median_interval(x, confidence)
    half = max(high - mid, mid - low)
    bound = math.log1p(tolerance)
    if low > bound:
        verdict = "slower"
    elif high < -bound:
        verdict = "faster"
    elif half > bound:
        verdict = "inconclusive"
    else:
        verdict = "same"
    return dict(ratio=math.exp(mid), low=math.exp(low), high=math.exp(high),
                detectable=math.expm1(bound + half), repeats=int(x.size), verdict=verdict)


def paired_times(run_base, run_head, setup) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(log(head/base) per pair, base ns per visit, head ns per visit) of
    ``bench.timing.paired_rounds`` on the two runs (each returns its elapsed ns): at
    least ``setup.repeats`` pairs, then until the ``setup.confidence`` interval is within
    a third of ``setup.tolerance`` or ``setup.budget`` seconds are spent; the one place
    this module uses ``bench.timing``."""
    from .timing import WARM_TIMED_CALLS, paired_rounds

    got = paired_rounds({"base": run_base, "head": run_head}, "base",
                        precision=setup.tolerance / 3, budget_s=setup.budget,
                        min_rounds=setup.repeats, max_rounds=MAX_PAIRS, flush="warm",
                        confidence=setup.confidence)
    calls = WARM_TIMED_CALLS
    return (-got.log_ratios["head"], got.times["base"] / calls, got.times["head"] / calls)


def instruction_verdict(base: dict, head: dict, tolerance=INSTRUCTION_TOLERANCE) -> dict:
    """Instructions and branches per ray of both builds, their ratios and the verdict:
    ``slower`` when either grew by more than ``tolerance``, ``faster`` when either fell by
    more and neither grew, else ``same``."""
    out = dict(base=base["instructions_per_ray"], head=head["instructions_per_ray"],
               branches_base=base["branches_per_ray"], branches_head=head["branches_per_ray"])
    ratios = [head[k] / base[k] if base[k] else 1.0 for k in ("instructions_per_ray", "branches_per_ray")]
    out["ratio"], out["branches_ratio"] = ratios
    if max(ratios) > 1 + tolerance:
        out["verdict"] = "slower"
    elif min(ratios) < 1 - tolerance:
        out["verdict"] = "faster"
    else:
        out["verdict"] = "same"
    return out


def counter_verdict(base: dict, head: dict) -> dict:
    """Counters per ray of both builds and the verdict: ``slower`` when a work counter
    grew, ``faster`` when one fell and none grew, else ``same``."""
    grew, changed = counter_changes(base, head)
    rays = max(head.get("rays", 1), 1)
    fell = any(head.get(k, 0) < base.get(k, 0) for k in WORK_COUNTERS)
    verdict = "slower" if grew else "faster" if fell else "same"
    return dict(base={k: v / rays for k, v in base.items() if k != "rays"},
                head={k: v / rays for k, v in head.items() if k != "rays"},
                changes=grew + changed, verdict=verdict)


def _overall(r: KernelResult) -> str:
    words = [m["verdict"] for m in (r.time, r.instructions, r.counters) if m]
    for word in ("slower", "inconclusive", "faster"):
        if word in words:
            return word
    return "same"


@dataclass
class Setup:
    """What ``compare`` runs: metrics, kernels, surface, tolerance, repeats, inputs."""

    metrics: tuple = DEFAULT_METRICS
    kernels: tuple | None = None
    surface: str = "triangles"
    tolerance: float = DEFAULT_TOLERANCE
    repeats: int = DEFAULT_REPEATS
    budget: float = DEFAULT_BUDGET
    confidence: float = DEFAULT_CONFIDENCE
    size: int = SIZE
    rays: int = RAYS

    def check(self):
        """``ValueError`` naming the option for a value out of range."""
        bad = [m for m in self.metrics if m not in METRICS]
        if bad or not self.metrics:
            raise ValueError(f"metric: expected some of {', '.join(METRICS)} or all, got {bad or 'none'}")
        if not 0 < self.tolerance < 1:
            raise ValueError(f"tolerance: expected a fraction in (0, 1), got {self.tolerance}")
        if not 3 <= self.repeats <= MAX_PAIRS:
            raise ValueError(f"repeats: expected 3 to {MAX_PAIRS} pairs, got {self.repeats}")
        if not self.budget > 0:
            raise ValueError(f"budget: expected a positive number of seconds, got {self.budget}")
        if not 0.5 < self.confidence < 1:
            raise ValueError(f"confidence: expected a level in (0.5, 1), got {self.confidence}")


def _select(setup: Setup, base_pkg, head_pkg) -> tuple[list[str], list[str]]:
    """(kernels measured, kernels new in head)."""
    in_head, in_base = intersector_names(head_pkg), set(intersector_names(base_pkg))
    wanted = list(setup.kernels) if setup.kernels else [k for k in DEFAULT_KERNELS if k in in_head]
    for k in wanted:
        if k not in in_head and k not in in_base:
            raise CompareError(f"kernels: {k!r} is not a C first-hit kernel of either revision "
                               f"(known: {', '.join(in_head)})")
        if k not in in_head:
            raise CompareError(f"kernels: {k!r} exists in the base but not in the head revision")
    known = sorted({sf for k in in_head for sf in head_pkg.INTERSECTOR_REGISTRY[k].surfaces})
    if setup.surface not in known:
        raise CompareError(f"surface: {setup.surface!r} is not a cell surface of the head "
                           f"revision (known: {', '.join(known)})")
    for k in wanted:
        if setup.surface not in head_pkg.INTERSECTOR_REGISTRY[k].surfaces:
            raise CompareError(f"kernels: {k!r} does not support the surface {setup.surface!r}")
    return [k for k in wanted if k in in_base], [k for k in wanted if k not in in_base]


def measure(base_build, head_build, base_pkg, head_pkg, setup: Setup, inputs=None, echo=print) -> dict:
    """Compare two loaded builds; the report (a dict, :func:`write_json`-able) with
    ``results`` (one :class:`KernelResult` per kernel, as dicts) and ``status`` (0 or 1)."""
    setup.check()
    inputs = inputs if inputs is not None else make_inputs(size=setup.size, first_hit_rays=setup.rays,
                                                           traversal_rays=16, r=R, seed=SEED)
    kernels, new = _select(setup, base_pkg, head_pkg)
    if not kernels:
        raise CompareError(f"kernels: {', '.join(new)} {'is' if len(new) == 1 else 'are'} new "
                           "in the head revision: the base has nothing to compare with "
                           "(time a new kernel against the others with `hftrace sweep` or "
                           "`hftrace targets`)")
    results = {k: KernelResult(k) for k in kernels}
    if "counters" in setup.metrics:
        cases = [(setup.surface, k) for k in kernels]
        cb = _on(base_build, "counters", counters, base_pkg, inputs, cases)
        ch = _on(head_build, "counters", counters, head_pkg, inputs, cases)
        for k in kernels:
            key = f"first_hit/{setup.surface}/{k}"
            results[k].counters = counter_verdict(cb[key], ch[key])
    if "instructions" in setup.metrics:
        from .regress import instructions_gate as ig

        if not ig.callgrind_available():
            raise CompareError("metric: instructions needs valgrind (apt-get install valgrind); "
                               "it is not on PATH")
        # the gate's small inputs (fBm 256^2, 200 rays): counts are exact, and callgrind
        # runs some 50 times slower than the hardware
        small = ig.gate_inputs()
        todo = [("first_hit", setup.surface, k) for k in kernels]
        ib = ig.measure(echo, root=base_build.root, inputs=small, todo=todo)
        ih = ig.measure(echo, root=head_build.root, inputs=small, todo=todo)
        for k in kernels:
            key = ig.key("first_hit", setup.surface, k)
            results[k].instructions = instruction_verdict(ib[key], ih[key])
    if "time" in setup.metrics:
        from .timing import pin_to_one_cpu

        pin_to_one_cpu()
        base_field = _on(base_build, "time", base_pkg.Field, inputs.heights)
        head_field = _on(head_build, "time", head_pkg.Field, inputs.heights)
        for k in kernels:
            echo(f"timing {k} (paired, at least {setup.repeats} pairs, at most "
                 f"{setup.budget:g} s) ...")
            run_b = _on(base_build, "time", _prepare, base_pkg, k, base_field, inputs, setup.surface)
            run_h = _on(head_build, "time", _prepare, head_pkg, k, head_field, inputs, setup.surface)
            logs, base_ns, head_ns = paired_times(run_b, run_h, setup)
            t = time_verdict(logs, setup.tolerance, setup.confidence)
            rays = len(inputs.o3)
            t.update(base_ns_per_ray=float(np.median(base_ns)) / rays,
                     head_ns_per_ray=float(np.median(head_ns)) / rays)
            results[k].time = t
    for r in results.values():
        r.verdict = _overall(r)
    status = 1 if any(r.verdict == "slower" for r in results.values()) else 0
    return dict(base=_describe(base_build), head=_describe(head_build),
                metrics=list(setup.metrics), surface=setup.surface, tolerance=setup.tolerance,
                instruction_tolerance=INSTRUCTION_TOLERANCE, confidence=setup.confidence,
                input=inputs.spec, hashes=inputs.hashes, toolchain=revisions.toolchain(),
                results=[r.__dict__ for r in results.values()], new_kernels=new, status=status)


def _on(build, metric, fn, *args):
    """``fn(*args)`` for one revision; its failure as one ``CompareError`` line naming the
    revision (an older tree whose API lacks what the measure needs, for instance)."""
    try:
        return fn(*args)
    except Exception as exc:
        raise CompareError(f"metric: {metric} cannot run on revision {build.label} ({build.short}): "
                           f"{type(exc).__name__}: {exc}") from exc


def _prepare(pkg, kernel, fld, inputs, surface):
    """The timed batch of one kernel of package ``pkg`` (its ``prepare_timed_intersect``)."""
    import importlib

    prepare = getattr(pkg, "prepare_timed_intersect", None) or \
        importlib.import_module(pkg.__name__ + ".intersect").prepare_timed_intersect
    run, _ = prepare(kernel, fld, inputs.o3, inputs.d3, surface=surface)
    return run


def _describe(b) -> dict:
    return dict(label=b.label, commit=b.commit, build=b.root)


def compare(repo: str, base: str, head: str | None, setup: Setup, echo=print) -> dict:
    """Build ``base`` and ``head`` (``None``: the working tree) of ``repo`` and compare them
    (:func:`measure`). ``CompareError``/``RevisionError`` on a user error."""
    setup.check()
    root = revisions.repo_root(repo)
    for revision in (base, head):  # both named revisions exist before either is built
        if revision is not None:
            revisions.resolve(root, revision)
    if head is None:
        # the working tree is the head: its registry is this process's, so a kernel or a
        # surface it does not have is refused before the builds (minutes), not after them
        import algos

        known = intersector_names(algos)
        unknown = [k for k in setup.kernels or () if k not in known]
        if unknown:
            what = "is not a C first-hit kernel" if len(unknown) == 1 else "are not C first-hit kernels"
            raise CompareError(f"kernels: {', '.join(map(repr, unknown))} {what} of the working "
                               f"tree (known: {', '.join(known)})")
        surfaces = sorted({sf for k in known for sf in algos.INTERSECTOR_REGISTRY[k].surfaces})
        if setup.surface not in surfaces:
            raise CompareError(f"surface: {setup.surface!r} is not a cell surface of the working "
                               f"tree (known: {', '.join(surfaces)})")
    b = revisions.build(repo, base, echo=echo)
    h = revisions.build(repo, head, echo=echo)
    return measure(b, h, revisions.load(b, "base"), revisions.load(h, "head"), setup, echo=echo)


def _fmt_pct(ratio) -> str:
    return f"{100 * (ratio - 1):+.2f} %"


def lines(report: dict) -> list[str]:
    """The text report: one line per kernel, its verdict word first after the name."""
    out = [f"base {report['base']['label']} ({report['base']['commit'][:10]})  head "
           f"{report['head']['label']} ({report['head']['commit'][:10]})  first_hit/{report['surface']}, "
           f"tolerance {100 * report['tolerance']:g} % (time), "
           f"{100 * report['instruction_tolerance']:g} % (instructions)"]
    for r in report["results"]:
        parts = []
        if r["time"]:
            t = r["time"]
            parts.append(f"time x{t['ratio']:.3f} [{t['low']:.3f}, {t['high']:.3f}] "
                         f"detectable {100 * t['detectable']:.1f} %")
        if r["instructions"]:
            i = r["instructions"]
            parts.append(f"instr/ray {i['base']:,.1f} -> {i['head']:,.1f} ({_fmt_pct(i['ratio'])}), "
                         f"branches/ray {i['branches_base']:,.1f} -> {i['branches_head']:,.1f}")
        if r["counters"]:
            c = r["counters"]
            parts.append("counters " + ("; ".join(c["changes"]) if c["changes"] else "identical"))
        out.append(f"{r['kernel']:14s} {r['verdict']:12s} " + " | ".join(parts))
    for k in report.get("new_kernels", []):
        out.append(f"{k:14s} {'new':12s} not in the base revision")
    slower = [r["kernel"] for r in report["results"] if r["verdict"] == "slower"]
    out.append(f"{len(slower)} kernel(s) slower" + (f": {', '.join(slower)}" if slower else ""))
    return out


def markdown(report: dict) -> str:
    """The GitHub job summary: one table row per kernel."""
    rows = ["### hftrace compare", "",
            f"base `{report['base']['commit'][:10]}` ({report['base']['label']}), head "
            f"`{report['head']['commit'][:10]}` ({report['head']['label']}); first hits on "
            f"{report['surface']}; tolerance {100 * report['tolerance']:g} %", "",
            "| kernel | verdict | time head/base [interval] | detectable | instructions/ray | counters |",
            "|---|---|---|---|---|---|"]
    for r in report["results"]:
        t, i, c = r["time"], r["instructions"], r["counters"]
        rows.append("| " + " | ".join([
            r["kernel"], f"**{r['verdict']}**",
            f"{t['ratio']:.3f} [{t['low']:.3f}, {t['high']:.3f}]" if t else "",
            f"{100 * t['detectable']:.1f} %" if t else "",
            f"{i['base']:,.0f} → {i['head']:,.0f}" if i else "",
            ("; ".join(c["changes"]) or "identical") if c else ""]) + " |")
    return "\n".join(rows) + "\n"


def publish(report: dict, json_path: str | None = None, echo=print) -> None:
    """Print the report; write ``json_path`` and, under GitHub Actions, append the job
    summary to ``$GITHUB_STEP_SUMMARY``."""
    for line in lines(report):
        echo(line)
    if json_path:
        from .timing import write_json

        write_json(json_path, report)
    summary = os.environ.get("GITHUB_STEP_SUMMARY")
    if summary:
        # the job summary is a copy for the reader: failing to write it must not turn a
        # verdict (exit 0 or 1) into an error
        try:
            with open(summary, "a") as f:
                f.write(markdown(report))
        except OSError as exc:
            print(f"warning: GITHUB_STEP_SUMMARY: cannot write {summary}: {exc.strerror or exc}",
                  file=sys.stderr)


def bisect(repo: str, good: str, bad: str, setup: Setup, echo=print) -> dict:
    """The first commit on the first-parent path from ``good`` to ``bad`` whose
    comparison with ``good`` has a slower kernel; about log2(K) builds for K commits.
    Returns ``{"first_bad": sha or None, "report": its comparison, "builds": n}``."""
    setup.check()
    repo = revisions.repo_root(repo)
    good_sha, bad_sha = revisions.resolve(repo, good), revisions.resolve(repo, bad)
    path = revisions.commits_between(repo, good_sha, bad_sha)
    if not path:
        raise CompareError(f"bisect: {bad!r} is not a descendant of {good!r} (no commits between)")
    g = revisions.build(repo, good_sha, echo=echo)
    g_pkg = revisions.load(g, "good")
    inputs = make_inputs(size=setup.size, first_hit_rays=setup.rays, traversal_rays=16, r=R, seed=SEED)
    reports, built = {}, [1]

    def regressed(index: int) -> bool:
        sha = path[index]
        if sha not in reports:
            b = revisions.build(repo, sha, echo=echo)
            built[0] += 1
            reports[sha] = measure(g, b, g_pkg, revisions.load(b, "probe"), setup, inputs, echo=echo)
            echo(f"bisect: {sha[:10]} {'bad' if reports[sha]['status'] else 'good'}")
        return reports[sha]["status"] == 1

    if not regressed(len(path) - 1):
        return dict(first_bad=None, report=reports[bad_sha], builds=built[0], commits=len(path))
    lo, hi = -1, len(path) - 1  # path[lo] good (good itself at -1), path[hi] bad
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if regressed(mid):
            hi = mid
        else:
            lo = mid
    return dict(first_bad=path[hi], report=reports[path[hi]], builds=built[0], commits=len(path))


def bisect_lines(result: dict, good: str, bad: str) -> list[str]:
    """``first bad commit: <sha>`` and the regressed kernels with their change (or that
    none regressed)."""
    if result["first_bad"] is None:
        return [f"no regression between {good} and {bad}: {bad} is not slower than {good} "
                f"({result['builds']} builds)"]
    out = [f"first bad commit: {result['first_bad']}"]
    for r in result["report"]["results"]:
        if r["verdict"] == "slower":
            what = []
            if r["time"] and r["time"]["verdict"] == "slower":
                what.append(f"time x{r['time']['ratio']:.3f}")
            if r["instructions"] and r["instructions"]["verdict"] == "slower":
                what.append(f"instructions/ray {_fmt_pct(r['instructions']['ratio'])}")
            if r["counters"] and r["counters"]["verdict"] == "slower":
                what.append("; ".join(r["counters"]["changes"]))
            out.append(f"  {r['kernel']}: {', '.join(what)}")
    out.append(f"({result['builds']} builds for {result['commits']} commits)")
    return out
