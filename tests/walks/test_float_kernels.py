"""Float kernels away from ties: on generic rays they must equal the reference.

Near ties (crossings of an x and a y grid line closer than the kernel's rounding) their
divergence is a result for the accuracy study, not a test failure, so these tests use
rays whose crossings are well separated, and say how separated.
"""
from fractions import Fraction

import numpy as np
import pytest

import algos
from algos.registry import TRAVERSAL_REGISTRY
from datasets_gen import rays as raysets

from ..helpers import as_tuples, reproducer

FLOAT = {t.name: t for t in TRAVERSAL_REGISTRY.values() if t.precision != "exact"}
# relative separation of distinct crossings (in units of the ray length) we call "away
# from ties" for each precision; also the distance of the end points from grid lines
SEPARATION = {"float64": 1e-9, "float32": 1e-4}


def _well_separated(o, d, shape, gap):
    """True when every pair of x/y crossing parameters within the grid, and the entry
    and exit, differ by more than `gap` times the total parameter span."""
    o = [Fraction(v) for v in o]
    d = [Fraction(v) for v in d]
    ts = []
    for axis in (0, 1):
        if d[axis] == 0:
            if abs(o[axis] - round(o[axis])) < gap:
                return False
            continue
        for k in range(0, shape[axis] + 1):
            ts.append((k - o[axis]) / d[axis])
    ts = sorted(t for t in ts if t >= 0)
    if not ts:
        return True
    span = max(ts[-1], Fraction(1))
    return all(b - a > gap * span for a, b in zip(ts, ts[1:])) and (not ts or ts[0] > gap * span)


@pytest.mark.parametrize("name", sorted(FLOAT))
def test_generic_rays_equal_reference(name):
    precision = FLOAT[name].precision
    rs = raysets.by_run_length("random", 600, (64, 48), seed=11, origins="inside")
    o, d = rs.origins, rs.directions
    keep = [k for k in range(len(o)) if _well_separated(o[k], d[k], (64, 48), SEPARATION[precision])]
    assert len(keep) > 300, "the filter must leave most rays"
    paths = algos.traverse(name, o[keep], d[keep], (64, 48))
    for idx, k in enumerate(keep):
        expected = algos.reference_cells(o[k], d[k], (64, 48))
        assert as_tuples(paths[idx]) == expected, reproducer(name, (64, 48), o[k], d[k], seed=11)


@pytest.mark.parametrize("name", sorted(FLOAT))
def test_axis_parallel_and_diagonal(name):
    """Exactly representable easy cases: axis-parallel rays and diagonals from cell centres."""
    o = np.array([[0.5, 1.5], [7.5, 1.5], [2.5, 0.5], [2.5, 7.5], [0.5, 0.5], [7.5, 7.5]])
    d = np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [-1, -1]], float)
    paths = algos.traverse(name, o, d, (8, 8))
    for k in range(len(o)):
        assert as_tuples(paths[k]) == algos.reference_cells(o[k], d[k], (8, 8)), name
