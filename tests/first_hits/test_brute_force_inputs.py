"""The brute force's inputs and numerics (found by a new user's trial): it validates its
input as ``algos.intersect`` does, an empty range is a miss everywhere, and it raises no
numpy warning (each cause removed, nothing suppressed)."""
import warnings

import numpy as np
import pytest

import algos
from algos.registry import INTERSECTOR_REGISTRY

from .exact_hits import exact_first_hit

C_KERNELS = [n for n, a in INTERSECTOR_REGISTRY.items() if a.kind != "peer" and a.plugin is None]

GOOD_H = np.zeros((5, 6), np.float32)
GOOD_O = [[1.5, 1.5, 2.0], [2.5, 0.5, 3.0]]
GOOD_D = [[1.0, 0.5, -1.0], [0.0, 1.0, -0.5]]


@pytest.mark.parametrize("change", [
    {"origins": [[1.5, np.nan, 2.0], [2.5, 0.5, 3.0]]},
    {"directions": [[1.0, 0.5, -1.0], [0.0, 0.0, 0.0]]},
    {"directions": [[1.0, 0.5, -1.0], [1e-200, 0.0, 0.0]]},
    {"origins": [[2.0 ** 31, 1.5, 2.0], [2.5, 0.5, 3.0]]},
    {"origins": [[1.5, 1.5], [2.5, 0.5]]},
    {"directions": [[1.0, 0.5, -1.0]]},
    {"tmin": [0.0, np.nan]},
    {"tmax": [1.0, 2.0, 3.0]},
    {"surface": "quads"},
    {"heights": np.zeros(5)},
    {"heights": "field.tif"},
    {"heights": np.array([[0.0, np.nan], [0.0, 0.0]])},
])
def test_brute_force_refuses_what_intersect_refuses(change):
    """The same error type, naming the same argument, as algos.intersect."""
    kw = dict(heights=GOOD_H, origins=GOOD_O, directions=GOOD_D, surface="flat")
    kw.update(change)
    with pytest.raises((ValueError, TypeError)) as expected:
        algos.intersect("dda", kw["heights"], kw["origins"], kw["directions"],
                        surface=kw["surface"], tmin=kw.get("tmin"), tmax=kw.get("tmax"))
    with pytest.raises(type(expected.value)) as got:
        algos.brute_force_hits(kw["heights"], kw["origins"], kw["directions"], kw["surface"],
                               tmin=kw.get("tmin"), tmax=kw.get("tmax"))
    assert str(got.value).split(":")[0] == str(expected.value).split(":")[0], (got.value,
                                                                               expected.value)


def test_brute_force_accepts_what_intersect_accepts():
    """Any float dtype, byte order and layout, a scalar range, a HeightField."""
    o = np.asarray(GOOD_O, dtype=">f4")
    d = np.asfortranarray(np.asarray(GOOD_D, dtype=np.float16))
    for heights in (GOOD_H.astype(np.float64), algos.HeightField(GOOD_H + 1)):
        t, cell = algos.brute_force_hits(heights, o, d, "triangles", tmin=0.0, tmax=5.0)
        ref = algos.intersect("dda", heights, o, d, surface="triangles", tmin=0.0, tmax=5.0)
        assert np.allclose(t, ref.t) and np.array_equal(cell, ref.cell)


def test_an_empty_range_is_a_miss_everywhere():
    """tmin > tmax: the conventions' range [tmin, tmax) (first hits: [t0, t1]) is empty, so
    the ray visits no cell and has no hit. Defined, so not refused: every traversal,
    every C intersector, the brute force and the exact references agree on it."""
    H = np.full((5, 6), 3.0, np.float32)  # every ray below starts inside the solid
    o, d = np.array([[0.5, 0.5, 1.0], [4.0, 3.0, 1.0]]), np.array([[1.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
    lo, hi = np.array([2.0, 1.0]), np.array([1.0, -1.0])
    assert algos.reference_cells(o[0, :2], d[0, :2], (5, 4), tmin=2.0, tmax=1.0) == []
    for name in algos.TRAVERSALS:
        paths = algos.traverse(name, o[:, :2], d[:, :2], (5, 4), tmin=lo, tmax=hi)
        assert len(paths.cells) == 0, name
    t, cell = algos.brute_force_hits(H, o, d, "flat", tmin=lo, tmax=hi)
    assert np.all(np.isinf(t)) and np.all(cell == -1)
    for k in range(len(o)):
        assert exact_first_hit(H, o[k], d[k], "flat", lo[k], hi[k]) == (None, (-1, -1))
    for name in C_KERNELS:
        for surface in INTERSECTOR_REGISTRY[name].surfaces:
            hits = algos.intersect(name, H, o, d, surface=surface, tmin=lo, tmax=hi)
            assert np.all(np.isinf(hits.t)) and np.all(hits.cell == -1), (name, surface)
    # the same rays over a one-point range hit at once
    hits = algos.intersect("runs", H, o, d, surface="flat", tmin=lo, tmax=lo)
    assert np.array_equal(hits.t, lo)


def _no_warning(call):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return call()


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_vertical_ray_from_minus_infinity(surface):
    """A vertical ray with tmin = -inf (or -1e300) comes down from above the field and hits
    the cell under it where z reaches the surface, as every kernel says. The brute force
    took z(-inf) * 0 = NaN (a numpy warning) and missed; from -1e300 the linear root over
    [-1e300, 11] rounded to t = 0 on flat, plane3 and triangles."""
    H = np.full((5, 5), 1.0, np.float32)
    o, d = [[2.5, 2.5, 10.0]], [[0.0, 0.0, -1.0]]
    for lo in (-np.inf, -1e300, 0.0):
        t, cell = _no_warning(lambda: algos.brute_force_hits(H, o, d, surface, tmin=lo))
        assert t[0] == 9.0 and tuple(cell[0]) == (2, 2), (lo, t, cell)
        for name in ("dda", "runs", "dda_maxmip"):
            assert algos.intersect(name, H, o, d, surface=surface, tmin=lo).t[0] == 9.0


def test_triangles_midpoint_beyond_the_float_range():
    """A ray with a subnormal dy entering from y = 8 above a 7-row field meets row 5 at
    t = 9.1e307, where the midpoint (ta + tb) / 2 of its one-point piece overflowed
    (inf * -0.0: a numpy warning). Now halved first: no warning, and the kernels' hit."""
    H = np.random.default_rng(5).uniform(0, 4, (7, 9)).astype(np.float32)
    o, d = [[3.0, 8.0, 1.361082540240893]], [[-0.0, -2.2e-308, -2.5822498780869086e+120]]
    t, cell = _no_warning(lambda: algos.brute_force_hits(H, o, d, "triangles", tmin=-1e300))
    ref = algos.intersect("dda", H, o, d, surface="triangles", tmin=-1e300)
    assert t[0] == ref.t[0] and np.array_equal(cell, ref.cell)


def test_a_vertical_ray_rising_from_minus_inf_is_refused_by_intersect_and_brute_force():
    """A ray (0, 0, dz > 0) over a range from tmin = -inf starts infinitely deep inside
    the solid: its hit would be at t = -inf. The kernels disagreed (flat: -inf in the cell
    under the origin, or in cell (0, 0) for the max-mipmap family; the other surfaces and
    the brute force: a miss), so both calls refuse it naming tmin and the ray; every
    finite tmin hits at tmin in the cell under the origin, and a falling ray from -inf is
    taken as before."""
    import algos

    H = np.random.default_rng(5).integers(0, 5, (9, 11)).astype(np.float32)
    o = np.array([[3.5, 2.5, 1.0], [3.5, 2.5, 1.0]])
    d = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.125]])
    message = r"tmin: ray 1 rises vertically from tmin\[1\] = -inf"
    for name in ("dda", "dda_maxmip", "cone"):
        with pytest.raises(ValueError, match=message):
            algos.intersect(name, H, o, d, tmin=[-np.inf, -np.inf])
    with pytest.raises(ValueError, match=message):
        algos.brute_force_hits(H, o, d, tmin=np.array([-np.inf, -np.inf]))
    for surface in ("flat", "triangles", "bilinear"):
        hits = [algos.intersect(n, H, o[1:], d[1:], surface=surface, tmin=[-1e300])
                for n in ("dda", "dda_maxmip", "cone")]
        assert all(h.t[0] == -1e300 and tuple(h.cell[0]) == (3, 2) for h in hits)
    falling = algos.intersect("dda", H, o[1:], -d[1:], tmin=[-np.inf])
    assert np.isfinite(falling.t[0])
