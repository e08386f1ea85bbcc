"""Every exact kernel equals the exact reference on every ray (docs/CONVENTIONS.md, Exactness).

The reference sequences of one seeded corpus (over 10^4 rays on grids from 1x1 to
1024x1024, non-square ones included, float64 rays and coarse dyadic lattices where ties
are the rule, random tmin/tmax) are computed once and every exact kernel is compared
with them in every output mode.
"""
from fractions import Fraction

import numpy as np
import pytest

import algos
from algos.registry import TRAVERSAL_REGISTRY
from datasets_gen import rays as raysets

from ..helpers import assert_paths_equal, reproducer

EXACT = [t.name for t in TRAVERSAL_REGISTRY.values() if t.precision == "exact"]
SEED = 20260522
BATCH = 100


def _grid(rng):
    # log-uniform sides in [1, 1024], drawn independently: most grids are not square
    nx, ny = (int(round(2 ** rng.uniform(0, 10))) for _ in range(2))
    return nx, ny


def _times(rng, n, lattice):
    tmin = np.where(rng.random(n) < 0.3, rng.uniform(-5, 60, n), 0.0)
    tmax = np.where(rng.random(n) < 0.3, tmin + rng.exponential(40, n), np.inf)
    if lattice:  # parameters that land exactly on grid lines and vertices
        tmin = np.where(rng.random(n) < 0.5, np.round(tmin * 2) / 2, tmin)
        tmax = np.where(rng.random(n) < 0.5, np.round(tmax * 2) / 2, tmax)
    return tmin, tmax


def _corpus():
    rng = np.random.Generator(np.random.PCG64(SEED))
    batches = []
    for b in range(102):
        shape = (1, 1) if b == 0 else (1024, 1024) if b == 1 else _grid(rng)
        kind = b % 3
        if kind == 0:
            rs = raysets.by_run_length("random", BATCH, shape, seed=SEED + b, origins="inside")
            o = rs.origins
            d = rs.directions * 10.0 ** rng.uniform(-3, 3, (BATCH, 1))
        elif kind == 1:
            rs = raysets.uniform(BATCH, shape, seed=SEED + b, origins="around")
            o, d = rs.origins, rs.directions
        else:
            step = 2.0 ** -int(rng.integers(0, 3))
            rs = raysets.lattice(BATCH, shape, seed=SEED + b, origin_step=step,
                                 direction_step=2.0 ** -int(rng.integers(0, 3)))
            o, d = rs.origins, rs.directions
        tmin, tmax = _times(rng, BATCH, lattice=kind == 2)
        oq, dq = algos.quantize(o, d)
        cells = [algos.reference_cells(oq[k], dq[k], shape, tmin[k], tmax[k])
                 for k in range(BATCH)]
        batches.append(dict(shape=shape, o=o, d=d, oq=oq, dq=dq, tmin=tmin, tmax=tmax,
                            cells=cells, seed=SEED + b))
    return batches


@pytest.fixture(scope="module")
def corpus():
    return _corpus()


def _periodic_reference(batch, q_max):
    """reference_cells of the ray runs_periodic walks: the rounded ray with its slope
    replaced by Fraction.limit_denominator(q_max), same origin and major speed."""
    out = []
    for k in range(len(batch["o"])):
        o, d = batch["oq"][k], batch["dq"][k]
        major = algos.major_axis(d)
        if d[major] == 0:
            out.append(batch["cells"][k])
            continue
        slope = (Fraction(abs(d[1 - major])) / Fraction(abs(d[major]))).limit_denominator(q_max)
        approx = [Fraction(d[0]), Fraction(d[1])]
        approx[1 - major] = Fraction(abs(d[major])) * slope * (1 if d[1 - major] >= 0 else -1)
        out.append(algos.reference_cells(o, approx, batch["shape"], batch["tmin"][k],
                                         batch["tmax"][k]))
    return out


def _expected(name, batch):
    if TRAVERSAL_REGISTRY[name].shared_direction:
        return _periodic_reference(batch, algos.DEFAULT_MAX_DENOMINATOR)
    return batch["cells"]


def test_corpus_size(corpus):
    n = sum(len(b["o"]) for b in corpus)
    cells = sum(len(c) for b in corpus for c in b["cells"])
    assert n >= 10_000
    assert cells >= 200_000, "the corpus must exercise long paths, not only misses"


@pytest.mark.parametrize("name", EXACT)
def test_cells_equal_reference(name, corpus):
    for batch in corpus:
        paths = algos.traverse(name, batch["o"], batch["d"], batch["shape"], batch["tmin"],
                               batch["tmax"])
        assert_paths_equal(name, paths, _expected(name, batch), batch["o"], batch["d"],
                           batch["shape"], batch["tmin"], batch["tmax"], batch["seed"])


@pytest.mark.parametrize("name", EXACT)
def test_runs_and_counts_equal_reference(name, corpus):
    for batch in corpus:
        expected_cells = _expected(name, batch)
        expected = [algos.runs_from_cells(c, algos.major_axis(batch["dq"][k]))
                    for k, c in enumerate(expected_cells)]
        runs = algos.traverse(name, batch["o"], batch["d"], batch["shape"], batch["tmin"],
                              batch["tmax"], output="runs")
        assert_paths_equal(name, runs, expected, batch["o"], batch["d"], batch["shape"],
                           batch["tmin"], batch["tmax"], batch["seed"], what="runs")
        counts = algos.traverse(name, batch["o"], batch["d"], batch["shape"],
                                batch["tmin"], batch["tmax"], output="count")
        assert counts.cells.tolist() == [len(c) for c in expected_cells]
        assert counts.runs.tolist() == [len(r) for r in expected]


@pytest.mark.parametrize("name", EXACT)
def test_checksums_agree_with_midpoint(name, corpus):
    """The timed workloads fold the same cells (and runs) as the stored outputs."""
    for batch in corpus[:30]:
        args = (batch["o"], batch["d"], batch["shape"])
        kw = dict(tmin=batch["tmin"], tmax=batch["tmax"])
        for workload in algos.WORKLOADS:
            _, mine = algos.walk_timed(name, *args, workload=workload, **kw)
            _, base = algos.walk_timed("midpoint", *args, workload=workload, **kw)
            if TRAVERSAL_REGISTRY[name].shared_direction:
                continue  # approximate slopes: compared cell by cell above
            assert np.array_equal(mine, base), reproducer(name, batch["shape"],
                                                          batch["o"][0], batch["d"][0])


def test_large_grid_long_rays():
    """Grids of 2^20 cells per side and rays across all of them (the exactness range)."""
    side = 2**20
    rng = np.random.Generator(np.random.PCG64(7))
    n = 6
    o = rng.uniform(0, side, (n, 2))
    phi = rng.uniform(0, 2 * np.pi, n)
    d = np.stack([np.cos(phi), np.sin(phi)], 1)
    tmax = np.full(n, 3000.0)
    expected = [algos.reference_cells(a, b, (side, side), 0.0, 3000.0)
                for a, b in zip(*algos.quantize(o, d))]
    for name in EXACT:
        if TRAVERSAL_REGISTRY[name].shared_direction:
            continue
        paths = algos.traverse(name, o, d, (side, side), tmax=tmax)
        assert_paths_equal(name, paths, expected, o, d, (side, side), None, tmax, 7)
        # full-length rays: counts follow from the end cells (|di| + |dj| + 1 - vertices)
        full = algos.traverse(name, o, d, (side, side), output="cells")
        for k in range(n):
            path = full[k].astype(np.int64)
            steps = np.abs(np.diff(path, axis=0)).sum(axis=1)
            assert np.all((steps == 1) | (steps == 2)), reproducer(name, (side, side), o[k], d[k])
            assert len(np.unique(path, axis=0)) == len(path)
