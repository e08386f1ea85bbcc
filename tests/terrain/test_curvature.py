"""Curvature and refraction on the horizon family: horizon, shadows and the
sky-view factor against the curvature-aware exact reference (algos.terrain.reference), the
issue's worked example, a closed-form peak inside a linear piece, routing and validation.
"""
import math

import numpy as np
import pytest

import algos
import algos.terrain as T
from algos.terrain.reference import horizon_reference

#: The exact paths that take curvature (the sweep and the Embree peer refuse it).
CURVED = ["pattern", "dda", "dda_maxmip"]
AZIMUTHS = [0.0, 90.0, 135.0, 200.0, 333.3, math.degrees(math.atan2(1, 2)),
            180 + math.degrees(math.atan2(2, 5))]


def _kappa(refraction, dx, radius):
    """The drop per squared cell distance, in cell heights (module docstring)."""
    return (1.0 - refraction) * dx / (2.0 * radius)


def _random_field(seed, shape=(9, 12)):
    rng = np.random.default_rng(seed)
    return rng.integers(0, 6, size=shape).astype(float) + rng.random(shape) * 0.5


def test_issue_example_peak_across_a_plain():
    """A 600 m ridge 60 km away across a flat plain, 100 m cells: 0.573 deg without,
    0.342 deg with curvature and refraction 1/7 (WGS 84 semi-major axis), the closed form
    atan((600 - (1 - 1/7) D^2 / (2 R)) / D) at D = 60 km, on every curved path."""
    h = np.zeros((3, 700))
    h[:, 600] = 600.0
    plain = algos.horizon(h, 90.0, spacing=100.0, units="degrees")[0, 1, 0]
    assert plain == pytest.approx(math.degrees(math.atan(600 / 60000)), abs=1e-12)
    assert round(plain, 3) == 0.573
    drop = (1 - 1 / 7) * 60000.0 ** 2 / (2 * algos.WGS84_SEMI_MAJOR_AXIS_M)
    expected = math.degrees(math.atan((600 - drop) / 60000))
    assert round(expected, 3) == 0.342
    for name in CURVED + [None]:
        got, stats = algos.horizon(h, 90.0, spacing=100.0, units="degrees", curvature=True,
                                   algorithm=name, return_stats=True)
        assert got[0, 1, 0] == pytest.approx(expected, abs=1e-12), name
    assert stats.algorithm == "dda_maxmip"  # unlimited, curved: not the sweep


def test_peak_inside_a_piece_closed_form():
    """From a vertex at height 0 over a straight slope z = -1 + b (x - 1) (x >= 1), the
    lowered ratio g(t) = -(1 + b) / t + b - kappa t peaks at t* = sqrt((1 + b) / kappa),
    between two breakpoints, where g = b - 2 sqrt(kappa (1 + b)): the supremum is not at
    any breakpoint (kappa = 0.01, b = 0.5: t* = 12.25)."""
    b, kappa = 0.5, 0.01
    x = np.arange(30, dtype=float)
    row = np.where(x == 0, 0.0, -1.0 + b * (x - 1))
    h = np.tile(row, (3, 1))
    expected = math.atan(b - 2 * math.sqrt(kappa * (1 + b)))
    at_breakpoints = max(math.atan(-(1 + b) / t + b - kappa * t) for t in range(1, 30))
    assert expected - at_breakpoints > 1e-6  # the peak matters
    for name in CURVED:
        got = algos.horizon(h, 90.0, spacing=1.0, curvature=True, refraction=0.0,
                            earth_radius=50.0, algorithm=name)[0, 1, 0]
        assert got == pytest.approx(expected, abs=1e-13), name
    ref = horizon_reference(h, (1.0, 0.0), kappa=kappa)[1][0]
    assert ref == pytest.approx(expected, abs=1e-15)


@pytest.mark.parametrize("seed", [3, 17, 29])
@pytest.mark.parametrize("max_distance", [None, 2.5, 6.0])
def test_horizon_matches_curved_reference(seed, max_distance):
    """Seeded random terrains, a strong curvature (R = 20 cells), every curved path."""
    h = _random_field(seed)
    kappa = _kappa(T.DEFAULT_REFRACTION, 1.0, 20.0)
    for az in AZIMUTHS:
        d = T.azimuth_direction(az)
        ref = np.array(horizon_reference(h, (d.dx, d.dy), max_distance, kappa=kappa))
        plain = np.array(horizon_reference(h, (d.dx, d.dy), max_distance))
        for name in CURVED:
            got = algos.horizon(h, az, max_distance, algorithm=name, spacing=1.0,
                                curvature=True, earth_radius=20.0)[0]
            np.testing.assert_allclose(
                got, ref, rtol=0, atol=1e-12,
                err_msg=f"{name} seed={seed} az={az!r} md={max_distance} kappa={kappa!r}")
        assert np.any(np.abs(ref - plain) > 1e-6)  # curvature changed something


def test_march_with_curvature_never_exceeds_the_supremum():
    h = _random_field(5)
    for az in (0.0, 30.0, 135.0):
        exact = algos.horizon(h, az, algorithm="dda", spacing=1.0, curvature=True,
                              earth_radius=20.0)[0]
        march = algos.horizon(h, az, algorithm="march", march_step=0.37, spacing=1.0,
                              curvature=True, earth_radius=20.0)[0]
        assert np.all(march <= exact + 1e-12)


def test_curvature_in_metres_of_a_field_unit():
    """earth_radius is metres; a field in kilometres converts it (unit_metres)."""
    h = np.round(_random_field(8) * 8) / 8  # exact in float32, a HeightField's storage
    metres = algos.horizon(h * 1000.0, 45.0, spacing=1000.0, curvature=True,
                           earth_radius=20000.0)
    field = algos.HeightField(h, spacing=1.0, unit="km", params={"unit_metres": 1000.0})
    km = algos.horizon(field, 45.0, curvature=True, earth_radius=20000.0)
    np.testing.assert_allclose(km, metres, rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", [4, 21])
def test_shadows_match_curved_reference(seed):
    h = _random_field(seed)
    kappa = _kappa(T.DEFAULT_REFRACTION, 1.0, 20.0)
    changed = 0
    for az in (90.0, 200.0, 333.3):
        d = T.azimuth_direction(az)
        ref = np.array(horizon_reference(h, (d.dx, d.dy), kappa=kappa))
        plain = np.array(horizon_reference(h, (d.dx, d.dy)))
        for el in (-20.0, 5.0, 20.0):
            rad = math.radians(el)
            assert np.all(np.abs(ref - rad) > 1e-9)  # no ties near rounding
            for name in CURVED:
                got = algos.shadows(h, az, el, algorithm=name, spacing=1.0, curvature=True,
                                    earth_radius=20.0)
                np.testing.assert_array_equal(got, ref > rad, err_msg=f"{name} {az} {el}")
            changed += int(np.sum((ref > rad) != (plain > rad)))
    assert changed > 0


@pytest.mark.parametrize("seed", [6, 13])
def test_sky_view_factor_matches_curved_reference(seed):
    h = _random_field(seed)
    kappa = _kappa(T.DEFAULT_REFRACTION, 1.0, 20.0)
    az = np.arange(8) * 45.0
    angles = []
    for a in az:
        d = T.azimuth_direction(a)
        angles.append(horizon_reference(h, (d.dx, d.dy), kappa=kappa))
    ref = 1.0 - np.mean(np.sin(np.maximum(np.array(angles), 0.0)), axis=0)
    for name in [None] + CURVED:
        got = algos.sky_view_factor(h, azimuths=az, algorithm=name, spacing=1.0,
                                    curvature=True, earth_radius=20.0)
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12, err_msg=str(name))
    plain = algos.sky_view_factor(h, azimuths=az, spacing=1.0)
    assert np.all(got >= plain - 1e-15) and np.any(got > plain + 1e-6)  # lower horizons


def test_curvature_off_is_unchanged():
    """curvature=False (the default) gives the same bits as before, on every path."""
    h = _random_field(2)
    for name in ["sweep", "pattern", "dda", "dda_maxmip", "march"]:
        a = algos.horizon(h, 45.0, algorithm=name)
        b = algos.horizon(h, 45.0, algorithm=name, spacing=1.0, curvature=False,
                          earth_radius=20.0)
        np.testing.assert_array_equal(a, b, err_msg=name)


def test_auto_routes_curvature_away_from_the_sweep():
    h = _random_field(1)
    def ran(*args, **kwargs):
        return algos.horizon(h, *args, return_stats=True, **kwargs)[1]

    assert ran(90.0, spacing=1.0).algorithm == "sweep"
    assert ran(90.0, spacing=1.0, curvature=True).algorithm == "dda_maxmip"
    assert ran(90.0, 5.0, spacing=1.0, curvature=True).algorithm == "pattern"
    # every azimuth class: the irrational ones too, which without curvature take the
    # chain walk or the rows, neither of which lowers the surface
    assert ran([90.0, 22.5], spacing=1.0).paths == ("sweep", "chain")
    assert ran([90.0, 22.5], spacing=1.0, curvature=True).paths == ("dda_maxmip", "dda_maxmip")
    assert ran([90.0, 22.5], 5.0, spacing=1.0, curvature=True).paths == ("pattern", "pattern")
    for name in ("rows", "chain", "sweep"):
        with pytest.raises(ValueError, match=f"curvature: algorithm='{name}' does not apply"):
            algos.horizon(h, 90.0, spacing=1.0, curvature=True, algorithm=name)


def test_units_degrees():
    h = _random_field(9)
    rad = algos.horizon(h, [10.0, 250.0])
    deg = algos.horizon(h, [10.0, 250.0], units="degrees")
    np.testing.assert_array_equal(deg, np.degrees(rad))
    with pytest.raises(ValueError, match="units: expected one of"):
        algos.horizon(h, 10.0, units="deg")


def test_dataarray_records_units_and_curvature():
    xr = pytest.importorskip("xarray")
    pytest.importorskip("rioxarray")
    h = _random_field(10)
    da = xr.DataArray(h * 10.0, dims=("y", "x"),
                      coords={"y": np.arange(h.shape[0]) * -10.0, "x": np.arange(h.shape[1]) * 10.0})
    da = da.rio.write_crs("EPSG:32617")  # coordinates in metres: curvature needs the unit
    out = algos.horizon(da, [0.0, 90.0], units="degrees", curvature=True, earth_radius=2000.0)
    assert out.attrs["units"] == "degrees"
    assert out.attrs["curvature"] == 1 and out.attrs["refraction"] == pytest.approx(1 / 7)
    plain = algos.horizon(da, [0.0, 90.0])
    assert plain.attrs["units"] == "radians" and plain.attrs["curvature"] == 0
    svf = algos.sky_view_factor(da, 4, curvature=True, earth_radius=2000.0)
    assert svf.attrs["curvature"] == 1


@pytest.mark.parametrize("call, error, match", [
    (lambda h: algos.horizon(h, 0.0, curvature=True), ValueError, "curvature: needs spacing"),
    (lambda h: algos.horizon(h, 0.0, spacing=(1, 2), curvature=True), ValueError,
     "curvature: needs square pixels"),
    (lambda h: algos.horizon(h, 0.0, spacing=1, curvature=1), TypeError, "curvature: expected a bool"),
    (lambda h: algos.horizon(h, 0.0, spacing=1, curvature=True, refraction=1.0), ValueError,
     "refraction: expected a coefficient"),
    (lambda h: algos.horizon(h, 0.0, spacing=1, curvature=True, earth_radius=-1), ValueError,
     "earth_radius: expected a positive length"),
    (lambda h: algos.horizon(h, 0.0, spacing=1, curvature=True, algorithm="sweep"), ValueError,
     "curvature: algorithm='sweep'"),
    (lambda h: algos.shadows(h, 0.0, 10.0, curvature=True), ValueError, "curvature: needs spacing"),
    (lambda h: algos.sky_view_factor(h, 4, curvature=True), ValueError, "curvature: needs spacing"),
    # refraction is checked without curvature too: out of range, or ignored (as the
    # command line's --refraction without --curvature)
    (lambda h: algos.horizon(h, 0.0, refraction=5.0), ValueError,
     r"refraction: expected a coefficient in \[0, 1\), got 5.0"),
    (lambda h: algos.horizon(h, 0.0, refraction=0.2), ValueError,
     r"refraction: applies with curvature=True only \(got refraction=0.2 without it\)"),
    (lambda h: algos.viewshed(h, (1, 1), refraction=0.2), ValueError,
     "refraction: applies with curvature=True only"),
    (lambda h: algos.sky_view_factor(h, 4, refraction="x"), TypeError,
     "refraction: expected a number, got 'x'"),
    (lambda h: algos.openness(h, "positive", 4, refraction=-0.5), ValueError,
     "refraction: expected a coefficient"),
])
def test_bad_curvature_arguments(call, error, match):
    with pytest.raises(error, match=match):
        call(np.zeros((4, 5)))


def test_kernels_refuse_non_finite_kappa():
    from algos import _kernels

    h = np.zeros((3, 3))
    out = np.empty(9)
    with pytest.raises(ValueError, match="kappa"):
        _kernels.horizon_walk(h, None, 1.0, 0.0, math.inf, 0, 9, out, math.nan)
    with pytest.raises(ValueError, match="kappa"):
        _kernels.horizon_march(h, 1.0, 0.0, 1.0, math.inf, 0.0, 0, 9, out, math.inf)


def test_cli_horizon_with_curvature(tmp_path, capsys):
    """``hftrace horizon --curvature``: the issue's example through the command, in
    degrees, with the curvature recorded in the file's tags."""
    rasterio = pytest.importorskip("rasterio")
    from bench.cli import main

    h = np.zeros((3, 700), np.float32)
    h[:, 600] = 600.0
    np.save(tmp_path / "plain.npy", h)
    out = str(tmp_path / "hz")
    # a .npy names no unit: --unit m gives the metres that curvature needs
    code = main(["horizon", str(tmp_path / "plain.npy"), "--spacing", "100", "--unit", "m",
                 "--azimuths", "90", "--curvature", "--out", out, "--no-progress"])
    assert code == 0, capsys.readouterr().err
    drop = (1 - 1 / 7) * 60000.0 ** 2 / (2 * algos.WGS84_SEMI_MAJOR_AXIS_M)
    with rasterio.open(out + ".tif") as src:
        tags = src.tags()
        assert tags["units"] == "degrees" and tags["curvature"] == "True"
        assert float(tags["refraction"]) == pytest.approx(1 / 7)
        assert src.read(1)[1, 0] == pytest.approx(math.degrees(math.atan((600 - drop) / 60000)),
                                                  abs=1e-5)
    code = main(["svf", str(tmp_path / "plain.npy"), "--spacing", "100", "--unit", "m",
                 "--n-azimuths", "4",
                 "--out", str(tmp_path / "svf"), "--no-progress"])
    assert code == 0
    with rasterio.open(str(tmp_path / "svf.tif")) as src:
        assert src.tags()["curvature"] == "False" and "refraction" not in src.tags()


def test_dask_tiles_apply_curvature_as_in_memory():
    da = pytest.importorskip("dask.array")
    h = _random_field(31, shape=(24, 26))
    want_h = algos.horizon(h, [30.0, 200.0], 5.0, spacing=1.0, curvature=True,
                           earth_radius=20.0, units="degrees")
    got_h = algos.horizon(da.from_array(h, chunks=(10, 12)), [30.0, 200.0], 5.0, spacing=1.0,
                          curvature=True, earth_radius=20.0, units="degrees").compute()
    np.testing.assert_allclose(got_h, want_h, rtol=0, atol=1e-12)
    want = algos.sky_view_factor(h, 8, 5.0, spacing=1.0, curvature=True, earth_radius=20.0)
    got = algos.sky_view_factor(da.from_array(h, chunks=(10, 12)), 8, 5.0, spacing=1.0,
                                curvature=True, earth_radius=20.0).compute()
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


# ---- a hand-built field's unit (names, their metres, and no unit) ---------------------------

def _flat_angle(unit, spacing=100.0):
    field = algos.HeightField(np.zeros((64, 64)), spacing=spacing, unit=unit)
    return algos.viewshed(field, (0, 0), mode="angle", curvature=True, observer_height=0)[63, 63]


def _curved_angle(metres_per_unit, spacing=100.0):
    """The view angle from (0, 0) to (63, 63) over flat ground, in closed form: the target
    drops (1 - k) d^2 / (2 R) with R the earth's radius in the field's unit."""
    d = 63 * math.sqrt(2) * spacing
    radius = algos.WGS84_SEMI_MAJOR_AXIS_M / metres_per_unit
    return math.atan2(-(1 - T.DEFAULT_REFRACTION) * d * d / (2 * radius), d)


@pytest.mark.parametrize("unit, metres", [("m", 1.0), ("metre", 1.0), ("meter", 1.0),
                                          ("km", 1000.0), ("ft", 0.3048), ("foot", 0.3048),
                                          ("US survey foot", 1200 / 3937),
                                          ("us-ft", 1200 / 3937)])
def test_unit_names_convert_the_earth_radius(unit, metres):
    """The user's report: 'ft', 'km' and 'm' all gave the metres value."""
    field = algos.HeightField(np.zeros((4, 4)), spacing=100, unit=unit)
    assert field.unit_metres == metres and field.params["unit_metres"] == metres
    assert _flat_angle(unit) == pytest.approx(_curved_angle(metres), rel=1e-12, abs=0)


def test_feet_and_metres_give_the_reported_angles():
    assert _flat_angle("ft") == pytest.approx(-0.000182474, abs=5e-10)
    assert _flat_angle("m") == pytest.approx(-0.000598666, abs=5e-10)
    assert _flat_angle("km") == pytest.approx(math.atan(-0.000598666 * 1000), rel=1e-6)


@pytest.mark.parametrize("spacing", [30.0, 1.0])
def test_curvature_without_a_real_unit_raises(spacing):
    """'map unit' (a spacing nobody named) and cell units carry no metres."""
    field = algos.HeightField(np.zeros((8, 8)), spacing=spacing)
    assert field.unit in algos.georef.NO_UNIT and field.unit_metres is None
    for product in (lambda: algos.viewshed(field, (0, 0), curvature=True),
                    lambda: algos.horizon(field, 45.0, curvature=True)):
        with pytest.raises(ValueError, match=r"curvature: needs spacing in a real unit.*"
                                             r"unit='m'"):
            product()
    # without curvature nothing changes
    assert algos.viewshed(field, (0, 0)).all()


@pytest.mark.parametrize("unit", ["furlong", "degree", "deg", "M", ""])
def test_unknown_unit_names_raise(unit):
    with pytest.raises(ValueError, match=rf"unit: {unit!r} is not a linear unit.*'m', 'km', "
                                         r"'ft', 'US survey foot'"):
        algos.HeightField(np.zeros((4, 4)), spacing=30, unit=unit)


def test_params_unit_metres_must_agree_with_the_unit():
    with pytest.raises(ValueError, match=r"params\['unit_metres'\]: 1.0 disagrees with the "
                                         r"unit 'ft'"):
        algos.HeightField(np.zeros((4, 4)), spacing=30, unit="ft", params={"unit_metres": 1.0})
    # a unit_metres without a unit names nothing: dropped, curvature still refused
    field = algos.HeightField(np.zeros((4, 4)), spacing=30, params={"unit_metres": 0.3048})
    assert field.unit_metres is None and "unit_metres" not in field.params


def test_generated_fields_and_the_embedded_dem_keep_their_units():
    import datasets_gen

    dem = datasets_gen.jacksboro(use_cache=False)
    assert (dem.unit, dem.height_unit, dem.unit_metres) == ("m", "cell", 1.0)
    field = datasets_gen.load("fbm", size=17, seed=1, use_cache=False)
    assert field.unit == "cell" and field.unit_metres is None
