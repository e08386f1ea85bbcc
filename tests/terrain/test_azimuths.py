"""Every azimuth fast: the chain walk and the row-vectorised pattern against the
exact reference and the other exact methods, the paths each azimuth takes, and explicit
snapping to rational directions."""
import math
import re

import numpy as np
import pytest

import algos.terrain as T
from algos import _kernels
from algos.terrain.reference import horizon_reference
from algos.terrain.walks import CHAIN_MAX_NEIGHBOURS

#: RVT's default: 16 equally spaced azimuths; the odd ones (22.5 + k 45) are irrational
SIXTEEN = [22.5 * k for k in range(16)]
IRRATIONAL = [22.5 + 45.0 * k for k in range(8)]


def _field(seed, shape, kind="noise"):
    rng = np.random.default_rng(seed)
    if kind == "noise":
        return rng.integers(0, 9, size=shape).astype(float)
    # a smooth field with a few peaks: long horizons, where borrowed bounds matter
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    h = np.zeros(shape)
    for _ in range(5):
        cy, cx, r = rng.uniform(0, shape[0]), rng.uniform(0, shape[1]), rng.uniform(3, 12)
        h += rng.uniform(2, 9) * np.exp(-((yy - cy) ** 2 + (xx - cx) ** 2) / r ** 2)
    return h + 0.1 * rng.normal(size=shape)


@pytest.mark.parametrize("name", ["chain", "rows"])
@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("max_distance", [None, 0.4, 3.0, 9.5])
def test_new_methods_match_exact_reference(name, seed, max_distance):
    h = _field(seed, (11 + seed, 14 - seed))
    for az in SIXTEEN + [7.0, 301.3]:
        d = T.azimuth_direction(az)
        ref = np.array(horizon_reference(h, (d.dx, d.dy), max_distance))
        got = T.horizon(h, az, max_distance, algorithm=name)[0]
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12,
                                   err_msg=f"{name} seed={seed} az={az!r} md={max_distance!r}")


@pytest.mark.parametrize("seed", [4, 5])
def test_chain_matches_dda_on_long_horizons(seed):
    """Larger smooth fields (lower bounds borrowed over many vertices) at every azimuth
    class: the chain walk equals the plain cell walk to rounding, and borrows bounds."""
    h = _field(seed, (57, 64), kind="peaks")
    for az in SIXTEEN + [3.3]:
        want = T.horizon(h, az, algorithm="dda")
        got, stats = T.horizon(h, az, algorithm="chain", return_stats=True)
        assert stats.bounded > 0.5 * h.size, (az, stats)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12, err_msg=f"seed={seed} az={az!r}")


def test_rows_bit_identical_to_pattern():
    h = _field(6, (23, 31), kind="peaks")
    for az in SIXTEEN + [10.0, 200.1]:
        for md in (None, 0.5, 2.0, 7.3, 40.0):
            a = T.horizon(h, az, md, algorithm="rows")
            b = T.horizon(h, az, md, algorithm="pattern")
            assert np.array_equal(a, b), f"az={az!r} md={md!r}"


def test_voids_and_rectangular_pixels():
    """Voids (NaN) and rectangular pixels go through the same paths: the chain walk and
    the rows pattern agree with the cell walk, which tests/gis/test_georef.py checks in map
    space."""
    h = _field(7, (19, 22), kind="peaks")
    h[5, 7] = h[12, 3] = np.nan
    for spacing in (1.0, (2.0, 3.0)):
        for md in (None, 6.0):
            want = T.horizon(h, SIXTEEN, md, algorithm="dda", spacing=spacing)
            for name in ("chain", "rows"):
                got = T.horizon(h, SIXTEEN, md, algorithm=name, spacing=spacing)
                assert np.array_equal(np.isnan(got), np.isnan(want))
                np.testing.assert_allclose(got, want, rtol=0, atol=1e-12,
                                           err_msg=f"{name} spacing={spacing} md={md}")


def test_threads_bit_identical():
    h = _field(8, (300, 40), kind="peaks")  # more than one block of chain rows
    for name in ("chain", "rows"):
        one = T.horizon(h, IRRATIONAL[:3], algorithm=name, threads=1)
        two = T.horizon(h, IRRATIONAL[:3], algorithm=name, threads=2)
        assert np.array_equal(one, two), name


def test_default_paths_per_azimuth():
    """The default takes the sweep for rational directions at unlimited distance, the chain
    walk for the others, and the row-vectorised pattern for short radii; the result says
    which, per azimuth."""
    h = _field(9, (12, 15))
    stats = T.horizon(h, SIXTEEN, return_stats=True)[1]
    assert stats.paths == tuple("sweep" if k % 2 == 0 else "chain" for k in range(16))
    assert stats.algorithm == "sweep+chain"
    stats = T.horizon(h, SIXTEEN, max_distance=10.0, return_stats=True)[1]
    assert set(stats.paths) == {"rows"}
    stats = T.horizon(h, SIXTEEN, max_distance=1000.0, return_stats=True)[1]
    assert set(stats.paths) == {"chain"}
    stats = T.horizon(h, SIXTEEN, algorithm="dda", return_stats=True)[1]
    assert stats.paths == ("dda",) * 16 and stats.algorithm == "dda"


def test_chain_neighbours_are_convergents_near_the_ray():
    for az in SIXTEEN + [1.0, 33.3]:
        d = T.azimuth_direction(az)
        gx, gy, dist = T.chain_neighbours(d)
        assert len(gx) >= 1
        for x, y, t in zip(gx, gy, dist):
            across = abs(x * d.dy - y * d.dx)  # distance of v + (x, y) from v's ray
            assert across <= T.CHAIN_MAX_OFFSET + 1e-12
            assert t == pytest.approx(x * d.dx + y * d.dy) and t > 0
    gx, gy, dist = T.chain_neighbours(T.azimuth_direction(math.degrees(math.atan2(2, 5))))
    assert (abs(gx[0]), abs(gy[0])) == (2, 5)  # a rational direction: its own period
    assert len(gx) == CHAIN_MAX_NEIGHBOURS + 1  # ... besides the two of smallest q
    # an irrational direction: the convergents of smallest q (1/1 and 2/1 of 22.5 degrees,
    # not 5/2, 12/5, ... further along)
    gx, gy, dist = T.chain_neighbours(T.azimuth_direction(22.5))
    assert sorted((abs(int(x)), abs(int(y))) for x, y in zip(gx, gy)) == [(0, 1), (1, 2)]
    assert len(T.chain_neighbours(T.azimuth_direction(22.5), max_neighbours=9)[0]) == 9


def test_snap_azimuths():
    snapped, change = T.snap_azimuths(SIXTEEN, 5)
    assert snapped[1] == pytest.approx(math.degrees(math.atan2(2, 5)))
    assert change == pytest.approx(22.5 - math.degrees(math.atan2(2, 5)))  # 0.699 deg
    assert np.all(snapped[::2] == SIXTEEN[::2])  # the axes and diagonals stay
    for a in snapped:
        assert T.azimuth_direction(a).rational is not None
    # a larger denominator moves less
    assert T.snap_azimuths(SIXTEEN, 12)[1] < 0.13 < change
    # rectangular pixels: snapped in cell space, reported in map azimuths
    snapped, change = T.snap_azimuths([22.5], 5, spacing=(2.0, 1.0))
    grid = T.Grid(np.zeros((2, 2)), 2.0, 1.0, 2.0, True, None, None)
    assert T.azimuth_direction(grid.cell_azimuth(snapped[0])).rational is not None
    assert change == pytest.approx(abs(snapped[0] - 22.5))


def test_snapping_is_explicit_and_recorded():
    h = _field(10, (12, 13))
    plain, stats = T.horizon(h, SIXTEEN, return_stats=True)
    assert stats.snapped_azimuths == () and stats.snap_max_change_deg == 0.0
    snapped, stats = T.horizon(h, SIXTEEN, snap_denominator=5, return_stats=True)
    assert stats.algorithm == "sweep"
    want, change = T.snap_azimuths(SIXTEEN, 5)
    assert stats.snapped_azimuths == tuple(want)
    assert stats.snap_max_change_deg == change
    np.testing.assert_array_equal(snapped, T.horizon(h, want))
    assert not np.array_equal(snapped, plain)
    svf, stats = T.sky_view_factor(h, 16, snap_denominator=5, return_stats=True)
    assert stats.snapped_azimuths == tuple(want)
    np.testing.assert_array_equal(svf, T.sky_view_factor(h, azimuths=want))
    stats = T.shadows(h, 22.5, 10.0, snap_denominator=5, return_stats=True)[1]
    assert stats.snapped_azimuths == (want[1],)


def test_dataarray_records_paths_and_snapping():
    xr = pytest.importorskip("xarray")
    h = _field(11, (10, 12))
    da = xr.DataArray(h, dims=("y", "x"), coords={"y": np.arange(10.0), "x": np.arange(12.0)})
    out = T.horizon(da, [0.0, 22.5])
    assert out.attrs["algorithm"] == "sweep+chain" and out.attrs["paths"] == "sweep,chain"
    assert "snapped_azimuths" not in out.attrs
    out = T.sky_view_factor(da, 16, snap_denominator=5)
    assert out.attrs["snapped_azimuths"] == [float(a) for a in T.snap_azimuths(SIXTEEN, 5)[0]]
    assert out.attrs["snap_max_change_deg"] == pytest.approx(0.6986, abs=1e-4)


def test_sky_view_factor_from_tangents_equals_angle_form():
    """sin(max(atan(x), 0)) = x / sqrt(1 + x^2) for x > 0: the sky-view factor equals its
    angle form to rounding, voids stay NaN."""
    h = _field(12, (20, 21), kind="peaks")
    h[3, 4] = np.nan
    angles = T.horizon(h, SIXTEEN)
    with np.errstate(invalid="ignore"):
        want = 1 - np.mean(np.sin(np.maximum(angles, 0)), axis=0)
    got = T.sky_view_factor(h, 16)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, rtol=0, atol=4e-16)
    assert T._sin_of_positive_atan(np.array([1e300, -np.inf, 0.0]))[0] == 1.0


@pytest.mark.parametrize("call, match", [
    (lambda: T.snap_azimuths([1.0], 0), "max_denominator"),
    (lambda: T.snap_azimuths([1.0], T.MAX_SNAP_DENOMINATOR + 1), "max_denominator"),
    (lambda: T.snap_azimuths([1.0, float("nan")], 5), r"azimuths\[1\]"),
    (lambda: T.horizon(np.zeros((3, 3)), [1.0], snap_denominator=True), "snap_denominator"),
])
def test_bad_snapping_raises_naming_the_argument(call, match):
    with pytest.raises((ValueError, TypeError), match=match):
        call()


def test_kernels_refuse_what_would_read_outside():
    h = np.zeros((4, 5))
    one = np.ones(1)
    ints = [np.zeros(1, np.int64) for _ in range(4)]
    with pytest.raises(ValueError, match="reach"):  # an offset beyond its reach
        _kernels.horizon_rows(h, one, np.array([2]), *ints[1:], one, np.array([1]),
                              np.array([0]), 1, 1, 1, -1, 0.0, 0.0, 0, 4, np.empty(20))
    with pytest.raises(ValueError, match="sx, sy"):
        _kernels.horizon_rows(h, one, *ints, one, ints[0], ints[0], 0, 1, 1, -1, 0.0, 0.0, 0,
                              4, np.empty(20))
    with pytest.raises(TypeError, match="strips"):
        _kernels.horizon_chain(h, None, 1.0, 0.0, math.inf, ints[0], ints[0], one, 4, 0, 1,
                               np.empty(20), np.empty(20))


# ---- the terrain-bench section ---------------------------------------------------------------

def test_numpy_baseline_is_rvts_method():
    """The NumPy baseline reproduces RVT's SVF (where rvt-py imports) and sees a full sky
    on a plane."""
    from bench.studies.terrain_azimuths import numpy_rvt_svf, rvt_svf

    assert np.all(numpy_rvt_svf(np.zeros((12, 13)), 16, 3) == 1.0)
    h = np.random.default_rng(13).normal(size=(30, 34)).cumsum(axis=0)
    ours = numpy_rvt_svf(h, 16, 5)
    assert np.all((ours > 0) & (ours <= 1))
    rvt = rvt_svf()
    if rvt is None:
        pytest.skip("rvt-py does not import (the Makefile's peers step installs it)")
    np.testing.assert_allclose(ours, rvt(h, 16, 5)["svf"], rtol=0, atol=1e-12)


def test_terrain_bench_azimuth_section_runs():
    from bench.studies.terrain_azimuths import run_azimuths

    lines, rows = run_azimuths(size=64, svf_size=40, radii=(3, 8), repeats=1, baseline=True,
                               echo=lambda *a: None)
    text = "\n".join(lines)
    assert "16 azimuths" in text and "`chain`" in text and "`sweep`" in text
    assert "| 3 |" in text and "| 8 |" in text and "hftrace vs RVT" in text
    assert {r["workload"] for r in rows} >= {"horizon16", "horizon16_snapped", "svf16_r3",
                                             "svf16_r8"}
    assert all(r["field_seconds"] > 0 for r in rows)


def test_cli_records_paths_and_snapping(tmp_path):
    rasterio = pytest.importorskip("rasterio")
    from bench.cli import main

    out = str(tmp_path / "svf")
    assert main(["svf", "jacksboro", "--size", "40", "--n-azimuths", "16", "--snap-denominator",
                 "5", "--out", out, "--no-progress"]) == 0
    with rasterio.open(out + ".tif") as src:
        tags = src.tags()
    assert tags["paths"] == ",".join(["sweep"] * 16)
    assert float(tags["snap_max_change_deg"]) == pytest.approx(0.6986, abs=1e-4)
    out = str(tmp_path / "hz")
    assert main(["horizon", "jacksboro", "--size", "40", "--azimuths", "0,22.5", "--out", out,
                 "--no-progress"]) == 0
    with rasterio.open(out + ".tif") as src:
        tags = src.tags()
    assert tags["paths"] == "sweep,chain" and "snapped_azimuths" not in tags


def test_snap_denominator_errors_name_it():
    with pytest.raises(ValueError, match=r"snap_denominator: expected an int in 1\.\.128, got 0"):
        T.horizon(np.zeros((4, 4)), [22.5], snap_denominator=0)
    with pytest.raises(ValueError, match=r"max_denominator: expected an int"):
        T.snap_azimuths([22.5], 200)


@pytest.mark.parametrize("azimuth, error, message", [
    (float("inf"), ValueError, "azimuth: expected a finite number of degrees, got inf"),
    (float("nan"), ValueError, "azimuth: expected a finite number of degrees, got nan"),
    ("north", TypeError, "azimuth: expected a number of degrees, got 'north'"),
    (True, TypeError, "azimuth: expected a number of degrees, got True"),
])
def test_shadows_errors_name_its_azimuth(azimuth, error, message):
    # shadows takes one azimuth: its errors name that argument, not horizon's azimuths[0]
    with pytest.raises(error, match="^" + re.escape(message) + "$"):
        T.shadows(np.zeros((4, 4)), azimuth, 10.0)
