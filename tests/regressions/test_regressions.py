"""Every bug found so far, pinned with the exact inputs that exposed it."""
import numpy as np
import pytest

import algos
from datasets_gen import fields

STRICT = [n for n, a in algos.INTERSECTOR_REGISTRY.items() if a.accuracy in ("exact", "float64")]


def _all_agree(H, o, d, surface, expected_t):
    for name in STRICT:
        t = algos.intersect(name, H, [o], [d], surface=surface).t[0]
        if np.isinf(expected_t):
            assert np.isinf(t), name
        else:
            assert t == pytest.approx(expected_t, rel=1e-9, abs=1e-12), name


def test_plane3_reaches_beyond_its_corners():
    """plane3 extrapolates to h10 + h01 - h00 at the fourth corner, outside the corner
    maximum and minimum: culling and the box clip once used the corners and missed.
    (uniform field, seed 1, shape (33, 41))"""
    H = fields.generate("uniform", (33, 41), seed=1)
    o = [44.036859990061934, 25.45495615266278, 0.22575937760422082]
    d = [-1.6238068064859852, -0.7126172349773741, -0.35659747600143765]
    t, _ = algos.brute_force_hits(H, [o], [d], "plane3")
    assert t[0] == pytest.approx(2.53961637, rel=1e-8)
    _all_agree(H, o, d, "plane3", t[0])


def test_below_hmin_when_entering_through_a_side():
    """A descending ray already below hmin at its entry: the z clip once made its interval
    empty; it hits the side wall at t0. (terraces, seed 1, shape (33, 41))"""
    H = fields.generate("terraces", (33, 41), seed=1)
    o = [43.08285968318934, 8.257714873029965, 7.4406334200266]
    d = [-0.7554195256557019, -0.05896497644148844, -0.3397005407575456]
    t0 = (40.0 - o[0]) / d[0]
    for surface in algos.SURFACES:
        _all_agree(H, o, d, surface, t0)


def test_ray_away_from_the_box_below_hmin_misses():
    """The fix above must not resurrect rays that miss the footprint."""
    H = fields.generate("fbm", (33, 41), seed=1, amplitude=6.0)
    o = [-3.62204434, 10.09402609, -2.19835895]
    d = [-2.85817538, 0.54977622, -0.23690856]
    _all_agree(H, o, d, "flat", np.inf)


def test_flat_field_hit_exactly_at_hmin_equals_hmax():
    """hmin == hmax: the z clip leaves a hair-thin interval; rounding in z(t) once pushed
    the hit out of it (and float32 collapsed it)."""
    H = np.zeros((33, 41), np.float32)
    o = [15.327119883776824, 27.348692653674945, 3.447692632548387]
    d = [1.1646712675099478, 0.5997488312710689, -0.7095066390341976]
    expected = 3.447692632548387 / 0.7095066390341976
    for surface in algos.SURFACES:
        _all_agree(H, o, d, surface, expected)
        t = algos.intersect("dda_f32", H, [o], [d], surface=surface).t[0]
        assert t == pytest.approx(expected, rel=1e-9)


def test_bilinear_hit_exactly_at_the_end_of_the_interval():
    """The linear branch of the quadratic solver found a root one ulp past the interval
    and gave up. (spike field, shape (33, 41))"""
    H = fields.generate("spike", (33, 41), seed=1)
    o = [22.479684383652973, 12.249198930075462, 4.2924332252096455]
    d = [0.9164229099842688, -0.0905729440598697, -0.3178381370070811]
    t, _ = algos.brute_force_hits(H, [o], [d], "bilinear")
    _all_agree(H, o, d, "bilinear", t[0])


def test_bilinear_near_linear_root_is_exact():
    """A tiny bilinear twist (one corner 6.4e-9): the C root matches the rational root to
    1e-16; the brute force's closed form was 2e-9 off until its roots were polished."""
    H = fields.generate("spike", (33, 41), seed=1)
    o = [22.870444004545504, 8.553104111834845, 0.4016805754443875]
    d = [-1.011149921008371, -1.2564974123803219, -0.526589012498888]
    exact = 0.762797100752577  # bisection in Fractions
    t, _ = algos.brute_force_hits(H, [o], [d], "bilinear")
    assert t[0] == pytest.approx(exact, rel=1e-12)
    for name in STRICT:
        assert algos.intersect(name, H, [o], [d], surface="bilinear").t[0] == pytest.approx(exact, rel=1e-12)


def test_vertical_ray_on_a_vertex():
    """A vertical ray: the brute force once evaluated inf * 0."""
    H = fields.generate("fbm", (33, 41), seed=3, amplitude=6.0, scale=16.0)
    o, d = [18.0, 9.0, 8.543740334754673], [0.0, 0.0, -1.0]
    for surface in algos.SURFACES:
        t, cell = algos.brute_force_hits(H, [o], [d], surface)
        assert np.isfinite(t[0]) and tuple(cell[0]) == (18, 9), surface
    # on the vertex's grid lines the kernels still test every cell around it where flat
    # and plane3 jump (pinned in tests/first_hits/test_conventions.py); the continuous surfaces agree
    for surface in ("triangles", "bilinear"):
        _all_agree(H, o, d, surface, algos.brute_force_hits(H, [o], [d], surface)[0][0])


def test_direction_near_the_float_limit():
    """Rounding a direction near DBL_MAX carried it to 2^1024 = inf; such directions are
    now rejected with a message (Hypothesis found it)."""
    with pytest.raises(ValueError, match=r"2\*\*1000"):
        algos.traverse("runs", [[0.0, 0.0]], [[1.7976931348623157e308, 1.0]], (4, 4))


def test_sub_lattice_offset_is_rounded_as_documented():
    """y = 7.99999992 lies below the 2^-16 lattice: the exact kernels walk y = 8."""
    o, d = [[59.0, 7.999999920312047]], [[1.0, 0.08355887502787454]]
    (oq,), (dq,) = algos.quantize(o, d)
    assert oq[1] == 8.0
    got = algos.traverse("runs", o, d, (64, 48))[0].tolist()
    assert got == [list(c) for c in algos.reference_cells(oq, dq, (64, 48))]


def test_ray_lying_in_a_flat_triangle():
    """A horizontal ray at exactly the height of a flat upper triangle: the first hit is
    where it crosses onto that triangle (the diagonal). Both the brute force and the C
    test once interpolated from the other triangle's value at the diagonal, which rounding
    can put a hair above the ray, and reported the end of the cell instead."""
    H = np.array([[4.0, 2.6666667461395264], [4.0, 4.0]], np.float32)
    o = [0.9, 0.2, 4.0]                # inside the lower triangle (u > v), heading to u < v
    d = [-1.2386443758091474, 1.7813206828903434, 0.0]
    # the diagonal u = v: 0.9 - 1.2386 t = 0.2 + 1.7813 t
    t_diag = (0.9 - 0.2) / (1.2386443758091474 + 1.7813206828903434)
    t, _ = algos.brute_force_hits(H, [o], [d], "triangles")
    assert t[0] == pytest.approx(t_diag, rel=1e-12)
    _all_agree(H, o, d, "triangles", t_diag)
    # the field it was found on (terraces, seed 2), with its exact literals
    from datasets_gen import load
    T = load("terraces", size=(97, 129), seed=2, levels=6, scale=24.0, amplitude=8.0, use_cache=False).heights
    o = [26.759644051837327, 54.05022559256715, 4.0]
    d = [-1.2386443758091474, 1.7813206828903434, 0.0]
    ref, _ = algos.brute_force_hits(T, [o], [d], "triangles")
    assert ref[0] == pytest.approx(7.188632330937978, rel=1e-9)
    _all_agree(T, o, d, "triangles", ref[0])
