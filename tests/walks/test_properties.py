"""Structural properties of the visited-cell sequence, drawn by Hypothesis (derandomized)."""
import numpy as np
from hypothesis import assume, given
from hypothesis import strategies as st

import algos
from algos.registry import TRAVERSAL_REGISTRY

from ..helpers import as_tuples, reproducer

EXACT = [t.name for t in TRAVERSAL_REGISTRY.values() if t.precision == "exact"]

# coordinates on a 2^-4 lattice (ties common) or arbitrary floats, magnitudes log-uniform
lattice_coord = st.integers(-80, 400).map(lambda k: k / 16)
float_coord = st.floats(-20, 100, allow_nan=False, allow_infinity=False)
coord = st.one_of(lattice_coord, float_coord)
component = st.one_of(
    st.integers(-8, 8).map(float),
    st.tuples(st.floats(-1, 1), st.integers(-30, 30)).map(lambda p: p[0] * 2.0 ** p[1]),
)
sides = st.integers(1, 24)


def _walk(name, o, d, shape, tmin=None, tmax=None):
    return as_tuples(algos.traverse(name, np.array([o]), np.array([d]), shape, tmin, tmax)[0])


def _check_structure(cells, o, d, shape):
    assert len(set(cells)) == len(cells), f"a cell repeats: {cells}"
    for (i0, j0), (i1, j1) in zip(cells, cells[1:]):
        di, dj = abs(i1 - i0), abs(j1 - j0)
        assert (di, dj) in ((1, 0), (0, 1), (1, 1)), f"not adjacent: {(i0, j0)} -> {(i1, j1)}"
        if (di, dj) == (1, 1):
            # a diagonal step only at an exact vertex crossing: the vertex between the
            # two cells lies on the ray
            vx, vy = max(i0, i1), max(j0, j1)
            assert (vx - o[0]) * d[1] == (vy - o[1]) * d[0], f"diagonal step off a vertex: {cells}"
    for i, j in cells:
        assert 0 <= i < shape[0] and 0 <= j < shape[1]


@given(ox=coord, oy=coord, dx=component, dy=component, nx=sides, ny=sides)
def test_structure(ox, oy, dx, dy, nx, ny):
    """Consecutive cells share an edge (a vertex only at a vertex crossing), no cell
    repeats, all cells are inside the grid; every exact kernel equals the reference."""
    (o,), (d,) = algos.quantize([(ox, oy)], [(dx, dy)])
    ref = algos.reference_cells(o, d, (nx, ny))
    _check_structure(ref, o, d, (nx, ny))
    for name in EXACT:
        if TRAVERSAL_REGISTRY[name].shared_direction:
            continue  # its approximated slope is checked in test_exact_kernels
        assert _walk(name, (ox, oy), (dx, dy), (nx, ny)) == ref, reproducer(
            name, (nx, ny), (ox, oy), (dx, dy))


@given(px=lattice_coord, py=lattice_coord, qx=lattice_coord, qy=lattice_coord,
       nx=sides, ny=sides)
def test_reversed_ray(px, py, qx, qy, nx, ny):
    """Walking the segment from Q back to P visits the same cells in reverse order.

    For P, Q on the lattice, the ray P + t (Q - P) on [0, 1) and the ray Q + t (P - Q) on
    [0, 1) give reversed sequences: each half-open rule assigns a point on a grid line to
    the cell ahead, which is the cell behind for the reversed ray, and the two end
    points trade places.
    """
    d = (qx - px, qy - py)
    assume(d != (0.0, 0.0))
    forward = algos.reference_cells((px, py), d, (nx, ny), 0.0, 1.0)
    backward = algos.reference_cells((qx, qy), (-d[0], -d[1]), (nx, ny), 0.0, 1.0)
    assert forward == backward[::-1]
    for name in EXACT:
        f = _walk(name, (px, py), d, (nx, ny), 0.0, 1.0)
        b = _walk(name, (qx, qy), (-d[0], -d[1]), (nx, ny), 0.0, 1.0)
        assert f == forward and b == backward, reproducer(name, (nx, ny), (px, py), d, 0.0, 1.0)


@given(ox=coord, oy=coord, dx=component, dy=component, nx=sides, ny=sides,
       t_split=st.integers(0, 64).map(lambda k: k / 8))
def test_split_range(ox, oy, dx, dy, nx, ny, t_split):
    """[0, s) followed by [s, inf) is [0, inf), with the cell at s shared at most once."""
    whole = algos.reference_cells((ox, oy), (dx, dy), (nx, ny))
    head = algos.reference_cells((ox, oy), (dx, dy), (nx, ny), 0.0, t_split)
    tail = algos.reference_cells((ox, oy), (dx, dy), (nx, ny), t_split)
    joined = head + (tail[1:] if head and tail and head[-1] == tail[0] else tail)
    assert joined == whole
    for name in EXACT:
        if TRAVERSAL_REGISTRY[name].shared_direction:
            continue
        (o,), (d,) = algos.quantize([(ox, oy)], [(dx, dy)])
        assert _walk(name, (ox, oy), (dx, dy), (nx, ny), 0.0, t_split) == \
            algos.reference_cells(o, d, (nx, ny), 0.0, t_split)
