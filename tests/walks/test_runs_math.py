"""The run mathematics of the seeds, derived and checked against the definition."""
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import algos
from algos.seed import digital_line_run_lengths, run_pattern, seed_run_lengths

slopes = st.tuples(st.integers(1, 200), st.integers(1, 200)).map(
    lambda pq: Fraction(min(pq), max(pq)))
offsets = st.integers(0, 999).map(lambda k: Fraction(k, 1000))


@given(alpha=slopes, beta=offsets)
def test_recurrence_matches_definition(alpha, beta):
    assert seed_run_lengths(alpha, beta, 40) == digital_line_run_lengths(alpha, beta, 40)


def test_slides_example_first_run_is_long():
    # y = 17/41 x, beta_0 = 0: the first run covers x = 0, 1, 2 (three samples: long)
    lengths = seed_run_lengths(Fraction(17, 41), 0, 17)
    assert lengths[0] == 3
    assert sum(lengths) == 41, "one period: 17 runs over 41 samples"
    assert run_pattern(17, 41) == "lslslsslslsslslss"


def test_printed_inequality_is_reversed():
    """The slides' "beta_j >= v -> long" contradicts the definition on their own example."""
    alpha = Fraction(17, 41)
    r = math.floor(1 / alpha)
    v = 1 - alpha * r
    printed, b = [], Fraction(0)
    for _ in range(5):
        long_run = b >= v  # as printed on the slides
        printed.append(r + 1 if long_run else r)
        b += alpha * printed[-1] - 1
    assert printed != digital_line_run_lengths(alpha, 0, 5)
    assert printed[0] == 2  # it would make the first run short


@given(alpha=slopes, beta=offsets)
def test_start_clipping_formulas(alpha, beta):
    r = math.floor(1 / alpha)
    v = 1 - alpha * r
    r0 = math.ceil((1 - beta) / alpha)
    assert r0 == r - math.floor((beta - v) / alpha)
    assert (r0 < r) == (beta >= alpha + v)


@pytest.mark.parametrize("p,q", [(17, 41), (1, 1), (1, 5), (2, 5), (5, 8), (13, 21), (99, 100)])
def test_pattern_is_periodic(p, q):
    lengths = seed_run_lengths(Fraction(p, q), 0, 3 * p)
    assert lengths[:p] == lengths[p:2 * p] == lengths[2 * p:]
    assert sum(lengths[:p]) == q
    assert set(lengths) <= {q // p, -(-q // p)}


@pytest.mark.parametrize("name", ["runs", "runs_periodic", "midpoint"])
@pytest.mark.parametrize("beta", [0.3, 0.0625, 0.9])
def test_kernel_runs_follow_the_recurrence(name, beta):
    """On the ray through (0, beta) with slope 17/41 the kernels' run starts advance by the
    seed's run lengths: no crossing hits an integer x, so cell runs and sample runs have
    the same lengths, and the first run ends in the column before the second begins."""
    runs = algos.traverse(name, np.array([[0.0, beta]]), np.array([[41.0, 17.0]]),
                          (400, 200), output="runs")[0]
    firsts = runs[:, 1].astype(int)
    lengths = seed_run_lengths(Fraction(17, 41), Fraction(beta), len(firsts))
    # row j >= 1 starts in column floor(x_cross) = x_j - 1, so the steps are the lengths
    assert np.diff(firsts)[1:].tolist() == lengths[1:len(firsts) - 1]
    # the clipped first run: r_0 samples, ending in the crossing column r_0 - 1
    assert runs[0, 1] == 0 and runs[0, 2] == lengths[0] - 1
