"""Viewshed modes and options: GDAL's output values (-vv/-iv/-ov) and output
modes (-om NORMAL|DEM|GROUND), xarray-spatial's minimum observable height and view angle,
observers and targets below the ground, one-row and one-column rasters.

The thresholds are checked three ways: against the rational-arithmetic bound of
``algos.terrain.reference.viewshed_threshold_exact``, by brute force with the exact line of sight
(``line_of_sight_exact``) just above and just below the threshold, and against the
visibility mode. The peers' own test cases are translated with the values this project's
surface gives (derivations beside each)."""
import math
from fractions import Fraction

import numpy as np
import pytest

import algos
import algos.terrain as T
from algos.terrain.reference import line_of_sight_exact, surface_exact, viewshed_threshold_exact

SEEDS = range(24)


def random_case(seed):
    """A seeded small terrain (integer or real heights, sometimes with voids), an
    observer (a vertex or a fractional point off every void), heights and options."""
    rng = np.random.default_rng(1000 + seed)
    rows, cols = int(rng.integers(4, 9)), int(rng.integers(4, 9))
    if seed % 3 == 0:
        h = rng.integers(0, 7, size=(rows, cols)).astype(float)
    else:
        h = np.round(rng.normal(0, 3, size=(rows, cols)), 3)
    if seed % 4 == 1:
        voids = rng.random((rows, cols)) < 0.12
        h[voids] = np.nan
    void = np.isnan(h)
    for _ in range(100):
        if seed % 2:
            ox, oy = float(rng.integers(0, cols)), float(rng.integers(0, rows))
        else:
            ox, oy = float(rng.integers(0, 4 * (cols - 1)) / 4), float(rng.integers(0, 4 * (rows - 1)) / 4)
        if not T._touches_void(void, ox, oy):
            break
    oh = float((-1.0, 0.0, 1.5, 4.0)[seed % 4])
    md = None if seed % 5 else float(rng.integers(2, 6))
    return h, (ox, oy), oh, md


def exact_inputs(h, observer, oh):
    """The kernels' heights (voids as the documented pit) as lists, and the eye, exactly."""
    hk = T._prepare(h, None).h.tolist()
    fx, fy = Fraction(observer[0]), Fraction(observer[1])
    ground = surface_exact(hk, fx, fy)
    return hk, (fx, fy), ground, ground + Fraction(oh)


def reproducer(seed, h, observer, oh, md, i, j):
    return (f"seed {seed}: observer {observer} observer_height {oh} max_distance {md} "
            f"vertex ({i}, {j})\nheights = {h.tolist()!r}")


@pytest.mark.parametrize("algorithm", sorted(T.VIEWSHED_ALGORITHMS))
@pytest.mark.parametrize("seed", SEEDS)
def test_ground_and_dem_match_exact_reference_and_brute_force(seed, algorithm):
    h, observer, oh, md = random_case(seed)
    ground = T.viewshed(h, observer, oh, max_distance=md, mode="ground", algorithm=algorithm)
    dem = T.viewshed(h, observer, oh, max_distance=md, mode="dem", algorithm=algorithm)
    normal = T.viewshed(h, observer, oh, max_distance=md, algorithm=algorithm)
    assert ground.dtype == np.float64 and ground.shape == h.shape
    hk, fo, _, z0 = exact_inputs(h, observer, oh)
    rows, cols = h.shape
    for j in range(rows):
        for i in range(cols):
            why = reproducer(seed, h, observer, oh, md, i, j)
            if np.isnan(h[j, i]):
                assert np.isnan(ground[j, i]) and np.isnan(dem[j, i]), why
                continue
            if md is not None and (i - observer[0]) ** 2 + (j - observer[1]) ** 2 > md * md:
                assert np.isnan(ground[j, i]) and np.isnan(dem[j, i]), why
                assert not normal[j, i], why
                continue
            m = viewshed_threshold_exact(hk, fo, z0, (i, j), hk[j][i], "target")
            want = 0.0 if m is None else max(0.0, float(z0 + m - Fraction(hk[j][i])))
            scale = 1e-9 * (1 + abs(float(z0)) + abs(hk[j][i]) + abs(want))
            assert abs(ground[j, i] - want) <= scale, f"{why}\ngot {ground[j, i]!r} want {want!r}"
            assert abs(dem[j, i] - (h[j, i] + want)) <= scale, why
            # brute force: the exact line of sight just above the threshold sees the
            # vertex, and just below (when there is room) does not
            top = Fraction(hk[j][i])
            above = top + Fraction(want) + Fraction(scale) * 2
            assert line_of_sight_exact(hk, fo, z0, (i, j), above), why
            if want > 1e-6:
                assert not line_of_sight_exact(hk, fo, z0, (i, j), top + Fraction(want) - Fraction(1e-6)), why
            # visibility at target height 0 is exactly "the threshold is 0"
            if want > scale or want == 0.0:
                assert normal[j, i] == (want == 0.0), why


@pytest.mark.parametrize("algorithm", sorted(T.VIEWSHED_ALGORITHMS))
@pytest.mark.parametrize("seed", SEEDS)
def test_observer_mode_matches_exact_reference_and_brute_force(seed, algorithm):
    h, observer, _, md = random_case(seed)
    th = (0.0, 0.5, 2.0)[seed % 3]
    got = T.viewshed(h, observer, target_height=th, max_distance=md, mode="observer",
                     algorithm=algorithm)
    hk, fo, ground, _ = exact_inputs(h, observer, 0.0)
    rows, cols = h.shape
    for j in range(rows):
        for i in range(cols):
            why = reproducer(seed, h, observer, None, md, i, j)
            out = md is not None and (i - observer[0]) ** 2 + (j - observer[1]) ** 2 > md * md
            if np.isnan(h[j, i]) or out:
                assert np.isnan(got[j, i]), why
                continue
            top = Fraction(hk[j][i]) + Fraction(th)
            n = viewshed_threshold_exact(hk, fo, ground, (i, j), top, "observer")
            want = 0.0 if n is None else max(0.0, float(n - ground))
            scale = 1e-9 * (1 + abs(float(ground)) + abs(hk[j][i]) + abs(want))
            assert abs(got[j, i] - want) <= scale, f"{why}\ngot {got[j, i]!r} want {want!r}"
            eye = ground + Fraction(want) + Fraction(scale) * 2
            assert line_of_sight_exact(hk, fo, eye, (i, j), top), why
            if want > 1e-6:
                assert not line_of_sight_exact(hk, fo, ground + Fraction(want) - Fraction(1e-6),
                                               (i, j), top), why


def test_thresholds_with_curvature_match_exact_reference():
    rng = np.random.default_rng(77)
    h = rng.integers(0, 5, size=(7, 9)).astype(float)
    radius = 30.0
    drop = (1 - 1 / 7) / (2 * radius)
    observer, oh = (4, 3), 1.0
    ground = T.viewshed(h, observer, oh, curvature=True, spacing=1.0, earth_radius=radius,
                        mode="ground")
    obs_mode = T.viewshed(h, observer, curvature=True, spacing=1.0, earth_radius=radius,
                          mode="observer")
    hk, fo, g, z0 = exact_inputs(h, observer, oh)
    for j in range(7):
        for i in range(9):
            d2 = Fraction((i - observer[0]) ** 2 + (j - observer[1]) ** 2)
            m = viewshed_threshold_exact(hk, fo, z0, (i, j), hk[j][i], "target", drop)
            sunk = Fraction(hk[j][i]) - Fraction(drop) * d2
            want = 0.0 if m is None else max(0.0, float(z0 + m - sunk))
            assert abs(ground[j, i] - want) <= 1e-9, (i, j)
            n = viewshed_threshold_exact(hk, fo, g, (i, j), hk[j][i], "observer", drop)
            want = 0.0 if n is None else max(0.0, float(n - g))
            assert abs(obs_mode[j, i] - want) <= 1e-9, (i, j)
    assert ground.sum() > T.viewshed(h, observer, oh, mode="ground").sum()  # the bulge hides


def test_plain_and_mipmap_thresholds_agree_on_a_larger_field():
    rng = np.random.default_rng(8)
    h = np.cumsum(np.cumsum(rng.normal(size=(70, 90)), axis=0), axis=1) * 0.1
    for mode in ("ground", "observer"):
        oh = 2.0 if mode == "ground" else None  # mode observer computes the eye's height
        plain = T.viewshed(h, (30.5, 41.25), oh, mode=mode, algorithm="dda")
        mip, stats = T.viewshed(h, (30.5, 41.25), oh, mode=mode, algorithm="dda_maxmip",
                                return_stats=True)
        assert stats.skips > 0
        np.testing.assert_allclose(mip, plain, rtol=1e-12, atol=1e-9, err_msg=mode)
        one = T.viewshed(h, (30.5, 41.25), oh, mode=mode, threads=1)
        two = T.viewshed(h, (30.5, 41.25), oh, mode=mode, threads=2)
        assert np.array_equal(one, two), mode


def test_angle_mode_is_the_elevation_angle_in_map_units():
    rng = np.random.default_rng(4)
    h = rng.normal(size=(6, 7)) * 20
    spacing = (10.0, 25.0)
    observer, oh, th = (2.25, 3.5), 3.0, 1.0
    got = T.viewshed(h, observer, oh, th, spacing=spacing, mode="angle")
    z0 = T._surface_float(h, *observer) + oh  # heights are in the map unit here
    for j in range(6):
        for i in range(7):
            d = math.hypot((i - observer[0]) * spacing[0], (j - observer[1]) * spacing[1])
            assert got[j, i] == pytest.approx(math.atan2(h[j, i] + th - z0, d), abs=1e-13)
    # under the eye: straight down, up or level
    assert T.viewshed(np.zeros((3, 3)), (1, 1), 2.0, mode="angle")[1, 1] == -math.pi / 2
    assert T.viewshed(np.zeros((3, 3)), (1, 1), 0.0, mode="angle")[1, 1] == 0.0


# ---- output values (GDAL's -vv, -iv, -ov) -------------------------------------------------

def test_output_values_and_dtype_rule():
    h = np.zeros((9, 9))
    h[4, 6] = 9.0  # a wall east of the observer
    seen = T.viewshed(h, (4, 4), 1.0, max_distance=3.0)
    within = np.hypot(*np.mgrid[0:9, 0:9] - 4.0) <= 3.0
    hidden = within & ~seen
    assert hidden.any()
    small = T.viewshed(h, (4, 4), 1.0, max_distance=3.0, visible_value=200, invisible_value=7,
                       out_of_range_value=3)
    assert small.dtype == np.uint8
    np.testing.assert_array_equal(small, np.where(within, np.where(seen, 200, 7), 3))
    # defaults for the values not given: 1 visible, 0 invisible, 0 out of range
    ov = T.viewshed(h, (4, 4), 1.0, max_distance=3.0, out_of_range_value=2)
    np.testing.assert_array_equal(ov, np.where(within, seen.astype(int), 2))
    # 255 (the uint8 nodata), negative or fractional values give float64
    gdal = T.viewshed(h, (4, 4), 1.0, max_distance=3.0, visible_value=255, invisible_value=-1,
                      out_of_range_value=0.5)
    assert gdal.dtype == np.float64
    np.testing.assert_array_equal(gdal, np.where(within, np.where(seen, 255.0, -1.0), 0.5))
    # float modes: out of range NaN by default, else the value given
    g = T.viewshed(h, (4, 4), 1.0, max_distance=3.0, mode="ground", out_of_range_value=-9)
    assert np.all(g[~within] == -9) and np.all(g[within] >= 0)
    assert np.all(g[hidden] > 0) and np.all(g[within & seen] == 0)


def test_voids_stay_nodata_in_every_output():
    h = np.arange(36, dtype=float).reshape(6, 6) % 5
    h[1, 4] = np.nan
    u8 = T.viewshed(h, (2, 3), 1.0, visible_value=2, invisible_value=1)
    assert u8.dtype == np.uint8 and u8[1, 4] == T.VIEWSHED_UINT8_NODATA
    assert np.isnan(T.viewshed(h, (2, 3), 1.0, visible_value=-1)[1, 4])
    for mode in ("ground", "dem", "observer", "angle"):
        out = T.viewshed(h, (2, 3), 1.0 if mode != "observer" else None, mode=mode)
        assert np.isnan(out[1, 4]) and np.isfinite(np.delete(out.ravel(), 10)).all(), mode


@pytest.mark.parametrize("kwargs, match", [
    (dict(mode="cumulative"), "mode: expected one of"),
    (dict(mode="ground", visible_value=1), "visible_value: applies to mode='normal'"),
    (dict(mode="angle", invisible_value=1), "invisible_value: applies to mode='normal'"),
    (dict(mode="ground", target_height=1.0), "target_height: mode='ground' computes"),
    (dict(mode="dem", target_height=1.0), "target_height: mode='dem' computes"),
    (dict(visible_value=np.inf), "visible_value: expected a finite number"),
    (dict(visible_value="255"), "visible_value: expected a number"),
    (dict(out_of_range_value=np.nan), "out_of_range_value: expected a finite number"),
    (dict(observer_height=np.nan), "observer_height: expected a finite length"),
    (dict(target_height=-np.inf), "target_height: expected a finite length"),
])
def test_bad_options_raise_naming_the_argument(kwargs, match):
    with pytest.raises((ValueError, TypeError), match=match):
        T.viewshed(np.zeros((4, 4)), (1, 1), **kwargs)


def test_several_observers_refuse_modes_and_values():
    with pytest.raises(ValueError, match=r"observer: mode='ground' needs one observer, got 2"):
        T.viewshed(np.zeros((4, 4)), [[0, 0], [1, 1]], mode="ground")
    with pytest.raises(ValueError, match="observer: mode='normal' and output values"):
        T.viewshed(np.zeros((4, 4)), [[0, 0], [1, 1]], visible_value=3)


def test_dask_refuses_modes_and_values():
    da = pytest.importorskip("dask.array")
    h = da.zeros((8, 8), chunks=4)
    with pytest.raises(ValueError, match="mode: the tiled .dask. viewshed gives visibility only"):
        T.viewshed(h, (3, 3), max_distance=3.0, mode="ground")
    with pytest.raises(ValueError, match="with output values"):
        T.viewshed(h, (3, 3), max_distance=3.0, out_of_range_value=2)
    lazy = T.viewshed(h, (3, 3), max_distance=3.0)  # visibility still tiles
    np.testing.assert_array_equal(lazy.compute(), T.viewshed(np.zeros((8, 8)), (3, 3),
                                                             max_distance=3.0))


def test_dataarray_records_mode_unit_and_values():
    xr = pytest.importorskip("xarray")
    rng = np.random.default_rng(42)
    data = rng.uniform(0, 10, (6, 8))
    xs, ys = np.linspace(0, 7, 8), np.linspace(0, 5, 6)
    r = xr.DataArray(data, coords=dict(x=xs, y=ys), dims=["y", "x"])
    out = T.viewshed(r, (3.0, 2.0), mode="observer")
    assert out.shape == r.shape and out.dims == r.dims
    np.testing.assert_array_equal(out.coords["x"].values, xs)
    np.testing.assert_array_equal(out.coords["y"].values, ys)
    assert out.attrs["mode"] == "observer" and out.attrs["units"] == "cell"
    vals = T.viewshed(r, (3.0, 2.0), 1.0, max_distance=2.0, out_of_range_value=9)
    assert vals.attrs["out_of_range_value"] == 9 and vals.dtype == np.uint8


# ---- xarray-spatial's viewshed cases ------------------------------------------------------

@pytest.mark.parametrize("observer_height", [-1, 0, 1])
@pytest.mark.parametrize("elev_at_vp", [-1, 0, 1])
def test_xarray_spatial_observer_on_a_bump_or_pit(observer_height, elev_at_vp):
    """xrspatial/tests/test_viewshed.py::test_viewshed: a flat 5x5 raster but for the
    observer's own vertex (-1, 0 or 1), the observer on it at -1, 0 or 1 above the ground:
    225 cases, 75 with the eye below the surface. Their assertions: the observer's vertex
    is visible; everything is visible when observer_height + elev >= 0 and
    observer_height >= |elev|; visibility is symmetric about both diagonals through the
    observer. The right value here: beyond the observer's own triangles the surface is
    flat at 0, so with the eye at z0 = elev + observer_height >= 0 everything is visible,
    and with z0 < 0 exactly the vertices with no breakpoint strictly between (six
    neighbours) and the observer's own."""
    n = 5
    for col in range(n):
        for row in range(n):
            h = np.zeros((n, n))
            h[row, col] = elev_at_vp
            v = T.viewshed(h, (col, row), observer_height)
            why = f"observer ({col}, {row}) height {observer_height} on {elev_at_vp}"
            assert v[row, col], why
            if observer_height + elev_at_vp >= 0 and observer_height >= abs(elev_at_vp):
                assert v.all(), why
            for (r, c) in np.argwhere(np.ones((n, n))):  # mirror images about both diagonals
                for rr, cc in ((row + (c - col), col + (r - row)), (row - (c - col), col - (r - row))):
                    if 0 <= rr < n and 0 <= cc < n:
                        assert v[r, c] == v[rr, cc], f"{why}: ({c}, {r}) and ({cc}, {rr})"
            jj, ii = np.mgrid[0:n, 0:n]
            # no breakpoint strictly between: the observer, its four neighbours along the
            # edges and the two along the cells' split diagonal u = v (the other diagonal
            # neighbours lie across that diagonal, at t = 1/2)
            di, dj = ii - col, jj - row
            near = (abs(di) + abs(dj) <= 1) | ((di == dj) & (abs(di) == 1))
            want = np.ones((n, n), bool) if elev_at_vp + observer_height >= 0 else near
            np.testing.assert_array_equal(v, want, err_msg=why)


@pytest.mark.parametrize("observer_height", [5, 2])
@pytest.mark.parametrize("target_height", [0, 1])
def test_xarray_spatial_flat_angles(observer_height, target_height):
    """xrspatial test_viewshed_flat (numpy backend): a flat 5x4 raster at 1.3 with pixels
    0.5 wide and 1.5 tall, the observer at the corner: everything is visible, at the angle
    from straight down degrees(atan2(d, observer - target)), which is 90 + degrees(angle)."""
    h = np.full((5, 4), 1.3)
    spacing = (0.5, 1.5)
    seen = T.viewshed(h, (0, 0), observer_height, target_height, spacing=spacing)
    angle = T.viewshed(h, (0, 0), observer_height, target_height, spacing=spacing, mode="angle")
    assert seen.all()
    ys, xs = np.mgrid[0:5, 0:4]
    d = np.hypot(xs * 0.5, ys * 1.5)
    theirs = np.degrees(np.arctan2(d, observer_height - target_height))
    np.testing.assert_allclose(90 + np.degrees(angle), theirs, atol=1e-12)


@pytest.mark.parametrize("shape", [(1, 5), (5, 1)])
def test_xarray_spatial_single_row_or_column(shape):
    """xrspatial test_viewshed_single_row_or_column: flat, the observer 5 up at the
    middle: every vertex is visible; the ground needed is 0 and the angles are those of
    the flat line."""
    rows, cols = shape
    h = np.zeros(shape)
    observer = (cols // 2, rows // 2)
    v = T.viewshed(h, observer, 5)
    assert v.shape == shape and v.dtype == bool and v.all()
    assert np.all(T.viewshed(h, observer, 5, mode="ground") == 0)
    d = np.abs(np.arange(max(shape)) - max(shape) // 2).reshape(shape)
    np.testing.assert_allclose(T.viewshed(h, observer, 5, mode="angle"), np.arctan2(-5, d))


@pytest.mark.parametrize("shape", [(1, 7), (7, 1)])
def test_xarray_spatial_single_row_or_column_max_distance(shape):
    """xrspatial test_viewshed_single_row_or_column_max_distance: max_distance 2, the
    vertex two steps along the line is visible, three steps is out of range."""
    rows, cols = shape
    observer = (cols // 2, rows // 2)
    v = T.viewshed(np.zeros(shape), observer, 5, max_distance=2.0, out_of_range_value=2)
    line = v.ravel()
    np.testing.assert_array_equal(line, [2, 1, 1, 1, 1, 1, 2])


def test_one_row_line_of_sight_is_the_profile():
    """A one-row raster's surface is the polyline through its samples: a bump hides what
    lies behind it, and the ground needed there is exact (the tangent over the bump)."""
    h = np.array([[0.0, 0.0, 3.0, 0.0, 0.0]])
    assert T.viewshed(h, (0, 0), 1.0).tolist() == [[True, True, True, False, False]]
    # eye at 1; over the bump at x = 2 (height 3): slope 1 per column, so x = 3 needs
    # 1 + 3 * 1 = 4 and x = 4 needs 1 + 4 * 1 = 5
    np.testing.assert_allclose(T.viewshed(h, (0, 0), 1.0, mode="ground"),
                               [[0, 0, 0, 4, 5]], atol=1e-12)
    np.testing.assert_array_equal(T.viewshed(h.T, (0, 0), 1.0), [[True]] * 3 + [[False]] * 2)
    with pytest.raises(ValueError, match=r"observer\[0\]: \(1.0, 0.5\) outside .* one-row"):
        T.viewshed(h, (1, 0.5))


def test_xarray_spatial_negative_observer_and_target_heights_are_accepted():
    """xrspatial test_viewshed_valid_elev_still_works: -5, 0 and 2.5 as both observer and
    target heights give a result of the raster's shape. Here the first (last) linear piece
    of the ray, the observer's (target's) own triangle, does not block, so on their raster
    the neighbours along an edge stay visible."""
    arr = np.array([[0, 0, 1, 0, 0], [1, 3, 0, 0, 0], [10, 2, 5, 2, -1], [11, 1, 2, 9, 0]],
                   dtype=float)
    for good in (-5.0, 0.0, 2.5):
        v = T.viewshed(arr, (2, 1), good, good)
        assert v.shape == arr.shape and v[1, 2]
        assert v[1, 1] and v[1, 3] and v[0, 2] and v[2, 2]  # no breakpoint in between
    below = T.viewshed(arr, (2, 1), -5.0, -5.0)
    assert not below[3, 0]  # far vertices are hidden from an eye 5 under the ground


# ---- xarray-spatial's minimum observable height, exactly ----------------------------------

def test_min_observable_height_flat_terrain_is_zero():
    """min_observable_height test_flat_terrain_all_visible_at_zero."""
    assert np.all(T.viewshed(np.full((5, 5), 10.0), (2, 2), mode="observer") == 0.0)


def test_min_observable_height_wall():
    """test_wall_requires_height: a wall 10 high at (x=2, y=1), the observer at (0, 1).
    Their comment derives h >= 30 for (3, 1): the sight line from (0, h) to (3, 0) must
    clear (2, 10), and h / 3 >= 10. That is the exact value here, where bisection gave a
    step of their height grid. The wall's own vertex needs 0, the observer's 0."""
    h = np.zeros((3, 5))
    h[1, 2] = 10.0
    got = T.viewshed(h, (0, 1), mode="observer")
    assert got[1, 0] == 0.0 and got[1, 1] == 0.0
    assert got[1, 3] == pytest.approx(30.0, abs=1e-12)
    assert got[1, 2] == 0.0 < got[1, 3]
    # precision: their search on linspace(0, max_height, n) heights returns the first
    # grid height that sees the vertex, never below the exact value (test_finer_precision)
    for max_height, precision in ((20.0, 5.0), (20.0, 0.5), (50.0, 1.0)):
        grid = np.linspace(0.0, max_height, max(2, math.ceil(math.log2(max_height / precision)) + 1))
        sees = [T.viewshed(h, (0, 1), float(g))[1, 3] for g in grid]
        assert all(g >= got[1, 3] for g, s in zip(grid, sees) if s)
        assert all(not s for g, s in zip(grid, sees) if g < got[1, 3])


def test_min_observable_height_peak():
    """test_tall_peak_blocks_cells_behind: a peak 8 high at (2, 1), the observer at (0, 1):
    (4, 1) needs 16 (the line from (0, h) to (4, 0) clears (2, 8) when h / 2 >= 8), (1, 1)
    needs 0."""
    h = np.zeros((3, 5))
    h[1, 2] = 8.0
    got = T.viewshed(h, (0, 1), mode="observer")
    assert got[1, 1] == 0.0
    assert got[1, 4] == pytest.approx(16.0, abs=1e-12)


def test_min_observable_height_unreachable():
    """test_unreachable_cells_are_nan: a 1000-high vertex at (1, 1), the observer at
    (0, 1); their far corner (2, 0) is NaN at max_height 5. Here it needs exactly 1000:
    the segment to (2, 0) crosses the diagonal of cell (0, 0) at t = 1/3, where the surface
    is 2000/3, and the edge x = 1 at t = 1/2, where it is 500; both give (s - 0 t) / (1 - t)
    = 1000."""
    h = np.zeros((3, 3))
    h[1, 1] = 1000.0
    got = T.viewshed(h, (0, 1), mode="observer")
    assert got[0, 2] == pytest.approx(1000.0, rel=1e-13) and got[0, 2] > 5.0


def test_min_observable_height_monotonicity():
    """test_monotonicity: an 8-high vertex at (3, 2), the observer at (0, 2); (4, 2) needs
    8 / (1 - 3/4) = 32. Visible from 32 (touching) and above, hidden below."""
    h = np.zeros((5, 5))
    h[2, 3] = 8.0
    need = T.viewshed(h, (0, 2), mode="observer")[2, 4]
    assert need == pytest.approx(32.0, abs=1e-12)
    assert T.viewshed(h, (0, 2), 32.0)[2, 4]
    assert T.viewshed(h, (0, 2), 33.0)[2, 4]
    assert not T.viewshed(h, (0, 2), 31.999)[2, 4]


# ---- the command line ----------------------------------------------------------------------

def _small_tif(tmp_path):
    rasterio = pytest.importorskip("rasterio")
    from affine import Affine

    rng = np.random.default_rng(12)
    h = (np.cumsum(rng.normal(size=(16, 20)), axis=1) * 5).astype(np.float32)
    h[3, 15] = -9999.0  # a void
    path = str(tmp_path / "dem.tif")
    with rasterio.open(path, "w", driver="GTiff", height=16, width=20, count=1,
                       dtype="float32", crs="EPSG:32615", nodata=-9999.0,
                       transform=Affine(30.0, 0, 600000.0, 0, -30.0, 3650000.0)) as dst:
        dst.write(h, 1)
    return rasterio, path


def _run(args, capsys):
    from bench.cli import main

    code = main(args)
    return code, capsys.readouterr()


def test_cli_modes_and_values_end_to_end(tmp_path, capsys):
    """hftrace viewshed --mode/-om and --visible-value/-vv etc. on a small GeoTIFF: the files
    equal the API on the same field, and record mode, unit and values as tags."""
    import datasets_gen

    rasterio, path = _small_tif(tmp_path)
    field = datasets_gen.load_file(path)
    common = [path, "--observer-pixel", "6,8", "--max-distance", "240", "--no-progress"]
    # GDAL's own spelling of the options
    code, cap = _run(["viewshed", *common, "-vv", "200", "-iv", "7", "-ov", "3",
                      "--out", str(tmp_path / "vals")], capsys)
    assert code == 0, cap.err
    want = algos_viewshed(field, 1.75, max_distance=240.0, visible_value=200, invisible_value=7,
                          out_of_range_value=3)
    assert want.dtype == np.uint8 and set(np.unique(want)) == {3, 7, 200, 255}
    with rasterio.open(tmp_path / "vals.tif") as src:
        assert src.dtypes[0] == "uint8" and src.nodata == 255
        tags = src.tags()
        assert tags["mode"] == "normal" and tags["visible_value"] == "200.0"
        assert tags["invisible_value"] == "7.0" and tags["out_of_range_value"] == "3.0"
        np.testing.assert_array_equal(src.read(1), want)
    for mode, unit in (("ground", None), ("dem", None), ("observer", None), ("angle", "degrees")):
        out = tmp_path / f"vs_{mode}"
        code, cap = _run(["viewshed", *common, "--mode", mode, "--out", str(out)], capsys)
        assert code == 0, cap.err
        want = algos_viewshed(field, None if mode == "observer" else 1.75, max_distance=240.0,
                              mode=mode)
        if mode == "angle":
            want = np.degrees(want)
        with rasterio.open(f"{out}.tif") as src:
            tags = src.tags()
            assert tags["mode"] == mode
            assert tags["units"] == (unit or field.unit), tags
            got = src.read(1, masked=True)
        assert got.mask[3, 15] and np.isnan(want[3, 15])
        np.testing.assert_allclose(got.filled(np.nan), want.astype(np.float32), rtol=1e-6,
                                   atol=1e-4, equal_nan=True, err_msg=mode)
    assert np.isfinite(want).sum() < want.size - 1  # out of range is nodata by default


def algos_viewshed(field, observer_height, **kwargs):
    import algos

    return algos.viewshed(field, (6.0, 8.0), observer_height, **kwargs)


@pytest.mark.parametrize("args, match", [
    (["--mode", "ground", "--visible-value", "1"], "--visible-value: applies to --mode normal"),
    (["--mode", "observer", "--observer-height", "2"], "--observer-height: --mode observer"),
    (["--mode", "ground", "--observer-pixel", "2,2"], "--observer: --mode ground needs one"),
    (["-om", "dem", "--dask", "local:1", "--max-distance", "60"], "--mode: --dask gives"),
])
def test_cli_refuses_contradicting_options(tmp_path, capsys, args, match):
    _, path = _small_tif(tmp_path)
    code, cap = _run(["viewshed", path, "--observer-pixel", "6,8", "--no-progress",
                      "--out", str(tmp_path / "x"), *args], capsys)
    assert code == 2 and match in cap.err, cap.err


def test_one_row_dataarray_is_refused_with_the_way_out():
    xr = pytest.importorskip("xarray")
    r = xr.DataArray(np.zeros((1, 5)), coords=dict(x=np.arange(5.0), y=[0.0]), dims=["y", "x"])
    with pytest.raises(ValueError, match="one-row or one-column DataArray .* spacing"):
        T.viewshed(r, (2, 0), 5)
    assert T.viewshed(np.asarray(r), (2, 0), 5, spacing=(1.0, 1.0)).all()


# ---- exact thresholds: the normal mode sees a vertex exactly from its threshold up ----------

def round_trip_case(seed):
    """A seeded field (float32 or float64, spacing 1, 30 or 0.5, sometimes voids), an
    observer off the voids, an observer height (negative too) and a max_distance."""
    rng = np.random.default_rng(5000 + seed)
    rows, cols = 9, 10
    h = rng.random((rows, cols)) * 50
    if seed % 3 == 1:
        h[rng.random((rows, cols)) < 0.1] = np.nan
    h = h.astype(np.float32 if seed % 2 else np.float64)
    for _ in range(100):
        ox, oy = float(rng.integers(0, 4 * (cols - 1)) / 4), float(rng.integers(0, 4 * (rows - 1)) / 4)
        if not T._touches_void(np.isnan(h), ox, oy):
            break
    spacing = (1.0, 30.0, 0.5)[seed % 3]
    oh = (1.5, -0.7, 0.0, 6.0)[seed % 4]
    md = None if seed % 4 == 3 else spacing * float(rng.integers(4, 9))
    return algos.HeightField(h, spacing=spacing, unit="m"), (ox, oy), oh, md


@pytest.mark.parametrize("mode", ["ground", "dem", "observer"])
@pytest.mark.parametrize("seed", range(6))
def test_exact_thresholds_round_trip_through_the_normal_mode(seed, mode):
    field, observer, oh, md = round_trip_case(seed)
    th = 0.8 if mode == "observer" else 0.0
    heights = np.asarray(field.heights, dtype=np.float64)
    kw = dict(max_distance=md)
    if mode == "observer":
        got = T.viewshed(field, observer, target_height=th, mode=mode, exact=True, **kw)
        rough = T.viewshed(field, observer, target_height=th, mode=mode, **kw)
    else:
        got = T.viewshed(field, observer, oh, mode=mode, exact=True, **kw)
        rough = T.viewshed(field, observer, oh, mode=mode, **kw)
    # the rounding moves the float walk's value by a few ulps only
    np.testing.assert_allclose(got, rough, rtol=1e-9, atol=1e-9)
    ground = got
    if mode == "dem":
        ground = T.viewshed(field, observer, oh, mode="ground", exact=True, **kw)
        np.testing.assert_array_equal(np.isnan(got), np.isnan(ground))
        ok = ~np.isnan(got)
        np.testing.assert_allclose(got[ok], heights[ok] + ground[ok], rtol=1e-15, atol=1e-12)
    checked = blocked = 0
    rows, cols = heights.shape
    for j in range(rows):
        for i in range(cols):
            g = ground[j, i]
            if np.isnan(g):
                continue
            assert g >= 0
            below = np.nextafter(g, -np.inf)
            if mode == "observer":
                def sees(x):
                    return T.viewshed(field, observer, x, th, **kw)[j, i]
            else:
                def sees(x):
                    return T.viewshed(field, observer, oh, x, **kw)[j, i]
            why = f"seed {seed} mode {mode} vertex ({i}, {j}) threshold {g!r}"
            assert sees(g), why
            if g > 0:
                blocked += 1
                assert not sees(below), why
            checked += 1
    assert checked > 20 and blocked > 5, (checked, blocked)


def test_exact_thresholds_fix_the_reported_wall():
    h = np.zeros((3, 64))
    h[:, 30] = 30
    f = algos.HeightField(h, spacing=30, unit="m")
    g = T.viewshed(f, (10, 1), mode="ground", observer_height=1.5, exact=True)[1, 50]
    assert abs(g - 58.5) < 1e-9
    assert T.viewshed(f, (10, 1), observer_height=1.5, target_height=g)[1, 50]
    assert not T.viewshed(f, (10, 1), observer_height=1.5,
                          target_height=np.nextafter(g, 0))[1, 50]
    with pytest.raises(TypeError, match="exact: expected a bool"):
        T.viewshed(f, (10, 1), mode="ground", exact=1)


def test_observer_mode_refuses_an_observer_height():
    with pytest.raises(ValueError, match=r"observer_height: mode='observer' computes .* got 5"):
        T.viewshed(np.zeros((4, 4)), (1, 1), 5, mode="observer")


def test_uint8_dataarray_carries_nodata_255_and_writes_it(tmp_path):
    rioxarray = pytest.importorskip("rioxarray")
    _, path = _small_tif(tmp_path)
    x = rioxarray.open_rasterio(path, masked=True).squeeze("band", drop=True)
    v = T.viewshed(x, (6, 8), visible_value=2, invisible_value=1, out_of_range_value=0,
                   max_distance=240)
    assert v.dtype == np.uint8 and v.rio.nodata == T.VIEWSHED_UINT8_NODATA
    assert v.values[3, 15] == 255 and (v.values == 255).sum() == 1
    assert set(np.unique(v.values)) <= {0, 1, 2, 255}
    out = str(tmp_path / "vs.tif")
    v.rio.to_raster(out)
    back = rioxarray.open_rasterio(out, masked=True).squeeze("band", drop=True)
    assert np.isnan(back.values[3, 15]) and np.isfinite(back.values).sum() == back.size - 1
    raw = rioxarray.open_rasterio(out).squeeze("band", drop=True)
    assert raw.rio.nodata == 255
    np.testing.assert_array_equal(raw.values, v.values)
    # a float output keeps NaN voids; the bool map has no nodata (False there)
    f = T.viewshed(x, (6, 8), visible_value=0.5, max_distance=240)
    assert f.dtype == np.float64 and np.isnan(f.rio.nodata)
    assert T.viewshed(x, (6, 8), max_distance=240).rio.nodata is None


def test_uint8_dataarray_without_crs_has_a_fill_value():
    xr = pytest.importorskip("xarray")
    r = xr.DataArray(np.zeros((6, 8)), coords=dict(x=np.arange(8.0), y=np.arange(6.0)),
                     dims=["y", "x"])
    v = T.viewshed(r, (3.0, 2.0), 1.0, visible_value=3)
    assert v.dtype == np.uint8
    fill = v.rio.nodata if hasattr(v, "rio") else v.attrs["_FillValue"]
    assert fill == T.VIEWSHED_UINT8_NODATA


def test_cli_refuses_a_non_finite_observer_height(tmp_path, capsys):
    _, path = _small_tif(tmp_path)
    for value in ("nan", "inf"):
        code, cap = _run(["viewshed", path, "--observer-pixel", "6,8", "--no-progress",
                          "--observer-height", value, "--out", str(tmp_path / "x")], capsys)
        assert code == 2, cap.err
        assert f"--observer-height: the observer height is not finite, got {value}" in cap.err
