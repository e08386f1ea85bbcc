"""Scale up and out: threads (bit-identical for every count), big-field layouts
(memory-mapped heights, streaming and lean structures), and Dask (sweeps and tiled
terrain products on a LocalCluster)."""
import csv
import dataclasses
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import algos
import datasets_gen
from algos import parallel
from algos.accel import maxima
from algos.accel.mipmap import max_mipmap as _mipmap
from algos.accel.mipmap import tile_max_rows as _tile_max_rows
from bench import sweep, sweep_dask
from datasets_gen.rays import first_hit_rays

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
#: AddressSanitizer's shadow memory inflates every worker's resident memory: no limits there
SANITIZED = "libasan" in os.environ.get("LD_PRELOAD", "")


@pytest.fixture(scope="module")
def field():
    return algos.Field(datasets_gen.load("fbm", size=(181, 233), seed=4).heights)


# ---- threads -------------------------------------------------------------------------
def test_resolve_threads_and_split():
    assert parallel.resolve_threads(None) == parallel.available_cores() >= 1
    assert parallel.resolve_threads(3) == 3
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="threads"):
            parallel.resolve_threads(bad)
    for n, threads in ((0, 4), (1, 4), (5000, 1), (100000, 2), (100001, 3)):
        ranges = parallel.split(n, threads)
        assert ranges[0][0] == 0 and ranges[-1][1] == max(n, 0)
        assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))
        assert threads > 1 or len(ranges) == 1


@pytest.mark.parametrize("name", algos.TRAVERSALS)
@pytest.mark.parametrize("output", ["cells", "runs", "count"])
def test_traverse_bit_identical_for_every_thread_count(name, output, field):
    o, d = first_hit_rays(field, 5, 6000, 3)
    o2, d2 = o[:, :2], d[:, :2]
    shape = (field.cols - 1, field.rows - 1)
    one = algos.traverse(name, o2, d2, shape, output=output, threads=1)
    for threads in (2, 3, None):
        other = algos.traverse(name, o2, d2, shape, output=output, threads=threads)
        if output == "count":
            assert np.array_equal(one.cells, other.cells) and np.array_equal(one.runs, other.runs)
        else:
            assert np.array_equal(one.offsets, other.offsets)
            data = "cells" if output == "cells" else "runs"
            assert np.array_equal(getattr(one, data), getattr(other, data))


def test_timed_walks_fill_the_same_checksums_on_threads(field):
    o, d = first_hit_rays(field, 25, 8000, 5)
    shape = (field.cols - 1, field.rows - 1)
    run1, sums1 = algos.prepare_timed("runs_periodic", o[:, :2], d[:, :2], shape, threads=1)
    run2, sums2 = algos.prepare_timed("runs_periodic", o[:, :2], d[:, :2], shape, threads=2)
    assert run1() > 0 and run2() > 0
    assert np.array_equal(sums1, sums2) and sums1.any()


@pytest.mark.parametrize("name", [n for n in algos.INTERSECTORS if n != "embree"])
@pytest.mark.parametrize("surface", algos.SURFACES)
def test_intersect_bit_identical_for_every_thread_count(name, surface, field):
    if surface not in algos.INTERSECTOR_REGISTRY[name].surfaces:
        pytest.skip(f"{name} does not support {surface}")
    o, d = first_hit_rays(field, 5, 5000, 8)
    # the BVH peers count no cells (their 'stats' is refused)
    peer = algos.INTERSECTOR_REGISTRY[name].kind == "peer"
    outs = ("t", "cell", "normal") + (() if peer else ("stats",))
    one = algos.intersect(name, field, o, d, surface=surface, outputs=outs, threads=1)
    for threads in (2, 3):
        other = algos.intersect(name, field, o, d, surface=surface, outputs=outs, threads=threads)
        assert np.array_equal(one.t, other.t)
        assert np.array_equal(one.cell, other.cell)
        assert np.array_equal(one.normal, other.normal, equal_nan=True)
        for key in one.stats or {}:
            assert np.array_equal(one.stats[key], other.stats[key]), key


def test_embree_peer_on_threads_matches_one_thread(field):
    o, d = first_hit_rays(field, 5, 5000, 9)
    one = algos.intersect("embree", field, o, d, threads=1)
    two = algos.intersect("embree", field, o, d, threads=2)
    assert np.array_equal(one.t, two.t) and np.array_equal(one.cell, two.cell)
    exact = algos.intersect("runs", field, o, d)
    both = np.isfinite(exact.t) & np.isfinite(two.t)
    assert (np.isfinite(exact.t) == np.isfinite(two.t)).mean() > 0.99 and both.sum() > 1000
    assert np.max(np.abs(exact.t[both] - two.t[both])) < 1e-2


def test_render_is_the_same_image_on_every_thread_count(tmp_path):
    from bench.cli import render

    paths = {}
    for threads in (1, 2):
        out = tmp_path / f"r{threads}"
        render.render_files("fbm", size=96, width=48, height=32, out=str(out),
                            threads=threads, echo=lambda *_: None)
        paths[threads] = out
    import OpenEXR

    with OpenEXR.File(str(paths[1]) + ".exr") as a, OpenEXR.File(str(paths[2]) + ".exr") as b:
        za, zb = a.channels()["Z"].pixels, b.channels()["Z"].pixels
        assert np.array_equal(za, zb, equal_nan=True) and np.isfinite(za).any()


def test_threads_are_checked():
    o = np.zeros((3, 3)) + [1, 1, 100]
    d = np.zeros((3, 3)) + [0.3, 0.4, -1]
    h = np.zeros((8, 8), np.float32)
    with pytest.raises(ValueError, match="threads"):
        algos.intersect("runs", h, o, d, threads=0)
    with pytest.raises(ValueError, match="threads"):
        algos.traverse("runs", o[:, :2], d[:, :2], (7, 7), threads="all")


# ---- big fields ----------------------------------------------------------------------
def test_memory_mapped_npy_is_used_in_place(tmp_path, field):
    path = tmp_path / "big.npy"
    np.save(path, field.heights)
    hf = datasets_gen.load_file(path)
    assert isinstance(hf.heights, np.memmap) and hf.params["memory_mapped"]
    f = algos.Field(hf.heights)
    assert np.shares_memory(f.heights, hf.heights)  # no copy
    o, d = first_hit_rays(field, 5, 2000, 2)
    assert np.array_equal(algos.intersect("runs", f, o, d).t, algos.intersect("runs", field, o, d).t)
    # a spacing converts nothing (heights are in its unit): still mapped
    assert isinstance(datasets_gen.load_file(path, spacing=2.0).heights, np.memmap)
    # a file that needs converting (a vertical scale) takes the general path, in memory
    converted = datasets_gen.load_file(path, vertical_scale=0.5)
    assert not isinstance(converted.heights, np.memmap)
    np.testing.assert_array_equal(converted.heights, field.heights / 2)


def test_memory_mapped_file_with_nan_names_the_sample(tmp_path):
    h = np.zeros((5, 6), np.float32)
    h[3, 4] = np.nan
    np.save(tmp_path / "bad.npy", h)
    with pytest.raises(ValueError, match=r"row 3, col 4"):
        datasets_gen.load_file(tmp_path / "bad.npy", nodata_policy="error")
    # the default policy keeps the void, and the map
    voids = datasets_gen.load_file(tmp_path / "bad.npy")
    assert isinstance(voids.heights, np.memmap) and voids.nodata_mask[3, 4]


def test_streaming_structures_equal_the_whole_field_ones(field):
    h = field.heights
    for kind in ("corners", "plane3"):
        whole = np.maximum(np.maximum(h[:-1, :-1], h[:-1, 1:]), np.maximum(h[1:, :-1], h[1:, 1:]))
        if kind == "plane3":
            fourth = h[:-1, 1:].astype(np.float64) + h[1:, :-1] - h[:-1, :-1]
            assert np.all(field.cellmax_for(kind) >= fourth)
        else:
            assert np.array_equal(field.cellmax_for(kind), whole)
        full = _mipmap(field.cellmax_for(kind))
        for level in (1, 2, 3, 5):
            assert np.array_equal(_tile_max_rows(h, kind, level), full[level]), (kind, level)


def test_band_edges_of_the_streaming_passes(monkeypatch, field):
    """Bands of a few rows (every band edge exercised) give the same structures."""
    monkeypatch.setattr(maxima, "BAND_SAMPLES", 3 * field.cols + 5)
    small = algos.Field(field.heights.copy())
    assert np.array_equal(small.cellmax, field.cellmax)
    assert np.array_equal(_tile_max_rows(field.heights, "corners", 3), _mipmap(field.cellmax)[3])


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_lean_runs_maxmip_gives_the_same_hits(surface, field):
    lean = algos.Field(field.heights, lean=True)
    o, d = first_hit_rays(field, 5, 6000, 6)
    outs = ("t", "cell", "normal")
    a = algos.intersect("runs_maxmip", field, o, d, surface=surface, outputs=outs)
    b = algos.intersect("runs_maxmip", lean, o, d, surface=surface, outputs=outs, threads=2)
    assert np.array_equal(a.t, b.t) and np.array_equal(a.cell, b.cell)
    assert np.array_equal(a.normal, b.normal, equal_nan=True)
    # the lean layout holds no cell maxima, only mipmap levels from fine_level (3) up
    assert not any(k.startswith("cellmax") for k in lean.build_stats)
    assert lean.nbytes - lean.heights.nbytes < 0.05 * lean.heights.nbytes


def test_the_binding_refuses_a_missing_cellmax_where_it_would_be_read(field):
    from algos import _kernels

    args = dict(kernel=algos.INTERSECTOR_REGISTRY["runs"].kernel_id)
    o = np.array([[1.0, 1.0, 500.0]])
    d = np.array([[0.3, 0.4, -1.0]])
    t = np.empty(1)
    with pytest.raises(ValueError, match="cellmax"):
        _kernels.intersect(args["kernel"], 2,
                           (field.heights, None, field.hmin, field.hmax, None, None, None),
                           (o, d, None, None), (0, 0, None, (1, 1, 1.0, 0.5, 0.0), 0, 4),
                           (t, None, None, None))


# ---- generators ----------------------------------------------------------------------
def test_generators_take_the_new_side_limit():
    h = datasets_gen.fields.generate("fbm", (2, 20000), seed=1)
    assert h.shape == (2, 20000) and np.isfinite(h).all()


# ---- Dask: tiled terrain products ----------------------------------------------------
da = pytest.importorskip("dask.array")
distributed = pytest.importorskip("dask.distributed")


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None,
                                       memory_limit=None if SANITIZED else "1GiB")
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


def test_tiled_products_equal_the_in_memory_ones(client):
    h = datasets_gen.load("fbm", size=(150, 210), seed=2).heights.astype(np.float64)
    lazy = da.from_array(h, chunks=(40, 64))
    for md in (6.0, 45.5):
        a = algos.horizon(h, [0, 37.0, 200], md)
        b = algos.horizon(lazy, [0, 37.0, 200], md).compute()
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
        assert np.array_equal(algos.shadows(h, 135, 10, max_distance=md),
                              algos.shadows(lazy, 135, 10, max_distance=md).compute())
        np.testing.assert_allclose(algos.sky_view_factor(lazy, 8, md).compute(),
                                   algos.sky_view_factor(h, 8, md), rtol=0, atol=1e-12)
        one = (100.3, 50.2)
        assert np.array_equal(algos.viewshed(lazy, one, max_distance=md).compute(),
                              algos.viewshed(h, one, max_distance=md))
        many = [(100.3, 50.2), (0, 0), (209, 149)]
        assert np.array_equal(algos.viewshed(lazy, many, max_distance=md).compute(),
                              algos.viewshed(h, many, max_distance=md))


def test_tiled_products_follow_a_heightfields_north_and_spacing(client):
    hf = datasets_gen.load("jacksboro", size=160)
    lazy = dataclasses.replace(hf, heights=da.from_array(hf.heights, chunks=50))
    a = algos.horizon(hf, [30, 300], 2500.0)
    b = algos.horizon(lazy, [30, 300], 2500.0).compute()
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)


def test_tiled_products_need_a_finite_max_distance():
    # the viewshed takes an unlimited one (tests/terrain/test_dask_viewshed.py)
    lazy = da.zeros((20, 20), chunks=10)
    with pytest.raises(ValueError, match="max_distance"):
        algos.horizon(lazy, [0], None)


# ---- Dask: sweeps --------------------------------------------------------------------
DASK_TINY = {
    "name": "dtiny", "rays": 40, "repeats": 3, "seed": 1,
    "algorithms": ["dda", "midpoint", "runs"],
    "workloads": ["visit", "first_hit"], "surfaces": ["triangles"],
    "run_lengths": [1, 25],
    "datasets": [{"name": "fbm", "size": 64, "seed": 1}, {"name": "uniform", "size": 48, "seed": 2}],
}


def _keys(rows):
    return sorted(sweep.row_key(r) for r in rows)


def test_dask_sweep_gives_the_serial_rows(tmp_path, monkeypatch):
    monkeypatch.setenv("HFTRACE_FLUSH_MB", "0")
    cfg = sweep.load_config(DASK_TINY)
    serial = sweep.run_sweep(cfg, str(tmp_path / "serial"), progress=False, echo=None)
    spread = sweep_dask.run_sweep_dask(cfg, str(tmp_path / "dask"), "local:2", progress=False,
                                  echo=None)
    assert _keys(serial) == _keys(spread) and len(set(_keys(spread))) == len(spread)
    assert list(serial[0]) == list(spread[0]) == sweep.COLUMNS
    by_key = {sweep.row_key(r): r for r in serial}
    for row in spread:  # what does not depend on timing is identical
        ref = by_key[sweep.row_key(row)]
        for col in ("cells_per_ray", "runs_per_ray", "agree", "rays", "grid"):
            assert row[col] == ref[col], col
    import json

    env = json.load(open(tmp_path / "dask" / "env.json"))
    assert env["dask_address"] == "local:2" and len(env["workers"]) >= 1
    assert all("cpu" in w and "pid" in w for w in env["workers"].values())


def test_dask_sweep_resumes_after_the_driver_is_killed(tmp_path):
    cfg_path = tmp_path / "c.toml"
    cfg_path.write_text(
        'name = "dkill"\nrays = 300\nrepeats = 3\nalgorithms = ["dda", "midpoint", "runs"]\n'
        'workloads = ["visit", "first_hit"]\nsurfaces = ["triangles"]\n'
        'run_lengths = [1, 2, 5, 25, 100, "random"]\n'
        '[[datasets]]\nname = "fbm"\nsize = 200\nseed = 1\n'
        '[[datasets]]\nname = "terraces"\nsize = 200\nseed = 1\n')
    out = tmp_path / "out"
    results = out / "results.csv"
    cmd = [sys.executable, "-m", "bench.cli", "sweep", str(cfg_path), "--out", str(out),
           "--no-progress", "--dask", "local:2"]
    env = dict(os.environ, HFTRACE_FLUSH_MB="0")
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env=env, start_new_session=True)
    deadline = time.time() + 180
    while time.time() < deadline:
        if results.exists() and sum(1 for _ in open(results)) > 4:
            break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # the driver and its LocalCluster
    proc.wait()
    before = list(csv.DictReader(open(results)))
    cfg = sweep.load_config(cfg_path)
    expected = sum(len(g[4]) for g in sweep.groups(cfg))
    assert 0 < len(before) < expected
    done = subprocess.run(cmd + ["--resume"], cwd=ROOT, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    after = list(csv.DictReader(open(results)))
    assert len(after) == expected == len(set(_keys(after)))
    # the rows written before the kill are kept as they were
    assert after[:len(before)] == before


def test_cli_tiled_horizon_on_a_file_equals_the_in_memory_product(tmp_path):
    import tifffile

    h = datasets_gen.load("fbm", size=(300, 260), seed=3).heights
    tifffile.imwrite(tmp_path / "f.tif", h)
    out = tmp_path / "hz"
    done = subprocess.run(
        [sys.executable, "-m", "bench.cli", "horizon", str(tmp_path / "f.tif"), "--dask",
         "local:2", "--max-distance", "40", "--chunk", "128", "--azimuths", "0,135", "--out",
         str(out)] + ([] if SANITIZED else ["--worker-memory", "300MiB"]),
        cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    import rasterio

    with rasterio.open(f"{out}.tif") as src:
        assert src.descriptions == ("azimuth 0", "azimuth 135")
        assert src.tags()["units"] == "degrees"
        for band, a in enumerate((0, 135), start=1):
            ref = np.degrees(algos.horizon(h.astype(np.float64), [a], 40.0)[0]).astype(np.float32)
            assert np.array_equal(src.read(band), ref), a
    assert os.path.getsize(f"{out}.png") > 0
    no_distance = subprocess.run(
        [sys.executable, "-m", "bench.cli", "horizon", str(tmp_path / "f.tif"), "--dask",
         "local:1"], cwd=ROOT, capture_output=True, text=True)
    assert no_distance.returncode != 0 and "max-distance" in no_distance.stderr


def test_lazy_raster_pickles_as_its_path(tmp_path):
    import pickle

    h = np.arange(30, dtype=np.float32).reshape(5, 6)
    np.save(tmp_path / "a.npy", h)
    hf = datasets_gen.open_lazy(tmp_path / "a.npy", chunks=3)
    raster = pickle.loads(pickle.dumps(datasets_gen.loaders.LazyRaster(tmp_path / "a.npy")))
    assert len(pickle.dumps(raster)) < 500
    np.testing.assert_array_equal(raster[1:3, 2:5], h[1:3, 2:5])
    np.testing.assert_array_equal(hf.heights.compute(), h)


@pytest.mark.parametrize("algorithm", ["sweep", "pattern", "dda_maxmip", "dda"])
def test_horizon_bit_identical_for_every_thread_count(algorithm):
    h = datasets_gen.load("fbm", size=(97, 131), seed=5).heights.astype(np.float64)
    md = None if algorithm == "sweep" else 40.0
    az = algos.rational_azimuths(5)
    one = algos.horizon(h, az, md, algorithm=algorithm, threads=1)
    for threads in (2, 3):
        assert np.array_equal(one, algos.horizon(h, az, md, algorithm=algorithm, threads=threads))


def test_dask_sweep_survives_a_killed_worker(tmp_path, monkeypatch):
    """A worker killed mid-sweep: its task is rerun elsewhere, and every row is written
    once (by the driver)."""
    import threading

    monkeypatch.setenv("HFTRACE_FLUSH_MB", "0")
    cfg = sweep.load_config({**DASK_TINY, "name": "wkill", "rays": 200,
                             "run_lengths": [1, 2, 5, 25, 100, "random"],
                             "datasets": [{"name": "fbm", "size": 160, "seed": 1},
                                          {"name": "terraces", "size": 160, "seed": 1}]})
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
    try:
        with distributed.Client(cluster) as c:
            pids = sorted(c.run(os.getpid).values())
        results = tmp_path / "out" / "results.csv"
        killed = []

        def killer():
            deadline = time.time() + 120
            while time.time() < deadline:
                if results.exists() and sum(1 for _ in open(results)) > 3:
                    os.kill(pids[0], signal.SIGKILL)
                    killed.append(pids[0])
                    return
                time.sleep(0.01)

        thread = threading.Thread(target=killer, daemon=True)
        thread.start()
        rows = sweep_dask.run_sweep_dask(cfg, str(tmp_path / "out"), cluster.scheduler_address,
                                    progress=False, echo=None)
        thread.join(timeout=10)
    finally:
        cluster.close()
    assert killed, "the sweep finished before a worker could be killed"
    expected = sum(len(g[4]) for g in sweep.groups(cfg))
    assert len(rows) == expected == len(set(_keys(rows)))


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (7, 1), (5, 9), (300, 517), (1025, 3)])
@pytest.mark.parametrize("band_samples", [7, 64, 1 << 20])
def test_banded_mipmap_equals_the_whole_array_reduction(shape, band_samples, monkeypatch):
    monkeypatch.setattr(maxima, "BAND_SAMPLES", band_samples)
    a = np.random.default_rng(1).random(shape)
    level = a
    for got in _mipmap(a)[1:]:
        r, c = level.shape
        padded = np.full((r + r % 2, c + c % 2), -np.inf)
        padded[:r, :c] = level
        level = padded.reshape(padded.shape[0] // 2, 2, padded.shape[1] // 2, 2).max(axis=(1, 3))
        assert np.array_equal(got, level)
    assert level.shape == (1, 1)


def test_geotiff_is_read_through_rasterio(tmp_path, field):
    """GeoTIFF goes through rasterio (GDAL), which decodes blocks into memory: the
    memory-mapped path of earlier versions is kept for .npy only."""
    import tifffile

    tifffile.imwrite(tmp_path / "f.tif", field.heights)
    hf = datasets_gen.load_file(tmp_path / "f.tif")
    assert not isinstance(hf.heights, np.memmap)
    np.testing.assert_array_equal(hf.heights, field.heights)
    tifffile.imwrite(tmp_path / "z.tif", field.heights, compression="zlib")
    z = datasets_gen.load_file(tmp_path / "z.tif")
    np.testing.assert_array_equal(z.heights, field.heights)


def test_big_study_runs_its_items_in_children_through_the_command_entry(tmp_path):
    """``scale --part big`` at a tiny side: each item runs in its own process through
    ``python -m bench.cli.big_item`` (which hands the render command to the study), writes
    its files and reports a peak RSS, with no error."""
    from bench.studies.big import run_big

    results = run_big(str(tmp_path), side=64, echo=lambda *a: None, items=("generate", "render"))
    assert set(results) == {"generate", "render"}
    assert all("error" not in r and r["peak_rss_bytes"] > 0 for r in results.values())
    assert (tmp_path / "render64.png").exists() and (tmp_path / "render64.exr").exists()
    assert (tmp_path / "big.md").exists()
