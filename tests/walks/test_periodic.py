"""runs_periodic: exact for slopes p/q with q <= Q, the documented approximation otherwise."""
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import algos
from algos import _kernels

from ..helpers import as_tuples, assert_paths_equal


@given(num=st.integers(0, 2**31), extra=st.integers(0, 2**31), q_max=st.integers(1, 2**24))
def test_best_rational_matches_limit_denominator(num, extra, q_max):
    den = max(1, num + extra)
    expected = Fraction(num, den).limit_denominator(q_max)
    assert _kernels.best_rational(num, den, q_max) == (expected.numerator, expected.denominator)


def _octants(p, q):
    """The direction of slope p/q mirrored into all 8 octants."""
    out = []
    for swap in (False, True):
        for sx in (1, -1):
            for sy in (1, -1):
                a, b = (p, q) if swap else (q, p)
                out.append((sx * a, sy * b))
    return out


@pytest.mark.parametrize("p,q", [(0, 1), (1, 1), (1, 2), (17, 41), (3, 1000), (999, 1000),
                                 (4093, 65521), (1, 65536)])
def test_exact_for_small_denominators(p, q):
    """Parallel rays of slope p/q (q <= Q) share one pattern and equal the exact kernels."""
    rng = np.random.Generator(np.random.PCG64(p * 7919 + q))
    n = 64
    shape = (300, 170)
    for direction in _octants(p, q):
        o = rng.uniform(-20, 320, (n, 2))
        o[: n // 4] = np.round(o[: n // 4])  # grid lines and corners
        d = np.tile(np.array(direction, float), (n, 1))
        tmin = np.where(rng.random(n) < 0.3, rng.uniform(0, 5, n), 0.0)
        got = algos.traverse("runs_periodic", o, d, shape, tmin=tmin)
        expected = algos.traverse("runs", o, d, shape, tmin=tmin)
        assert got.cells.tolist() == expected.cells.tolist(), direction
        assert got.offsets.tolist() == expected.offsets.tolist()


def test_small_q_is_the_documented_approximation():
    """With Q = 16 the walk is the exact walk of the ray with slope limit_denominator(16)."""
    rng = np.random.Generator(np.random.PCG64(5))
    n, shape, q_max = 200, (120, 90), 16
    phi = rng.uniform(0, 2 * np.pi)
    o = rng.uniform(0, 120, (n, 2))
    d = np.tile([np.cos(phi), np.sin(phi)], (n, 1))
    got = algos.traverse("runs_periodic", o, d, shape, max_denominator=q_max)
    oq, dq = algos.quantize(o, d)
    major = algos.major_axis(dq[0])
    slope = (Fraction(abs(dq[0, 1 - major])) / Fraction(abs(dq[0, major]))).limit_denominator(q_max)
    approx = [Fraction(dq[0, 0]), Fraction(dq[0, 1])]
    approx[1 - major] = abs(Fraction(dq[0, major])) * slope * (1 if dq[0, 1 - major] >= 0 else -1)
    expected = [algos.reference_cells(oq[k], approx, shape) for k in range(n)]
    assert_paths_equal("runs_periodic", got, expected, o, d, shape)
    # and it is an approximation: the exact walk differs somewhere
    exact = algos.traverse("runs", o, d, shape)
    assert got.cells.tolist() != exact.cells.tolist()


def test_pattern_repeats_every_p_runs():
    p, q = 17, 41
    runs = algos.traverse("runs_periodic", np.array([[0.0, 0.5]]), np.array([[q, p]], float),
                          (2000, 1000), output="runs")[0]
    lengths = np.diff(runs[1:, 1])  # 8-connected lengths of the complete runs
    assert len(lengths) > 3 * p
    assert np.array_equal(lengths[:p], lengths[p:2 * p])
    assert lengths[:p].sum() == q


def test_changing_directions_rebuild_the_pattern():
    """Directions that change from ray to ray are still walked correctly."""
    d = np.array([[41, 17], [17, 41], [41, 17], [-5, 3], [1, 0], [41, 17]], float)
    o = np.full((len(d), 2), 10.3)
    got = algos.traverse("runs_periodic", o, d, (50, 50))
    expected = algos.traverse("runs", o, d, (50, 50))
    assert [as_tuples(p) for p in got] == [as_tuples(p) for p in expected]


def test_max_denominator_validation():
    o, d = np.zeros((1, 2)), np.ones((1, 2))
    with pytest.raises(ValueError, match="max_denominator"):
        algos.traverse("runs_periodic", o, d, (4, 4), max_denominator=0)
    with pytest.raises(ValueError, match="max_denominator"):
        algos.traverse("runs", o, d, (4, 4), max_denominator=16)
    with pytest.raises(TypeError, match="max_denominator"):
        algos.traverse("runs_periodic", o, d, (4, 4), max_denominator=2.5)
