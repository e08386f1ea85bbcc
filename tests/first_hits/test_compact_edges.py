"""dda_compact equals dda_maxmip bit for bit (t, cell, normal) on the rays where a walk
that decides a node's children at once could part from the walk child by child: through
the children's corners (ties of the x and y faces), ending inside a node, at the grid's
edge (children outside the grid), ascending or level (z at the entry, dz 0), and from
far away or with tiny components (faces too close to tell apart). Written for the
node-at-once test of issue 31 (docs/kernels.md, "All children of a node at once"), which
was measured and not merged; the rays stay as edge cases of the walk child by child and
of the uint8 leaves."""
import numpy as np
import pytest

import algos
from datasets_gen import fields

OUTPUTS = ("t", "cell", "normal")


def _field(rows, cols, seed):
    return algos.Field(np.asarray(fields.fbm(rows, cols, seed=seed), np.float32))


def _assert_equal_to_maxmip(fld, o, d, label, **kw):
    """dda_compact's t, cell and normal are dda_maxmip's, bit for bit, on every ray."""
    for surface in ("triangles", "bilinear"):
        got = algos.intersect("dda_compact", fld, o, d, surface=surface, outputs=OUTPUTS, **kw)
        ref = algos.intersect("dda_maxmip", fld, o, d, surface=surface, outputs=OUTPUTS, **kw)
        for k in OUTPUTS:
            a, b = getattr(got, k), getattr(ref, k)
            same = (a == b) | (np.isnan(a) & np.isnan(b))
            bad = np.flatnonzero(~same.reshape(len(o), -1).all(axis=1))
            assert bad.size == 0, (
                f"{label}, {surface}: {k} differs on ray {bad[0]}: origin "
                f"{o[bad[0]].tolist()!r}, direction {d[bad[0]].tolist()!r}, grid "
                f"{fld.heights.shape}: dda_compact {a[bad[0]]!r}, dda_maxmip {b[bad[0]]!r}")


def _lattice_origins(rng, fld, n, step, z):
    rows, cols = fld.heights.shape
    return np.c_[(rng.integers(0, cols, n) // step) * step,
                 (rng.integers(0, rows, n) // step) * step, np.full(n, z)].astype(float)


@pytest.mark.parametrize("step", [1, 4, 16, 64])
def test_diagonal_rays_through_children_corners(step):
    """|dx| == |dy| from lattice points on multiples of `step`: the x and y faces tie at
    every corner of a child, so the walk steps diagonally past two children."""
    rng = np.random.Generator(np.random.PCG64(step))
    fld = _field(257, 300, 3)
    n = 1500
    o = _lattice_origins(rng, fld, n, step, float(fld.heights.max()) + 0.5)
    signs = rng.choice([-1.0, 1.0], (n, 2))
    d = np.c_[signs, -rng.uniform(0.001, 0.2, n)]
    _assert_equal_to_maxmip(fld, o, d, f"diagonal, step {step}")


def test_small_integer_directions_from_the_lattice():
    """Directions of small integers from lattice points: faces tie with other faces."""
    rng = np.random.Generator(np.random.PCG64(7))
    fld = _field(257, 300, 5)
    n = 3000
    o = _lattice_origins(rng, fld, n, 4, float(fld.heights.max()) + 1.0)
    d = np.c_[rng.integers(-4, 5, n), rng.integers(-4, 5, n), -rng.uniform(0.01, 1.0, n)]
    d[(d[:, 0] == 0) & (d[:, 1] == 0), 0] = 1.0
    _assert_equal_to_maxmip(fld, o, d.astype(float), "integer directions")


def test_rays_ending_inside_nodes():
    """tmax inside the grid: the ray's end falls inside a node, before its last child."""
    rng = np.random.Generator(np.random.PCG64(11))
    fld = _field(300, 300, 2)
    n = 3000
    o = np.c_[rng.uniform(0, 299, (n, 2)), np.full(n, float(fld.heights.max()) + 1.0)]
    az = rng.uniform(0, 2 * np.pi, n)
    d = np.c_[np.cos(az), np.sin(az), -rng.uniform(0.01, 0.3, n)]
    tmax = rng.uniform(1.0, 200.0, n)
    _assert_equal_to_maxmip(fld, o, d, "ending inside", tmin=np.zeros(n), tmax=tmax)


@pytest.mark.parametrize("shape", [(5, 17), (67, 131), (130, 66), (259, 261)])
def test_nodes_at_the_grid_edge(shape):
    """Grids whose sides are no multiple of 4^L: nodes at the high edges hold children
    outside the grid; rays head for those edges from inside."""
    rng = np.random.Generator(np.random.PCG64(shape[0]))
    fld = _field(*shape, 4)
    rows, cols = shape
    n = 2000
    o = np.c_[rng.uniform(0, cols - 1, n), rng.uniform(0, rows - 1, n),
              rng.uniform(float(fld.heights.min()), float(fld.heights.max()) + 1.0, n)]
    d = np.c_[rng.uniform(0.05, 1.0, (n, 2)) * rng.choice([-1.0, 1.0, 1.0], (n, 2)),
              -rng.uniform(0.0, 0.2, n)]
    _assert_equal_to_maxmip(fld, o, d, f"grid {shape}")


@pytest.mark.parametrize("dz", [0.0, -0.0, 0.05, 0.5])
def test_level_and_ascending_rays(dz):
    """dz >= 0 (and -0.0): the tile's lowest z is at its entry; dz 0 makes -inf * 0."""
    rng = np.random.Generator(np.random.PCG64(int(dz * 100) + 1))
    fld = _field(257, 300, 6)
    n = 2000
    lo, hi = float(fld.heights.min()), float(fld.heights.max())
    o = np.c_[rng.uniform(0, 299, n), rng.uniform(0, 256, n), rng.uniform(lo - 1.0, hi, n)]
    az = rng.uniform(0, 2 * np.pi, n)
    d = np.c_[np.cos(az), np.sin(az), np.full(n, dz)]
    _assert_equal_to_maxmip(fld, o, d, f"dz {dz!r}")


def test_far_origins_and_extreme_directions():
    """Origins up to 10^9 away (2^30 is the documented limit), and one direction component
    down to 10^-300: its inverse beyond 2^900, a ray the nodes' test leaves to the walk
    child by child, and rays just inside that range."""
    rng = np.random.Generator(np.random.PCG64(13))
    fld = _field(257, 300, 8)
    n = 1500
    target = np.c_[rng.uniform(0, 299, n), rng.uniform(0, 256, n),
                   rng.uniform(float(fld.heights.min()), float(fld.heights.max()), n)]
    far = 10.0 ** rng.uniform(6, 9, n)[:, None] * rng.choice([-1.0, 1.0], (n, 2))
    o = np.c_[far, target[:, 2:] + 1.0]
    _assert_equal_to_maxmip(fld, o, target - o, "far origins")
    tiny = np.c_[rng.normal(size=(n, 2)) * 10.0 ** rng.uniform(-300, 0, (n, 2)),
                 -rng.uniform(0.1, 1.0, n)]
    o = np.c_[target[:, :2], np.full(n, float(fld.heights.max()) + 1.0)]
    _assert_equal_to_maxmip(fld, o, tiny, "tiny components")
