"""bench/studies/horizon_oracle.py: the chain walk started from each vertex's own exact
horizon (the oracle bound, read through the neighbour (0, 0)) gives bit-identical angles
and never more work than the borrowed bounds, on terrain and on a terraced field."""
import numpy as np
import pytest

import datasets_gen
from algos import _kernels
from bench.studies import horizon_oracle


@pytest.mark.parametrize("azimuth", [22.5, 67.5, 200.0, 45.0])
def test_the_oracle_bound_prunes_at_least_as_much_and_changes_no_angle(azimuth):
    h = datasets_gen.load("fbm", size=96, seed=3).heights.astype(np.float64)
    for heights in (h, np.floor(h / 4.0) * 4.0):  # terraces: ties everywhere
        borrowed, oracle, same = horizon_oracle.chain_counts(heights, azimuth)
        assert same
        assert borrowed["bounded"] < 1.0 and oracle["bounded"] > borrowed["bounded"]
        # fewer cells evaluated (the strip tests may rise a little: a higher bound passes
        # more bins, and the climb tests the level above each)
        assert oracle["cells"] <= borrowed["cells"]


def test_a_neighbour_at_zero_needs_distance_zero():
    from algos.terrain.directions import azimuth_direction
    from algos.terrain.walks import chain_strips

    h = np.zeros((8, 8))
    out, occ = np.empty(64), np.full(64, np.nan)
    strips, _ = chain_strips(h, azimuth_direction(90.0))
    with pytest.raises(ValueError, match=r"neighbour 0: expected an offset ahead \(nb_d > 0\), "
                                         r"or \(0, 0\) with nb_d = 0"):
        _kernels.horizon_chain(h, strips, 1.0, 0.0, np.inf, np.zeros(1, np.int64),
                               np.zeros(1, np.int64), np.ones(1), 1, 0, 1, out, occ)
