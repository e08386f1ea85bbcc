"""The accuracy and stress studies: their exactness claims hold on small runs."""
import numpy as np

import algos
from bench.studies import accuracy, stress


def test_lattice_rays_are_on_the_lattice():
    o, d = accuracy.lattice_rays(50, 64, seed=1)
    oq, dq = algos.quantize(o, d)
    assert np.array_equal(o, oq) and np.array_equal(d, dq)


def test_traversal_rows_exact_kernels_never_diverge():
    rows = accuracy.traversal_rows(256, 60, (32, 256), seed=2, q_values=(16, 65536))
    for r in rows:
        if r["algorithm"] in ("midpoint", "runs", "runs_periodic[Q=2^16]"):
            assert r["diverged_fraction"] == 0, r
    coarse = [r for r in rows if r["algorithm"] == "runs_periodic[Q=2^4]" and r["cells"] == 256]
    assert coarse[0]["diverged_fraction"] > 0  # a coarse slope approximation shows


def test_exact_triangle_hits_agree_with_kernels():
    H = algos.Field(np.asarray(
        __import__("datasets_gen").load("fbm", size=32, seed=3, scale=8.0, amplitude=3.0).heights))
    rng = np.random.Generator(np.random.PCG64(4))
    n = 12
    o = np.column_stack([rng.uniform(0, 31, (n, 2)), np.full(n, 5.0)])
    d = np.column_stack([rng.normal(size=(n, 2)), np.full(n, -0.3)])
    exact = accuracy.exact_triangle_hits(H.heights, o, d)
    ours = algos.intersect("runs", H, o, d).t
    assert np.array_equal(np.isfinite(exact), np.isfinite(ours))
    ok = np.isfinite(exact)
    assert np.allclose(ours[ok], exact[ok], rtol=1e-12, atol=1e-12)


def test_pareto_front():
    points = [(1, 5), (2, 2), (3, 3), (4, 1), (2, 6)]
    assert accuracy.pareto(points) == [0, 1, 3]


def test_long_rays_exact_kernels_do_not_drift():
    rows = stress.drift_rows([2**10, 2**12], seed=9)
    for r in rows:
        if r["precision"] == "exact":
            assert r["diverged_percent"] == 0.0, r
    f32 = [r for r in rows if r["algorithm"] == "dda_f32" and r["cells"] == 2**12]
    assert f32[0]["diverged_percent"] > 0  # near 2^16 float32 resolves 0.004 cell


def test_adversarial_families_exact_kernels_match():
    rows = stress.family_rows((64, 48), 16, seed=4)
    for r in rows:
        if r["algorithm"] in ("midpoint", "runs"):
            assert r["differ"] == 0, r
