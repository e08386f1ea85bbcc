"""``hftrace stress``: adversarial rays and very long rays.

* Adversarial 2D families (``datasets_gen.rays.adversarial``): every traversal against
  ``reference_cells``: of the lattice-rounded ray for exact kernels (their contract), of
  the caller's float ray for float kernels (what a user gets).
* Long rays: N = 2^10 ... 2^20 cells on a 2^20 x 2^20 grid, origins near (2^16, 2^16)
  where float32 resolves only about 0.004 cell, generic directions on the 2^-16 lattice
  (so the exact walk is the truth for every kernel; ``runs`` is checked against
  ``midpoint`` on every ray). The drift table gives the percentage of rays whose first N
  cells differ from the exact walk, per algorithm and precision, and the exact kernels'
  time against the float32 DDA on the same rays.
* First-hit families on a terraced field full of equal heights: grazing rays at exactly
  a terrace level, rays starting below the surface, rays entering through the sides:
  every intersector against the brute force.

Writes ``drift.csv``, ``families.csv``, ``first_hit.csv`` and ``stress.md``.
"""
from __future__ import annotations

import math
import os

import numpy as np

import algos
import datasets_gen
from datasets_gen import rays as raysets

from ..report import RowWriter
from ..timing import environment, write_json

SIDE = 2**20
LATTICE = 2.0**-16


def family_rows(shape, n, seed):
    """Per adversarial family (``datasets_gen.rays.adversarial`` on ``shape``, ``n`` rays)
    and traversal: how many rays' cells differ from ``reference_cells`` (of the quantized
    ray for exact kernels, of the float ray for float kernels)."""
    rows = []
    for family, rs in raysets.adversarial(shape, seed, n=n).items():
        oq, dq = algos.quantize(rs.origins, rs.directions)
        truth_exact = [algos.reference_cells(oq[k], dq[k], shape) for k in range(len(rs))]
        truth_float = [algos.reference_cells(rs.origins[k], rs.directions[k], shape) for k in range(len(rs))]
        for name, entry in algos.TRAVERSAL_REGISTRY.items():
            got = algos.traverse(name, rs.origins, rs.directions, shape)
            truth = truth_exact if entry.precision == "exact" else truth_float
            bad = sum(1 for k in range(len(rs))
                      if [tuple(c) for c in got[k].tolist()] != truth[k])
            rows.append(dict(family=family, algorithm=name, precision=entry.precision,
                             rays=len(rs), differ=bad, differ_fraction=bad / len(rs)))
    return rows


def long_rays(n, seed):
    """Rays on the 2^-16 lattice with origins in [2^16, 2^16 + 64)^2, far from the grid's
    origin (``datasets_gen.rays.isotropic``); (origins, directions) of shape (n, 2)."""
    rs = raysets.isotropic(n, (64, 64), seed, offset=2.0**16, snap=LATTICE)
    return rs.origins, rs.directions


def drift_rows(lengths, seed):
    """Per length N in ``lengths`` and traversal: the percentage of long rays
    (:func:`long_rays`) whose first N cells differ from the exact walk, the median first
    divergence, and ns per ray against ``dda_f32``. AssertionError when ``runs`` and
    ``midpoint`` disagree."""
    rows = []
    shape = (SIDE, SIDE)
    for n_cells in lengths:
        n = int(max(8, min(400, 2**22 // n_cells)))
        o, d = long_rays(n, seed + n_cells)
        # tmax ends each ray after about n_cells cells (|dx| + |dy| cells per unit t)
        tmax = n_cells / np.abs(d).sum(axis=1)
        exact = algos.traverse("midpoint", o, d, shape, tmax=tmax)
        check = algos.traverse("runs", o, d, shape, tmax=tmax)
        if not np.array_equal(exact.cells, check.cells):
            raise AssertionError(f"runs differs from midpoint on long rays (N={n_cells})")
        times = {}
        for name in ("dda_f32", "dda", "midpoint", "runs"):
            run, _ = algos.prepare_timed(name, o, d, shape, "visit", tmax=tmax)
            run()
            times[name] = float(np.median([run() for _ in range(3)]))
        for name, entry in algos.TRAVERSAL_REGISTRY.items():
            got = exact if name == "midpoint" else algos.traverse(name, o, d, shape, tmax=tmax)
            diverged, first = 0, []
            for k in range(n):
                a, b = exact[k], got[k]
                m = min(len(a), len(b))
                diff = np.nonzero(np.any(a[:m] != b[:m], axis=1))[0]
                if len(diff) or len(a) != len(b):
                    diverged += 1
                    first.append(int(diff[0]) if len(diff) else m)
            rows.append(dict(cells=n_cells, algorithm=name, precision=entry.precision, rays=n,
                             diverged_percent=100.0 * diverged / n,
                             first_divergence_median=float(np.median(first)) if first else math.nan,
                             ns_per_ray=round(times[name] / n, 1) if name in times else math.nan,
                             time_over_dda_f32=round(times[name] / times["dda_f32"], 3)
                             if name in times else math.nan))
    return rows


def first_hit_rows(seed):
    """Per first-hit family on a terraced field (grazing at a level, tangent to the max
    planes, starting below, entering by the sides), surface and intersector: the rays
    whose hit/miss or t (1e-9 relative; 1e-4 for Embree) differ from the brute force."""
    H = datasets_gen.load("terraces", size=(97, 129), seed=seed, levels=6, scale=24.0,
                          amplitude=8.0).heights
    field = algos.Field(H)
    rows_, cols_ = H.shape
    rng = np.random.Generator(np.random.PCG64(seed))
    levels = np.unique(H)
    n = 150
    fam = {}
    # grazing at exactly a terrace level (ties everywhere), horizontal
    z = rng.choice(levels, n)
    fam["grazing_at_level"] = (np.column_stack([rng.uniform(0, cols_ - 1, (n, 2)) * [1, (rows_ - 1) / (cols_ - 1)], z]),
                               np.column_stack([rng.normal(size=(n, 2)), np.zeros(n)]))
    # tangent to the mipmap's max planes: descending to exactly the maximum
    hmax = float(H.max())
    o = np.column_stack([rng.uniform(0, cols_ - 1, n), rng.uniform(0, rows_ - 1, n), np.full(n, hmax + 1)])
    fam["to_the_max_plane"] = (o, np.column_stack([rng.normal(size=(n, 2)), np.full(n, -0.05)]))
    # starting below the surface
    o = np.column_stack([rng.uniform(0, cols_ - 1, n), rng.uniform(0, rows_ - 1, n),
                         rng.uniform(-2, float(H.min()), n)])
    fam["start_below"] = (o, rng.normal(size=(n, 3)))
    # entering through the sides below the rim
    o = np.column_stack([np.full(n, -5.0), rng.uniform(0, rows_ - 1, n), rng.uniform(float(H.min()), hmax, n)])
    fam["side_entry"] = (o, np.column_stack([np.ones(n), rng.normal(size=n) * 0.3, rng.normal(size=n) * 0.05]))
    out = []
    for family, (o, d) in fam.items():
        for surface in algos.SURFACES:
            ref, _ = algos.brute_force_hits(H, o, d, surface)
            for name, entry in algos.INTERSECTOR_REGISTRY.items():
                if surface not in entry.surfaces or entry.kind == "march":
                    continue
                t = algos.intersect(name, field, o, d, surface=surface).t
                hit, ref_hit = np.isfinite(t), np.isfinite(ref)
                both = hit & ref_hit
                tol = 1e-4 if name == "embree" else 1e-9
                far = np.zeros(n, bool)
                far[both] = np.abs(t[both] - ref[both]) > tol * (1 + np.abs(ref[both]))
                out.append(dict(family=family, surface=surface, algorithm=name,
                                accuracy=entry.accuracy, rays=n,
                                disagree=int(np.sum((hit != ref_hit) | far))))
    return out


def run(out_dir="results/stress", full=False, echo=print):
    """The three tables (``full``: lengths up to 2^20 cells) into ``out_dir``: families.csv,
    drift.csv, first_hit.csv, stress.md and env.json."""
    os.makedirs(out_dir, exist_ok=True)
    env = environment()
    write_json(os.path.join(out_dir, "env.json"), env)
    lengths = [2**k for k in (range(10, 21, 2) if full else range(10, 19, 2))]
    fam = family_rows((256, 192), 96 if full else 48, 3)
    drift = drift_rows(lengths, 5)
    hits = first_hit_rows(2)
    for name, rows in (("families.csv", fam), ("drift.csv", drift), ("first_hit.csv", hits)):
        with RowWriter(os.path.join(out_dir, name), list(rows[0])) as w:
            for r in rows:
                w.write(r)
    names = list(algos.TRAVERSALS)
    lines = ["# hftrace stress", "", f"Machine: {env['cpu']}, commit `{env['git_commit']}`. "
             "Method: bench/studies/stress.py.", "",
             "## Drift: % of rays whose first N cells differ from the exact walk "
             "(grid 2^20 per side, origins near 2^16)", "",
             "| N | " + " | ".join(names) + " | exact time / dda_f32 (midpoint, runs) |",
             "|---" * (len(names) + 2) + "|"]
    for n_cells in lengths:
        part = {r["algorithm"]: r for r in drift if r["cells"] == n_cells}
        lines.append(f"| 2^{int(math.log2(n_cells))} | " + " | ".join(
            f"{part[n]['diverged_percent']:.1f}" for n in names) +
            f" | {part['midpoint']['time_over_dda_f32']:.2f}, {part['runs']['time_over_dda_f32']:.2f} |")
    lines += ["", "## Adversarial families: rays that differ from the reference", "",
              "| family | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for family in dict.fromkeys(r["family"] for r in fam):
        part = {r["algorithm"]: r for r in fam if r["family"] == family}
        lines.append(f"| {family} | " + " | ".join(f"{part[n]['differ']}/{part[n]['rays']}" for n in names) + " |")
    lines += ["", "Exact kernels are compared with the reference of the lattice-rounded ray "
              "(their contract), float kernels with the reference of the float ray.", "",
              "## First hits on a terraced field (ties everywhere): rays that disagree with the brute force", ""]
    inter = [n for n in algos.INTERSECTORS if algos.INTERSECTOR_REGISTRY[n].kind != "march"]
    lines += ["| family | surface | " + " | ".join(inter) + " |", "|---" * (len(inter) + 2) + "|"]
    for family in dict.fromkeys(r["family"] for r in hits):
        for surface in algos.SURFACES:
            part = {r["algorithm"]: r for r in hits if r["family"] == family and r["surface"] == surface}
            lines.append(f"| {family} | {surface} | " + " | ".join(
                f"{part[n]['disagree']}" if n in part else "-" for n in inter) + " |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(out_dir, "stress.md"), "w") as f:
        f.write(text)
    echo(text)
    return fam, drift, hits
