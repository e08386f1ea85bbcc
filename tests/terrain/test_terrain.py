"""Terrain products: every algorithm against the exact references of
algos.terrain.reference, the conventions (azimuth, ties, units), and bad input."""
import math

import numpy as np
import pytest

import algos
import algos.terrain as T
from algos import _kernels
from algos.terrain.reference import horizon_reference, viewshed_reference
from datasets_gen.loaders import HeightField

EXACT = [name for name, a in T.HORIZON_ALGORITHMS.items() if a.exact]
AZIMUTHS = [0.0, 90.0, 180.0, 270.0, 45.0, 135.0, 225.0, 315.0, 30.0, 200.0, 333.3,
            math.degrees(math.atan2(1, 2)), 180 + math.degrees(math.atan2(2, 5))]


def lattice_fields():
    """Small lattice fields over the usual families: integer noise, flat, a tilted plane,
    a spike, ridges and a pit."""
    rng = np.random.default_rng(11)
    yy, xx = np.mgrid[0:9, 0:11]
    return {
        "noise": rng.integers(0, 6, size=(9, 11)).astype(float),
        "flat": np.zeros((7, 8)),
        "tilted": (xx + 2 * yy).astype(float),
        "spike": np.where((xx == 5) & (yy == 4), 7.0, 0.0),
        "ridges": (3 * ((xx + yy) % 4 == 0)).astype(float),
        "pit": np.minimum(np.abs(xx - 5) + np.abs(yy - 4), 4).astype(float) * 2,
    }


FIELDS = lattice_fields()


def _applies(name, direction, max_distance):
    info = T.HORIZON_ALGORITHMS[name]
    if info.rational_only and direction.rational is None:
        return False
    return max_distance is None or info.max_distance


@pytest.mark.parametrize("family", sorted(FIELDS))
@pytest.mark.parametrize("max_distance", [None, 0.5, 2.5, 6.0])
def test_horizon_matches_exact_reference(family, max_distance):
    h = FIELDS[family]
    for az in AZIMUTHS:
        d = T.azimuth_direction(az)
        ref = np.array(horizon_reference(h, (d.dx, d.dy), max_distance))
        for name in EXACT:
            if not _applies(name, d, max_distance):
                continue
            got = T.horizon(h, az, max_distance, algorithm=name)[0]
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12,
                                       err_msg=f"{name} az={az} md={max_distance}")


def test_march_never_exceeds_the_supremum():
    """The marcher samples surface points on the ray, so it can only miss the maximum."""
    h = FIELDS["noise"]
    for az in (0.0, 30.0, 135.0):
        exact = T.horizon(h, az, algorithm="dda")[0]
        march = T.horizon(h, az, algorithm="march", march_step=0.37)[0]
        assert np.all(march <= exact + 1e-12)
        assert np.mean(march < exact - 1e-9) > 0.05  # and it does miss some


def test_embree_peer_close_to_exact():
    h = FIELDS["noise"]
    exact = T.horizon(h, 30.0, algorithm="dda")[0]
    peer = T.horizon(h, 30.0, algorithm="embree", embree_tolerance=1e-5)[0]
    finite = np.isfinite(exact) & (exact > -math.pi / 2)
    assert np.array_equal(exact == -math.pi / 2, peer == -math.pi / 2)
    err = np.abs(peer - exact)[finite]
    assert np.median(err) < 1e-3


def test_default_algorithm_choice():
    h = FIELDS["noise"]
    assert T.horizon(h, T.rational_azimuths(8), return_stats=True)[1].algorithm == "sweep"
    assert T.horizon(h, [10.0], return_stats=True)[1].algorithm == "chain"
    assert T.horizon(h, [10.0], max_distance=5, return_stats=True)[1].algorithm == "rows"


def test_statistics_come_with_the_result():
    """``return_stats=True`` returns ``(result, TerrainStats)`` with the same result as
    without; the module keeps no statistics of its own."""
    h = FIELDS["noise"]
    plain = T.horizon(h, [10.0, 90.0], max_distance=6.0)
    got, stats = T.horizon(h, [10.0, 90.0], max_distance=6.0, return_stats=True)
    np.testing.assert_array_equal(got, plain)
    assert isinstance(stats, T.TerrainStats) and stats.paths == ("rows", "rows")
    for product, args in ((T.shadows, (45.0, 10.0)), (T.sky_view_factor, (8,)),
                          (T.openness, ()), (T.viewshed, ((2.5, 3.0),))):
        alone = product(h, *args)
        got, stats = product(h, *args, return_stats=True)
        np.testing.assert_array_equal(got, alone, err_msg=product.__name__)
        assert isinstance(stats, T.TerrainStats) and stats.algorithm, product.__name__
    assert not hasattr(T, "LAST_STATS")
    with pytest.raises(TypeError, match="return_stats"):
        T.horizon(h, 10.0, return_stats="yes")


def test_statistics_of_concurrent_calls_do_not_mix():
    """Calls on several threads (as dask runs tiles) each get their own statistics."""
    from concurrent.futures import ThreadPoolExecutor

    h = FIELDS["noise"]
    names = ["dda", "dda_maxmip", "pattern", "chain", "rows", "march"] * 4

    def one(name):
        return name, T.horizon(h, [10.0, 33.0], max_distance=8.0, algorithm=name,
                               return_stats=True)[1]

    with ThreadPoolExecutor(4) as pool:
        for name, stats in pool.map(one, names):
            assert stats.algorithm == name and stats.paths == (name, name), (name, stats)


def test_statistics_of_a_lazy_result_are_refused():
    """A dask input's statistics are per tile: asking for them raises, naming the flag."""
    da = pytest.importorskip("dask.array")
    h = da.from_array(FIELDS["noise"], chunks=8)
    with pytest.raises(ValueError, match="return_stats"):
        T.horizon(h, 10.0, max_distance=3.0, return_stats=True)
    with pytest.raises(ValueError, match="return_stats"):
        T.viewshed(h, (2.0, 2.0), return_stats=True)
    lazy = T.sky_view_factor(h, 4, max_distance=3.0)
    np.testing.assert_allclose(lazy.compute(), T.sky_view_factor(FIELDS["noise"], 4,
                                                                 max_distance=3.0), atol=1e-12)


def test_sweep_refuses_what_it_cannot_do():
    h = FIELDS["noise"]
    with pytest.raises(ValueError, match=r"azimuths\[1\].*rational"):
        T.horizon(h, [0.0, 10.0], algorithm="sweep")
    with pytest.raises(ValueError, match="max_distance"):
        T.horizon(h, [0.0], max_distance=3, algorithm="sweep")


def test_azimuth_convention():
    """Azimuth 90 looks along +x (east), 0 along -y (north, row 0)."""
    h = np.zeros((6, 6))
    h[:, 5] = 3.0  # a wall on the east edge
    h[0, :] = 2.0  # a lower wall on the north edge
    east, west, north, south = T.horizon(h, [90.0, 270.0, 0.0, 180.0])[:, 3, 2]
    assert east == pytest.approx(math.atan2(3.0, 3.0))
    assert north == pytest.approx(math.atan2(2.0, 3.0))
    assert west == 0.0 and south == 0.0
    d = T.azimuth_direction(90.0)
    assert (d.dx, d.dy) == (1.0, 0.0)
    d = T.azimuth_direction(0.0)
    assert (d.dx, d.dy) == (0.0, -1.0)


def test_empty_horizon_is_minus_half_pi():
    h = FIELDS["noise"]
    out = T.horizon(h, 90.0)[0]
    assert np.all(out[:, -1] == -math.pi / 2)  # the east edge looks out of the field
    assert np.all(out[:, :-1] > -math.pi / 2)


def test_rational_azimuths():
    az = T.rational_azimuths(16)
    assert len(az) == 16
    spaced = np.arange(16) * 22.5
    assert np.max(np.abs(az - spaced)) < 0.71
    assert all(T.azimuth_direction(a).rational is not None for a in az)
    fine = T.rational_azimuths(16, max_denominator=12)
    assert np.max(np.abs(fine - spaced)) < 0.13


def test_shadows_strict_and_ties_lit():
    h = np.zeros((5, 7))
    h[:, 6] = 2.0  # a wall 2 high on the east edge; vertex (4, j) sees it at 45 degrees
    sh = T.shadows(h, 90.0, 45.0)
    assert not sh[2, 4]  # tie: lit
    assert sh[2, 5]  # atan(2) > 45 degrees
    assert not T.shadows(h, 90.0, 64.0)[2, 5]
    flat = T.shadows(np.zeros((4, 4)), 123.0, 0.0)
    assert not flat.any()  # horizon 0 equals elevation 0: lit
    noise = FIELDS["noise"]
    np.testing.assert_array_equal(T.shadows(noise, 30.0, 20.0),
                                  T.horizon(noise, 30.0)[0] > math.radians(20.0))


def test_sky_view_factor():
    assert np.all(T.sky_view_factor(np.zeros((5, 5)), 8) == 1.0)
    h = FIELDS["pit"]
    az = np.arange(8) * 45.0
    expected = 1 - np.mean(np.sin(np.maximum(T.horizon(h, az), 0)), axis=0)
    np.testing.assert_allclose(T.sky_view_factor(h, 8), expected, atol=1e-15)
    assert T.sky_view_factor(h, 8)[4, 5] < 0.9  # the bottom of the pit sees less sky
    rat, stats = T.sky_view_factor(h, 16, rational=True, return_stats=True)
    assert stats.algorithm == "sweep"
    assert np.all((rat > 0) & (rat <= 1))


@pytest.mark.parametrize("family", ["noise", "tilted", "spike", "ridges", "pit", "flat"])
def test_viewshed_matches_exact_reference(family):
    h = FIELDS[family]
    rows, cols = h.shape
    for observer in [(0, 0), (5, 4), (2.5, 3.25), (cols - 1, rows - 1)]:
        for oh, th in [(0.0, 0.0), (1.75, 0.0), (0.5, 1.0)]:
            ref = np.array(viewshed_reference(h, observer, oh, th))
            for name in T.VIEWSHED_ALGORITHMS:
                got = T.viewshed(h, observer, oh, th, algorithm=name)
                assert got.dtype == bool
                np.testing.assert_array_equal(got, ref, err_msg=f"{name} {observer} {oh} {th}")


def test_viewshed_ties_survive_a_pixel_size():
    # a line of sight is unchanged by scaling x, y and z, so heights in metres on 30 m
    # (or 30 x 20 m) pixels see what the same numbers see in cells, ties included. The
    # heights used to be divided by dx first, which rounds (1/30 is no float64): the
    # grazing line from (1, 0, 0) to (0, 1, 5) over the diagonal's 2.5 went hidden
    g = np.array([[1.0, 0.0], [5.0, 4.0]])
    assert viewshed_reference(g, (1, 0), 0.0)[1][0]
    for spacing in (None, 30, (30, 20), (20, 30), 7):
        assert T.viewshed(g, (1, 0), 0.0, spacing=spacing)[1, 0], spacing
    rng = np.random.default_rng(5)
    for _ in range(4):
        h = rng.integers(0, 6, (7, 9)).astype(float)
        for observer in [(0, 0), (8, 6), (3.5, 2.25), (0, 6)]:
            for oh in (0.0, 0.5):
                ref = np.array(viewshed_reference(h, observer, oh))
                for spacing in ((30, 20), (20, 30), 7):
                    field = HeightField(h, spacing=spacing, unit="m")
                    for given, sp in ((h, spacing), (field, None)):
                        for name in T.VIEWSHED_ALGORITHMS:
                            got = T.viewshed(given, observer, oh, spacing=sp, algorithm=name)
                            np.testing.assert_array_equal(
                                got, ref, err_msg=f"{name} {observer} {oh} {spacing}")


def test_viewshed_curvature_and_many_observers():
    h = FIELDS["noise"]
    obs = np.array([[0, 0], [5, 4], [10, 8]])
    count = T.viewshed(h, obs, 1.0)
    assert count.dtype == np.uint16
    expected = sum(T.viewshed(h, o, 1.0).astype(int) for o in obs)
    np.testing.assert_array_equal(count, expected)
    with pytest.raises(ValueError, match="curvature: needs spacing"):
        T.viewshed(h, (1, 1), curvature=True)
    # a tiny earth lowers distant terrain, targets included: the answer changes, exactly
    plain = T.viewshed(h, (5, 4), 3.0, spacing=1.0)
    curved = T.viewshed(h, (5, 4), 3.0, curvature=True, spacing=1.0, earth_radius=20.0)
    assert np.all(curved <= plain) and curved.sum() < plain.sum()  # the bulge hides
    ref = np.array(viewshed_reference(h, (5, 4), 3.0, 0.0, drop=(1 - 1 / 7) / 40.0))
    np.testing.assert_array_equal(curved, ref)
    near = T.viewshed(h, (5, 4), 0.5, max_distance=2.0)
    jj, ii = np.mgrid[0:9, 0:11]
    assert not near[(ii - 5) ** 2 + (jj - 4) ** 2 > 4].any()


def test_threads_bit_identical():
    rng = np.random.default_rng(3)
    h = np.cumsum(rng.normal(size=(80, 90)), axis=1)
    for name in ("pattern", "dda_maxmip", "march"):
        one = T.horizon(h, [17.0, 200.0], algorithm=name, threads=1)
        two = T.horizon(h, [17.0, 200.0], algorithm=name, threads=2)
        assert np.array_equal(one, two), name
    np.testing.assert_array_equal(T.viewshed(h, (40, 30), threads=1),
                                  T.viewshed(h, (40, 30), threads=2))


def test_heightfield_units_and_north():
    """A HeightField's spacing makes heights and lengths metres; fields whose rows run
    north (north='+y', as jacksboro) are flipped so that azimuths stay geographic.
    (Heights are in the unit of the spacing; heights in cells
    say so with height_unit='cell'.)"""
    rng = np.random.default_rng(5)
    h = rng.integers(0, 5, size=(8, 9)).astype(np.float32)
    want = T.horizon(h[::-1], [0.0, 90.0], max_distance=3.0)[:, ::-1]
    for field in (HeightField(h * 32, "t", spacing=32.0, unit="m", north="+y"),
                  HeightField(h, "t", spacing=32.0, unit="m", height_unit="cell",
                              params={"north": "+y"})):
        got = T.horizon(field, [0.0, 90.0], max_distance=96.0)  # 3 cells
        np.testing.assert_allclose(got, want, atol=0)
        v = T.viewshed(field, (2, 1), observer_height=32.0)
        np.testing.assert_array_equal(v, T.viewshed(h[::-1], (2, 6), observer_height=1.0)[::-1])


@pytest.mark.parametrize("call, match", [
    (lambda: T.horizon(np.zeros(5), 0), "heights: expected a 2D"),
    (lambda: T.horizon(np.zeros((1, 5)), 0), "heights: each side"),
    (lambda: T.horizon(np.array([[0, 1], [np.inf, 2]]), 0), r"heights: non-finite .*row 1, col 0"),
    (lambda: T.horizon(np.zeros((3, 3)), [0, np.inf]), r"azimuths\[1\]"),
    (lambda: T.horizon(np.array([[0, 1], [2, 1e300]]), 0), r"row 1, col 1\) exceeds"),
    (lambda: T.horizon(np.zeros((3, 3)), 0, max_distance=-1), "max_distance"),
    (lambda: T.horizon(np.zeros((3, 3)), 0, algorithm="nope"), "algorithm"),
    (lambda: T.horizon(np.zeros((3, 3)), 0, surface="flat"), "surface"),
    (lambda: T.horizon(np.zeros((3, 3)), 0, threads=0), "threads"),
    (lambda: T.shadows(np.zeros((3, 3)), 0, 95), "elevation"),
    (lambda: T.viewshed(np.zeros((3, 3)), (5, 0)), r"observer\[0\]"),
    (lambda: T.viewshed(np.zeros((3, 3)), [[0, 0], [1, np.nan]]), r"observer\[1\]"),
    (lambda: T.viewshed(np.zeros((3, 3)), (1, 1), observer_height=np.nan), "observer_height"),
    (lambda: T.viewshed(np.zeros((3, 3)), (1, 1), curvature=True, spacing=1, refraction=2),
     "refraction"),
    (lambda: T.sky_view_factor(np.zeros((3, 3)), 0), "n_azimuths"),
])
def test_bad_input_raises_naming_the_argument(call, match):
    with pytest.raises((ValueError, TypeError), match=match):
        call()


def test_string_heights_rejected():
    with pytest.raises(TypeError, match="heights"):
        T.horizon(np.array([["a", "b"], ["c", "d"]]), 0)


def test_kernel_rejects_a_pattern_reading_outside():
    """The binding checks that every breakpoint a limit admits stays inside the field."""
    h = np.zeros((4, 4))
    one = np.ones(1)
    far = np.array([5], dtype=np.int64)
    zero = np.zeros(1, dtype=np.int64)
    out = np.empty(16)
    with pytest.raises(ValueError, match="outside the field"):
        _kernels.horizon_pattern(h, one, far, zero, far, zero, one,
                                 np.ones(4, dtype=np.int64), np.ones(4, dtype=np.int64),
                                 -1, 0.0, 0.0, 0.0, 0, 0, 16, out)
    with pytest.raises(ValueError, match="vertex range"):
        _kernels.horizon_walk(h, None, 1.0, 0.0, np.inf, 0, 17, out)
    with pytest.raises(ValueError, match="next vertex"):
        _kernels.horizon_sweep(h, 2, 1, one, zero, zero, zero, zero, one, zero, zero, 1.0, 0, 1,
                               out)
    with pytest.raises(ValueError, match="line range"):
        _kernels.horizon_sweep(h, 2, 1, one, zero, zero, zero, zero, one, zero, zero, 1.0, 0,
                               10**6, out)


def test_public_names():
    for name in ("horizon", "shadows", "sky_view_factor", "viewshed", "rational_azimuths",
                 "HORIZON_ALGORITHMS", "VIEWSHED_ALGORITHMS"):
        assert hasattr(algos, name)


def test_cli_products_write_files(tmp_path):
    import tifffile

    from bench.cli import main

    prefix = str(tmp_path / "sh")
    assert main(["shadows", "jacksboro", "--size", "48", "--azimuth", "135",
                 "--elevation", "5", "--out", prefix, "--no-progress"]) == 0
    for ext in (".tif", ".exr", ".png"):
        assert (tmp_path / f"sh{ext}").stat().st_size > 0
    import datasets_gen

    hf = datasets_gen.load("jacksboro", size=48)
    want = T.shadows(hf, 135.0, 5.0)[::-1]  # files are north-up
    np.testing.assert_array_equal(tifffile.imread(prefix + ".tif"), want.astype(np.float32))
    # a generated field has no map coordinates: pixels, counted from the north-west corner
    assert main(["viewshed", "fbm", "--size", "32", "--observer", "3,4",
                 "--out", str(tmp_path / "vs"), "--no-progress"]) == 2
    assert main(["viewshed", "fbm", "--size", "32", "--observer-pixel", "3,4",
                 "--observer-pixel", "20,20", "--out", str(tmp_path / "vs"),
                 "--no-progress"]) == 0
    count = tifffile.imread(str(tmp_path / "vs.tif"))
    hf = datasets_gen.load("fbm", size=32, seed=1)  # the CLI's default seed
    np.testing.assert_array_equal(count, T.viewshed(hf, [[3, 4], [20, 20]]).astype(np.float32))
    assert main(["svf", "fbm", "--size", "32", "--rational", "--out", str(tmp_path / "svf"),
                 "--no-progress"]) == 0
    assert main(["horizon", "fbm", "--size", "32", "--azimuths", "0,45", "--max-distance", "8",
                 "--out", str(tmp_path / "hz"), "--no-progress"]) == 0
    import rasterio

    with rasterio.open(tmp_path / "hz.tif") as src:  # one band per azimuth
        assert src.count == 2 and src.descriptions == ("azimuth 0", "azimuth 45")
        want = np.degrees(T.horizon(hf, [0, 45], 8.0)).astype(np.float32)
        np.testing.assert_array_equal(src.read(), want)


def test_parallel_section_writes_and_resumes(tmp_path):
    from bench.studies import parallel_rays

    out = str(tmp_path / "rep")
    rows = parallel_rays.run_parallel(out_dir=out, size=40, run_lengths=(1, 5), repeats=1,
                                      sample=400, rays=40, echo=lambda *a: None, figure=True)
    algorithms = {r["algorithm"] for r in rows}
    assert set(parallel_rays.HORIZON_METHODS) <= algorithms
    assert set(parallel_rays.HIT_METHODS) <= algorithms
    exact = [r for r in rows if r["workload"] == "horizon" and
             T.HORIZON_ALGORITHMS[r["algorithm"]].exact]
    assert all(float(r["max_err_deg"]) < 1e-9 for r in exact)
    text = (tmp_path / "rep" / "parallel.md").read_text()
    assert "What the periodic patterns buy" in text and "`runs_periodic`" in text
    assert (tmp_path / "rep" / "products.png").stat().st_size > 0
    # a resumed run measures nothing again
    again = parallel_rays.run_parallel(out_dir=out, size=40, run_lengths=(1, 5), repeats=1,
                                       sample=400, rays=40, resume=True, echo=lambda *a: None,
                                       figure=False)
    assert len(again) == len(rows)


def test_sample_ranges_spread_and_disjoint():
    from bench.studies.terrain import sample_ranges

    ranges = sample_ranges(100, 50, 640)
    assert sum(b - a for a, b in ranges) == 640
    assert all(a < b for a, b in ranges)
    assert all(ranges[k][1] <= ranges[k + 1][0] for k in range(len(ranges) - 1))
    assert ranges[0][0] < 50 and ranges[-1][1] > 99 * 50


@pytest.mark.parametrize("max_distance", [0.0, 5e-324, 1e-300, 1e-9])
def test_tiny_max_distance(max_distance):
    """Found by fuzzing: o + t d rounds back onto o for tiny t, so the end of the ray must
    come from the linear piece it lies on (the first piece's slope), and 0 is empty."""
    h = FIELDS["noise"]
    for az in (270.0, 30.0, 242.59375):
        d = T.azimuth_direction(az)
        ref = np.array(horizon_reference(h, (d.dx, d.dy), max_distance))
        for name in ("pattern", "dda", "dda_maxmip"):
            got = T.horizon(h, az, max_distance, algorithm=name)[0]
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12, err_msg=f"{name} {az}")


def test_wide_dynamic_range():
    """Found by fuzzing: heights of 1e20 next to 1 must not leak into the points beside
    them (edge values with weights exactly 0 and 1, the end taken from its nearer end)."""
    h = np.array([[46.0, -23.8349609375, -11.0], [1.0, -256.46875, -182.75],
                  [-12.72265625, -2.4263538525227962e20, -1073741824.0],
                  [26.0107421875, 9.04296875, 2.0], [-25.173828125, 3.0, 0.0]])
    for az in (242.59375, 270.0, 90.0, 17.0):
        d = T.azimuth_direction(az)
        ref = np.array(horizon_reference(h, (d.dx, d.dy)))
        for name in ("pattern", "dda", "dda_maxmip"):
            got = T.horizon(h, az, algorithm=name)[0]
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9, err_msg=f"{name} {az}")
