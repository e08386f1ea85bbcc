"""Which cache regime the sweep needs: the same groups measured under several designs,
each design's speedups divided by those of the flushed design (docs/METHOD.md, "Cache
regimes compared").

Designs (``bench.sweep.measure_group`` with ``bench.timing.paired_rounds``):

* ``call-1000``: the caches flushed before every timed call of 1000 rays (the former
  design; the reference);
* ``round-1000``: flushed once per round of calls, 1000 rays;
* ``call-long``, ``round-long``, ``none-long``: calls of ``call_ms`` (rays doubled from
  1000 until the baseline's call lasts that long), flushed per call, per round, never;
* ``warm-1000``, ``warm-long``: each visit warm (``bench.timing.FLUSH_MODES``: an
  untimed call of the same kernel on the same rays before its timed calls), the sweep's
  default;
* ``big-none-long`` and ``big-warm-long`` against ``big-call-long``: a field larger than
  the last-level cache (fBm 4096^2, 64 MiB of heights) never flushed, or warm, against
  flushed per call.

Each group runs until every ratio is within ``precision`` or ``budget_s`` is spent. The
table gives, per design and kernel, the speedup over ``dda``, its half-width, the ratio
to the reference design's speedup (with the two half-widths added in quadrature), the
timed share of the group's wall time, and the load average. Run it on a quiet machine,
one core: ``taskset -c 1 python -m bench.studies.cache_regimes``. ``--paired SECONDS``
compares the designs side by side instead (:func:`paired_designs`): every meta-round
runs one round of each, so the load they share cancels in the comparison.
"""
from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time

import numpy as np

from .. import load as machine_load
from ..sweep import load_field, measure_group
from ..timing import environment, write_json

KERNELS = ["dda", "runs", "dda_maxmip", "embree"]
BIG_KERNELS = ["dda", "runs", "dda_maxmip"]
#: (design, flush, long calls, field): the reference first.
DESIGNS = [("call-1000", "call", False, "fbm1024"), ("round-1000", "round", False, "fbm1024"),
           ("warm-1000", "warm", False, "fbm1024"),
           ("call-long", "call", True, "fbm1024"), ("round-long", "round", True, "fbm1024"),
           ("none-long", "none", True, "fbm1024"), ("warm-long", "warm", True, "fbm1024"),
           ("big-call-long", "call", True, "fbm4096"), ("big-none-long", "none", True, "fbm4096"),
           ("big-warm-long", "warm", True, "fbm4096")]
REFERENCE = {"fbm1024": "call-1000", "fbm4096": "big-call-long"}
FIELDS = {"fbm1024": {"name": "fbm", "size": 1024, "seed": 1},
          "fbm4096": {"name": "fbm", "size": 4096, "seed": 1}}


def run(out_dir="results/cache_regimes", run_lengths=(5, "random"), precision=0.005,
        budget_s=5.0, call_ms=8.0, big=True, echo=print, fields=None, kernels=None) -> list:
    """Measure every design of :data:`DESIGNS` on fBm (1024^2, and 4096^2 with ``big``)
    for each run length; write ``regimes.csv``, ``regimes.md`` and ``env.json`` to
    ``out_dir`` and return the rows. ``fields`` (name -> dataset entry) and ``kernels``
    replace :data:`FIELDS` and the kernels (tests use small ones)."""
    os.makedirs(out_dir, exist_ok=True)
    fields = fields or FIELDS
    rows = []
    for field_name in ("fbm1024", "fbm4096") if big else ("fbm1024",):
        field = load_field(fields[field_name])
        chosen = kernels or (KERNELS if field_name == "fbm1024" else BIG_KERNELS)
        for r in run_lengths:
            long_rays = None  # sized by the first long design, then the same for the others
            for design, flush, long_calls, where in DESIGNS:
                if where != field_name:
                    continue
                load_before = machine_load.load_average()
                got = measure_group(field, field_name, "first_hit", "triangles", r, chosen,
                                    1000, 10, 2004, precision=precision, budget_s=budget_s,
                                    call_ms=call_ms, flush=flush,
                                    rays_per_call=long_rays if long_calls else 1000)
                if long_calls and long_rays is None:
                    long_rays = got[0]["call_rays"]
                for row in got:
                    rows.append({"field": field_name, "run_length": r, "design": design,
                                 "kernel": row["algorithm"], "call_rays": row["call_rays"],
                                 "rounds": row["rounds"], "speedup": row["speedup"],
                                 "half_width": row["half_width"],
                                 "timed_share": round(row["timed_s"] / row["wall_s"], 3),
                                 "flush_s": row["flush_s"], "wall_s": row["wall_s"],
                                 "other_cpu": row["other_cpu"], "load_before": load_before,
                                 "contended": row["contended"]})
                if echo:
                    echo(f"  {field_name} r={r} {design}: {got[0]['wall_s']:.1f} s")
        del field  # one field in memory at a time
    _relative(rows)
    with open(os.path.join(out_dir, "regimes.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    text = markdown(rows)
    with open(os.path.join(out_dir, "regimes.md"), "w") as f:
        f.write(text)
    write_json(os.path.join(out_dir, "env.json"),
               dict(environment(), load_after=machine_load.load_average()))
    if echo:
        echo(text)
    return rows


def _relative(rows):
    """Each row's speedup over its reference design's, same field, r and kernel."""
    ref = {(x["field"], str(x["run_length"]), x["kernel"]): x for x in rows
           if x["design"] == REFERENCE[x["field"]]}
    for x in rows:
        base = ref.get((x["field"], str(x["run_length"]), x["kernel"]))
        if base is None or x["kernel"] == "dda" or not base["speedup"]:
            x["vs_reference"], x["vs_half_width"] = "", ""
            continue
        x["vs_reference"] = round(x["speedup"] / base["speedup"], 4)
        x["vs_half_width"] = round(math.hypot(x["half_width"], base["half_width"]), 4)


def markdown(rows) -> str:
    """The comparison table: one line per (field, r, design), one column per kernel, each
    cell the speedup's ratio to the reference design's ±the combined half-width."""
    kernels = list(dict.fromkeys(x["kernel"] for x in rows if x["kernel"] != "dda"))
    head = ["field", "r", "design", "rays/call", "timed share", "load"] + kernels
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    keys = list(dict.fromkeys((x["field"], str(x["run_length"]), x["design"]) for x in rows))
    for key in keys:
        part = {x["kernel"]: x for x in rows if (x["field"], str(x["run_length"]), x["design"]) == key}
        any_row = next(iter(part.values()))
        cells = []
        for k in kernels:
            x = part.get(k)
            if x is None or x["vs_reference"] == "":
                cells.append("")
                continue
            cells.append(f"{x['vs_reference']:.3f} ±{100 * x['vs_half_width']:.1f} % "
                         f"({x['speedup']:.2f})")
        lines.append("| " + " | ".join([*key[:2], key[2], str(any_row["call_rays"]),
                                         f"{100 * any_row['timed_share']:.0f} %",
                                         f"{any_row['load_before']}"] + cells) + " |")
    return "\n".join(lines) + "\n"


#: The designs of :func:`paired_designs` (flush, long calls): the reference first.
PAIRED_DESIGNS = [("call-1000", "call", False), ("round-1000", "round", False),
                  ("call-long", "call", True), ("round-long", "round", True),
                  ("none-long", "none", True)]


def paired_designs(field, r, kernels, seconds=30.0, call_ms=8.0, seed=2004):
    """The designs of :data:`PAIRED_DESIGNS` compared side by side: every meta-round runs
    one round of every design (in a fresh random order), so a load that shifts over
    seconds hits every design alike, and the per-meta-round difference of a kernel's
    log-speedup between a design and the reference cancels it. Returns rows (design,
    kernel, ratio to the reference's speedup with its 95 % interval, meta-rounds,
    rays per call) after about ``seconds``."""
    from ..sweep import _group_rays, _prepare
    from ..timing import call_rays, flush_caches, log_ratio_interval

    rows_, cols_ = field.heights.shape
    shape = (cols_ - 1, rows_ - 1)
    if kernels[0] != "dda":
        raise ValueError(f"kernels: expected the baseline dda first, got {kernels[0]!r}")
    o, d, *_ = _group_rays(field, "first_hit", "triangles", r, 1000, seed)
    jobs = {False: {k: _prepare(k, "first_hit", field, o, d, shape, "triangles", "runs")[0]
                    for k in kernels}}
    probe = jobs[False][kernels[0]]
    probe()
    long_rays = call_rays(min(probe() for _ in range(5)), 1000, call_ms)
    o, d, *_ = _group_rays(field, "first_hit", "triangles", r, long_rays, seed)
    jobs[True] = {k: _prepare(k, "first_hit", field, o, d, shape, "triangles", "runs")[0]
                  for k in kernels}
    for group in jobs.values():  # warm-up: branch predictors, page faults
        for job in group.values():
            job()
    rng = np.random.Generator(np.random.PCG64(seed))
    logs = {name: {k: [] for k in kernels} for name, *_ in PAIRED_DESIGNS}
    start, meta = time.perf_counter(), 0
    while time.perf_counter() - start < seconds or meta < 10:
        for index in rng.permutation(len(PAIRED_DESIGNS)):
            name, flush, long_calls = PAIRED_DESIGNS[index]
            group = jobs[long_calls]
            if flush == "round":
                flush_caches()
            got = {}
            for k in (kernels[j] for j in rng.permutation(len(kernels))):
                if flush == "call":
                    flush_caches()
                got[k] = float(group[k]())
            for k in kernels:
                logs[name][k].append(math.log(got[kernels[0]]) - math.log(got[k]))
        meta += 1
    reference = PAIRED_DESIGNS[0][0]
    out = []
    for name, _, long_calls in PAIRED_DESIGNS:
        for k in kernels[1:]:
            # exp(mean of the differences of log-speedups) and its t interval
            diff = np.exp(np.asarray(logs[name][k]) - np.asarray(logs[reference][k]))
            ratio, low, high = log_ratio_interval(diff, np.ones_like(diff))
            out.append({"r": r, "design": name, "kernel": k, "vs_reference": round(ratio, 4),
                        "low": round(low, 4), "high": round(high, 4), "meta_rounds": meta,
                        "call_rays": long_rays if long_calls else 1000,
                        "speedup": round(float(np.exp(np.mean(logs[name][k]))), 4)})
    return out


def paired_markdown(rows) -> str:
    """The side-by-side comparison: one line per (r, design), one column per kernel, each
    cell the ratio of the design's speedup to the reference's ±its 95 % half-width."""
    kernels = list(dict.fromkeys(x["kernel"] for x in rows))
    head = ["r", "design", "rays/call", "meta-rounds"] + kernels
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for key in dict.fromkeys((str(x["r"]), x["design"]) for x in rows):
        part = {x["kernel"]: x for x in rows if (str(x["r"]), x["design"]) == key}
        first = next(iter(part.values()))
        cells = [f"{x['vs_reference']:.3f} ±{100 * (x['high'] - x['low']) / 2 / x['vs_reference']:.1f} %"
                 for x in (part[k] for k in kernels)]
        lines.append("| " + " | ".join([*key, str(first["call_rays"]), str(first["meta_rounds"])]
                                        + cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """``python -m bench.studies.cache_regimes [--out DIR] [--budget S] [--no-big]``."""
    p = argparse.ArgumentParser(prog="python -m bench.studies.cache_regimes",
                                description="compare the cache regimes of the sweep's design")
    p.add_argument("--out", default="results/cache_regimes")
    p.add_argument("--budget", type=float, default=5.0, help="seconds per group and design")
    p.add_argument("--no-big", action="store_true", help="skip the 4096^2 field")
    p.add_argument("--paired", type=float, default=0.0, metavar="SECONDS",
                   help="instead, the designs side by side in shared meta-rounds for this "
                        "many seconds per run length (fBm 1024^2)")
    args = p.parse_args(argv)
    if not args.budget > 0:
        raise SystemExit(f"--budget: expected a positive number of seconds, got {args.budget}")
    if args.paired < 0:
        raise SystemExit(f"--paired: expected a number of seconds >= 0, got {args.paired}")
    if args.paired:
        os.makedirs(args.out, exist_ok=True)
        field = load_field(FIELDS["fbm1024"])
        load_before = machine_load.load_average()
        rows = [row for r in (5, "random")
                for row in paired_designs(field, r, KERNELS, seconds=args.paired)]
        text = paired_markdown(rows)
        with open(os.path.join(args.out, "paired.md"), "w") as f:
            f.write(text)
        write_json(os.path.join(args.out, "paired.json"),
                   dict(environment(), rows=rows, load_before=load_before,
                        load_after=machine_load.load_average()))
        print(text + f"load average {load_before} before, {machine_load.load_average()} after")
        return 0
    run(out_dir=args.out, budget_s=args.budget, big=not args.no_big)
    return 0


if __name__ == "__main__":
    sys.exit(main())
