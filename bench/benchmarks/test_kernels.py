"""The pytest-benchmark suite: every kernel at a fixed r on a fixed dataset.

Run with ``pytest bench/benchmarks --benchmark-only`` (``make bench-ci``); compare runs with
pytest-benchmark's ``--benchmark-autosave`` / ``--benchmark-compare``. Each benchmark
times one whole batch walked in C; the rays and the field are seeded.
"""
import pytest

import algos
import datasets_gen
from algos.intersect import prepare_timed_intersect
from datasets_gen import rays as raysets

R = 25          # mean run length of every ray set here
N_RAYS = 2000   # rays per batch
SIDE = 512      # fBm 512^2, seed 1


@pytest.fixture(scope="module")
def field():
    return algos.Field(datasets_gen.load("fbm", size=SIDE, seed=1).heights)


@pytest.fixture(scope="module")
def rays2():
    rs = raysets.by_run_length(R, N_RAYS, (SIDE - 1, SIDE - 1), seed=3)
    return rs.origins, rs.directions


@pytest.fixture(scope="module")
def rays3(field):
    from datasets_gen.rays import first_hit_rays

    return first_hit_rays(field, R, N_RAYS, 3)


@pytest.mark.parametrize("name", algos.TRAVERSALS)
@pytest.mark.parametrize("workload", list(algos.WORKLOADS))
def test_traverse(benchmark, name, workload, rays2):
    o, d = rays2
    run, _ = algos.prepare_timed(name, o, d, (SIDE - 1, SIDE - 1), workload)
    benchmark(run)


@pytest.mark.parametrize("name", algos.INTERSECTORS)
def test_first_hit_triangles(benchmark, name, field, rays3):
    o, d = rays3
    run, _ = prepare_timed_intersect(name, field, o, d, surface="triangles")
    benchmark(run)


@pytest.mark.parametrize("threads", [1, None])
@pytest.mark.parametrize("name", ["runs", "runs_maxmip", "embree"])
def test_first_hit_threads(benchmark, name, threads, field):
    """One thread against every core, on 16x the rays (ranges of 1024 rays or more)."""
    from datasets_gen.rays import first_hit_rays

    o, d = first_hit_rays(field, R, 16 * N_RAYS, 5)
    run, _ = prepare_timed_intersect(name, field, o, d, surface="triangles", threads=threads)
    benchmark(run)


@pytest.mark.parametrize("name", [n for n in algos.HORIZON_ALGORITHMS if n != "embree"])
def test_horizon_one_azimuth(benchmark, name, field):
    """Every vertex's horizon along atan(2/5) (rational: the sweep applies); the per-vertex
    walks on a 4096-vertex sample, so that the suite stays quick."""
    import numpy as np

    from algos.terrain import prepare_horizon_timed, rational_azimuths
    from bench.studies.terrain import sample_ranges

    h = np.asarray(field.heights, dtype=np.float64)
    ranges = None if name == "sweep" else sample_ranges(*h.shape, 4096)
    run, _, _ = prepare_horizon_timed(h, rational_azimuths(16)[1], name, ranges=ranges)
    benchmark(run)


@pytest.mark.parametrize("name", list(algos.VIEWSHED_ALGORITHMS))
def test_viewshed(benchmark, name, field):
    benchmark(lambda: algos.viewshed(field.heights, (SIDE // 2, SIDE // 2), algorithm=name,
                                     threads=1))
