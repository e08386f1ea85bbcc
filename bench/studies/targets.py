"""``hftrace targets``: the table of the kernels' targets against their peers, every ratio from one run.

One process, pinned to one CPU (every contender single-threaded: our kernels, embreex's
loop, Embree's builder and the C Embree 3 peer), in one cache regime
(``bench.timing.REGIMES``; default ``warm``). Rows:

1. best exact kernel vs Embree, random azimuths (fbm 2048^2 and 8192^2 in the full tier);
2. best exact kernel vs Embree, a camera batch (``render``'s pinhole rays, 1280 x 720, its
   default camera) on Jacksboro 2048 and fbm 8192^2;
3. the packet traversal (registry name :data:`PACKET_KERNEL`) vs the per-ray
   ``dda_maxmip`` on the same camera rays;
4. ``runs_periodic`` vs ``runs`` on parallel first hits (orthographic rays of slope 1/r,
   r >= 5);
5. last-level cache misses per ray (callgrind's cache simulation) of the compact hierarchy
   (:data:`COMPACT_KERNEL`) vs today's (``dda_maxmip``) at 8192^2, random azimuths.

"Exact" kernels are the registry's strict intersectors (accuracy ``exact`` or ``float64``:
equal to the brute force to 1e-9 relative) other than peers; the best is the fastest in
the group. Embree is every configuration we can reach: embreex (single-ray triangle
queries only: its fastest configuration, ``algos.peers.embree.embree_timed``) and, where
built, the C Embree 3 peer (``algos.peers.embree3``: grid and triangle geometry, single
rays and every native packet width, coherent flag on camera and parallel batches); the
ratio is against the fastest of them, and every one is listed. A triangle mesh of a
field larger than ``embree_mesh_max_side`` is timed in its own interleaved pair with the
best exact kernel (one mesh in memory at a time); its ratio is the pair's.

A kernel the registry does not hold (the packet and compact kernels are built on other
branches) gives a row that says "not available"; the rest still runs. The command prints
the regime and ``os.getloadavg()`` before and after: on a shared machine the ratios are
indicative only.
"""
from __future__ import annotations

import csv
import math
import os
import time

import numpy as np

import algos
import datasets_gen
from algos.intersect import prepare_timed_intersect
from datasets_gen.rays import first_hit_rays

from ..sweep import hit_agreement
from ..timing import REGIMES, environment, pin_to_one_cpu, timed_in_regime, write_json

__all__ = ["run", "TIERS", "PACKET_KERNEL", "COMPACT_KERNEL", "PER_RAY_KERNEL", "COLUMNS"]

#: Registry names looked up for rows 3 and 5 (override with ``--packet-kernel`` and
#: ``--compact-kernel``); absent names give "not available".
PACKET_KERNEL = "packet_maxmip"
COMPACT_KERNEL = "dda_compact"
#: Today's per-ray hierarchy walk, the reference of rows 3 and 5.
PER_RAY_KERNEL = "dda_maxmip"
#: Targets from the issue (ratio >= target, except the misses: ratio <= target).
TARGETS = {"random": 3.0, "camera": 4.0, "packet": 2.0, "periodic": 1.3, "misses": 0.5}

#: Tiers: the fields and sizes of each row. ``quick`` checks that everything runs (tests);
#: ``full`` is the issue's table.
TIERS = {
    "quick": dict(random=(("fbm", 256),), camera=(("fbm", 256),), image=(96, 54), rays=1500,
                  repeats=3, parallel=("fbm", 256), run_lengths=(5, 25), cache=("fbm", 256),
                  cache_rays=100, embree_mesh_max_side=4096, judge=False),
    # the kernels and batches at 2048^2 only, a 640 x 360 image: about 15 minutes
    "medium": dict(random=(("fbm", 2048),), camera=(("jacksboro", 2048), ("fbm", 2048)),
                   image=(640, 360), rays=20000, repeats=5, parallel=("fbm", 2048),
                   run_lengths=(5, 25, 100), cache=("fbm", 2048), cache_rays=1000,
                   embree_mesh_max_side=4096),
    "full": dict(random=(("fbm", 2048), ("fbm", 8192)), camera=(("jacksboro", 2048), ("fbm", 8192)),
                 image=(1280, 720), rays=20000, repeats=7, parallel=("fbm", 2048),
                 run_lengths=(5, 25, 100), cache=("fbm", 8192), cache_rays=1000,
                 embree_mesh_max_side=4096),
}

COLUMNS = ("row", "measure", "setting", "ours", "ours_ns_per_ray", "theirs", "theirs_ns_per_ray",
           "ratio", "target", "status", "agree", "note", "regime", "load_before", "load_after")


def _load() -> str:
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "unavailable"


def _exact_names(surface="triangles"):
    return [n for n, a in algos.INTERSECTOR_REGISTRY.items()
            if a.kind not in ("peer", "plugin") and a.accuracy in ("exact", "float64")
            and surface in a.surfaces]


def embree_configs(coherent: bool):
    """(label, prepare(field, o, d) -> (run, t), is_mesh) of every Embree configuration
    this machine reaches: embreex (single ray, triangles) and the C peer's geometries and
    native packet widths."""
    from algos.peers import embree3 as embree3_peer
    from algos.peers.embree import embree_timed

    out = [("embreex triangles x1", lambda f, o, d: embree_timed(f, o, d, threads=1), True)]
    if embree3_peer.available():
        for geometry in ("grid", "triangles"):
            for width in embree3_peer.native_widths():
                flag = " coherent" if coherent and width > 1 else ""
                label = f"embree3 {geometry} x{width}{flag}"
                out.append((label, lambda f, o, d, g=geometry, w=width: embree3_peer.embree3_timed(
                    f, o, d, geometry=g, packet=w, coherent=coherent and w > 1, threads=1),
                    geometry == "triangles"))
    return out


def _per_ray(times, n):
    return {name: float(np.median(v)) / n for name, v in times.items()}


def _versus_embree(field, o, d, repeats, regime, mesh_max_side, coherent, echo):
    """Our exact kernels and every Embree configuration on the same rays: (ns per ray of
    ours, the best exact name, {embree label: (ns per ray, ratio embree/best)},
    agreement per name)."""
    reference = algos.intersect("runs", field, o, d, threads=1).t
    n = len(o)
    jobs, outs = {}, {}
    for name in _exact_names():
        jobs[name], outs[name] = prepare_timed_intersect(name, field, o, d)
    configs = embree_configs(coherent)
    big = max(field.heights.shape) > mesh_max_side
    alone = []
    for label, prepare, is_mesh in configs:
        if is_mesh and big:
            alone.append((label, prepare))
        else:
            jobs[label], outs[label] = prepare(field, o, d)
    times = timed_in_regime(jobs, repeats, regime)
    per = _per_ray(times, n)
    ours = {k: v for k, v in per.items() if k in algos.INTERSECTOR_REGISTRY}
    best = min(ours, key=ours.get)
    agree = {k: hit_agreement(outs[k](), reference, 1e-9 if k in ours else 1e-4) for k in jobs}
    embree = {k: (per[k], per[k] / per[best], (times[k], times[best])) for k in per
              if k not in ours}
    for label, prepare in alone:
        # one triangle mesh at a time, on a Field of its own freed after its pair
        own = algos.Field(field.heights)
        job, out = prepare(own, o, d)
        pair = timed_in_regime({best: jobs[best], label: job}, repeats, regime)
        p = _per_ray(pair, n)
        embree[label] = (p[label], p[label] / p[best], (pair[label], pair[best]))
        agree[label] = hit_agreement(out(), reference, 1e-4)
        del own, job, out
        echo(f"    {label}: {p[label]:.0f} ns/ray, in its pair with {best}")
    return ours, best, embree, agree


def _camera_rays(heights, width, height):
    from algos.render import default_camera
    from datasets_gen import rays as raysets

    position, look_at = default_camera(heights)
    rs = raysets.pinhole(position, look_at, 60.0, width, height)
    return rs.origins, rs.directions


def _status(ratio, target, smaller_is_better=False, paired=None):
    """met, missed, not measured or, for a timed ratio (``paired``: the numerator's and
    the denominator's per-repeat times), inconclusive when ``bench.analysis.finding``
    says so of its interval or the interval contains the target."""
    if not math.isfinite(ratio):
        return "not measured"
    if paired is not None:
        from ..analysis import finding
        from ..timing import log_ratio_interval

        geo, low, high = log_ratio_interval(*paired)
        said = finding(geo, low, high)
        if said.startswith("inconclusive"):
            return f"inconclusive ({said.split(': ', 1)[1]}; {geo:.2f} [{low:.2f}, {high:.2f}])"
        if low <= target <= high:
            return f"inconclusive (the interval [{low:.2f}, {high:.2f}] contains the target)"
    ok = ratio <= target if smaller_is_better else ratio >= target
    return "met" if ok else "missed"


def _embree_rows(row, measure, setting, ours, best, embree, agree, target, common):
    label = min(embree, key=lambda k: embree[k][1])
    ns, ratio, paired = embree[label]
    listing = "; ".join(f"{k} {v[0]:.0f} ns ({v[1]:.2f}x)" for k, v in sorted(embree.items()))
    note = (f"Embree's fastest configuration here: {label}. embreex reaches single-ray "
            f"triangle queries only; the C Embree 3 peer (grid, packets) is listed beside it "
            f"where built. All configurations: {listing}")
    return dict(common, row=row, measure=measure, setting=setting, ours=best,
                ours_ns_per_ray=round(ours[best], 2), theirs=label, theirs_ns_per_ray=round(ns, 2),
                ratio=round(ratio, 4), target=f">= {target}",
                status=_status(ratio, target, paired=paired),
                agree=f"{best} {agree[best]:.4f}; {label} {agree[label]:.4f}", note=note)


def _missing(row, measure, setting, name, target, common, why=None):
    return dict(common, row=row, measure=measure, setting=setting, ours=name, ours_ns_per_ray="",
                theirs="", theirs_ns_per_ray="", ratio="", target=target, status="not available",
                agree="", note=why or f"`{name}` is not registered (algos.INTERSECTOR_REGISTRY)")


def _load_field(name, side):
    return algos.Field(datasets_gen.load(name, size=side, seed=1).heights)


def run(out_dir="results/targets", tier="quick", regime="warm", seed=2008, counts=True,
        packet_kernel=PACKET_KERNEL, compact_kernel=COMPACT_KERNEL, echo=print) -> list[dict]:
    """Measure the targets table; write ``targets.csv``, ``targets.md`` and ``env.json`` to
    ``out_dir``, print the table and return its rows. ``counts``: the cache-miss row
    (callgrind; skipped with a "not measured" row when False or valgrind is missing)."""
    if tier not in TIERS:
        raise ValueError(f"tier: expected one of {', '.join(TIERS)}, got {tier!r}")
    if regime not in REGIMES:
        raise ValueError(f"regime: expected one of {', '.join(REGIMES)}, got {regime!r}")
    cfg = TIERS[tier]
    os.makedirs(out_dir, exist_ok=True)
    cpu = pin_to_one_cpu()
    load_before = _load()
    echo(f"targets ({tier} tier): one process, one thread pinned to CPU {cpu}, cache regime "
         f"'{regime}'; os.getloadavg() = {load_before}")
    env = dict(environment(), pinned_cpu=cpu, regime=regime, tier=tier, load_before=load_before)
    common = dict(regime=regime, load_before=load_before, load_after="")
    rows = []
    start = time.perf_counter()
    repeats, n = cfg["repeats"], cfg["rays"]
    mesh_max = cfg["embree_mesh_max_side"]

    # 1. random azimuths
    for name, side in cfg["random"]:
        field = _load_field(name, side)
        o, d = first_hit_rays(field, "random", n, seed)
        ours, best, embree, agree = _versus_embree(field, o, d, repeats, regime, mesh_max, False, echo)
        rows.append(_embree_rows(1, "best exact kernel vs Embree, random azimuths",
                                 f"{name} {side}^2, {n} rays", ours, best, embree, agree,
                                 TARGETS["random"], common))
        echo(f"  row 1 {name}{side}: done ({time.perf_counter() - start:.1f} s)")
        del field

    # 2 and 3. camera batches
    width, height = cfg["image"]
    for name, side in cfg["camera"]:
        field = _load_field(name, side)
        o, d = _camera_rays(field.heights, width, height)
        ours, best, embree, agree = _versus_embree(field, o, d, repeats, regime, mesh_max, True, echo)
        setting = f"{name} {side}^2, camera {width}x{height}"
        rows.append(_embree_rows(2, "best exact kernel vs Embree, camera batch", setting, ours,
                                 best, embree, agree, TARGETS["camera"], common))
        measure = f"packet traversal vs per-ray {PER_RAY_KERNEL}, same camera rays"
        if packet_kernel in algos.INTERSECTOR_REGISTRY:
            pair = {k: prepare_timed_intersect(k, field, o, d)
                    for k in (PER_RAY_KERNEL, packet_kernel)}
            times = timed_in_regime({k: v[0] for k, v in pair.items()}, repeats, regime)
            per = _per_ray(times, len(o))
            ratio = per[PER_RAY_KERNEL] / per[packet_kernel]
            same = bool(np.array_equal(pair[packet_kernel][1](), pair[PER_RAY_KERNEL][1]()))
            rows.append(dict(common, row=3, measure=measure, setting=setting, ours=packet_kernel,
                             ours_ns_per_ray=round(per[packet_kernel], 2), theirs=PER_RAY_KERNEL,
                             theirs_ns_per_ray=round(per[PER_RAY_KERNEL], 2), ratio=round(ratio, 4),
                             target=f">= {TARGETS['packet']}",
                             status=_status(ratio, TARGETS["packet"],
                                            paired=(times[PER_RAY_KERNEL], times[packet_kernel])),
                             agree=f"bit-identical t: {same}", note=""))
        else:
            rows.append(_missing(3, measure, setting, packet_kernel, f">= {TARGETS['packet']}", common))
        echo(f"  rows 2-3 {name}{side}: done ({time.perf_counter() - start:.1f} s)")
        del field

    # 4. runs_periodic vs runs, parallel first hits
    from datasets_gen.rays import orthographic_rays

    name, side = cfg["parallel"]
    field = _load_field(name, side)
    for r in cfg["run_lengths"]:
        o, d = orthographic_rays((side - 1, side - 1), r, n, seed, top=field.hmax)
        pair = {k: prepare_timed_intersect(k, field, o, d) for k in ("runs", "runs_periodic")}
        times = timed_in_regime({k: v[0] for k, v in pair.items()}, repeats, regime)
        per = _per_ray(times, len(o))
        ratio = per["runs"] / per["runs_periodic"]
        same = bool(np.array_equal(pair["runs"][1](), pair["runs_periodic"][1]()))
        rows.append(dict(common, row=4, measure="runs_periodic vs runs, parallel first hits",
                         setting=f"{name} {side}^2, r = {r}, {n} parallel rays", ours="runs_periodic",
                         ours_ns_per_ray=round(per["runs_periodic"], 2), theirs="runs",
                         theirs_ns_per_ray=round(per["runs"], 2), ratio=round(ratio, 4),
                         target=f">= {TARGETS['periodic']}",
                         status=_status(ratio, TARGETS["periodic"],
                                        paired=(times["runs"], times["runs_periodic"])),
                         agree=f"equal t: {same}", note=""))
    echo(f"  row 4: done ({time.perf_counter() - start:.1f} s)")
    del field

    # 5. last-level cache misses per ray (callgrind)
    rows.append(_misses_row(cfg, compact_kernel, seed, counts, common))
    echo(f"  row 5: done ({time.perf_counter() - start:.1f} s)")

    load_after = _load()
    for row in rows:
        row["load_after"] = load_after
        if not cfg.get("judge", True) and row["status"].startswith(("met", "missed", "inconclusive")):
            # the quick tier's fields fit in every cache and its counts are a handful:
            # it checks that each row runs, and judges no target
            row["status"] = f"not judged ({tier} tier)"
    env["load_after"] = load_after
    write_json(os.path.join(out_dir, "env.json"), env)
    with open(os.path.join(out_dir, "targets.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    text = _table(rows, env, tier, regime, load_before, load_after, counts)
    with open(os.path.join(out_dir, "targets.md"), "w") as f:
        f.write(text)
    echo(text)
    echo(f"os.getloadavg() after: {load_after}")
    return rows


def _misses_row(cfg, compact_kernel, seed, counts, common):
    from ..profile import callgrind_available, profile

    name, side = cfg["cache"]
    measure = f"LL cache misses per ray (callgrind), compact vs {PER_RAY_KERNEL}"
    setting = f"{name} {side}^2, random azimuths, {cfg['cache_rays']} rays"
    target = f"<= {TARGETS['misses']}"
    if compact_kernel not in algos.INTERSECTOR_REGISTRY:
        return _missing(5, measure, setting, compact_kernel, target, common)
    if not counts or not callgrind_available():
        why = "valgrind is not installed" if counts else "counts switched off (--no-counts)"
        return _missing(5, measure, setting, compact_kernel, target, common, why)
    misses = {}
    for kernel in (PER_RAY_KERNEL, compact_kernel):
        p = profile(kernel, dataset=name, size=side, r="random", rays=cfg["cache_rays"],
                    cache_sim=True, seed=seed)
        misses[kernel] = p["ll_misses"] / cfg["cache_rays"]
    ratio = misses[compact_kernel] / misses[PER_RAY_KERNEL] if misses[PER_RAY_KERNEL] else math.nan
    return dict(common, row=5, measure=measure, setting=setting, ours=compact_kernel,
                ours_ns_per_ray=f"{misses[compact_kernel]:.2f} misses", theirs=PER_RAY_KERNEL,
                theirs_ns_per_ray=f"{misses[PER_RAY_KERNEL]:.2f} misses", ratio=round(ratio, 4),
                target=target, status=_status(ratio, TARGETS["misses"], smaller_is_better=True),
                agree="", note="callgrind's simulated last-level cache, not ns")


def _table(rows, env, tier, regime, load_before, load_after, counts=True) -> str:
    lines = [f"# Targets, {tier} tier", "",
             f"One process, one thread pinned to CPU {env.get('pinned_cpu')}, cache regime "
             f"**{regime}** (docs/METHOD.md, \"Cache regimes\"); machine {env.get('cpu')}, "
             f"commit {env.get('git_commit')}; load averages (1, 5, 15 min) {load_before} "
             f"before, {load_after} after. Ratio = their ns/ray / our ns/ray (row 5: our "
             "misses / theirs). Every Embree figure: embreex reaches single-ray triangle "
             "queries only; the C Embree 3 peer (grid geometry, packets) is reported beside it "
             "where libembree-dev is installed.", "",
             "| # | measure | setting | ours | theirs | ratio | target | status |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ours = f"`{r['ours']}`" + (f" {_fmt(r['ours_ns_per_ray'])}" if r["ours_ns_per_ray"] != "" else "")
        theirs = (f"{r['theirs']} {_fmt(r['theirs_ns_per_ray'])}" if r["theirs"] else "")
        ratio = f"{float(r['ratio']):.2f}x" if r["ratio"] != "" else ""
        lines.append(f"| {r['row']} | {r['measure']} | {r['setting']} | {ours} | {theirs} | "
                     f"{ratio} | {r['target']} | {r['status']} |")
    lines += ["", "Notes:", ""]
    for r in rows:
        extra = "; ".join(x for x in (r["agree"] and f"agreement: {r['agree']}", r["note"]) if x)
        if extra:
            lines.append(f"- row {r['row']} ({r['setting']}): {extra}")
    lines += ["", "Command: `hftrace targets" + (f" --tier {tier}" if tier != "quick" else "")
              + (f" --regime {regime}" if regime != "warm" else "")
              + ("" if counts else " --no-counts") + "`", ""]
    return "\n".join(lines)


def _fmt(value):
    if isinstance(value, str):
        return value
    return f"{value:.0f} ns"
