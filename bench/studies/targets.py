"""``hftrace targets``: the table of the round's targets, our best exact kernel against
Embree on the same rays, one line per target.

Lines (the targets of the round; :data:`LINES` holds each line's wording, the figure
measured before the round, and its targets):

1. 4000 random rays (``datasets_gen.rays.first_hit_rays``: azimuths uniform, 5 to 20
   degrees down), fBm 2048^2, measured in ``processes`` fresh processes, since one run on
   a VM can move by 1.5x: the spread (min, median, max) of every ratio over the processes;
2. the same rays on fBm 4096^2 and 8192^2 (8192^2 in the ``full`` tier only);
3. a level camera, 640 x 360, 60 degrees, grazing (``bench.studies.plane_counts``'s view:
   every image column one vertical plane), fBm 2048^2;
4. a pitched pinhole, 640 x 360, 60 degrees, 2.6 degrees down (``bench.studies.
   pitched_counts``'s view), fBm 2048^2;
5. the horizon at 16 equal azimuths at every vertex of Jacksboro 2048, unlimited
   distance, one thread: seconds against the target
   (``bench.studies.terrain_azimuths``'s call).

Every row is measured in a process of its own (:mod:`bench.studies.targets_measure`),
pinned to one CPU, every contender single-threaded. For a ray row, every strict
intersector of the registry (accuracy ``exact`` or ``float64``: equal to the brute force
to 1e-9 relative, peers and plugins left out) and every Embree configuration reached are
timed side by side, interleaved, in both cache regimes of ``bench.timing.REGIMES``
(``timed_in_regime``), except the kernels a screening call finds ``SCREEN`` (3) times
slower than the fastest. In each regime the best exact kernel is the fastest of those
whose hits agree with the exact reference (``runs``) on every ray, so a kernel
registered later enters by itself. Embree is compared as two peers: embreex (single-ray triangle queries,
its fastest, ``algos.peers.embree.embree_timed``), and the C Embree 3 peer at its fastest
configuration in that regime (``algos.peers.embree3``: grid and triangle geometry, single
rays and every native packet width, the coherent flag on camera rays). The interleaved
repeats only select: the best exact kernel and each peer's fastest configuration. A ratio
(the peer's time over ours) is then measured afresh, in paired rounds of the two with the
peer as baseline (``bench.timing.paired_rounds``) until its interval is ``precision``
(2 %) wide on either side or ``confirm_budget_s`` is spent, and read as the median pair
with its distribution-free interval (``bench.timing.median_ratio_interval``). Selecting
and measuring on separate calls keeps out the winner's luck: the fastest of several
equal kernels on the same few repeats is the luckiest of them.

Counts: each contender (the best exact kernel, embreex and the C peer's fastest
configuration of the warm regime) runs once more in a process of its own under
``valgrind --tool=callgrind --cache-sim=yes`` (the fixed cache model of
``bench.studies.compact.CACHE``), on a subsample of the same rays, collecting only inside
our C batch entry or Embree's ``rtcIntersect`` calls (:mod:`bench.studies.targets_counts`):
instructions and last-level data misses per ray, after a flush (``flushed``) and right
after a call of its own (``warm``). A configuration valgrind cannot run (a packet width
it does not emulate, a triangle BVH whose build under valgrind outlasts the tier) is
replaced or skipped, and the row says so.

Status of a target: ``met`` when the whole evidence interval is on the target's side
(the paired interval of one process; with several processes, the range of their
ratios), ``missed`` when the whole of it is on the other side, ``inconclusive`` otherwise.
A line is met when all its targets are met in both regimes. The results are written as
each row finishes, and ``resume`` keeps the rows already measured.
"""
from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass

import numpy as np

from .targets_counts import row_counts
from .targets_measure import PEERS, SCREEN, _child_env, _jsonable

__all__ = ["run", "LINES", "ROWS", "TIERS", "COLUMNS", "judge", "line_status", "spread",
           "measure_row", "csv_rows", "table"]


@dataclass(frozen=True)
class Line:
    """One line of the targets table: the rays as the table words them, the figure
    measured before the round (``today``), and its targets: peer -> the smallest ratio
    (``"embreex"``, ``"embree3"``), or ``"seconds"`` -> the largest time."""

    number: int
    rays: str
    today: str
    targets: dict


LINES = (
    Line(1, "4000 random, fBm 2048^2",
         "1.15-1.41x embreex (this VM spreads 1.1-1.7x run to run)",
         {"embreex": 2.0, "embree3": 1.5}),
    Line(2, "4000 random, fBm 4096^2 and 8192^2",
         "1.40x at 4096^2, 0.95-1.15x at 8192^2 (`dda_maxmip`)", {"embreex": 2.0}),
    Line(3, "level camera, 640x360, grazing, fBm 2048^2", "0.68x (no such kernel yet)",
         {"embreex": 3.0, "embree3": 3.0}),
    Line(4, "pitched pinhole, 640x360, grazing (2.6 deg), fBm 2048^2", "0.64-0.72x",
         {"embreex": 1.2, "embree3": 1.2}),
    Line(5, "16 equal azimuths, Jacksboro 2048, 1 thread", "76.9 s", {"seconds": 20.0}),
)


@dataclass(frozen=True)
class Row:
    """One measured setting of a line: ``kind`` is ``random``, ``level``, ``pitched`` or
    ``horizon``; the field is ``dataset`` at the side the tier gives for ``key``."""

    key: str
    line: int
    kind: str
    dataset: str


ROWS = (
    Row("random2048", 1, "random", "fbm"),
    Row("random4096", 2, "random", "fbm"),
    Row("random8192", 2, "random", "fbm"),
    Row("level", 3, "level", "fbm"),
    Row("pitched", 4, "pitched", "fbm"),
    Row("horizon16", 5, "horizon", "jacksboro"),
)

#: Tiers. ``sides``: row key -> field side (a row absent from it is not measured in the
#: tier); ``rays``: random rays per row; ``image``: the cameras' width and height;
#: ``repeats``: interleaved repeats per regime; ``processes``: processes of line 1;
#: ``horizon_repeats``: timed calls of line 5; ``precision`` and ``confirm_budget_s``: when a
#: confirmation's paired rounds stop (``targets_measure.confirm``); ``count_rays``: about the rays counted
#: under callgrind, None for all (``targets_measure.counted_rays``); ``count_mesh_max_side``: the largest field whose
#: triangle BVHs are built under valgrind for the counts; ``mesh_max_side``: larger
#: triangle meshes are timed in a pair of their own with the best exact kernel (one mesh
#: in memory at a time); ``judge``: False in the quick tier (tiny fields fit in every
#: cache: it checks that every row runs); ``counts``: whether callgrind counts (minutes a
#: row, so not in the quick tier); ``kernels``/``peers``: None for every strict
#: intersector and both peers.
TIERS = {
    "quick": dict(sides=dict(random2048=64, random4096=96, level=64, pitched=64, horizon16=64),
                  rays=300, image=(32, 18), repeats=3, processes=2, horizon_repeats=1,
                  precision=0.02, confirm_budget_s=0.3,
                  count_rays=40, count_mesh_max_side=256, mesh_max_side=4096, judge=False, counts=False,
                  kernels=None, peers=None),
    # the targets' sizes but 8192^2: about 25 minutes on a quiet 2-core machine (23 min 23 s at 3d143b9)
    "medium": dict(sides=dict(random2048=2048, random4096=4096, level=2048, pitched=2048,
                              horizon16=2048),
                   rays=4000, image=(640, 360), repeats=7, processes=3, horizon_repeats=3,
                   precision=0.02, confirm_budget_s=8.0,
                   count_rays=None, count_mesh_max_side=1024, mesh_max_side=4096, judge=True, counts=True,
                   kernels=None, peers=None),
    "full": dict(sides=dict(random2048=2048, random4096=4096, random8192=8192, level=2048,
                            pitched=2048, horizon16=2048),
                 rays=4000, image=(640, 360), repeats=9, processes=5, horizon_repeats=3,
                 precision=0.02, confirm_budget_s=15.0,
                 count_rays=None, count_mesh_max_side=4096, mesh_max_side=4096, judge=True, counts=True,
                 kernels=None, peers=None),
}

#: Columns of targets.csv: one line per row, regime and peer (line 5: one per row).
COLUMNS = ("line", "row", "setting", "regime", "peer", "peer_config", "ours", "ours_ns_per_ray",
           "peer_ns_per_ray", "ratio", "low", "high", "processes", "spread_min",
           "spread_median", "spread_max", "target", "status", "ours_instructions_per_ray",
           "ours_ll_misses_per_ray", "peer_instructions_per_ray", "peer_ll_misses_per_ray",
           "note", "load_before", "load_after")


# ---- judging -------------------------------------------------------------------------------

def judge(low, high, target, smaller_is_better=False) -> str:
    """``met`` when the evidence interval ``[low, high]`` lies wholly on the target's side
    (``>= target``, or ``<= target`` when ``smaller_is_better``), ``missed`` when it lies
    wholly on the other side, ``inconclusive`` when it contains the target, and
    ``not measured`` when either end is missing (NaN or None)."""
    values = [low, high]
    if any(v is None or not math.isfinite(float(v)) for v in values):
        return "not measured"
    low, high = sorted(float(v) for v in values)
    if smaller_is_better:
        return "met" if high <= target else "missed" if low > target else "inconclusive"
    return "met" if low >= target else "missed" if high < target else "inconclusive"


def line_status(statuses) -> str:
    """One status for a line from the statuses of its targets: ``missed`` if any is
    missed, else ``inconclusive`` if any is, else ``met`` if at least one is met and the
    rest are met; a line without any judged target takes the first of its statuses
    (``not available``, ``not measured ...``, ``not judged ...``, ``failed ...``)."""
    statuses = list(statuses)
    if not statuses:
        return "not measured"
    judged = [s for s in statuses if s in ("met", "missed", "inconclusive")]
    if "missed" in judged:
        return "missed"
    if "inconclusive" in judged:
        return "inconclusive"
    if judged and len(judged) == len(statuses):
        return "met"
    if judged:  # some met, some not measured: say what is missing
        other = next(s for s in statuses if s not in judged)
        return f"met where measured; {other} elsewhere"
    return statuses[0]


def spread(values):
    """(min, median, max) of the finite values (NaNs when there is none)."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], np.float64)
    if len(v) == 0:
        return math.nan, math.nan, math.nan
    return float(v.min()), float(np.median(v)), float(v.max())


# ---- the parent: processes, gathering, tables ----------------------------------------------

def _run_child(row, side, cfg, seed):
    """Measure one row in a fresh ``python -m bench.studies.targets_measure`` process;
    its result dict (``{"error": ...}`` when the process failed)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "row.json")
        spec = dict(kind=row.kind, side=side, cfg=cfg, seed=seed, out=path)
        proc = subprocess.run([sys.executable, "-m", "bench.studies.targets_measure", "--child",
                               json.dumps(spec)], capture_output=True, text=True,
                              env=_child_env())
        if proc.returncode != 0 or not os.path.exists(path):
            return {"error": (proc.stderr or proc.stdout).strip()[-1500:] or
                    f"exit status {proc.returncode}"}
        with open(path) as f:
            return json.load(f)


def _processes(n) -> str:
    """The number of processes in words: 1 process, 3 processes."""
    return f"{n} process" + ("es" if n != 1 else "")


def _load() -> str:
    """``os.getloadavg()`` as text (1, 5 and 15 minutes), or "unavailable"."""
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "unavailable"


def _summarise_rays(line, runs, cfg):
    """Per regime and peer of a ray row: the ratios of every process, the evidence
    interval and the status against the line's target (None: no target for that peer)."""
    from ..timing import REGIMES

    ok = [r for r in runs if "error" not in r]
    out = {}
    peers = cfg.get("peers") or PEERS
    for regime in REGIMES:
        for peer in peers:
            entries = [r["regimes"][regime]["peers"].get(peer) for r in ok]
            entries = [e for e in entries if e]
            target = line.targets.get(peer)
            bests = [r["regimes"][regime]["best"] for r in ok]
            key = f"{regime}/{peer}"
            if not ok:
                out[key] = dict(status="failed", target=target)
                continue
            if not entries:
                why = ok[0]["missing"].get(peer) or (
                    "not available (no strict kernel agrees with the exact reference)"
                    if not any(bests) else "not available")
                out[key] = dict(status=why, target=target, ours=bests[0])
                continue
            ratios = [e["ratio"] for e in entries]
            lo, med, hi = spread(ratios)
            if len(entries) == 1:
                low, high = entries[0]["low"], entries[0]["high"]
            else:
                low, high = lo, hi
            status = ("no target" if target is None else judge(low, high, target)
                      if cfg["judge"] else f"not judged ({cfg.get('name', 'quick')} tier)")
            out[key] = dict(status=status, target=target, ratio=med, low=low, high=high,
                            spread=[lo, med, hi], processes=len(entries),
                            ours=_most_common(bests),
                            # ours beside the peer: from the same paired rounds as its ratio
                            ours_ns=float(np.median([
                                e["ours_ns"] if "ours_ns" in e else r["regimes"][regime]["ns"][b]
                                for r, b in zip(ok, bests)
                                for e in [r["regimes"][regime]["peers"].get(peer)] if e and b])),
                            config=_most_common([e["config"] for e in entries]),
                            peer_ns=float(np.median([e["ns"] for e in entries])))
    return out


def _most_common(names):
    names = [n for n in names if n]
    if not names:
        return None
    counts = {n: names.count(n) for n in names}
    best = max(counts, key=counts.get)
    return best if counts[best] == len(names) else f"{best} ({counts[best]}/{len(names)})"


def _summarise_horizon(line, run, cfg):
    if "error" in run:
        return {"seconds": dict(status="failed", target=line.targets["seconds"])}
    lo, med, hi = spread(run["seconds"])
    target = line.targets["seconds"]
    status = (judge(lo, hi, target, smaller_is_better=True) if cfg["judge"]
              else f"not judged ({cfg.get('name', 'quick')} tier)")
    return {"seconds": dict(status=status, target=target, seconds=med, spread=[lo, med, hi],
                            repeats=len(run["seconds"]))}


def measure_row(row, cfg, seed, processes, counts, echo=print) -> dict:
    """One row: its process(es), their summary and the counts; a JSON-ready dict."""
    side = cfg["sides"][row.key]
    line = LINES[row.line - 1]
    record = dict(key=row.key, line=row.line, side=side, load_before=_load())
    if row.kind == "horizon":
        run = _run_child(row, side, cfg, seed)
        record.update(runs=[run], setting=run.get("setting", ""),
                      summary=_summarise_horizon(line, run, cfg))
    else:
        n = processes if row.line == 1 else 1
        runs = []
        for k in range(n):
            echo(f"  {row.key}: process {k + 1} of {n}")
            runs.append(_run_child(row, side, cfg, seed))
        ok = [r for r in runs if "error" not in r]
        record.update(runs=runs, setting=ok[0]["setting"] if ok else "",
                      summary=_summarise_rays(line, runs, cfg))
        if counts and cfg["counts"] and ok:
            record["counts"] = row_counts(row.kind, side, cfg, seed, ok[0], echo)
        elif ok:
            record["counts"] = {"note": "counts switched off (--no-counts)" if not counts else
                                f"no counts in the {cfg.get('name')} tier (callgrind takes "
                                "minutes a row: the medium and full tiers count)"}
    errors = [r["error"] for r in record["runs"] if "error" in r]
    if errors:
        record["error"] = errors[0]
        echo(f"  {row.key}: FAILED: {errors[0][-500:]}")
    record["load_after"] = _load()
    return record


#: where ``hftrace targets`` writes by default, and with ``--publish``
DEFAULT_OUT, PUBLISH_OUT = "results/targets", "reports/targets"


def run(out_dir=DEFAULT_OUT, tier="quick", processes=None, seed=2008, counts=True,
        resume=False, only=None, echo=print) -> dict:
    """Measure the targets table; write ``targets.csv``, ``targets.json``,
    ``targets.md`` and ``env.json`` to ``out_dir`` after every row, and return the
    record (``rows``: key -> row record). ``processes``: processes of line 1 (default
    the tier's); ``only``: row keys to measure (default every row of the tier);
    ``resume``: keep the rows ``targets.json`` already holds."""
    from ..timing import environment

    if tier not in TIERS:
        raise ValueError(f"tier: expected one of {', '.join(TIERS)}, got {tier!r}")
    cfg = dict(TIERS[tier], name=tier)
    if processes is None:
        processes = cfg["processes"]
    if isinstance(processes, bool) or not isinstance(processes, int) or processes < 1:
        raise ValueError(f"processes: expected a positive integer, got {processes!r}")
    keys = [r.key for r in ROWS]
    for key in only or ():
        if key not in keys:
            raise ValueError(f"only: unknown row {key!r}; valid: {', '.join(keys)}")
        if key not in cfg["sides"]:
            raise ValueError(f"only: row {key!r} is not in the {tier} tier, whose rows are "
                             f"{', '.join(k for k in keys if k in cfg['sides'])} "
                             "(--tier full measures every row)")
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "targets.json")
    record = dict(tier=tier, processes=processes, seed=seed,
                  only=list(only) if only else None, out=out_dir, rows={})
    if resume and os.path.exists(path):
        with open(path) as f:
            previous = json.load(f)
        if previous.get("tier") != tier:
            raise ValueError(f"resume: {path} holds the {previous.get('tier')} tier, not {tier}")
        # the kept rows were measured with the previous settings: mixing them with other
        # ones would label those rows with settings they were not measured with
        for name, value in (("seed", seed), ("processes", processes)):
            if name in previous and previous[name] != value:
                raise ValueError(f"resume: {path} was measured with {name} "
                                 f"{previous[name]!r}, not {value!r}; give --{name} "
                                 f"{previous[name]} to resume it, or another --out")
        record["rows"] = {k: v for k, v in previous.get("rows", {}).items() if "error" not in v}
        # the table holds the rows of both runs: its command names them all (none when
        # either run measured the whole tier)
        before = previous.get("only")
        if record["only"] and before:
            record["only"] = [r.key for r in ROWS if r.key in record["only"] or r.key in before]
        else:
            record["only"] = None
    env = dict(environment(), tier=tier, processes=processes, load_before=_load())
    echo(f"targets ({tier} tier): one process per row pinned to one CPU, line 1 in "
         f"{_processes(processes)}; os.getloadavg() = {env['load_before']}")
    start = time.perf_counter()
    for row in ROWS:
        if row.key not in cfg["sides"] or (only and row.key not in only):
            continue
        if row.key in record["rows"]:
            echo(f"  {row.key}: kept from {path}")
            continue
        record["rows"][row.key] = measure_row(row, cfg, seed, processes, counts, echo)
        echo(f"  {row.key}: done ({time.perf_counter() - start:.0f} s)")
        _write(out_dir, record, env, cfg, counts)
    env["load_after"] = _load()
    env["seconds"] = round(time.perf_counter() - start, 1)
    text = _write(out_dir, record, env, cfg, counts)
    echo(text)
    echo(f"os.getloadavg() after: {env['load_after']}")
    return record


def _write(out_dir, record, env, cfg, counts):
    """targets.json, targets.csv, targets.md and env.json from what is measured so far."""
    from ..timing import write_json

    write_json(os.path.join(out_dir, "env.json"), env)
    with open(os.path.join(out_dir, "targets.json"), "w") as f:
        json.dump(record, f, indent=1, default=_jsonable)
    rows = csv_rows(record, cfg)
    with open(os.path.join(out_dir, "targets.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    text = table(record, env, cfg, counts)
    with open(os.path.join(out_dir, "targets.md"), "w") as f:
        f.write(text)
    return text


def _row_missing(row, cfg, record):
    """Why a row has no record: not in the tier, or not measured yet."""
    if row.key not in cfg["sides"]:
        return f"not measured ({record['tier']} tier; `--tier full`)"
    return "not measured yet"


def csv_rows(record, cfg):
    """The detail lines of targets.csv: one per row, regime and peer (line 5: one)."""
    out = []
    for row in ROWS:
        rec = record["rows"].get(row.key)
        base = dict(line=row.line, row=row.key)
        if rec is None:
            out.append(dict(base, status=_row_missing(row, cfg, record)))
            continue
        base.update(setting=rec.get("setting", ""), load_before=rec["load_before"],
                    load_after=rec["load_after"], note=rec.get("error", "")[-300:])
        for key, s in rec["summary"].items():
            line = dict(base, status=s["status"], target=_target_text(s.get("target"), key))
            if key == "seconds":
                if "spread" in s:  # seconds, not a ratio: the calls' median and range
                    line.update(ratio=_num(s["seconds"]), spread_min=_num(s["spread"][0]),
                                spread_median=_num(s["spread"][1]),
                                spread_max=_num(s["spread"][2]), processes=1)
                out.append(line)
                continue
            regime, peer = key.split("/")
            line.update(regime=regime, peer=peer, peer_config=s.get("config", ""),
                        ours=s.get("ours") or "", ours_ns_per_ray=_num(s.get("ours_ns")),
                        peer_ns_per_ray=_num(s.get("peer_ns")), ratio=_num(s.get("ratio")),
                        low=_num(s.get("low")), high=_num(s.get("high")),
                        processes=s.get("processes", ""))
            if "spread" in s:
                line.update(spread_min=_num(s["spread"][0]), spread_median=_num(s["spread"][1]),
                            spread_max=_num(s["spread"][2]))
            c = rec.get("counts", {})
            for who, prefix in (("ours", "ours"), (peer, "peer")):
                entry = c.get(who, {})
                if regime in entry:
                    line[f"{prefix}_instructions_per_ray"] = round(entry[regime]["instructions"], 1)
                    line[f"{prefix}_ll_misses_per_ray"] = round(entry[regime]["ll_misses"], 3)
            out.append(line)
    return out


def _num(value, digits=4):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    return round(float(value), digits)


def _target_text(target, key):
    if target is None:
        return ""
    return f"<= {target:g} s" if key == "seconds" else f">= {target:g}x"


def _ratio_text(s):
    if s.get("ratio") is None:
        return s["status"]
    text = f"{s['ratio']:.2f}x"
    if s.get("processes", 1) > 1:
        lo, med, hi = s["spread"]
        return f"{text} (min-median-max over {s['processes']} processes {lo:.2f}-{med:.2f}-{hi:.2f})"
    return f"{text} [{s['low']:.2f}, {s['high']:.2f}]"


def _measured_text(row, rec, cfg):
    """The "measured" cell of a row: the ratios per regime against each peer, or the
    seconds. A tier that judges nothing measures other sizes than the line names, so its
    cell starts with the row's own setting."""
    summary = rec["summary"]
    prefix = "" if cfg["judge"] else f"{rec.get('setting') or row.key}: "
    if "seconds" in summary:
        s = summary["seconds"]
        if "spread" not in s:
            return prefix + s["status"]
        lo, med, hi = s["spread"]
        return prefix + f"{med:.1f} s" + (f" (min-max {lo:.1f}-{hi:.1f}, {s['repeats']} calls)"
                                          if s["repeats"] > 1 else "")
    parts = []
    for regime in ("warm", "flushed"):
        peers = [f"{_ratio_text(s)} {k.split('/')[1]}" for k, s in summary.items()
                 if k.startswith(regime + "/")]
        parts.append(f"{regime}: " + ", ".join(peers))
    if not prefix and row.kind == "random" and row.line == 2:
        prefix = f"{cfg['sides'][row.key]}^2: "
    return prefix + "; ".join(parts)


def table(record, env, cfg, counts=True) -> str:
    """targets.md: the targets table (rays | today | measured | target | status), then
    the detail per row, regime and peer, with the counts."""
    tier = record["tier"]
    lines = [f"# Targets, {tier} tier", "",
             f"Our best exact kernel against Embree on the same rays, one CPU (pinned), one "
             f"thread, one process per row, in two cache regimes (flushed and warm, "
             f"docs/METHOD.md): {cfg['repeats']} interleaved repeats select our best kernel "
             f"and each peer's fastest configuration, then paired rounds of the two measure "
             f"the ratio afresh (median pair, distribution-free interval; until ±"
             f"{100 * cfg.get('precision', 0.02):g} % or {cfg.get('confirm_budget_s', 10):g} s); line 1 in "
             f"{_processes(record['processes'])} (min-median-max of the ratio). Ratio = "
             f"Embree's time / ours (> 1: we are faster); [95 % interval]. A name with (k/n) "
             f"was the selection in k of the n processes. Machine {env.get('cpu')}, commit "
             f"{env.get('git_commit')}; load averages (1, 5, 15 min) {env.get('load_before')} "
             f"before, {env.get('load_after', 'unfinished')} after. The targets' wording is "
             "the round's; a status is met only in both regimes and against every peer "
             "named." + ("" if cfg["judge"] else f" The {tier} tier measures tiny fields (the "
                         "detail gives each setting) and judges nothing."), "",
             "| rays | today | measured | target | status |", "|---|---|---|---|---|"]
    for line in LINES:
        rows = [r for r in ROWS if r.line == line.number]
        measured, statuses = [], []
        for row in rows:
            rec = record["rows"].get(row.key)
            if rec is None:
                why = _row_missing(row, cfg, record)
                measured.append(f"{row.key[len('random'):]}^2: {why}" if line.number == 2
                                else why)
                statuses.append(why)
                continue
            measured.append(_measured_text(row, rec, cfg))
            statuses += [s["status"] for s in rec["summary"].values() if s["status"] != "no target"]
        target = ", ".join(f"<= {v:g} s" if k == "seconds" else f">= {v:g}x {k}"
                           for k, v in line.targets.items())
        lines.append(f"| {line.rays} | {line.today} | {'<br>'.join(measured)} | {target} | "
                     f"{line_status(statuses)} |")
    lines += ["", "## Detail", "",
              "| row | regime | peer (fastest configuration) | ours | ours ns/ray | peer ns/ray "
              "| ratio | pairs (stop) | target | status | instructions / ray (ours, peer) "
              "| LL misses / ray (ours, peer) |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    notes = []
    for row in ROWS:
        rec = record["rows"].get(row.key)
        if rec is None or row.kind == "horizon":
            continue
        c = rec.get("counts", {})
        for key, s in rec["summary"].items():
            regime, peer = key.split("/")
            ours_c, peer_c = c.get("ours", {}).get(regime), c.get(peer, {}).get(regime)
            instr = " / ".join(f"{x['instructions']:.0f}" if x else "-" for x in (ours_c, peer_c))
            misses = " / ".join(f"{x['ll_misses']:.2f}" if x else "-" for x in (ours_c, peer_c))
            ns = (f"{s['ours_ns']:.0f}", f"{s['peer_ns']:.0f}") if "ours_ns" in s else ("", "")
            lines.append(f"| {rec['setting']} | {regime} | {peer} ({s.get('config', '-')}) | "
                         f"`{s.get('ours')}` | {ns[0]} | {ns[1]} | {_ratio_text(s)} | "
                         f"{_pairs_text(rec, regime, peer)} | "
                         f"{_target_text(s.get('target'), key)} | {s['status']} | {instr} | "
                         f"{misses} |")
        if c.get("ours", {}).get("contender"):
            notes.append(f"- {rec['setting']}: the counts of ours are "
                         f"`{c['ours']['contender']}`'s, in both regimes")
        for who, entry in c.items():
            if who == "note":
                notes.append(f"- {rec['setting']}: {entry}")
            elif entry.get("note"):
                notes.append(f"- {rec['setting']}, {who}: {entry['note']}")
        runs = [r for r in rec["runs"] if "error" not in r]
        if runs and runs[0].get("left_out"):
            notes.append(f"- {rec['setting']}: left out after a screening call {SCREEN:g}x "
                         "slower than the fastest (ns/ray): " + ", ".join(
                             f"{k} {v:.0f}" for k, v in sorted(runs[0]["left_out"].items())))
        if runs:
            bad = {k: v for k, v in runs[0]["agree"].items() if v < 1.0}
            if bad:
                notes.append(f"- {rec['setting']}: agreement with the exact reference below 1 "
                             "(a kernel below 1 is never the best; Embree, float32, within "
                             "1e-4): " + ", ".join(f"{k} {v:.4f}" for k, v in sorted(bad.items())))
        if rec.get("error"):
            notes.append(f"- {row.key}: failed: {rec['error'][-300:]}")
    if notes:
        lines += ["", "Notes:", ""] + notes
    lines_pairs = ("Pairs (stop): the paired rounds behind each process's ratio, and why "
                   "they stopped (`precision`: the interval reached the precision asked; "
                   "`budget`: the time budget was spent first; docs/METHOD.md).")
    which = ("every ray of the row" if cfg["count_rays"] is None else
             f"an even subsample of about {cfg['count_rays']} of the row's rays")
    lines += ["", lines_pairs, "", "Counts: callgrind's cache simulation (I1/D1 32 KiB 8-way, LL 8 MiB 16-way) on "
              f"{which}, collected inside our C batch entry or Embree's rtcIntersect calls "
              "only; flushed = after a cache flush, warm = right after its own call.", "",
              "Command: `" + command_line(record, cfg, counts) + "`", ""]
    return "\n".join(lines)


def _pairs_text(rec, regime, peer):
    """The paired rounds of one ratio, per process: "173 (precision)", or
    "173, 99, 120 (precision, budget, precision)" over several processes."""
    found = [r["regimes"][regime]["peers"][peer] for r in rec.get("runs", ())
             if "error" not in r and peer in r.get("regimes", {}).get(regime, {}).get("peers", {})]
    found = [f for f in found if "pairs" in f]
    if not found:
        return "-"
    return (", ".join(str(f["pairs"]) for f in found) + " ("
            + ", ".join(str(f.get("stop", "?")) for f in found) + ")")


def command_line(record, cfg, counts=True) -> str:
    """The ``hftrace targets`` command that reproduces ``record``: tier, processes,
    rows (``--only``), output directory (``--out``) and ``--no-counts`` as they were."""
    words = ["hftrace targets --tier", record["tier"]]
    if record["processes"] != cfg["processes"]:
        words.append(f"--processes {record['processes']}")
    if record.get("only"):
        words.append("--only " + ",".join(record["only"]))
    out = os.path.normpath(record.get("out") or DEFAULT_OUT)
    if out == os.path.normpath(PUBLISH_OUT):
        words.append("--publish")
    elif out != os.path.normpath(DEFAULT_OUT):
        words.append(f"--out {record['out']}")
    if not counts:
        words.append("--no-counts")
    return " ".join(words)
