"""Rays on which the strict kernels (and in one case the brute force) still disagree with
the rational reference ``exact_first_hit`` after the exact first hits of
``test_exact_touches.py``: found by a fuzz of small-denominator rays (break-exact).

Each case is a minimal reproducer: heights, origin, direction, range and surface, the
reference's answer and what the kernels gave. The open ones are marked
``xfail(strict=True)``, so that a fix shows up as an XPASS; the fixed ones pass. The
classes:

- **the box clip in float64**: the range ``[t0, t1]`` clipped to the field's box is
  computed in float64, so a ray that touches the box at one point at a parameter that is
  not a float (1/5 at a box corner) gets an empty float range and misses, and a ``tmax``
  of ``fl(1/3)`` just before the box entry at 1/3 gets a one-point float range and a hit
  where the exact range is empty. The brute force decides these exactly.
- **the cell at tmin**: a finite ``tmin`` that rounds onto a grid line (``p(fl(1/3))`` is a
  hair past ``x = 1`` in exact arithmetic) is placed in the cell past the line in float64:
  the hit at ``tmin`` is reported in the wrong cell, by every kernel and the brute force;
  with a one-point range at ``fl(1/3)`` the kernels test the cell past the line and miss.
- **the cell at the box entry**: a ray entering the box exactly through a grid vertex on its
  side at t = 20/49 is placed in the side cell it only touches there (every kernel).
- **tmax an ulp past a crossing**: ``tmax = fl(5/24)`` lies an ulp past the crossing of
  x = 2 at 5/24, where the ray meets a wall: runs_f64 misses it (dda too, on plane3 terraces).
- **the float walks near the diagonal**: a direction a few ulps off ``dx == dy`` passes
  a vertex at a hair's distance; the float walks (dda and the hierarchies over it) miss.
- **the culls at a vertex** (fixed, so these cases pass): a ray that touches a cell's
  surface at its maximum where it leaves the box through a grid vertex at t = 44/9, and a
  rising ray that touches a peak vertex (the maximum of the cell entered) at t = 57/13,
  where fl(57/13) > 57/13 put z a hair above the maximum, were culled by every kernel.
  Every cull now compares z from an origin lowered by the ray's rounding bound
  (``oz_cull``, cext/surfaces/cell_test.h), so no cull rejects a cell the exact ray
  touches.
- (Not a case: runs_periodic misses a horizontal ray from x = 1000004 with
  d = (-300000, -1, 0) under a plateau. That is its documented approximation: the slope
  1/300000 becomes the best rational with a denominator up to ``max_denominator``, 0/1 for
  2^16, and from that far the line with slope 0 passes outside the grid; with
  ``max_denominator=2**20`` it is exact. The registry says so in ``exact_when``.)
"""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

import algos

from .exact_hits import exact_first_hit

STRICT = [n for n, a in algos.registry.INTERSECTOR_REGISTRY.items()
          if a.accuracy in ("exact", "float64")]
FLOAT_WALKS = ["dda", "dda_maxmip", "packet_maxmip", "plane_maxmip", "pitched_maxmip",
               "ring_maxmip", "cone", "dda_compact"]
SURFACES = ("flat", "plane3", "triangles")


def _vertex_exit_heights():
    H = np.zeros((3, 9), np.float32)
    H[0, 6] = 2
    return H


def _block_heights():
    H = np.zeros((4, 6), np.float32)
    H[1:3, 4:6] = 3
    return H


def _peak_heights():
    H = np.zeros((3, 3), np.float32)
    H[1, 1] = 6
    return H


# (id, heights, origin, direction, tmin, tmax, surfaces, want t (str or None), want cell,
#  what the kernels give, the kernels that disagree, whether the brute force does too)
CASES = [
    ("box_corner_touch", np.ones((2, 2)), (-2.0, -6.0, 0.0), (10.0, 35.0, 1.0), 0.0, math.inf,
     SURFACES, "1/5", (0, 0), "a miss: 7 * fl(1/35) < fl(0.2) empties the float range",
     STRICT, False),
    ("tmax_before_box_entry", np.ones((2, 2)), (-1.0, 0.5, 0.0), (3.0, 0.0, 0.0), 0.0, 1 / 3,
     SURFACES, None, (-1, -1), "a hit at fl(1/3) in (0, 0): fl(1/3) < 1/3, the box entry",
     STRICT, False),
    ("cell_at_tmin", np.full((2, 3), 3.0), (2.0, 0.5, 0.0), (-3.0, 0.0, 0.0), 1 / 3, math.inf,
     SURFACES, "fl(1/3)", (1, 0), "the hit at tmin in (0, 0): 2 - 3 fl(1/3) rounds to 1",
     STRICT, True),
    # found by a new user's trial (trial9): the same rounding turns a hit into a miss
    ("one_point_range_off_a_grid_line", _block_heights(), (4.0, 1.0, 3.0), (1.0, 3.0, -2.0),
     1 / 3, 1 / 3, ("flat",), "fl(1/3)", (4, 1),
     "a miss: 1 + 3 fl(1/3) rounds to 2, so cell (4, 2) (1.5 high) is tested, not (4, 1) (3)",
     STRICT, False),
    ("near_diagonal_walk", [[4.0, 2.0, 3.0, 3.0, 4.0], [0.0, 2.0, 0.0, 2.0, 5.0]],
     (2.5, 0.5, 3.0), (-7.0, -6.999999999999998, 1.0), -10.0, 0.07142857142857145,
     ("flat",), "-281474976710656/3940649673949183", (3, 0), "a miss", FLOAT_WALKS, False),
    ("touch_at_box_side_vertex", _vertex_exit_heights(), (138.0, 44.0, 46.0),
     (-27.0, -9.0, -9.0), 0.0, math.inf, ("plane3", "triangles"), "44/9", (6, 0),
     "a miss", STRICT, False),
    ("box_entry_at_vertex", np.zeros((2, 3)), (-19.0, 21.0, 0.5), (49.0, -49.0, -4.0), 0.0,
     math.inf, SURFACES, "20/49", (1, 0),
     "the hit at the box entry in (0, 0), a cell the ray touches only at the vertex (1, 1)",
     STRICT, False),
    ("tmax_an_ulp_past_a_crossing", np.tile([0.0, 0.0, 5.0, 5.0], (2, 1)), (0.75, 0.5, 3.0),
     (6.0, 0.0, 0.0), 0.0, 5 / 24, ("flat",), "5/24", (2, 0),
     "a miss: fl(5/24) > 5/24, the wall of column 2", ["runs_f64"], False),
    ("rising_touch_at_a_peak_vertex", _peak_heights(), (-170.0, 58.0, -51.0),
     (39.0, -13.0, 13.0), 0.0, math.inf, ("plane3",), "57/13", (1, 0),
     "a miss: z(fl(57/13)) = 6.000000000000007 > the cell maximum 6 culls the cell entered",
     STRICT, False),
]
#: the classes fixed since they were found (the culls' z: oz_cull)
FIXED = {"touch_at_box_side_vertex", "rising_touch_at_a_peak_vertex"}
PARAMS = [pytest.param(c[0], surface, *c[1:6], *c[7:], id=f"{c[0]}-{surface}",
                       marks=() if c[0] in FIXED else pytest.mark.xfail(strict=True, reason=c[9]))
          for c in CASES for surface in c[6]]


def _want_t(text, tmin):
    if text is None:
        return None
    return Fraction(tmin) if text == "fl(1/3)" else Fraction(text)


@pytest.mark.parametrize(
    "name, surface, H, o, d, tmin, tmax, want_t, want_cell, got, kernels, brute", PARAMS)
def test_found(name, surface, H, o, d, tmin, tmax, want_t, want_cell, got, kernels, brute):
    H = np.asarray(H, np.float32)
    want = (_want_t(want_t, tmin), want_cell)
    # the reference says so (this part holds; the kernels below do not)
    assert exact_first_hit(H, o, d, surface, tmin, tmax) == want
    failures = []
    runs = [(name_, lambda k=name_: algos.intersect(k, H, [o], [d], surface=surface,
                                                       tmin=tmin, tmax=tmax))
            for name_ in kernels]
    runs.append(("brute", lambda: algos.brute_force_hits(H, [o], [d], surface, tmin=tmin,
                                                         tmax=tmax)))
    for kernel, call in runs:
        out = call()
        t, cell = (out.t, out.cell) if kernel != "brute" else out
        if want[0] is None:
            ok = math.isinf(t[0]) and tuple(cell[0]) == (-1, -1)
        else:
            ok = (math.isclose(t[0], float(want[0]), rel_tol=1e-12)
                  and tuple(int(v) for v in cell[0]) == want[1])
        if not ok:
            failures.append((kernel, float(t[0]), tuple(int(v) for v in cell[0])))
    assert not failures, (name, surface, "want", want, "got", failures)
