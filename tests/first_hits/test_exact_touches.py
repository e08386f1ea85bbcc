"""Touches at parameters that are not floats, decided exactly.

Integer rays on integer heights meet the surface exactly at events whose parameter is
not a float: a grid-line crossing ``t = (k - o) / d`` (1/3 ...) or the triangles' crossing
of the diagonal u = v. There float64 cannot tell the sign of z - s (docs/CONVENTIONS.md,
"The first hit", "Points on a cell border"): before, the brute force missed about 1 ray
in 300 of these (a touch missed, a hit found one cell early, a hit where the exact ray
stays above). It now decides every ray with a gap near 0 at an event in rational
arithmetic (``algos.exact_hits``), so it equals the rational reference ``exact_first_hit``
on these rays, t to 1e-12 and the cell.

``check_exact_touches(hits)`` holds any ``hits(H, o, d, surface, tmin, tmax) -> (t, cell)``
to the reference on the fuzzed rays; only the brute force is checked here.
"""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

import algos

from .exact_hits import exact_first_hit

SURFACES = ("flat", "plane3", "triangles")


def brute_force(H, o, d, surface, tmin, tmax):
    """The brute force as a ``hits`` callable: (t (n,), cell (n, 2))."""
    return algos.brute_force_hits(H, o, d, surface, tmin=tmin, tmax=tmax)


def _integer_rays(rng, n, shape):
    """n integer rays around a grid of ``shape`` (rows, cols): origins from 2 cells outside
    the box, heights 0..7, components -3..3 (never vertical); 30 % start at tmin = -10,
    and 30 % end at a finite tmax where the ray crosses a grid line (a crossing of x or y
    at an integer coordinate in front of the origin)."""
    rows, cols = shape
    o = np.column_stack([rng.integers(-2, cols + 2, n), rng.integers(-2, rows + 2, n),
                         rng.integers(0, 8, n)]).astype(float)
    d = rng.integers(-3, 4, (n, 3)).astype(float)
    d[np.all(d[:, :2] == 0, axis=1), 0] = 1
    tmin = np.where(rng.random(n) < 0.3, -10.0, 0.0)
    tmax = np.full(n, np.inf)
    for k in np.nonzero(rng.random(n) < 0.3)[0]:
        axis = 0 if d[k, 0] != 0 and (d[k, 1] == 0 or rng.random() < 0.5) else 1
        line = o[k, axis] + np.sign(d[k, axis]) * rng.integers(1, 6)
        tmax[k] = (line - o[k, axis]) / d[k, axis]  # 1/3, 2/3 ...: rounded, as a caller would
    return o, d, tmin, tmax


def check_exact_touches(hits, surface, seed, n=400, shape=(8, 9)):
    """Assert that ``hits`` equals ``exact_first_hit`` (t to rtol 1e-12, the same cell;
    misses alike) on n seeded integer rays over integer heights 0..5 on ``shape``."""
    rng = np.random.Generator(np.random.PCG64(seed))
    H = rng.integers(0, 6, shape).astype(np.float32)
    o, d, tmin, tmax = _integer_rays(rng, n, shape)
    t, cell = hits(H, o, d, surface, tmin, tmax)
    for k in range(n):
        want_t, want_cell = exact_first_hit(H, o[k], d[k], surface, tmin[k], tmax[k])
        if want_t is None:
            ok = math.isinf(t[k]) and tuple(cell[k]) == (-1, -1)
        else:
            ok = (math.isclose(t[k], float(want_t), rel_tol=1e-12, abs_tol=1e-300)
                  and tuple(int(v) for v in cell[k]) == want_cell)
        assert ok, (surface, seed, "H", H.tolist(), "o", o[k].tolist(), "d", d[k].tolist(),
                    "tmin", tmin[k], "tmax", tmax[k], "want", want_t, want_cell,
                    "got", t[k], tuple(cell[k]))


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("surface", SURFACES)
def test_brute_force_equals_the_rational_reference(surface, seed):
    check_exact_touches(brute_force, surface, seed)


def _named_heights():
    """The 10 x 10 heights (integers 0..5) of the named examples: those of
    /work/notes/s9/fuzz_d3.py's seed 0 (``default_rng(0)``)."""
    return np.random.default_rng(0).integers(0, 6, size=(10, 10)).astype(np.float32)


# (surface, origin, direction, exact t, cell): found by that fuzz, each missed by the
# float64 brute force before (its float t and cell in the comment)
NAMED = [
    # a touch at t = 2/3 where the ray crosses into (8, 1): float64 missed it
    ("triangles", (7, 2, 4), (3, -1, 1), "2/3", (8, 1)),
    # a hit at t = 1/3 on the entry into (8, 8): float64 found 0.33333333333333287 in (7, 8)
    ("plane3", (7, 8, 3), (3, 2, -1), "1/3", (8, 8)),
]


@pytest.mark.parametrize("surface, o, d, t, cell", NAMED, ids=[n[0] for n in NAMED])
def test_named_touches(surface, o, d, t, cell):
    H = _named_heights()
    assert exact_first_hit(H, o, d, surface) == (Fraction(t), cell)
    got_t, got_cell = brute_force(H, [o], [d], surface, None, None)
    assert got_t[0] == float(Fraction(t)) and tuple(got_cell[0]) == cell
