"""The tuned kernels: the tight paths against the general ones, runs_periodic's two paths,
the Embree peer's fast query, and the callgrind profile."""
import os
import shutil

import numpy as np
import pytest

import algos
from algos.intersect import prepare_timed_intersect
from algos.peers.embree import embree_timed, far_bounds
from datasets_gen import fields
from datasets_gen.rays import first_hit_rays


@pytest.fixture(scope="module")
def field():
    return algos.Field(fields.generate("fbm", (130, 160), seed=9, amplitude=30.0, scale=40.0))


@pytest.mark.parametrize("name", ["dda", "dda_f32", "midpoint", "runs", "runs_f64",
                                  "runs_periodic", "dda_maxmip", "runs_maxmip"])
@pytest.mark.parametrize("surface", algos.SURFACES)
def test_tight_path_equals_the_unculled_walk(name, surface, field):
    """Culling (the carried bound, the run bound) never changes a first hit: the tight
    path equals the same walk with every cull off, bit for bit, on descending rays (the
    tight path) and ascending ones (the general path)."""
    o, d = first_hit_rays(field, 3, 400, seed=5)
    up = d.copy()
    up[:200, 2] = np.abs(up[:200, 2]) * 0.3  # half of them rising
    o2 = o.copy()
    o2[:200, 2] = field.heights.min() - 0.5
    for dirs, orig in ((d, o), (up, o2)):
        fast = algos.intersect(name, field, orig, dirs, surface=surface, outputs=("t", "cell"))
        base = name.replace("_maxmip", "") if name != "dda_maxmip" else "dda"
        opts = {"cull_cells": False}
        if base.startswith("runs"):
            opts["cull_runs"] = False
        slow = algos.intersect(base, field, orig, dirs, surface=surface, outputs=("t", "cell"), **opts)
        if name.endswith("_maxmip"):
            # the mipmap changes the walk's pieces, not the answer (test_intersect pins it)
            assert np.array_equal(np.isfinite(fast.t), np.isfinite(slow.t))
            both = np.isfinite(fast.t)
            assert np.allclose(fast.t[both], slow.t[both], rtol=1e-12, atol=1e-12)
        else:
            assert np.array_equal(fast.t, slow.t), (name, surface)
            assert np.array_equal(fast.cell, slow.cell)


@pytest.mark.parametrize("name,base", [("dda_maxmip", "dda"), ("runs_maxmip", "runs")])
@pytest.mark.parametrize("surface", algos.SURFACES)
def test_maxmip_floors_equal_their_base_walk(name, base, surface):
    """Every floor level of the max-mipmap walks gives the base walk's t and cell, bit for
    bit: on rays that descend, rise, cross the whole field (the run walker's seeks over
    many rows) or run along an axis; on a field whose sides are not powers of two."""
    heights = fields.generate("fbm", (301, 517), seed=4, amplitude=60.0, scale=90.0)
    fld = algos.Field(heights)
    rng = np.random.Generator(np.random.PCG64(11))
    n = 600
    o = np.column_stack([rng.uniform(-20, 540, n), rng.uniform(-20, 320, n),
                         rng.uniform(heights.min() - 5, heights.max() + 40, n)])
    az = rng.uniform(0, 2 * np.pi, n)
    az[:60] = rng.integers(0, 8, 60) * (np.pi / 4)   # axis-aligned and diagonal
    el = rng.uniform(-0.4, 0.15, n)
    el[60:120] = rng.uniform(-0.01, 0.0, 60)          # grazing: long rays, wide skips
    d = np.column_stack([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
    ref = algos.intersect(base, fld, o, d, surface=surface)
    assert np.isfinite(ref.t).sum() > n // 4
    for floor in range(0, 7):
        got = algos.intersect(name, fld, o, d, surface=surface, fine_level=floor)
        assert np.array_equal(got.t, ref.t), (name, floor)
        assert np.array_equal(got.cell, ref.cell), (name, floor)


def test_runs_periodic_paths_agree():
    """Short rays take the plain recurrence, long parallel rays the pattern: both are the
    exact runs of the same rational line, so both equal `runs` on exactly rational
    directions."""
    shape = (600, 500)
    rng = np.random.Generator(np.random.PCG64(3))
    for p, q in ((3, 7), (17, 41), (5, 512), (89, 144)):
        n = 120
        d = np.tile([float(q), float(p)], (n, 1))
        d[1::2] *= -1
        o = np.column_stack([rng.uniform(0, 500, n), rng.uniform(0, 600, n)])
        tmax = np.where(np.arange(n) % 3 == 0, 0.5 * rng.uniform(0, 1, n), np.inf)  # short ones
        got = algos.traverse("runs_periodic", o, d, shape, tmax=tmax, output="runs")
        want = algos.traverse("runs", o, d, shape, tmax=tmax, output="runs")
        for k in range(n):
            assert np.array_equal(got[k], want[k]), (p, q, k)


def test_embree_fast_query_agrees_with_the_robust_scene(field):
    o, d = first_hit_rays(field, 5, 500, seed=8)
    run, t = embree_timed(field, o, d)
    assert run() > 0
    fast = t()
    robust = algos.intersect("embree", field, o, d).t
    exact = algos.intersect("runs", field, o, d).t
    assert np.mean(np.isfinite(fast) == np.isfinite(robust)) > 0.99
    both = np.isfinite(fast) & np.isfinite(exact)
    assert both.sum() > 200
    assert np.allclose(fast[both], exact[both], rtol=1e-3, atol=1e-3)
    far = far_bounds(field, o, d)
    assert np.all(fast[both] <= far[both])
    # the benchmark path is this one
    bench_run, bench_t = prepare_timed_intersect("embree", field, o, d)
    bench_run()
    assert np.array_equal(np.isfinite(bench_t()), np.isfinite(fast))


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
@pytest.mark.skipif("libasan" in os.environ.get("LD_PRELOAD", ""),
                    reason="valgrind cannot run a process with AddressSanitizer preloaded")
def test_profile_counts_are_exact_and_repeatable():
    from bench.profile import profile

    a = profile("dda", size=128, r=5, rays=40)
    b = profile("dda", size=128, r=5, rays=40)
    assert a["instructions"] == b["instructions"] > 0
    assert a["branches"] == b["branches"] > 0
    assert a["cells"] > 40
    assert 5 < a["instructions_per_cell"] < 1000
    assert any("dda" in fn for fn, _ in a["functions"])
