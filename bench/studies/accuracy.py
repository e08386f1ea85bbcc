"""``hftrace accuracy``: run time against error for every algorithm.

Traversal error. Rays whose origin and direction components are multiples of 2^-16
(|d| < 2^15) are left unchanged by the exact kernels' lattice, so the exact walk
(``midpoint``; ``runs`` is checked to equal it) *is* ``reference_cells`` of the very ray
the float kernels see, and long rays can be checked at scale. For each algorithm and ray
length N: the fraction of rays whose first N cells differ from the exact sequence, the
median index of the first divergence among those, and the cells missed and extra (set
differences over the first N cells). ``runs_periodic`` is measured at Q = 2^4, 2^8,
2^12 and 2^16 on generic slopes (its exact case, q <= Q, is tested elsewhere).

First-hit error. Against the float64 brute force (``algos.brute_force_hits``) on a
smaller field: hit/miss disagreement and the |dt| distribution (median, p99, max) of
every intersector, with ray marching at 16 to 1024 steps; for ``triangles`` also against
an exact rational evaluation (``exact_triangle_hits``) on a subset.

Writes ``traversal.csv``, ``first_hit.csv``, ``time_vs_error.png`` (log axes, Pareto
front marked) and ``accuracy.md`` to the output directory.
"""
from __future__ import annotations

import math
import os
from fractions import Fraction

import numpy as np

import algos
import datasets_gen
from datasets_gen import rays as raysets

from ..report import RowWriter
from ..timing import environment, write_json

LATTICE = 2.0**-16


def lattice_rays(n, side, seed):
    """Generic rays exactly on the 2^-16 lattice, from inside a side x side grid
    (``datasets_gen.rays.isotropic``); (origins, directions) of shape (n, 2)."""
    rs = raysets.isotropic(n, (side, side), seed, snap=LATTICE)
    return rs.origins, rs.directions


def _first_divergence(a, b):
    n = min(len(a), len(b))
    diff = np.nonzero(np.any(a[:n] != b[:n], axis=1))[0]
    if len(diff):
        return int(diff[0])
    return n if len(a) != len(b) else -1


def traversal_rows(side, n_rays, lengths, seed, q_values):
    """Traversal accuracy on ``n_rays`` lattice rays of a side x side grid: per kernel (and
    ``runs_periodic`` per ``max_denominator`` in ``q_values``) and per prefix length in
    ``lengths``, the fraction of rays whose first cells diverge from the exact ``midpoint``
    walk, the median index of the first divergence, cells missed and extra per ray, and
    ns per ray. AssertionError when the two exact kernels disagree."""
    o, d = lattice_rays(n_rays, side, seed)
    shape = (side, side)
    exact = algos.traverse("midpoint", o, d, shape)
    check = algos.traverse("runs", o, d, shape)
    if not (np.array_equal(exact.cells, check.cells) and np.array_equal(exact.offsets, check.offsets)):
        raise AssertionError("midpoint and runs disagree on lattice rays: an exact kernel is wrong")
    variants = [(name, {}) for name in algos.TRAVERSALS if name != "runs_periodic"]
    variants += [("runs_periodic", {"max_denominator": q}) for q in q_values]
    rows = []
    for name, opts in variants:
        got = algos.traverse(name, o, d, shape, **opts)
        run, _ = algos.prepare_timed(name, o, d, shape, "visit", **opts)
        run()
        ns = float(np.median([run() for _ in range(5)])) / n_rays
        label = name if not opts else f"{name}[Q=2^{int(math.log2(opts['max_denominator']))}]"
        for n_cells in lengths:
            diverged, first, missed, extra = 0, [], 0, 0
            for k in range(n_rays):
                a = exact[k][:n_cells]
                b = got[k][:n_cells]
                f = _first_divergence(a, b)
                if f >= 0:
                    diverged += 1
                    first.append(f)
                    sa = {tuple(c) for c in a.tolist()}
                    sb = {tuple(c) for c in b.tolist()}
                    missed += len(sa - sb)
                    extra += len(sb - sa)
            rows.append(dict(algorithm=label, grid=f"{side}x{side}", rays=n_rays, cells=n_cells,
                             diverged_fraction=diverged / n_rays,
                             first_divergence_median=float(np.median(first)) if first else math.nan,
                             cells_missed_per_ray=missed / n_rays,
                             cells_extra_per_ray=extra / n_rays, ns_per_ray=round(ns, 2),
                             exact=algos.TRAVERSAL_REGISTRY[name].exact))
    return rows


# ---- exact rational first hits on triangles ---------------------------------------------
def exact_triangle_hits(H, origins, directions):
    """First hits on ``triangles`` in exact rational arithmetic: the exact cell sequence
    of each ray (``reference_cells``), and in each cell the exact root of the piecewise
    linear gap on its two triangles. Slow; for a subset."""
    rows, cols = H.shape
    out = np.full(len(origins), np.inf)
    for k, (o, d) in enumerate(zip(origins, directions)):
        of = [Fraction(float(v)) for v in o]
        df = [Fraction(float(v)) for v in d]
        cells = algos.reference_cells(o[:2], d[:2], (cols - 1, rows - 1), 0.0, math.inf)
        best = None
        for i, j in cells:
            h00, h10 = Fraction(float(H[j, i])), Fraction(float(H[j, i + 1]))
            h01, h11 = Fraction(float(H[j + 1, i])), Fraction(float(H[j + 1, i + 1]))
            lo, hi = Fraction(0), None
            for axis, c in ((0, i), (1, j)):
                if df[axis] != 0:
                    a, b = (c - of[axis]) / df[axis], (c + 1 - of[axis]) / df[axis]
                    a, b = min(a, b), max(a, b)
                    lo = max(lo, a)
                    hi = b if hi is None else min(hi, b)
            if hi is None or lo > hi:
                continue
            pts = [lo, hi]
            w = df[0] - df[1]
            if w != 0:
                ts = ((i - j) - (of[0] - of[1])) / w
                if lo < ts < hi:
                    pts = [lo, ts, hi]

            def gap(t):
                u = of[0] + t * df[0] - i
                v = of[1] + t * df[1] - j
                s = (h00 + (h10 - h00) * u + (h11 - h10) * v) if u >= v else \
                    (h00 + (h11 - h01) * u + (h01 - h00) * v)
                return of[2] + t * df[2] - s

            g0 = gap(pts[0])
            if g0 <= 0:
                best = pts[0]
                break
            found = None
            for a, b in zip(pts, pts[1:]):
                ga, gb = gap(a), gap(b)
                if ga > 0 and gb <= 0:
                    # the gap is linear on [a, b] (one triangle): the exact root
                    found = a + (b - a) * ga / (ga - gb)
                    break
            if found is not None:
                best = found
                break
        if best is not None:
            out[k] = float(best)
    return out


def first_hit_rows(side, n_rays, seed, n_exact, march_steps):
    """First-hit accuracy on an fBm field of ``side``: per intersector (and the marchers per
    step count in ``march_steps``) and surface, ns per ray and hit/miss and t disagreement
    against the exact ``runs`` kernel, plus on triangles the disagreement with the
    rational-arithmetic hits of the first ``n_exact`` rays."""
    H = datasets_gen.load("fbm", size=side, seed=seed, scale=side / 8, amplitude=side / 16).heights
    field = algos.Field(H)
    rng = np.random.Generator(np.random.PCG64(seed))
    phi = rng.uniform(0, 2 * np.pi, n_rays)
    elev = np.radians(rng.uniform(5, 30, n_rays))
    o = np.column_stack([rng.uniform(0, side - 1, (n_rays, 2)), np.full(n_rays, float(H.max()) + 1)])
    d = np.column_stack([np.cos(phi) * np.cos(elev), np.sin(phi) * np.cos(elev), -np.sin(elev)])
    rows = []
    variants = [(n, {}) for n in algos.INTERSECTORS if not n.startswith("march_")]
    for steps in march_steps:
        variants += [("march_linear", {"march_steps": steps}), ("march_binary", {"march_steps": steps})]
    variants += [("march_growing", {})]
    exact_t = exact_triangle_hits(H, o[:n_exact], d[:n_exact]) if n_exact else None
    for surface in algos.SURFACES:
        ref, _ = algos.brute_force_hits(H, o, d, surface)
        for name, opts in variants:
            if surface not in algos.INTERSECTOR_REGISTRY[name].surfaces:
                continue
            from algos.intersect import prepare_timed_intersect

            run, result = prepare_timed_intersect(name, field, o, d, surface=surface, **opts)
            run()
            ns = float(np.median([run() for _ in range(5)])) / n_rays
            t = result()
            hit, ref_hit = np.isfinite(t), np.isfinite(ref)
            both = hit & ref_hit
            dt = np.abs(t[both] - ref[both])
            label = name + "".join(f"[{k.replace('march_', '')}={v}]" for k, v in opts.items())
            row = dict(algorithm=label, surface=surface, rays=n_rays, ns_per_ray=round(ns, 2),
                       hit_miss_disagree=float(np.mean(hit != ref_hit)),
                       dt_median=float(np.median(dt)) if dt.size else math.nan,
                       dt_p99=float(np.percentile(dt, 99)) if dt.size else math.nan,
                       dt_max=float(dt.max()) if dt.size else math.nan,
                       accuracy=algos.INTERSECTOR_REGISTRY[name].accuracy)
            if surface == "triangles" and exact_t is not None:
                te = exact_t
                tk = t[:n_exact]
                ok = np.isfinite(te) & np.isfinite(tk)
                row["exact_subset_disagree"] = float(np.mean(np.isfinite(te) != np.isfinite(tk)))
                row["exact_subset_dt_max"] = float(np.max(np.abs(tk[ok] - te[ok]))) if ok.any() else math.nan
            rows.append(row)
    return rows


def pareto(points):
    """Indices of the points (time, error) not dominated by another."""
    keep = []
    for i, (t, e) in enumerate(points):
        if not any((t2 <= t and e2 <= e) and (t2 < t or e2 < e) for j, (t2, e2) in enumerate(points) if j != i):
            keep.append(i)
    return keep


def plot_time_vs_error(first_hit, path):
    """The time-against-error figure of the ``first_hit`` rows (triangles): ns per ray
    against the error (99th percentile |dt| plus the hit/miss disagreement, floored at
    1e-17 for the log axis), the Pareto front marked; PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in first_hit if r["surface"] == "triangles"]
    floor = 1e-17
    pts = [(r["ns_per_ray"], max(r["dt_p99"] if np.isfinite(r["dt_p99"]) else 1.0, floor) +
            r["hit_miss_disagree"]) for r in rows]
    front = set(pareto(pts))
    fig, ax = plt.subplots(figsize=(8, 5), dpi=120)
    for i, (r, (x, y)) in enumerate(zip(rows, pts)):
        ax.scatter(x, y, s=40 if i in front else 15, c="C3" if i in front else "C0",
                   edgecolors="k" if i in front else "none", zorder=3)
        ax.annotate(r["algorithm"], (x, y), fontsize=6, xytext=(3, 2), textcoords="offset points")
    xs = sorted((pts[i] for i in front))
    ax.plot([p[0] for p in xs], [p[1] for p in xs], "C3--", lw=1, label="Pareto front")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("ns per ray (first hit, triangles)")
    ax.set_ylabel(f"error: p99 |dt| + hit/miss disagreement (floor {floor:g})")
    ax.set_title("time against error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _md_table(rows, columns):
    lines = ["| " + " | ".join(columns) + " |", "|---" * len(columns) + "|"]
    for r in rows:
        cells = []
        for c in columns:
            v = r.get(c, "")
            if isinstance(v, float):
                v = f"{v:.3g}" if np.isfinite(v) else "-"
            cells.append(str(v))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def run(out_dir="results/accuracy", full=False, echo=print):
    """Both tables and the figure (``full``: larger grids, more rays) into ``out_dir``:
    traversal.csv, first_hit.csv, time_vs_error.png, accuracy.md and env.json."""
    os.makedirs(out_dir, exist_ok=True)
    env = environment()
    write_json(os.path.join(out_dir, "env.json"), env)
    if full:
        side, n2, lengths, n3, side3, n_exact = 4096, 4000, (64, 256, 1024, 4096), 2000, 256, 60
    else:
        side, n2, lengths, n3, side3, n_exact = 2048, 1500, (64, 256, 1024, 2048), 600, 128, 25
    q_values = (2**4, 2**8, 2**12, 2**16)
    march = (16, 64, 256, 1024)
    trav = traversal_rows(side, n2, lengths, 11, q_values)
    with RowWriter(os.path.join(out_dir, "traversal.csv"), list(trav[0])) as w:
        for r in trav:
            w.write(r)
    echo(f"traversal: {len(trav)} rows")
    hits = first_hit_rows(side3, n3, 5, n_exact, march)
    cols = sorted({k for r in hits for k in r}, key=lambda k: list(hits[0]).index(k) if k in hits[0] else 99)
    with RowWriter(os.path.join(out_dir, "first_hit.csv"), cols) as w:
        for r in hits:
            w.write(r)
    echo(f"first hits: {len(hits)} rows")
    plot_time_vs_error(hits, os.path.join(out_dir, "time_vs_error.png"))
    longest = max(lengths)
    text = ["# hftrace accuracy: time against error", "",
            f"Machine: {env['cpu']}, commit `{env['git_commit']}`. Method: bench/studies/accuracy.py.", "",
            f"## Traversal: {n2} generic lattice rays on {side}x{side}, first N cells", "",
            _md_table([r for r in trav if r["cells"] == longest],
                      ["algorithm", "exact", "cells", "diverged_fraction", "first_divergence_median",
                       "cells_missed_per_ray", "cells_extra_per_ray", "ns_per_ray"]), "",
            "Divergence by ray length:", "",
            _md_table(trav, ["algorithm", "cells", "diverged_fraction"]), "",
            f"## First hits: {n3} rays on fBm {side3}^2 against the float64 brute force", ""]
    for surface in algos.SURFACES:
        part = [r for r in hits if r["surface"] == surface]
        columns = ["algorithm", "accuracy", "ns_per_ray", "hit_miss_disagree", "dt_median", "dt_p99", "dt_max"]
        if surface == "triangles":
            columns += ["exact_subset_disagree", "exact_subset_dt_max"]
        text += [f"### {surface}", "", _md_table(part, columns), ""]
    text += ["![time vs error](time_vs_error.png)", ""]
    with open(os.path.join(out_dir, "accuracy.md"), "w") as f:
        f.write("\n".join(text))
    echo("\n".join(text[:12]))
    return trav, hits
