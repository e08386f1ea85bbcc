"""``runs_periodic`` with a user-set ``max_denominator``: its walk follows a rational
approximation p/q (q <= the option) of the rounded ray's slope, but its first hit is the
caller's ray's (docs/kernels.md, "A user's max_denominator in first hits"). Held to the
brute force on all four surfaces and to the rational reference on the piecewise linear
ones, t and cell, for denominators 1, 2, 3, 7 and 64 and the default.

Found by a new user's trial: at ``max_denominator=2``, 49 of 2,000 rays reported a hit on
triangles or bilinear that the ray never makes. A cell of the walked run that the
caller's ray reaches only after leaving the run's row was tested on the one point where
the ray leaves the row, with that cell's surface extrapolated beyond the cell."""
import numpy as np
import pytest

import algos

from .exact_hits import exact_first_hit

DENOMINATORS = (1, 2, 3, 7, 64, None)


def _rays(shape, seed, n):
    """Random descending rays over and around the field, plus rays of small rational
    slopes a hair off them (many cells near the approximation's line) and long rays
    crossing the whole field."""
    rows, cols = shape
    rng = np.random.Generator(np.random.PCG64(seed))
    o = np.column_stack([rng.uniform(-2, cols + 1, n), rng.uniform(-2, rows + 1, n),
                         rng.uniform(3.0, 6.0, n)])
    d = np.column_stack([rng.normal(size=n), rng.normal(size=n), np.zeros(n)])
    m = n // 3
    p, q = rng.integers(1, 6, m), rng.integers(1, 6, m)
    d[:m, 0] = q * rng.choice([-1, 1], m) * (1 + rng.uniform(-0.05, 0.05, m))
    d[:m, 1] = p * rng.choice([-1, 1], m)
    d[:, 2] = -rng.uniform(0.3, 1.0, n) * np.hypot(d[:, 0], d[:, 1])
    d[m:2 * m, 2] *= 0.05 # nearly level and lower: long walks
    o[m:2 * m, 2] = rng.uniform(1.5, 4.0, m)
    return o, d


CASES = {"uniform": (lambda rng, s: rng.uniform(0, 4, s)),
         "steps": (lambda rng, s: rng.integers(0, 9, s) / 2.0)}


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    shape = (13, 17)
    rng = np.random.Generator(np.random.PCG64(11))
    H = CASES[request.param](rng, shape).astype(np.float32)
    o, d = _rays(shape, seed=12 + len(request.param), n=240)
    return request.param, H, o, d


def _check(what, t, cell, ref_t, ref_cell, o, d):
    hit, ref_hit = np.isfinite(t), np.isfinite(ref_t)
    both = hit & ref_hit
    err = np.zeros_like(ref_t)
    err[both] = np.abs(t[both] - ref_t[both]) / (1 + np.abs(ref_t[both]))
    bad = np.nonzero((hit != ref_hit) | (err > 1e-9) | np.any(cell != ref_cell, axis=1))[0]
    assert not len(bad), (
        f"{what}: {len(bad)} of {len(t)} rays differ; first origin={o[bad[0]].tolist()} "
        f"direction={d[bad[0]].tolist()} want t={ref_t[bad[0]]!r} cell={ref_cell[bad[0]]} "
        f"got t={t[bad[0]]!r} cell={cell[bad[0]]}")


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_runs_periodic_equals_the_brute_force_at_every_denominator(case, surface):
    fname, H, o, d = case
    ref_t, ref_cell = algos.brute_force_hits(H, o, d, surface)
    assert np.isfinite(ref_t).sum() > len(o) // 3  # the rays do hit
    for q in DENOMINATORS:
        kw = {} if q is None else {"max_denominator": q}
        for cull in (True, False):
            hits = algos.intersect("runs_periodic", H, o, d, surface=surface, cull_cells=cull,
                                   cull_runs=cull, **kw)
            _check(f"runs_periodic max_denominator={q} cull={cull} on {surface}/{fname}",
                   hits.t, hits.cell, ref_t, ref_cell, o, d)


@pytest.mark.parametrize("surface", ["flat", "plane3", "triangles"])
def test_runs_periodic_equals_the_rational_reference(case, surface):
    fname, H, o, d = case
    o, d = o[:90], d[:90]
    exact = [exact_first_hit(H, o[k], d[k], surface) for k in range(len(o))]
    ref_t = np.array([np.inf if t is None else float(t) for t, _ in exact])
    ref_cell = np.array([c for _, c in exact], dtype=np.int32)
    for q in DENOMINATORS:
        kw = {} if q is None else {"max_denominator": q}
        hits = algos.intersect("runs_periodic", H, o, d, surface=surface, **kw)
        _check(f"runs_periodic max_denominator={q} on {surface}/{fname} (exact reference)",
               hits.t, hits.cell, ref_t, ref_cell, o, d)


def test_the_reported_kind_of_ray():
    """One of the trial's kind: slope ~0.65 walked as 1/2 (q = 2); the walked row 10 runs
    on to column 6, which the caller's ray reaches only after it leaves row 10 at x = 5.65.
    Before the fix, cell (6, 10) was tested at that exit point with its triangle
    extrapolated to u = -0.35, a hit at t = 3.14 the ray never makes."""
    rng = np.random.default_rng(1)
    H = rng.uniform(0, 4, (13, 17)).astype(np.float32)
    o = np.array([[3.5237424381040707, 9.621046910922727, 4.990072943172399]])
    d = np.array([[0.6767085152932947, 0.43909363803175605, -0.6204636443454845]])
    assert algos.traverse("runs_periodic", o[:, :2], d[:, :2], (16, 12),
                          max_denominator=2)[0].tolist()[3:5] == [[5, 10], [6, 10]]
    for surface in ("triangles", "bilinear"):
        ref_t, ref_cell = algos.brute_force_hits(H, o, d, surface)
        got = algos.intersect("runs_periodic", H, o, d, surface=surface, max_denominator=2)
        assert got.t[0] == pytest.approx(ref_t[0], rel=1e-12), surface
        assert tuple(got.cell[0]) == tuple(ref_cell[0]) == (6, 11), surface
