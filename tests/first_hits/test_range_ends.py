"""The ends of a ray's range on grid lines and vertices (docs/CONVENTIONS.md, "Points on a
cell border"; this repository's reading: "a cell met at one point only is not hit").

A cell whose parameter interval is one point inside a range that is not (a side cell of
a vertex crossing, a cell the ray only touches at tmin or at tmax) is not visited by the
half-open rule, on any surface: the point belongs to the cell entered there, or at the
range's closed end to the cell left. Two faults of the kernels, found by a new user's
trial, broke it:

- ``tmin`` on a grid line of a ray along the box's far face (``dy = 0`` at ``y = ny``):
  the exact kernels report the hit at t0 (t right) in the column before the line, which
  the ray only touches there. Their walk's origin is moved a hair inside the last row
  there, so the off-lattice band lists the caller's rectangle, padded by rounding: it
  starts one column early, whose one-point interval ``[t0, t0]`` took the hit on the
  continuous surfaces.
- ``tmax`` exactly on a vertex: ``dda``'s incremental crossings (a direction of 3 or 5
  cells per unit) can step into a side cell of that vertex just before ``tmax``; its
  interval is the one point ``[tmax, tmax]``, the range's closed end, and ``flat`` and
  ``plane3`` took a hit there that the ray never makes in that cell.

Both cases are held to the rational reference (``exact_first_hit``) and the brute force."""
import numpy as np
import pytest

import algos
from algos.registry import INTERSECTOR_REGISTRY

from .exact_hits import exact_first_hit

STRICT = [n for n, a in INTERSECTOR_REGISTRY.items() if a.accuracy in ("exact", "float64")]
EXACT = [n for n, a in INTERSECTOR_REGISTRY.items() if a.accuracy == "exact"]


def _exact(H, o, d, surface, lo, hi):
    exact = [exact_first_hit(H, o[k], d[k], surface, lo[k], hi[k]) for k in range(len(o))]
    t = np.array([np.inf if v is None else float(v) for v, _ in exact])
    return t, np.array([c for _, c in exact], dtype=np.int32)


def test_tmin_on_a_grid_line_along_the_far_face():
    """The trial's kind of case: the ray runs along y = 8, the far face of a 9-row field
    (dy = 0: it reads the last row, 7), from tmin = 3 where it crosses x = 1 (moving +x:
    column 1). It starts inside the solid, so the hit is at t0 = 3, in cell (1, 7), on
    every surface; the exact kernels gave (0, 7) on triangles and bilinear."""
    H = np.zeros((9, 10), np.float32)
    H[:, :2] = 5.0  # columns 0 and 1 reach 5 at x = 1, the point at tmin
    o, d = np.array([[0.25, 8.0, 1.25]]), np.array([[0.25, 0.0, 0.25]])
    lo = np.array([3.0])
    for surface in algos.SURFACES:
        ref_t, ref_cell = algos.brute_force_hits(H, o, d, surface, tmin=lo)
        assert ref_t[0] == 3.0 and tuple(ref_cell[0]) == (1, 7), surface
        if surface != "bilinear":
            assert exact_first_hit(H, o[0], d[0], surface, 3.0) == (3, (1, 7))
        for name in STRICT:
            got = algos.intersect(name, H, o, d, surface=surface, tmin=lo)
            assert got.t[0] == 3.0 and tuple(got.cell[0]) == (1, 7), (name, surface,
                                                                       got.t, got.cell)


def _tmin_on_lines(shape, seed, n=400):
    """Dyadic rays (origins on a 1/4 lattice, some outside the box; components in
    {0, +-1/4, +-1/2, +-1, +-2}) with tmin where the ray crosses a grid line of the box,
    far faces included, and a dyadic tmax or none."""
    rows, cols = shape
    rng = np.random.Generator(np.random.PCG64(seed))
    o = np.column_stack([rng.integers(-8, 4 * cols + 4, n) / 4, rng.integers(-8, 4 * rows + 4, n) / 4,
                         rng.integers(0, 19, n) / 4])
    d = np.column_stack([rng.choice([1.0, -1, 2, -2, 0.5, -0.5, 0, 0.25], (n, 2)),
                         rng.choice([-1.0, -0.5, -0.25, 0, 0.25], n)])
    d[(d[:, 0] == 0) & (d[:, 1] == 0), 0] = 1.0
    # rays along the far faces, where the walk's origin is moved inside
    far = rng.random(n) < 0.25
    axis = rng.integers(0, 2, n)
    o[far & (axis == 1), 1] = rows - 1
    d[far & (axis == 1), 1] = 0.0
    o[far & (axis == 0), 0] = cols - 1
    d[far & (axis == 0), 0] = 0.0
    d[(d[:, 0] == 0) & (d[:, 1] == 0), 0] = 1.0
    lo = np.zeros(n)
    for k in range(n):
        a = int(rng.integers(2))
        if d[k, a] == 0:
            a = 1 - a
        line = rng.integers(0, (cols if a == 0 else rows))
        lo[k] = (line - o[k, a]) / d[k, a]
    hi = np.where(rng.random(n) < 0.5, np.inf, lo + rng.integers(0, 8, n) / 4)
    return o, d, lo, hi


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_hits_at_tmin_on_a_grid_line_are_in_the_cell_entered(surface):
    """Every strict kernel's hit at t0 (the ray starts inside the solid where tmin puts it
    on a grid line) has the reference's t and cell: the rational reference on flat,
    plane3 and triangles, the brute force on bilinear. Before the fix, 120 of 5,447
    checks (hits at t0, every strict kernel and surface) had the wrong cell: the four
    exact kernels on 15 rays each on triangles and on bilinear, all along a far face."""
    shape = (9, 10)
    rng = np.random.Generator(np.random.PCG64(10))
    H = rng.integers(0, 4, shape).astype(np.float32)
    o, d, lo, hi = _tmin_on_lines(shape, seed=10)
    if surface == "bilinear":
        ref_t, ref_cell = algos.brute_force_hits(H, o, d, surface, tmin=lo, tmax=hi)
    else:
        ref_t, ref_cell = _exact(H, o, d, surface, lo, hi)
    at_t0 = np.isfinite(ref_t) & (ref_t == lo)
    assert at_t0.sum() >= 40  # many rays start inside the solid on a line
    for name in STRICT:
        got = algos.intersect(name, H, o, d, surface=surface, tmin=lo, tmax=hi)
        bad = np.nonzero(at_t0 & ((got.t != ref_t) | np.any(got.cell != ref_cell, axis=1)))[0]
        assert not len(bad), (name, surface, len(bad), o[bad[0]].tolist(), d[bad[0]].tolist(),
                              lo[bad[0]], hi[bad[0]], ref_t[bad[0]], ref_cell[bad[0]],
                              got.t[bad[0]], got.cell[bad[0]])


def test_dda_side_cell_at_tmax_on_a_vertex():
    """flat: the ray from (11, 7) along (-5, -1) reaches the vertex (1, 5) at t = tmax = 2.
    There it leaves cell (1, 5) (the cell left holds the range's closed end); the side
    cells (0, 5) and (1, 4) only touch it there. dda's incremental crossing of x = 1 came
    out just below 2, so it stepped into (0, 5) with the one-point interval [2, 2] and
    took a hit on its top (5 high) at t = 2; the ray never goes below any cell it visits."""
    H = np.zeros((9, 10), np.float32)
    H[5:7, 0:2] = 5.0  # cell (0, 5) all 5; (1, 5) has two corners at 5: flat 2.5
    o, d = np.array([[11.0, 7.0, 5.0]]), np.array([[-5.0, -1.0, -1.0]])
    hi = np.array([2.0])
    assert exact_first_hit(H, o[0], d[0], "flat", 0.0, 2.0) == (None, (-1, -1))
    ref_t, _ = algos.brute_force_hits(H, o, d, "flat", tmax=hi)
    assert ref_t[0] == np.inf
    for name in STRICT:
        got = algos.intersect(name, H, o, d, surface="flat", tmax=hi)
        assert got.t[0] == np.inf, (name, got.t, got.cell)


def _tmax_on_vertices(shape, seed, n=500):
    """Rays through a vertex inside the grid with tmax exactly there: origins on a dyadic
    lattice behind the vertex, integer and dyadic components (3, 5, 7 cells per unit make
    dda's incremental crossings inexact), and some one-point ranges (tmin = tmax)."""
    rows, cols = shape
    rng = np.random.Generator(np.random.PCG64(seed))
    v = np.column_stack([rng.integers(1, cols - 1, n), rng.integers(1, rows - 1, n)]).astype(float)
    dxy = rng.choice([1.0, -1, 3, -3, 5, -5, 7, -7, 0.75, -1.25], (n, 2))
    back = rng.integers(1, 9, n) / 4
    o = np.column_stack([v - back[:, None] * dxy, rng.integers(0, 21, n) / 4])
    d = np.column_stack([dxy, rng.choice([-1.0, -0.5, -0.25, 0, 0.25], n)])
    lo = np.where(rng.random(n) < 0.3, back, 0.0)
    return o, d, lo, back.copy()


@pytest.mark.parametrize("surface", ["flat", "plane3", "triangles"])
def test_tmax_on_a_vertex(surface):
    """Every strict kernel's t equals the brute force's (hit or miss alike, 1e-12), and a
    hit at tmax is in its cell (the one holding p(tmax): inside the grid the cell entered,
    test_border_points.py). The brute force, not the rational
    reference, for speed: since the brute force decides touches at non-float parameters
    exactly (test_exact_touches.py), the two agree on these rays. A direction of 3 cells
    per unit puts some box entries at parameters like 1/3, where float64 decides a level
    touch either way: brute force and kernels now decide it exactly. Before the fix, dda differed
    on 9 of 4,500 rays (flat and plane3). (On bilinear every kernel differs from the
    brute force on two rays here, before and after alike: a level ray tangent to the
    surface, t to 5e-9, and that touch at a box entry at t = 1/3.)"""
    shape = (9, 10)
    for seed in (1, 2, 3):
        rng = np.random.Generator(np.random.PCG64(seed))
        H = (rng.integers(0, 9, shape) / 2).astype(np.float32)
        o, d, lo, hi = _tmax_on_vertices(shape, seed)
        ref_t, ref_cell = algos.brute_force_hits(H, o, d, surface, tmin=lo, tmax=hi)
        at_end = np.isfinite(ref_t) & (ref_t == hi)
        assert at_end.sum() >= 5
        for name in STRICT:
            got = algos.intersect(name, H, o, d, surface=surface, tmin=lo, tmax=hi)
            bad_t = ~(np.isclose(got.t, ref_t, rtol=1e-12, atol=0)
                      | (np.isinf(got.t) & np.isinf(ref_t)))
            # the cell where the kernel's t is tmax itself (a root that rounds a hair below
            # a vertex is a hit of the cell left: 1 ray of seed 3 on triangles)
            exact_end = at_end & (got.t == ref_t)
            bad = np.nonzero(bad_t | (exact_end & np.any(got.cell != ref_cell, axis=1)))[0]
            assert not len(bad), (name, surface, seed, len(bad), o[bad[0]].tolist(),
                                  d[bad[0]].tolist(), lo[bad[0]], hi[bad[0]], ref_t[bad[0]],
                                  ref_cell[bad[0]], got.t[bad[0]], got.cell[bad[0]])
