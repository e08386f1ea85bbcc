"""Topographic openness (Yokoyama, Shirasawa & Pike 2002): closed-form terrains,
the exact horizons it comes from, voids, curvature, units, and RVT where rvt-py installs."""
import math
import warnings

import numpy as np
import pytest

import algos
import algos.terrain as T
from algos.terrain.reference import horizon_reference

YY, XX = np.mgrid[0:15, 0:17].astype(float)


def _mean_deg(angles_rad):
    return float(np.mean(np.degrees(angles_rad)))


@pytest.mark.parametrize("kind", ["positive", "negative"])
@pytest.mark.parametrize("n_azimuths", [1, 8, 16])
def test_flat_plane_is_ninety_everywhere(kind, n_azimuths):
    """Every elevation angle is 0, at the edges too: an azimuth that leaves the footprint at
    once has no angle and is left out of the mean. With the one azimuth north, the north
    row has none left: NaN."""
    got = algos.openness(np.zeros((6, 7)), kind, n_azimuths)
    if n_azimuths == 1:
        assert np.isnan(got[0]).all()
        got = got[1:]
    np.testing.assert_array_equal(got, 90.0)


@pytest.mark.parametrize("slope", [0.25, 1.0, 3.0])
def test_v_valley_and_ridge_closed_form(slope):
    """z = s |x - c|: from a vertex on the valley floor every ray climbs a straight line,
    so both the largest and the smallest elevation angle along azimuth A are
    atan(s |sin A|): positive openness is the mean of 90 - that, negative the mean of
    90 + that. The ridge -z swaps the two."""
    c = 8
    valley = slope * np.abs(XX - c)
    az = np.arange(16) * 22.5
    phi = np.arctan(slope * np.abs(np.sin(np.radians(az))))
    low = 90.0 - _mean_deg(phi)
    high = 90.0 + _mean_deg(phi)
    rows = slice(1, -1)  # every azimuth has a point from an interior row
    for terrain, positive, negative in ((valley, low, high), (-valley, high, low)):
        po = algos.openness(terrain, "positive", 16)
        ne = algos.openness(terrain, "negative", 16)
        np.testing.assert_allclose(po[rows, c], positive, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ne[rows, c], negative, rtol=0, atol=1e-12)


def test_tilted_plane_with_a_short_radius():
    """A plane z = a x + b y: along azimuth A the elevation angle is atan(a sin A - b cos A)
    (north is -y), both the largest and the smallest."""
    a, b = 0.4, -0.7
    h = a * XX + b * YY
    az = np.arange(8) * 45.0
    phi = np.arctan(a * np.sin(np.radians(az)) - b * np.cos(np.radians(az)))
    po = algos.openness(h, "positive", 8, 3.0)
    ne = algos.openness(h, "negative", 8, 3.0)
    np.testing.assert_allclose(po[3:-3, 3:-3], 90.0 - _mean_deg(phi), rtol=0, atol=1e-12)
    np.testing.assert_allclose(ne[3:-3, 3:-3], 90.0 + _mean_deg(phi), rtol=0, atol=1e-12)


@pytest.mark.parametrize("max_distance", [None, 4.0])
def test_matches_the_exact_horizons(max_distance):
    """Positive openness is 90 minus the mean exact horizon; negative the same on -H."""
    rng = np.random.default_rng(7)
    h = rng.integers(0, 6, size=(8, 10)).astype(float)
    az = [0.0, 60.0, 135.0, 200.0, 300.0]
    for kind, terrain in (("positive", h), ("negative", -h)):
        angles = []
        for a in az:
            d = T.azimuth_direction(a)
            angles.append(horizon_reference(terrain, (d.dx, d.dy), max_distance))
        angles = np.array(angles)
        seen = angles > -math.pi / 2
        expected = np.degrees(np.where(seen, math.pi / 2 - angles, 0).sum(0) / seen.sum(0))
        got = algos.openness(h, kind, azimuths=az, max_distance=max_distance)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12, err_msg=kind)


def test_negative_is_positive_of_the_mirror():
    h = np.random.default_rng(3).random((9, 9)) * 5
    np.testing.assert_array_equal(algos.openness(h, "negative"), algos.openness(-h, "positive"))


def test_negative_with_curvature_reads_the_lowered_surface():
    """With curvature the smallest elevation angle is taken on the lowered surface: the
    horizon of -H raised by kappa D^2 (kappa negated in the reference)."""
    rng = np.random.default_rng(12)
    h = rng.integers(0, 6, size=(8, 10)).astype(float)
    kappa = (1 - T.DEFAULT_REFRACTION) * 1.0 / (2 * 20.0)
    az = [0.0, 45.0, 100.0, 250.0]
    for kind, terrain, k in (("positive", h, kappa), ("negative", -h, -kappa)):
        angles = np.array([horizon_reference(terrain, (d.dx, d.dy), kappa=k)
                           for d in map(T.azimuth_direction, az)])
        seen = angles > -math.pi / 2
        expected = np.degrees(np.where(seen, math.pi / 2 - angles, 0).sum(0) / seen.sum(0))
        for name in ("pattern", "dda", "dda_maxmip", None):
            got = algos.openness(h, kind, azimuths=az, spacing=1.0, curvature=True,
                                 earth_radius=20.0, algorithm=name)
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10,
                                       err_msg=f"{kind} {name}")
    flat = algos.openness(h, "negative", azimuths=az, spacing=1.0)
    assert np.any(np.abs(got - flat) > 1e-3)


def test_voids_are_nodata_and_contribute_nothing():
    """A void is nodata (NaN); away from it a flat plane still reads 90 on both kinds: a
    void is a pit in the terrain and in its mirror, so it gives no elevation angle."""
    h = np.zeros((9, 11))
    h[4, 5] = np.nan
    for kind in ("positive", "negative"):
        got = algos.openness(h, kind, 8)
        assert np.isnan(got[4, 5])
        near = np.zeros(h.shape, dtype=bool)
        near[3:6, 4:7] = True
        np.testing.assert_allclose(got[~near], 90.0, rtol=0, atol=1e-12, err_msg=kind)


def test_units_and_dataarray_attrs():
    h = np.random.default_rng(4).random((7, 8))
    deg = algos.openness(h, "positive", 8)
    rad = algos.openness(h, "positive", 8, units="radians")
    np.testing.assert_allclose(np.degrees(rad), deg, rtol=0, atol=1e-12)
    assert np.all((deg >= 0) & (deg <= 180))
    xr = pytest.importorskip("xarray")
    da = xr.DataArray(h, dims=("y", "x"),
                      coords={"y": -np.arange(7.0), "x": np.arange(8.0)})
    out = algos.openness(da, "negative", 8)
    assert out.attrs["units"] == "degrees" and out.attrs["kind"] == "negative"
    assert out.attrs["n_azimuths"] == 8 and out.attrs["curvature"] == 0


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(kind="both"), ValueError, "kind: expected one of"),
    (dict(units="deg"), ValueError, "units: expected one of"),
    (dict(n_azimuths=0), ValueError, "n_azimuths: expected a positive int"),
    (dict(curvature=True), ValueError, "curvature: needs spacing"),
    (dict(algorithm="sweep", curvature=True, spacing=1.0), ValueError, "curvature: algorithm"),
])
def test_bad_arguments(kwargs, error, match):
    with pytest.raises(error, match=match):
        algos.openness(np.zeros((4, 4)), **kwargs)


def test_agrees_with_rvt_on_the_axes():
    """RVT (rvt-py) samples pixel offsets rounded to the grid along each direction, with
    mirrored padding at the edges; along the four axis directions those offsets are the
    vertices themselves, where the two-triangle surface's supremum lies, so away from the
    edges the two agree to RVT's float32. (With 16 directions RVT's rounding differs from
    the exact openness by up to a few degrees.)"""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import rvt.vis
    except ImportError:
        pytest.skip("rvt-py is not installed (pip install --no-deps rvt-py, plus scipy)")
    h = np.round(np.random.default_rng(1).random((41, 41)) * 160) / 8  # exact in float32
    core = (slice(10, 31), slice(10, 31))
    for kind, dem in (("positive", h), ("negative", -h)):
        theirs = rvt.vis.sky_view_factor(dem.copy(), 1.0, compute_svf=False, compute_opns=True,
                                         svf_n_dir=4, svf_r_max=10)["opns"]
        ours = algos.openness(h, kind, 4, 10.0)
        np.testing.assert_allclose(ours[core], theirs[core], rtol=0, atol=1e-4, err_msg=kind)


def test_cli_openness(tmp_path, capsys):
    """``hftrace openness --kind negative``: the API's values, in degrees, kind and
    parameters in the tags."""
    rasterio = pytest.importorskip("rasterio")
    from bench.cli import main

    h = (np.random.default_rng(2).random((12, 14)) * 40).astype(np.float32)
    np.save(tmp_path / "dem.npy", h)
    out = str(tmp_path / "open")
    code = main(["openness", str(tmp_path / "dem.npy"), "--spacing", "10", "--kind", "negative",
                 "--n-azimuths", "8", "--max-distance", "50", "--out", out, "--no-progress"])
    assert code == 0, capsys.readouterr().err
    field = algos.HeightField(h, spacing=10.0, unit="m")
    want = algos.openness(field, "negative", 8, 50.0)
    with rasterio.open(out + ".tif") as src:
        tags = src.tags()
        assert tags["units"] == "degrees" and tags["kind"] == "negative"
        assert tags["product"] == "openness_negative" and tags["n_azimuths"] == "8"
        np.testing.assert_allclose(src.read(1), want.astype(np.float32), rtol=0, atol=1e-4)


def test_snapping_is_recorded():
    """Openness with snap_denominator: the snapped azimuths give the same values as asking
    for them directly, and the snapping is recorded."""
    rng = np.random.default_rng(7)
    h = rng.random((24, 30)) * 5
    got, stats = algos.openness(h, azimuths=[22.5, 100.0], snap_denominator=3, return_stats=True)
    used = tuple(stats.snapped_azimuths)
    assert len(used) == 2 and stats.snap_max_change_deg > 0
    np.testing.assert_array_equal(got, algos.openness(h, azimuths=list(used)))


def test_cli_horizon_and_openness_in_radians(tmp_path, capsys):
    """``--units radians`` writes the API's radians and records the unit; ``--dask`` with
    ``--snap-denominator`` is refused, not ignored."""
    rasterio = pytest.importorskip("rasterio")
    from bench.cli import main

    h = (np.random.default_rng(3).random((12, 14)) * 40).astype(np.float32)
    np.save(tmp_path / "dem.npy", h)
    field = algos.HeightField(h, spacing=10.0, unit="m")
    for command, want, extra in (
            ("horizon", algos.horizon(field, [30.0], 50.0)[0], ["--azimuths", "30"]),
            ("openness", algos.openness(field, "positive", 8, 50.0, units="radians"),
             ["--n-azimuths", "8"])):
        out = str(tmp_path / command)
        code = main([command, str(tmp_path / "dem.npy"), "--spacing", "10", "--max-distance",
                     "50", "--units", "radians", "--out", out, "--no-progress"] + extra)
        assert code == 0, capsys.readouterr().err
        with rasterio.open(out + ".tif") as src:
            assert src.tags()["units"] == "radians"
            np.testing.assert_allclose(src.read(1), want.astype(np.float32), rtol=0, atol=1e-6)
    code = main(["horizon", str(tmp_path / "dem.npy"), "--spacing", "10", "--max-distance", "50",
                 "--dask", "local:1", "--snap-denominator", "3", "--out",
                 str(tmp_path / "d"), "--no-progress"])
    assert code != 0 and "--snap-denominator: not available with --dask" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["svf", "openness"])
def test_cli_refuses_rational_with_explicit_azimuths(tmp_path, capsys, command):
    """--rational moves the equally spaced azimuths only: with --azimuths it was ignored
    (the files' paths said chain, not sweep); --snap-denominator 5 is the spelling."""
    from bench.cli import main

    np.save(tmp_path / "dem.npy", np.zeros((8, 8), np.float32))
    base = [command, str(tmp_path / "dem.npy"), "--out", str(tmp_path / "p"), "--no-progress",
            "--azimuths", "10,20"]
    assert main(base + ["--rational"]) != 0
    assert "--rational: moves the equally spaced azimuths" in capsys.readouterr().err
    assert main(base + ["--snap-denominator", "5"]) == 0, capsys.readouterr().err
    assert main([command, str(tmp_path / "dem.npy"), "--out", str(tmp_path / "q"),
                 "--no-progress", "--n-azimuths", "8", "--rational"]) == 0


@pytest.mark.parametrize("product", [algos.sky_view_factor, algos.openness])
def test_explicit_azimuths_refuse_what_would_be_ignored(product):
    """n_azimuths and rational=True apply to the equally spaced azimuths: with explicit
    azimuths they were ignored; the default (16, not rational) is unchanged."""
    h = np.arange(64, dtype=np.float64).reshape(8, 8) % 5
    with pytest.raises(ValueError, match=r"azimuths: give n_azimuths or azimuths, not both "
                                         r"\(got n_azimuths=8 with explicit azimuths\)"):
        product(h, n_azimuths=8, azimuths=[10.0, 20.0])
    with pytest.raises(ValueError, match=r"rational: applies to the n_azimuths equally spaced "
                                         r"azimuths only .* snap_denominator=5"):
        product(h, azimuths=[10.0, 20.0], rational=True)
    np.testing.assert_array_equal(product(h), product(h, n_azimuths=16))
    np.testing.assert_array_equal(product(h), product(h, azimuths=np.arange(16) * 22.5))


@pytest.mark.parametrize("argv, message", [
    (["--azimuths", ""], "--azimuths: expected comma-separated degrees, got ''"),
    (["--refraction", "0.5"], "--refraction: applies with --curvature only"),
])
def test_cli_refuses_options_it_would_ignore(tmp_path, capsys, argv, message):
    """An empty --azimuths and a --refraction without --curvature are refused, not
    silently replaced by the defaults."""
    from bench.cli import main

    np.save(tmp_path / "dem.npy", np.zeros((8, 8), np.float32))
    code = main(["horizon", str(tmp_path / "dem.npy"), "--out", str(tmp_path / "h"),
                 "--no-progress"] + argv)
    assert code != 0 and message in capsys.readouterr().err
