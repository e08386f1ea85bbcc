"""The range's closed end inside the grid, and the cell of a hit on a border.

docs/CONVENTIONS.md, "The first hit": the first hit is the smallest t in [t0, t1] with
z(t) <= s(x(t), y(t)), where s on a cell border is the surface of the cell that holds the
point by the half-open rule. So where tmax ends the range exactly on a border the ray
crosses there, p(tmax) is the entered cell's to decide, and the first hit over [tmin, T] is
the first hit over [tmin, inf) whenever that one lies at or before T (with the same cell).
Before, the brute force, the rational reference and every kernel tested p(tmax) in the
cell being left: a ray reaching a wall exactly at tmax missed over [0, tmax] and hit over
[0, inf) at tmax. And a touch where two continuous cells meet was reported in the cell
left (kernels) or the first in row-major order (brute force); it is the cell entered.
"""
from __future__ import annotations

import numpy as np
import pytest

import algos
from algos.registry import INTERSECTOR_REGISTRY

from .exact_hits import exact_first_hit

STRICT = [n for n, a in INTERSECTOR_REGISTRY.items() if a.accuracy in ("exact", "float64")]


def _hit(name, H, o, d, surface, **kw):
    if name == "brute force":
        t, cell = algos.brute_force_hits(H, [o], [d], surface, **kw)
    else:
        got = algos.intersect(name, H, [o], [d], surface=surface, **kw)
        t, cell = got.t, got.cell
    return float(t[0]), tuple(int(v) for v in cell[0])


@pytest.mark.parametrize("name", ["brute force"] + STRICT)
def test_a_wall_reached_exactly_at_tmax_is_hit(name):
    """flat: columns 0-1 stand 0 high, columns 2-3 5 high. A level ray at z = 3 along x
    meets the wall x = 2 at t = 1.5. Over [0, 1.5] that point belongs to column 2 (the
    half-open rule), which is above the ray: a hit at t = 1.5 in (2, 0), as over [0, inf)
    and over [1.5, 1.5]. Over [0, 1.25] it misses."""
    H = np.array([[0, 0, 5, 5], [0, 0, 5, 5]], np.float32)
    o, d = (0.5, 0.5, 3.0), (1.0, 0.0, 0.0)
    for tmin, tmax in ((0.0, np.inf), (0.0, 1.5), (1.5, 1.5)):
        assert _hit(name, H, o, d, "flat", tmin=tmin, tmax=tmax) == (1.5, (2, 0)), (tmin, tmax)
        assert exact_first_hit(H, o, d, "flat", tmin, tmax) == (1.5, (2, 0))
    assert _hit(name, H, o, d, "flat", tmax=1.25) == (np.inf, (-1, -1))


@pytest.mark.parametrize("name", ["brute force"] + STRICT)
def test_a_touch_at_tmax_on_a_lower_cell_is_not_a_hit(name):
    """flat: cell (0, 0) stands 2 high, (1, 0) 0. The ray comes down to z = 2 exactly at
    x = 1, where it leaves (0, 0), at t = 0.5 = tmax. That point belongs to (1, 0), which
    is lower: over [0, 0.5] the ray misses (before, every kernel took the touch in (0, 0),
    which the border rule already refused over longer ranges)."""
    H = np.array([[2, 2, 0, 0], [2, 2, 0, 0]], np.float32)
    o, d = (0.5, 0.5, 2.5), (1.0, 0.0, -1.0)
    assert exact_first_hit(H, o, d, "flat", 0.0, 0.5) == (None, (-1, -1))
    assert _hit(name, H, o, d, "flat", tmax=0.5) == (np.inf, (-1, -1))
    # and over [0, inf) the first hit is (1, 0)'s top, at x = 2.5 where z = 0
    assert _hit(name, H, o, d, "flat") == (2.5, (2, 0)) == exact_first_hit(H, o, d, "flat")


def _dyadic_cases(surface, seed, n=160):
    """Integer terraces and dyadic rays (every border crossing and flat root dyadic)."""
    rng = np.random.Generator(np.random.PCG64(seed))
    shape = (7, 8)
    H = rng.integers(0, 4, shape).astype(np.float32)
    o = np.column_stack([rng.integers(-2, 4 * shape[1] + 2, n) / 4,
                         rng.integers(-2, 4 * shape[0] + 2, n) / 4,
                         rng.integers(0, 17, n) / 4])
    d = np.column_stack([rng.choice([0.0, 1, -1, 2, -2, 0.5, -0.5], (n, 2)),
                         rng.choice([-1.0, -0.5, -0.25, 0.0, 0.25], n)])
    d[(d[:, 0] == 0) & (d[:, 1] == 0), 0] = 1.0
    return H, o, d


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_the_first_hit_does_not_depend_on_where_the_range_ends_after_it(surface):
    """For every ray with a first hit t* over [0, inf): over [0, t*] it is the same hit,
    t and cell, for the brute force and every strict kernel; over [0, t* - 2^-10] (a
    dyadic end, evaluated exactly) a miss. The ends t* fall on borders often here (dyadic
    rays on integer terraces)."""
    H, o, d = _dyadic_cases(surface, seed=11, n=600)
    names = ["brute force"] + STRICT
    for name in names:
        checked = 0
        for k in range(len(o)):
            t, cell = _hit(name, H, o[k], d[k], surface)
            # only exact hits: walls, and roots on a 2^-10 grid (a root inside a plane3,
            # triangles or bilinear piece is often not dyadic, and on the shorter
            # interval its last bit may round beyond the end)
            if not np.isfinite(t) or t <= 0 or t * 1024 != np.floor(t * 1024):
                continue
            checked += 1
            assert _hit(name, H, o[k], d[k], surface, tmax=t) == (t, cell), (
                name, o[k].tolist(), d[k].tolist(), t, cell)
            below = t - 2.0 ** -10
            if below < 0:
                continue
            assert _hit(name, H, o[k], d[k], surface, tmax=below)[0] == np.inf, (
                name, o[k].tolist(), d[k].tolist(), t)
        assert checked >= 40, (name, checked)


@pytest.mark.parametrize("surface", ["flat", "plane3", "triangles"])
def test_cells_equal_the_exact_reference_with_ranges_ending_on_borders(surface):
    """t and cell of the brute force and every strict kernel equal the rational
    reference's, on dyadic rays whose tmax is a quarter step (often a border crossing)."""
    H, o, d = _dyadic_cases(surface, seed=12, n=200)
    rng = np.random.Generator(np.random.PCG64(13))
    tmax = rng.integers(1, 24, len(o)) / 4
    want = []
    for k in range(len(o)):
        t, cell = exact_first_hit(H, o[k], d[k], surface, 0.0, tmax[k])
        want.append((np.inf if t is None else float(t), cell))
    for name in ["brute force"] + STRICT:
        for k in range(len(o)):
            got = _hit(name, H, o[k], d[k], surface, tmax=tmax[k])
            ok = got[1] == tuple(want[k][1]) and (
                got[0] == want[k][0] or np.isclose(got[0], want[k][0], rtol=1e-12, atol=0))
            assert ok, (name, o[k].tolist(), d[k].tolist(), tmax[k], want[k], got)


@pytest.mark.parametrize("name", ["brute force"] + STRICT)
def test_a_cell_stepped_into_as_the_box_ends_is_not_hit(name):
    """flat: rows 0-4 are low, the cells of row 5 reach 4 (row 6 stands 8 high). The ray
    leaves the box through x = 0 exactly at the vertex (0, 5), t = 2, z = 2. Its last cell
    is (0, 4); (0, 5) is met at that one point only, where the box ends, so it is not hit:
    a miss. dda stepped into (0, 5) with the one-point interval [2, 2] and took it as a
    hit (found by a new user's trial)."""
    H = np.array([[0, 0]] * 6 + [[8, 8]] * 2, np.float32)
    o, d = (1.0, -1.0, 3.0), (-0.5, 3.0, -0.5)
    assert exact_first_hit(H, o, d, "flat") == (None, (-1, -1))
    assert _hit(name, H, o, d, "flat") == (np.inf, (-1, -1))


# ---- a touch on a border whose parameter is not a float (t = 1/3, 5/3) -------------------
_TOUCH_FIELD = np.random.default_rng(5).integers(0, 5, size=(9, 11)).astype(np.float32)


@pytest.mark.parametrize("name", ["brute force"] + STRICT)
@pytest.mark.parametrize("o,d,tmin,tmax,expected", [
    # level at z = 2 along (1, -3): on the triangles of (1, 1) and (1, 0) alike where it
    # crosses y = 1 at t = 1/3, which rounds below 1/3
    ((1, 2, 2), (1, -3, 0), 0.0, np.inf, (1 / 3, (1, 0))),
    # coming down onto the border y = 4 at t = 5/3: the root in the cell left rounds an ulp
    # below the border, the cell entered hits at its entry an ulp later
    ((1, 9, 5), (2, -3, -2), -10.0, 3.0, (5 / 3, (4, 3))),
])
def test_a_touch_where_the_border_parameter_is_not_a_float(name, o, d, tmin, tmax, expected):
    """The brute force reported these touches in the cell left, (1, 1) and (4, 4): it
    located p(t) at the rounded t (below the border) or took the root an ulp before the
    border. The rational reference and every strict kernel give the cell entered."""
    assert exact_first_hit(_TOUCH_FIELD, o, d, "triangles", tmin, tmax)[1] == expected[1]
    t, cell = _hit(name, _TOUCH_FIELD, o, d, "triangles", tmin=tmin, tmax=tmax)
    assert abs(t - expected[0]) <= 1e-12 and cell == expected[1], (t, cell)


def test_brute_force_cells_of_border_touches_match_the_rational_reference():
    """Seeded level and descending rays with directions of 1, 2, 3 along each axis on an
    integer field, so that many of them touch the surface on a border at a parameter that
    is not a float: the brute force's cell against the rational reference's on triangles,
    wherever their t agree. (Where they do not, the ray lies exactly in a triangle's plane
    after touching it: the float gap along that piece is rounding noise, and the linear
    root of the brute force and of every kernel lands at the piece's far end, e.g.
    o = (5, 6, 4), d = (2, -1, -1): t = 1 in (7, 4) against 2/3 in (6, 5). Two such rays
    here; that is a separate, open issue, so they are only counted.)"""
    rng = np.random.default_rng(8)
    H = _TOUCH_FIELD
    wrong, planar = [], 0
    for _ in range(160):
        o = (float(rng.integers(0, 11)), float(rng.integers(0, 9)), float(rng.integers(1, 5)))
        d = (float(rng.choice([-3, -2, -1, 1, 2, 3])), float(rng.choice([-3, -2, -1, 1, 2, 3])),
             float(rng.choice([0, 0, -0.5, -1])))
        t_ref, cell_ref = exact_first_hit(H, o, d, "triangles", 0.0, np.inf)
        t, cell = algos.brute_force_hits(H, [o], [d], "triangles", tmin=0.0)
        got = (float(t[0]), tuple(int(v) for v in cell[0]))
        want = (np.inf if t_ref is None else float(t_ref), tuple(cell_ref))
        if not (got[0] == want[0] or abs(got[0] - want[0]) <= 1e-12):
            planar += 1
        elif got[1] != want[1]:
            wrong.append((o, d, got, want))
    assert not wrong, wrong[:5]
    assert planar <= 2
