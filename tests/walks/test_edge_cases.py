"""Named edge cases: each exact kernel and the reference must give the stated cells."""
import math

import numpy as np
import pytest

import algos
from algos.registry import TRAVERSAL_REGISTRY

from ..helpers import as_tuples

EXACT = [t.name for t in TRAVERSAL_REGISTRY.values() if t.precision == "exact"]


def walk(name, origin, direction, shape, tmin=None, tmax=None):
    paths = algos.traverse(name, np.array([origin], float), np.array([direction], float),
                           shape, tmin, tmax)
    return as_tuples(paths[0])


def check(origin, direction, shape, expected, tmin=0.0, tmax=math.inf):
    """The reference and every exact kernel give `expected`."""
    assert algos.reference_cells(origin, direction, shape, tmin, tmax) == expected
    for name in EXACT:
        got = walk(name, origin, direction, shape, tmin, tmax)
        assert got == expected, f"{name}: origin={origin} direction={direction} shape={shape}"


def test_conventions_examples():
    check((0.5, 0.5), (2, 3), (4, 4), [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 3)])
    check((0, 0), (1, 1), (4, 4), [(0, 0), (1, 1), (2, 2), (3, 3)])
    check((3.5, 0.5), (-1, 0.25), (4, 4), [(3, 0), (2, 0), (1, 0), (1, 1), (0, 1)])


def test_conventions_runs_example():
    expected = [(0, 0, 1), (1, 1, 4), (2, 4, 6), (3, 6, 9), (4, 9, 11)]
    assert algos.reference_runs((0.1, 0.3), (41, 17), (50, 50))[:5] == expected
    for name in EXACT:
        runs = algos.traverse(name, np.array([[0.1, 0.3]]), np.array([[41.0, 17.0]]),
                              (50, 50), output="runs")
        assert as_tuples(runs[0])[:5] == expected, name


def test_axis_parallel_positive():
    check((0.5, 1.5), (1, 0), (4, 3), [(0, 1), (1, 1), (2, 1), (3, 1)])
    check((1.5, 0.25), (0, 2), (3, 3), [(1, 0), (1, 1), (1, 2)])


def test_axis_parallel_negative():
    check((3.5, 1.5), (-1, 0), (4, 3), [(3, 1), (2, 1), (1, 1), (0, 1)])
    check((1.5, 2.75), (0, -0.5), (3, 3), [(1, 2), (1, 1), (1, 0)])


def test_axis_parallel_along_grid_line():
    # y = 1 exactly: with dy = 0 row j holds [j, j+1), so the ray runs in row 1
    check((0.0, 1.0), (1, 0), (3, 3), [(0, 1), (1, 1), (2, 1)])
    check((3.0, 1.0), (-1, 0), (3, 3), [(2, 1), (1, 1), (0, 1)])
    # along the far boundary y = ny: row ny does not exist, so nothing is visited
    check((0.0, 3.0), (1, 0), (3, 3), [])
    # along x = 0 going down: column 0 holds [0, 1)
    check((0.0, 2.5), (0, -1), (3, 3), [(0, 2), (0, 1), (0, 0)])


def test_exact_diagonals():
    check((0, 0), (1, 1), (3, 3), [(0, 0), (1, 1), (2, 2)])
    check((3, 3), (-1, -1), (3, 3), [(2, 2), (1, 1), (0, 0)])
    check((0, 3), (1, -1), (3, 3), [(0, 2), (1, 1), (2, 0)])
    check((3, 0), (-1, 1), (3, 3), [(2, 0), (1, 1), (0, 2)])


def test_vertex_crossing():
    # slope 1/2 from a vertex: passes the vertices (2, 1) and (4, 2)
    check((0, 0), (2, 1), (6, 3),
          [(0, 0), (1, 0), (2, 1), (3, 1), (4, 2), (5, 2)])
    # the two cells that touch the ray only at the vertex (1, 0) and (0, 1) are skipped
    check((0.5, 0.5), (1, 1), (3, 3), [(0, 0), (1, 1), (2, 2)])


def test_origin_on_grid_line():
    check((1.0, 0.5), (1, 0.125), (4, 2), [(1, 0), (2, 0), (3, 0)])
    check((1.0, 0.5), (1, 0.25), (4, 2), [(1, 0), (2, 0), (3, 1)])  # vertex (3, 1)
    check((1.0, 0.5), (-1, 0.25), (4, 2), [(0, 0)])


def test_origin_on_corner():
    check((2.0, 2.0), (1, 2), (4, 4), [(2, 2), (2, 3)])
    check((2.0, 2.0), (-1, -2), (4, 4), [(1, 1), (1, 0)])
    check((2.0, 2.0), (-2, 1), (4, 4), [(1, 2), (0, 2)])


def test_entering_through_each_side():
    check((-1.5, 0.5), (1, 0), (2, 1), [(0, 0), (1, 0)])        # left
    check((3.5, 0.5), (-1, 0), (2, 1), [(1, 0), (0, 0)])        # right
    check((0.5, -2.0), (0, 1), (1, 2), [(0, 0), (0, 1)])        # bottom
    check((0.5, 5.0), (0, -1), (1, 2), [(0, 1), (0, 0)])        # top
    check((-1.0, -0.5), (1, 1), (3, 3), [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2)])


def test_misses():
    check((-1, -1), (-1, 1), (3, 3), [])          # pointing away
    check((-1, 4), (1, 1), (3, 3), [])            # passes above
    check((5, 0.5), (1, 0), (3, 3), [])           # starts past the grid
    check((-1, 0), (1, -1), (3, 3), [])           # heads away below the grid


def test_passes_exactly_through_box_corner():
    # touches the box only at its corner (0, 2): no cell is visited
    check((-1, 1), (1, 1), (2, 2), [])
    # enters exactly through the corner (0, 0)
    check((-1, -1), (1, 1), (2, 2), [(0, 0), (1, 1)])


def test_tmin_tmax_inside_cell():
    check((0.5, 0.5), (1, 0), (5, 1), [(1, 0), (2, 0)], tmin=0.75, tmax=2.25)
    # tmax ending exactly on a grid line: the cell beyond is not visited
    check((0.5, 0.5), (1, 0), (5, 1), [(0, 0), (1, 0)], tmax=1.5)
    # tmin exactly on a grid line: the cell ahead is the first one
    check((0.5, 0.5), (1, 0), (5, 1), [(1, 0), (2, 0)], tmin=0.5, tmax=2.5)
    # empty and negative ranges
    check((0.5, 0.5), (1, 0), (5, 1), [], tmin=2.0, tmax=2.0)
    check((0.5, 0.5), (1, 0), (5, 1), [], tmin=3.0, tmax=1.0)
    check((0.5, 0.5), (1, 0), (5, 1), [(0, 0), (1, 0), (2, 0), (3, 0), (4, 0)], tmin=-math.inf)
    check((2.5, 0.5), (-1, 0), (5, 1), [(2, 0), (1, 0), (0, 0)])


def test_tmin_backwards_reaches_behind_origin():
    check((2.5, 0.5), (1, 0), (5, 1), [(1, 0), (2, 0), (3, 0)], tmin=-1.0, tmax=1.0)


def test_tiny_and_huge_t():
    # a subnormal tmax on a grid line still ends the ray before the next cell
    check((1.0, 0.5), (-1, 0), (3, 1), [(0, 0)], tmax=5e-324)
    check((1.0, 0.5), (1, 0), (3, 1), [(1, 0)], tmax=5e-324)
    check((1.0, 0.5), (1, 0), (3, 1), [(1, 0), (2, 0)], tmax=1e300)
    check((1.0, 0.5), (1, 0), (3, 1), [], tmin=1e300)


def test_negative_zero_components():
    # -0.0 is 0: the half-open rule is the one for dx = 0, [i, i+1)
    check((1.0, 0.5), (-0.0, 1), (3, 2), [(1, 0), (1, 1)])
    check((1.0, 2.0), (-0.0, -1), (3, 2), [(1, 1), (1, 0)])
    check((0.5, 1.0), (1, -0.0), (2, 3), [(0, 1), (1, 1)])
    check((-0.0, -0.0), (1, 1), (2, 2), [(0, 0), (1, 1)])


def test_one_by_one_grid():
    check((0.5, 0.5), (1, 0.3), (1, 1), [(0, 0)])
    check((-3, 0.5), (1, 0), (1, 1), [(0, 0)])
    check((1.0, 0.5), (1, 0), (1, 1), [])
    check((1.0, 0.5), (-1, 0), (1, 1), [(0, 0)])


def test_vertical_ray():
    check((1.5, 0.5), (0, 0), (3, 1), [(1, 0)])
    check((1.0, 0.0), (0, 0), (3, 1), [(1, 0)])     # the forward rule: [i, i+1)
    check((3.0, 0.5), (0, 0), (3, 1), [])
    check((1.5, 0.5), (0, 0), (3, 1), [], tmin=1.0, tmax=1.0)


def test_tiny_and_huge_directions():
    # the direction's scale never matters (the lattice rescales it by a power of two)
    for scale in (2.0**-60, 1e-300, 1e300, 3.0):
        check((0.5, 0.5), (2 * scale, 3 * scale), (4, 4),
              [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 3)])


def test_nearly_flat_direction_rounds_to_axis_parallel():
    # 2^-40 relative is below the lattice's 31 bits: the exact kernels walk the rounded ray
    d = (1.0, 2.0**-40)
    o_q, d_q = algos.quantize([(0.5, 0.5)], [d])
    assert d_q[0, 1] == 0.0
    for name in EXACT:
        assert walk(name, (0.5, 0.5), d, (5, 2)) == [(0, 0), (1, 0), (2, 0), (3, 0), (4, 0)]


@pytest.mark.parametrize("name", EXACT)
def test_origin_far_outside(name):
    """Origins near the 2^30 limit, on a ray that crosses the grid."""
    o = np.array([[-2.0**30, 0.5], [2.0**30, 2.0**30]])
    d = np.array([[1.0, 0.0], [-1.0, -1.0]])
    got = algos.traverse(name, o, d, (4, 4))
    assert as_tuples(got[0]) == [(0, 0), (1, 0), (2, 0), (3, 0)]
    assert as_tuples(got[1]) == [(3, 3), (2, 2), (1, 1), (0, 0)]


@pytest.mark.parametrize("name", list(TRAVERSAL_REGISTRY))
def test_vertical_ray_with_unbounded_range(name):
    """A vertical ray over [-inf, t) visits the cell under its origin in every kernel, the
    float walks too: dda and dda_f32 took its entry point o + (-inf) * 0 = NaN and clamped
    it to cell (0, 0). dda_f32's float32 range makes -1e308 such a tmin as well."""
    for tmin, tmax in ((-math.inf, math.inf), (-math.inf, 1.0), (-1e308, 1e308)):
        expected = algos.reference_cells((1.5, 2.5), (0, 0), (4, 4), tmin, tmax)
        assert expected == [(1, 2)]
        assert walk(name, (1.5, 2.5), (0, 0), (4, 4), tmin, tmax) == expected, (tmin, tmax)
