"""Rays on which the strict kernels (and in one case the brute force) disagree with the
rational reference ``exact_first_hit``: found by break10's fuzz of batch-coherent rays
(pinhole cameras of ``datasets_gen.rays.pinhole`` with eyes on integer coordinates, fans of
integer rays from one eye, planes of rays, image layouts, ring and packet batches, rays
with rounded rational directions such as ``fl(2/3)``).

Most come from one natural source: a pinhole camera with an odd image size aims its centre
pixel exactly at ``look_at``; with ``look_at`` on a grid vertex (integer coordinates), the
normalised direction misses that vertex by about 1e-16, and float64 puts the ray on it.
Each case is a minimal reproducer (heights, origin, direction, range, surface), the
reference's answer and what the kernels give, marked ``xfail(strict=True)`` so that a fix
shows up as an XPASS. The classes:

- **a side cell a hair wide inside the grid** (``vertex_hair_side_cell``): the ray passes
  the vertex (3, 3) 2e-16 above it and enters cell (3, 3) through its x face, a wall;
  every strict kernel reports the hit in the diagonal cell (3, 2) (normal (0, 1, 0), its
  y face), whose wall the exact ray meets about 1e-15 later. The brute force is right.
  Not the open "float walks near the diagonal" case: the direction is far from the
  diagonal, the exact kernels (midpoint, runs, runs_maxmip) fail too, and t agrees.
- **a side cell whose float interval collapses** (``sliver_side_cell_*``): the direction
  ``(1, fl(2/3), -1)`` from (0, 0) crosses x = 3 at t = 3 and y = 2 at
  t = 3 + 1/6004799503160661, which rounds to 3: float64 sees a vertex crossing, but the
  exact ray visits the side cell (3, 1) for 1.7e-16, and meets its wall at t = 3. Every
  strict kernel, the exact ones included, skips it: the hit goes to the diagonal cell
  (3, 2) (normal (-1, 0, 0)), or, where that cell is low, the ray misses. The brute force
  is right. (The fix of the last round drops a float walk's hit in a side cell the exact
  ray does not visit; this is the converse: a side cell it does visit, dropped.) The same
  direction from a level camera (``datasets_gen.rays.level_camera``) found it.
  Also on plane3 (``sliver_side_cell_plane3``: a hit 4 units late), and on triangles
  where the sliver is a cell's corner at the box's side (``sliver_at_box_side_triangles``:
  a miss). A fuzz of such rounded rational directions (``d = (a, fl(p/q) b, dz)`` from
  integer origins, 10,800 rays over three surfaces) found 38 rays where all 13 strict
  kernels disagree with the reference (0.35 %), in these classes and the box classes below.
- **the box entry a hair beside a vertex** (``box_entry_beside_vertex_*``): the ray enters
  the face x = 0 at y = 1 + 2.2e-16, which rounds onto y = 1; every strict kernel tests
  cell (0, 0) at the entry instead of (0, 1): the wall of (0, 1) is reported in (0, 0)
  (the brute force does the same there, on every linear surface), or missed and the hit
  found later in (0, 0) (the brute force is right there). With ``d = (1, -fl(2/3), -1)``
  from (-3, 3) the entry parameter is the float 3 itself and only ``y = 1 + 2**-53``
  rounds (``box_entry_beside_vertex_level``): every strict kernel misses the wall. The
  open class "box entry exactly through a vertex" is a ray on the vertex; this one is off
  it.
- **a ray a hair outside the box corner** (``passes_outside_box_corner``): the exact ray
  crosses x = 0 at y = -1.3e-16, below the corner (0, 0), and never enters the box; every
  strict kernel reports a wall hit in (0, 0). The brute force misses, as the reference.
  With ``d = (-1, -fl(2/3), -fl(2/3))`` the ray passes 2**-53 outside the corner
  (``passes_outside_box_corner_two_thirds``).
- **a touch a hair below the surface at the box exit** (``exit_below_surface``): the exact
  ray leaves through y = 0 at x = 1 + 9e-17 with z = -6e-17, below the surface (0): the
  reference hits at that closed end; every strict kernel misses (the float box exit comes
  first). The brute force is right.
- **t at an exact 0** (``vertical_hit_at_zero``, minor): a vertical ray from tmin = -5
  reaches a peak vertex at t = 0 exactly (a float); on plane3 every strict kernel gives
  t = -4.1e-25 (a hit before the origin), not within any number of ulps of 0; the brute
  force gives 0.
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
SURFACES = ("flat", "plane3", "triangles")

# the directions: centre pixels of datasets_gen.rays.pinhole cameras aimed at grid vertices
TOWARD_3_3 = (0.5454545454545454, -0.18181818181818177, -0.8181818181818181)
TOWARD_0_1 = (0.24806946917841693, -0.6201736729460423, -0.7442084075352507)
TOWARD_0_0 = (0.20845633738713573, -0.10422816869356788, -0.9724620528606378)
TOWARD_1_0 = (0.13018891098082389, -0.9113223768657671, -0.39056673294247163)


def _one_wall_heights():
    H = np.zeros((5, 5), np.float32)
    H[3, 4] = 4  # cells (3, 2) and (3, 3) stand 1 high on flat
    return H


def _side_wall_heights(low_diagonal):
    H = np.zeros((4, 5), np.float32)
    H[1, 4] = H[2, 4] = 16  # cell (3, 1) stands 8 high on flat, (3, 2) 4
    if low_diagonal:
        H[3, 3] = H[3, 4] = -40  # (3, 2) -16: past (3, 1) the ray meets nothing
    return H


def _plane3_peak_heights():
    H = np.zeros((7, 7), np.float32)
    H[2, 5] = 7
    return H


def _triangles_corner_heights():
    H = np.zeros((5, 4), np.float32)
    H[0, 0], H[0, 1] = 5, 3
    return H


def _peak_heights():
    H = np.zeros((3, 3), np.float32)
    H[1, 1] = 2
    return H


TWO_THIRDS = 0.6666666666666666  # fl(2/3) < 2/3
ONE_THIRD = 0.3333333333333333  # fl(1/3) < 1/3

# (id, heights, origin, direction, tmin, surfaces, want t (str or None), want cell, what the
#  kernels give, whether the brute force disagrees too)
CASES = [
    ("vertex_hair_side_cell", _one_wall_heights(), (0.0, 4.0, 5.0), TOWARD_3_3, 0.0,
     ("flat",), "6755399441055744/1228254443828317", (3, 3),
     "t 5.5 in (3, 2), normal (0, 1, 0): the diagonal cell's y face", False),
    ("sliver_side_cell_missed", _side_wall_heights(True), (0.0, 0.0, 6.0),
     (1.0, TWO_THIRDS, -1.0), 0.0, ("flat",), "3", (3, 1),
     "a miss: the side cell (3, 1), visited on [3, 3 + 1.7e-16), is skipped", False),
    ("sliver_side_cell_wrong_cell", _side_wall_heights(False), (0.0, 0.0, 6.0),
     (1.0, TWO_THIRDS, -1.0), 0.0, ("flat",), "3", (3, 1),
     "t 3 in the diagonal cell (3, 2), normal (-1, 0, 0), not the side cell (3, 1)", False),
    # plane3: the side cell (4, 2) of vertex (5, 3) holds the peak H[2, 5] = 7 at its corner;
    # every strict kernel skips it and hits at t = 7 in (0, 5)
    ("sliver_side_cell_plane3", _plane3_peak_heights(), (8.0, 1.0, 7.0),
     (-1.0, TWO_THIRDS, -1.0), 0.0, ("plane3",), "3", (4, 2),
     "a hit at t = 7 in (0, 5): the side cell (4, 2), visited on [3, 3 + 1.7e-16), is skipped",
     False),
    # triangles: the sliver is the corner of (0, 0) at the box's side y = 0, left at
    # t = 3 + 1.7e-16, where the exact ray lies a hair below the surface
    ("sliver_at_box_side_triangles", _triangles_corner_heights(), (4.0, 1.0, 4.0),
     (-1.0, -ONE_THIRD, -ONE_THIRD), 0.0, ("triangles",),
     "45035996273704960/15011998757901653", (0, 0), "a miss", False),
    # a flat zero field: the exact ray passes 2**-53 outside the corner (0, 2)
    ("passes_outside_box_corner_two_thirds", np.zeros((3, 8)), (3.0, 4.0, 1.0),
     (-1.0, -TWO_THIRDS, -TWO_THIRDS), 0.0, SURFACES, None, (-1, -1),
     "a wall hit at t = 3 in (0, 1)", False),
    ("box_entry_beside_vertex_level", [[0, 0], [0, 0], [8, 8]], (-3.0, 3.0, 6.0),
     (1.0, -TWO_THIRDS, -1.0), 0.0, ("flat",), "3", (0, 1),
     "a miss: the entry at t = 3 lies at y = 1 + 2**-53, which rounds onto the vertex",
     False),
    ("box_entry_beside_vertex_cell", [[0, 0], [4, 2], [5, 5]], (-2.0, 6.0, 7.0), TOWARD_0_1,
     0.0, SURFACES, "36028797018963968/4468822275815661", (0, 1),
     "the entry wall in (0, 0): y = 1 + 2.2e-16 at x = 0 rounds onto the vertex", True),
    ("box_entry_beside_vertex_late", [[0, 0], [0, 0], [8, 8]], (-2.0, 6.0, 7.0), TOWARD_0_1,
     0.0, ("flat",), "36028797018963968/4468822275815661", (0, 1),
     "the wall of (0, 1) missed: a hit at t = 9.405967373014974 in (0, 0)", False),
    ("passes_outside_box_corner", np.zeros((2, 2)), (-2.0, 1.0, 7.0), TOWARD_0_0, 0.0,
     SURFACES, None, (-1, -1),
     "a wall hit at t = 9.594335317739416 in (0, 0): y = -1.3e-16 at x = 0 rounds to 0",
     False),
    ("exit_below_surface", np.zeros((8, 3)), (0.0, 7.0, 3.0), TOWARD_1_0, 0.0, SURFACES,
     "54043195528445952/7035824771772109", (1, 0),
     "a miss: z = -6e-17 at the exact exit through y = 0, after the float exit", False),
    ("vertical_hit_at_zero", _peak_heights(), (1.0, 1.0, 2.0), (0.0, 0.0, -3.0), -5.0,
     ("plane3",), "0", (1, 1), "t = -4.1359030627651384e-25 in (1, 1)", False),
]
PARAMS = [pytest.param(c[0], surface, *c[1:5], *c[6:], id=f"{c[0]}-{surface}",
                       marks=pytest.mark.xfail(strict=True, reason=c[8]))
          for c in CASES for surface in c[5]]


@pytest.mark.parametrize("name, surface, H, o, d, tmin, want_t, want_cell, got, brute", PARAMS)
def test_found(name, surface, H, o, d, tmin, want_t, want_cell, got, brute):
    H = np.asarray(H, np.float32)
    want = (None if want_t is None else Fraction(want_t), want_cell)
    # the reference says so (this part holds; the kernels below do not)
    assert exact_first_hit(H, o, d, surface, tmin) == want
    outcomes = []
    for kernel in STRICT:
        out = algos.intersect(kernel, H, [o], [d], surface=surface, tmin=tmin)
        outcomes.append((kernel, float(out.t[0]), tuple(int(v) for v in out.cell[0])))
    t, cell = algos.brute_force_hits(H, [o], [d], surface, tmin=tmin)
    outcomes.append(("brute", float(t[0]), tuple(int(v) for v in cell[0])))
    failures = []
    for kernel, t, cell in outcomes:
        if want[0] is None:
            ok = math.isinf(t) and cell == (-1, -1)
        else:
            ok = math.isclose(t, float(want[0]), rel_tol=1e-12) and cell == want[1]
        if not ok:
            failures.append((kernel, t, cell))
    assert not failures, (name, surface, "want", want, "got", failures)
