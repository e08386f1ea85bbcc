"""Exact first-hit kernels on rays off their 2^-16 lattice (docs/kernels.md, "Off-lattice
rays in first hits").

The exact kernels walk the ray rounded onto the lattice but define the first hit on the
caller's ray; where the two lie on different sides of a grid line the walk tests the band
of cells the caller's ray can reach as well. These tests build rays that pass within
1e-6 .. 1e-12 of grid lines and vertices and compare every exact kernel with the brute
force, which tests every cell."""
import numpy as np
import pytest

import algos
from algos.registry import INTERSECTOR_REGISTRY
from datasets_gen import fields

EXACT = [n for n, a in INTERSECTOR_REGISTRY.items() if a.accuracy == "exact"]


def test_the_exact_kernels_are_the_four_lattice_walks():
    assert sorted(EXACT) == ["midpoint", "runs", "runs_maxmip", "runs_periodic"]


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_the_reported_ray(surface):
    """A flat zero field, the ray 1e-6 below the line y = 3 (rounded onto it): t = 0.5."""
    h = np.zeros((8, 7))
    o, d = np.array([[1.9, 2.999999, 0.5]]), np.array([[1.0, 1e-7, -1.0]])
    ref_t, ref_cell = algos.brute_force_hits(h, o, d, surface=surface)
    assert ref_t[0] == 0.5 and tuple(ref_cell[0]) == (2, 2)  # z = 0 at (2.4, 3 - 1e-6)
    for name in EXACT + ["dda", "dda_maxmip"]:
        hits = algos.intersect(name, h, o, d, surface=surface, outputs=("t", "cell"))
        assert hits.t[0] == 0.5 and tuple(hits.cell[0]) == (2, 2), name


def _delta(rng):
    return rng.choice([-1, 1]) * 10.0 ** -rng.uniform(6, 12)


def near_line_rays(shape, seed, n):
    """Off-lattice rays built to pass within 1e-6 .. 1e-12 of grid lines and vertices, in
    six kinds (n // 6 each): an origin just off a line with a near-axis direction; an
    origin near a vertex with a near-diagonal direction; a ray through the near side of a
    vertex mid-flight; a small rational slope (many near-vertex crossings) from a point
    near a vertex; entering through a box face near a corner or nearly along an edge; a
    long ray ending near a face or vertex. z descends from above the field."""
    ny, nx = shape[0] - 1, shape[1] - 1
    rng = np.random.default_rng(seed)
    origins, directions = [], []
    for k in range(n):
        kind = k % 6
        if kind == 0:
            tiny = rng.choice([-1, 1]) * 10.0 ** -rng.uniform(4, 11)
            if rng.random() < 0.5:
                o, d = [rng.uniform(0.2, nx - 0.2), rng.integers(1, ny) + _delta(rng)], [rng.choice([-1, 1]), tiny]
            else:
                o, d = [rng.integers(1, nx) + _delta(rng), rng.uniform(0.2, ny - 0.2)], [tiny, rng.choice([-1, 1])]
        elif kind == 1:
            o = [rng.integers(1, nx) + _delta(rng), rng.integers(1, ny) + _delta(rng)]
            d = [rng.choice([-1, 1]) * (1 + _delta(rng)), rng.choice([-1, 1]) * (1 + _delta(rng))]
        elif kind == 2:
            v = np.array([rng.integers(1, nx), rng.integers(1, ny)], float)
            d = rng.normal(size=2)
            d /= np.abs(d).max()
            perp = np.array([-d[1], d[0]]) / np.hypot(*d)
            o = list(v - rng.uniform(0.5, min(nx, ny) / 2) * d + perp * _delta(rng))
            d = list(d)
        elif kind == 3:
            p, q = rng.integers(1, 5), rng.integers(1, 5)
            d = [q * rng.choice([-1, 1]) * (1 + _delta(rng) * 1e-3), p * rng.choice([-1, 1])]
            o = [rng.integers(1, nx) + _delta(rng), rng.integers(1, ny) + _delta(rng)]
        elif kind == 4:
            side = rng.integers(4)
            d = list(rng.normal(size=2))
            if side < 2:
                o = [-rng.uniform(0.5, 3) if side == 0 else nx + rng.uniform(0.5, 3), _delta(rng) + rng.choice([0, ny])]
                d[0] = abs(d[0]) if side == 0 else -abs(d[0])
            else:
                o = [_delta(rng) + rng.choice([0, nx]), -rng.uniform(0.5, 3) if side == 2 else ny + rng.uniform(0.5, 3)]
                d[1] = abs(d[1]) if side == 2 else -abs(d[1])
            if rng.random() < 0.5:  # nearly along the edge
                a = int(np.argmax(np.abs(d)))
                d[1 - a] = np.sign(d[1 - a] or 1.0) * 10.0 ** -rng.uniform(5, 11)
        else:
            o = [rng.uniform(0, nx), rng.uniform(0, ny)]
            end = [rng.integers(0, nx + 1) + _delta(rng), rng.integers(0, ny + 1) + _delta(rng)]
            d = [end[0] - o[0], end[1] - o[1]]
        origins.append([o[0], o[1], rng.uniform(2.0, 9.0)])
        directions.append([d[0], d[1], -rng.uniform(0.02, 0.6) * max(abs(d[0]), abs(d[1]))])
    return np.array(origins), np.array(directions)


def _near_vertex(o, d, t, tol=1e-8):
    """Rays whose hit lies within tol of a grid vertex: there the caller's ray touches the
    side cells within float64's resolution of t, and a hit at the same t may be reported
    in either cell (the brute force decides such touches in exact arithmetic)."""
    with np.errstate(invalid="ignore"):
        p = o[:, :2] + np.where(np.isfinite(t), t, 0)[:, None] * d[:, :2]
    return np.all(np.abs(p - np.round(p)) < tol, axis=1) & np.isfinite(t)


# (shape, seed, rays): small grids, and a larger one so that long rays carry the direction
# rounding over hundreds of cells
CASES = [((24, 31), 1, 300), ((200, 170), 2, 120)]


@pytest.fixture(scope="module", params=CASES, ids=lambda c: f"{c[0][0]}x{c[0][1]}")
def field_rays(request):
    shape, seed, n = request.param
    o, d = near_line_rays(shape, seed, n)
    return {
        "terraces": fields.generate("terraces", shape, seed=4, amplitude=6.0, scale=16.0),
        "uniform": fields.generate("uniform", shape, seed=5, high=6.0),
    }, o, d


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_off_lattice_rays_match_the_brute_force(field_rays, surface):
    """t equal to the brute force's (the tolerance of test_intersect, 1e-9 (1 + |t|)) and
    hit/miss alike for every ray; the cell too, but for hits within 1e-8 of a vertex."""
    fs, o, d = field_rays
    lattice = np.all(np.round(o[:, :2] * 65536) == o[:, :2] * 65536, axis=1)
    assert not lattice.any()  # every origin is off the lattice
    for fname, H in fs.items():
        ref_t, ref_cell = algos.brute_force_hits(H, o, d, surface)
        assert np.isfinite(ref_t).sum() > len(ref_t) // 2  # the rays do hit
        tie = _near_vertex(o, d, ref_t)
        for name in EXACT:
            hits = algos.intersect(name, H, o, d, surface=surface, outputs=("t", "cell"))
            same = np.isfinite(hits.t) == np.isfinite(ref_t)
            both = np.isfinite(hits.t) & np.isfinite(ref_t)
            same[both] &= np.abs(hits.t[both] - ref_t[both]) <= 1e-9 * (1 + np.abs(ref_t[both]))
            # (a run kernel may still meet a side cell of a vertex the caller's ray passes
            # by ~1e-8 on a one-point interval: the cell test does not take such a cell,
            # docs/CONVENTIONS.md, "Points on a cell border")
            bad = np.nonzero(~same)[0]
            assert not len(bad), (name, fname, surface, o[bad[0]].tolist(), d[bad[0]].tolist(),
                                  ref_t[bad[0]], hits.t[bad[0]])
            skip = tie.copy()
            cell_bad = np.nonzero(np.any(hits.cell != ref_cell, axis=1) & ~skip)[0]
            assert not len(cell_bad), (name, fname, surface, o[cell_bad[0]].tolist(),
                                       d[cell_bad[0]].tolist(), ref_cell[cell_bad[0]],
                                       hits.cell[cell_bad[0]])


def test_lattice_rays_do_not_pay_for_the_band():
    """On the lattice the band is off: the work counters are the walk's alone, and equal
    to those of the same rays a hair off the lattice where no line is near (the band
    adds a cell only near a line)."""
    H = fields.generate("uniform", (40, 40), seed=9, high=6.0)
    o = np.array([[3.25, 4.5, 9.0], [20.125, 30.0625, 9.0]])
    d = np.array([[1.0, 0.5, -0.2], [-0.75, -0.25, -0.1]])
    off = o + np.array([1e-9, 1e-9, 0.0])
    for name in EXACT:
        a = algos.intersect(name, H, o, d, outputs=("t", "stats"))
        b = algos.intersect(name, H, off, d, outputs=("t", "stats"))
        ref_t, _ = algos.brute_force_hits(H, off, d)
        assert np.allclose(b.t, ref_t, rtol=1e-9, atol=1e-9), name
        assert np.array_equal(a.stats["cells_visited"], b.stats["cells_visited"]), name


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_rounded_ray_outside_the_box_or_parallel_to_an_axis(surface):
    """Rays whose rounded ray meets no cell of the grid while the caller's ray does (it
    creeps into the box along an edge: the rounded origin lies 1.5e-5 outside and its
    rounded slope enters only beyond the far side), and rays whose rounded direction is
    parallel to an axis (a component below 2^-31 of the other, 1e-13) 3e-6 below a grid
    line: every exact kernel equals the brute force."""
    H = fields.generate("terraces", (24, 31), seed=4, amplitude=6.0, scale=16.0)
    o = np.array([[-1.0, -8e-6, 9.0], [31.0, 23 + 8e-6, 9.0], [-1.0, 5.0 - 3e-6, 9.0],
                  [12.5 - 3e-6, 25.0, 9.0]])
    d = np.array([[1.0, 3e-7, -0.3], [-1.0, -3e-7, -0.3], [1.0, 1e-13, -0.3], [-1e-13, -1.0, -0.3]])
    ref_t, ref_cell = algos.brute_force_hits(H, o, d, surface)
    assert np.all(np.isfinite(ref_t))
    for name in EXACT:
        hits = algos.intersect(name, H, o, d, surface=surface, outputs=("t", "cell"))
        assert np.allclose(hits.t, ref_t, rtol=1e-9, atol=1e-9), (name, hits.t, ref_t)
        assert np.array_equal(hits.cell, ref_cell), (name, hits.cell, ref_cell)
