"""Terrain products a GIS user can trust: each row of the GIS round's table of failures, a
GeoTIFF round trip, rectangular pixels against a brute-force reference, voids, observers
in map coordinates, xarray in and out, pictures, and a peer on a projected DEM.

Every GeoTIFF is made here with rasterio."""
import math
import warnings

import numpy as np
import pytest

import algos
import datasets_gen
from algos import HeightField
from algos.field import is_dask
from datasets_gen import fields, raster

rasterio = pytest.importorskip("rasterio")
from affine import Affine  # noqa: E402  (rasterio's dependency)

UTM17 = "EPSG:32617"


def write_tif(path, data, *, crs=UTM17, transform=None, nodata=None, dtype=None, **options):
    data = np.asarray(data)
    rows, cols = data.shape
    transform = transform or Affine(30.0, 0.0, 500000.0, 0.0, -30.0, 4000000.0)
    with rasterio.open(path, "w", driver="GTiff", height=rows, width=cols, count=1,
                       dtype=dtype or data.dtype.name, crs=crs, transform=transform,
                       nodata=nodata, **options) as dst:
        dst.write(data.astype(dtype or data.dtype), 1)
    return path


def deg(x):
    return float(np.degrees(x))


# ---- the GIS round's table ----------------------------------------------------------------

def test_metres_with_spacing_give_45_degrees():
    H = np.zeros((5, 5))
    H[:, 3:] = 30
    assert deg(algos.horizon(H, [90], spacing=30)[0, 2, 2]) == pytest.approx(45.0, abs=1e-12)
    # cell units are spacing 1: the same array is a 30-cell cliff one cell away
    assert deg(algos.horizon(H, [90])[0, 2, 2]) == pytest.approx(math.degrees(math.atan(30)))


def test_geographic_raster_is_refused_with_the_fix_or_reprojected(tmp_path):
    """EPSG:4326, 3" pixels, a 92.6 m cliff running north-south at 46 N: looking east from
    its foot, the rise is 92.6 m over one pixel of 64.4 m, atan(92.6 / 64.4) = 55.2 deg."""
    lat = 46.0
    dem = np.zeros((40, 40), np.float32)
    dem[:, 20:] = 92.6
    path = write_tif(tmp_path / "geo.tif", dem, crs="EPSG:4326",
                     transform=Affine(1 / 1200, 0, -84.0, 0, -1 / 1200, lat + 20 / 1200))
    with pytest.raises(ValueError, match=r"geo.tif: its CRS \(EPSG:4326\) is geographic.*"
                                         r"gdalwarp -t_srs EPSG:32617 -tr 64\.\d+ 92\.\d+"):
        datasets_gen.load_file(path)
    field = datasets_gen.load_file(path, reproject="utm")
    assert field.crs.to_epsg() == 32617 and field.unit == "m"
    assert field.dx == pytest.approx(64.37, abs=0.01) and field.dy == pytest.approx(92.66, abs=0.01)
    east = np.degrees(algos.horizon(field, [90])[0])
    right = math.degrees(math.atan(92.6 / field.dx))
    assert right == pytest.approx(55.2, abs=0.05)
    # bilinear resampling onto the UTM grid smears the cliff by part of a pixel
    assert np.nanmax(east[5:-5, 5:-5]) == pytest.approx(right, abs=1.0)


def test_south_up_raster_keeps_north(tmp_path):
    north_up = np.zeros((6, 7), np.float32)
    north_up[:2] = 30  # a wall along the northern edge
    path = write_tif(tmp_path / "south.tif", north_up[::-1],
                     transform=Affine(30.0, 0, 500000.0, 0, 30.0, 4000000.0))
    field = datasets_gen.load_file(path)
    assert field.north == "+y" and field.spacing == 30.0
    stored_row = 5 - 2  # north-up row 2, stored from the south
    assert deg(algos.horizon(field, [0])[0, stored_row, 3]) == pytest.approx(45.0, abs=1e-12)
    assert deg(algos.horizon(field, [180])[0, stored_row, 3]) <= 0.0
    # the result is on the input's grid: the same as the north-up file's, flipped
    up = datasets_gen.load_file(write_tif(tmp_path / "north.tif", north_up))
    np.testing.assert_array_equal(algos.horizon(field, [0, 90, 200])[:, ::-1],
                                  algos.horizon(up, [0, 90, 200]))


def test_rotated_geotransform_is_refused(tmp_path):
    path = write_tif(tmp_path / "rot.tif", np.zeros((6, 7), np.float32),
                     transform=Affine(30.0, 5.0, 500000.0, 5.0, -30.0, 4000000.0))
    with pytest.raises(ValueError, match="rot.tif: transform: the geotransform is rotated or "
                                         "sheared .*b = 5, d = 5"):
        datasets_gen.load_file(path)


def test_columns_running_west_are_refused(tmp_path):
    """A geotransform with a negative x pixel size (columns running west) is refused by
    load_file, open_lazy, the DataArray path and the constructor; before, every azimuth
    was mirrored east-west (a slope rising 45 degrees to the west read -45 looking west)."""
    rows, cols = 20, 24
    rising_west = 30.0 * np.tile(np.arange(cols, dtype=np.float32), (rows, 1))
    west = Affine(-30.0, 0.0, 500000.0, 0.0, -30.0, 4000000.0)
    path = write_tif(tmp_path / "west.tif", rising_west, transform=west)
    fix = r"x pixel size is negative \(-30\): its columns run west.*gdalwarp"
    with pytest.raises(ValueError, match="west.tif: transform: the geotransform's " + fix):
        datasets_gen.load_file(path)
    with pytest.raises(ValueError, match=fix):
        datasets_gen.open_lazy(path)
    with pytest.raises(ValueError, match=fix):
        HeightField(rising_west, crs=UTM17, transform=west)
    # the DataArray of the east-running grid, stored with x descending
    da = _dataarray(rising_west[:, ::-1].copy()).isel(x=slice(None, None, -1))
    with pytest.raises(ValueError, match=fix + r".*sortby\('x'\)"):
        algos.horizon(da, [270])
    # sorted, the same terrain reads right: rising west, uphill looking west
    assert deg(algos.horizon(da.sortby("x"), [270]).values[0, 10, 10]) == \
        pytest.approx(45.0, abs=1e-9)


@pytest.mark.parametrize("crs, factor", [("EPSG:32617+6360", 1200 / 3937),  # ftUS heights
                                          ("EPSG:2277+5703", 3937 / 1200),   # metre heights
                                          ("EPSG:32617+5703", 1.0)])         # one unit
def test_compound_crs_heights_in_another_unit(tmp_path, crs, factor):
    """A compound CRS whose heights are in another unit than its lengths: load_file
    converts the heights (a 45-degree ramp stays 45 degrees; before, UTM metres with
    NAVD88 heights in US feet read 73 degrees), while a DataArray or a hand-built field,
    which hftrace cannot rescale behind the caller's back, is refused with the factor;
    open_lazy converts on read as load_file does."""
    rows, cols = 20, 24
    ramp = 30.0 * np.tile(np.arange(cols, dtype=np.float64), (rows, 1))  # in length units
    stored = (ramp / factor).astype(np.float32)  # the same terrain in the vertical unit
    transform = Affine(30.0, 0.0, 500000.0, 0.0, -30.0, 4000000.0)
    path = write_tif(tmp_path / "compound.tif", stored, crs=crs, transform=transform)
    field = datasets_gen.load_file(path)
    assert deg(algos.horizon(field, [90])[0, 10, 10]) == pytest.approx(45.0, abs=1e-4)
    lazy = datasets_gen.open_lazy(path, chunks=16)  # the --dask route converts on read
    np.testing.assert_allclose(np.asarray(lazy.heights.compute()), field.heights, rtol=1e-6)
    if factor == 1.0:
        assert "heights_converted_from" not in field.params
        return
    assert field.params["heights_factor"] == pytest.approx(factor, rel=1e-12)
    fix = r"gives heights in .* but lengths in .*multiply by " + f"{factor:.10g}"[:8]
    with pytest.raises(ValueError, match=fix):
        HeightField(stored, crs=crs, transform=transform)
    pytest.importorskip("rioxarray")
    import rioxarray

    with pytest.raises(ValueError, match=fix):
        algos.horizon(rioxarray.open_rasterio(path).squeeze("band"), [90])


def test_int16_scale_and_offset_are_applied(tmp_path):
    raw = np.zeros((5, 5), np.int16)
    raw[:, 3:] = 60
    path = tmp_path / "i16.tif"
    with rasterio.open(path, "w", driver="GTiff", height=5, width=5, count=1, dtype="int16",
                       crs=UTM17, transform=Affine(30.0, 0, 500000.0, 0, -30.0, 4000000.0),
                       compress="lzw") as dst:
        dst.write(raw, 1)
        dst.scales, dst.offsets = (0.5,), (100.0,)
    field = datasets_gen.load_file(path)
    np.testing.assert_array_equal(field.heights[0], [100, 100, 100, 130, 130])
    assert deg(algos.horizon(field, [90])[0, 2, 2]) == pytest.approx(45.0, abs=1e-9)


def test_rectangular_pixels_10_by_20_metres(tmp_path):
    H = np.zeros((5, 5), np.float32)
    H[:, 3:] = 10
    path = write_tif(tmp_path / "rect.tif", H,
                     transform=Affine(10.0, 0, 500000.0, 0, -20.0, 4000000.0))
    field = datasets_gen.load_file(path)
    assert (field.dx, field.dy) == (10.0, 20.0) and field.spacing == (10.0, 20.0)
    assert deg(algos.horizon(field, [90])[0, 2, 2]) == pytest.approx(45.0, abs=1e-12)
    wall = np.zeros((5, 5))
    wall[:2] = 20  # to the north, one 20 m row away
    assert deg(algos.horizon(wall, [0], spacing=(10, 20))[0, 2, 2]) == pytest.approx(45.0, abs=1e-12)
    # every product takes them
    assert algos.shadows(field, 90, 44)[2, 2] and not algos.shadows(field, 90, 46)[2, 2]
    svf = algos.sky_view_factor(field, 8)
    assert svf.shape == (5, 5) and np.all((svf > 0) & (svf <= 1))
    assert algos.viewshed(field, (0, 2), observer_height=1.0).shape == (5, 5)


@pytest.mark.parametrize("compress, predictor", [("lzw", 2), ("zstd", 2), ("zstd", 3),
                                                 ("deflate", 3)])
def test_compressed_tiled_bigtiff_is_read(tmp_path, compress, predictor):
    dem = (fields.generate("fbm", (40, 48), seed=2) * 50).astype(np.float32)
    path = write_tif(tmp_path / "c.tif", dem, compress=compress, predictor=predictor,
                     tiled=True, blockxsize=16, blockysize=16, BIGTIFF="YES")
    np.testing.assert_array_equal(datasets_gen.load_file(path).heights, dem)


def test_vrt_and_band_number(tmp_path):
    dem = (fields.generate("fbm", (20, 24), seed=3) * 50).astype(np.float32)
    path = tmp_path / "two.tif"
    with rasterio.open(path, "w", driver="GTiff", height=20, width=24, count=2,
                       dtype="float32", crs=UTM17,
                       transform=Affine(30.0, 0, 0, 0, -30.0, 0)) as dst:
        dst.write(dem, 1)
        dst.write(dem * 2, 2)
    np.testing.assert_array_equal(datasets_gen.load_file(path, band=2).heights, dem * 2)
    with pytest.raises(ValueError, match="band: 3 is not a band of .*two.tif, which has 2 bands"):
        datasets_gen.load_file(path, band=3)
    from rasterio.shutil import copy as rio_copy

    rio_copy(path, tmp_path / "two.vrt", driver="VRT")
    np.testing.assert_array_equal(datasets_gen.load_file(tmp_path / "two.vrt").heights, dem)


def test_nodata_dem_gives_nodata_products_without_options(tmp_path):
    dem = (fields.generate("fbm", (30, 36), seed=4) * 80).astype(np.float32)
    dem[10:13, 14:16] = -9999.0
    field = datasets_gen.load_file(write_tif(tmp_path / "void.tif", dem, nodata=-9999.0))
    assert field.nodata_mask.sum() == 6 and np.isnan(field.heights[11, 15])
    svf = algos.sky_view_factor(field, 8)
    assert np.isnan(svf[field.nodata_mask]).all() and np.isfinite(svf[~field.nodata_mask]).all()
    assert not algos.shadows(field, 135, 20)[field.nodata_mask].any()
    seen = algos.viewshed(field, (2, 2))
    assert not seen[field.nodata_mask].any()


# ---- voids: "a void blocks nothing" ----------------------------------------------------------

def _touching(mask):
    """Vertices that share a cell with a void vertex."""
    near = mask.copy()
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            near |= np.roll(np.roll(mask, dj, 0), di, 1)
    return near


def test_no_valid_pixel_away_from_a_void_changes():
    """The products of a DEM with voids equal, on every vertex that does not touch a void,
    those of the same DEM where the voids are a much lower (finite) value: a void blocks
    nothing that an infinitely deep pit would not."""
    dem = fields.generate("fbm", (40, 46), seed=6, amplitude=60.0, scale=20.0).astype(np.float64)
    void = np.zeros(dem.shape, bool)
    void[12:15, 20:23] = True
    void[30, 5] = True
    holes = np.where(void, np.nan, dem)
    deep = np.where(void, -1e7, dem)
    away = ~_touching(void)
    az = [0.0, 37.0, 90.0, 200.0, 315.0]
    a = algos.horizon(holes, az, spacing=10.0)
    b = algos.horizon(deep, az, spacing=10.0)
    assert np.isnan(a[:, void]).all()
    np.testing.assert_allclose(a[:, away], b[:, away], rtol=0, atol=1e-6)
    for md in (80.0, 250.0):
        np.testing.assert_allclose(algos.horizon(holes, az, md, spacing=10.0)[:, away],
                                   algos.horizon(deep, az, md, spacing=10.0)[:, away],
                                   rtol=0, atol=1e-6)
    np.testing.assert_array_equal(algos.shadows(holes, 120, 15, spacing=10.0)[away],
                                  algos.shadows(deep, 120, 15, spacing=10.0)[away])
    np.testing.assert_array_equal(algos.viewshed(holes, (3, 4), spacing=10.0)[away],
                                  algos.viewshed(deep, (3, 4), spacing=10.0)[away])
    # and the void really takes away what stood there: a peak hid the vertex behind it
    peak = dem.copy()
    peak[13, 21] = dem.max() + 500
    hidden = algos.viewshed(peak, (21, 2), 1.0, spacing=10.0)
    opened = algos.viewshed(np.where(void, np.nan, peak), (21, 2), 1.0, spacing=10.0)
    assert (opened & ~hidden & away).any()


def test_observer_on_a_void_is_refused():
    dem = np.zeros((8, 8))
    dem[3, 3] = np.nan
    with pytest.raises(ValueError, match=r"observer\[0\]: \(3.5, 2.5\) stands on a cell "
                                         r"touching a void"):
        algos.viewshed(dem, (3.5, 2.5))


def test_fill_policy_stays_explicit(tmp_path):
    dem = np.full((6, 6), 50.0, np.float32)
    dem[2, 2] = -9999
    path = write_tif(tmp_path / "f.tif", dem, nodata=-9999.0)
    filled = datasets_gen.load_file(path, nodata_policy="fill-min")
    assert filled.nodata_mask is None and filled.heights[2, 2] == 50
    field = datasets_gen.load_file(path)
    assert field.filled("value", 7.0).heights[2, 2] == 7.0
    with pytest.raises(ValueError, match=r"heights: sample \(row 2, col 2\) is nan \(nodata\)"):
        algos.intersect("runs", field, [[1, 1, 90]], [[1, 1, -1]])


# ---- rectangular pixels against a brute-force reference -------------------------------------

def _surface(H, x, y):
    rows, cols = H.shape
    i, j = min(int(math.floor(x)), cols - 2), min(int(math.floor(y)), rows - 2)
    u, v = x - i, y - j
    h00, h10, h01, h11 = H[j, i], H[j, i + 1], H[j + 1, i], H[j + 1, i + 1]
    if u >= v:
        return h00 + (h10 - h00) * u + (h11 - h10) * v
    return h00 + (h11 - h01) * u + (h01 - h00) * v


def brute_horizon(H, dx, dy, i, j, azimuth, max_distance=math.inf):
    """Every crossing of the map-space ray with a grid line or a cell diagonal, in map
    distance t, written independently of the product's cell-space derivation."""
    rows, cols = H.shape
    a = math.radians(azimuth)
    cx, cy = math.sin(a) / dx, -math.cos(a) / dy  # cells per metre
    ends = []
    for c, p, n in ((cx, i, cols), (cy, j, rows)):
        if c > 1e-15:
            ends.append((n - 1 - p) / c)
        elif c < -1e-15:
            ends.append(-p / c)
    t_end = min(ends + [max_distance])
    ts = {t_end} if t_end > 0 else set()
    for c, p in ((cx, i), (cy, j), (cx - cy, i - j)):
        if abs(c) > 1e-15:
            for k in range(-2 * (rows + cols), 2 * (rows + cols)):
                t = (k - p) / c
                if 0 < t <= t_end:
                    ts.add(t)
    best = -math.inf
    for t in ts:
        x, y = i + t * cx, j + t * cy
        x, y = min(max(x, 0.0), cols - 1.0), min(max(y, 0.0), rows - 1.0)
        best = max(best, (_surface(H, x, y) - H[j, i]) / t)
    return -math.pi / 2 if best == -math.inf else math.atan(best)


@pytest.mark.parametrize("spacing", [(10.0, 20.0), (30.0, 7.5), (25.0, 25.0)])
def test_rectangular_pixels_match_the_brute_force_horizon(spacing):
    rng = np.random.default_rng(11)
    H = np.round(rng.uniform(0, 60, size=(7, 9)), 1)
    dx, dy = spacing
    for azimuth in (0.0, 17.3, 45.0, 90.0, 123.0, 200.0, 251.7, 333.0):
        for md in (None, 47.0):
            got = algos.horizon(H, [azimuth], md, spacing=spacing)[0]
            for j in range(7):
                for i in range(9):
                    want = brute_horizon(H, dx, dy, i, j, azimuth,
                                         math.inf if md is None else md)
                    assert got[j, i] == pytest.approx(want, abs=1e-9), (spacing, azimuth, md, i, j)


def test_rectangular_max_distance_is_in_map_units():
    H = np.zeros((9, 9))
    seen = algos.viewshed(H, (4, 4), 1.0, max_distance=35.0, spacing=(10.0, 20.0))
    jj, ii = np.mgrid[0:9, 0:9]
    np.testing.assert_array_equal(seen, ((ii - 4) * 10.0) ** 2 + ((jj - 4) * 20.0) ** 2 <= 35 ** 2)


def test_old_spacing_calls_fail_loudly():
    with pytest.raises(TypeError, match="positional spacing and unit held heights in cell units"):
        HeightField(np.zeros((3, 3)), "t", 30.0, "m")
    field = HeightField(np.zeros((3, 3)), "t", spacing=30.0, unit="m")
    with pytest.raises(ValueError, match="spacing: 10.0, but t carries its own pixel size"):
        algos.horizon(field, [0], spacing=10.0)
    with pytest.raises(ValueError, match="curvature: needs spacing"):
        algos.viewshed(np.zeros((3, 3)), (1, 1), curvature=True)
    with pytest.raises(ValueError, match="curvature: needs square pixels"):
        algos.viewshed(np.zeros((3, 3)), (1, 1), curvature=True, spacing=(1, 2))
    with pytest.raises(ValueError, match=r"spacing: spacing\[0\] = -1"):
        algos.horizon(np.zeros((3, 3)), [0], spacing=(-1, 2))
    with pytest.raises(ValueError, match="spacing: spacing = -1.0; a pixel size must be"):
        algos.horizon(np.zeros((3, 3)), [0], spacing=-1)


# ---- one type everywhere -------------------------------------------------------------------

def test_one_height_field_type_everywhere():
    assert algos.Field is algos.HeightField is datasets_gen.HeightField
    hf = datasets_gen.load("fbm", size=33, seed=1)
    o, d = [[3.0, 4.0, 20.0]], [[1.0, 0.5, -0.3]]
    np.testing.assert_array_equal(algos.intersect("runs", hf, o, d).t,
                                  algos.intersect("runs", hf.heights, o, d).t)
    np.testing.assert_array_equal(algos.horizon(hf, [30]), algos.horizon(hf.heights, [30]))
    assert len(algos.traverse("runs", [[0.5, 0.5]], [[1.0, 0.3]], hf)[0]) > 0
    for bad in ("fbm", {"heights": 1}, None):
        with pytest.raises(TypeError, match="heights: expected a 2D array of real numbers, an "
                                            "algos.HeightField"):
            algos.horizon(bad, [0])
    with pytest.raises(TypeError, match="heights: .*algos.HeightField"):
        algos.intersect("runs", "fbm", o, d)


def test_refraction_default_is_one_seventh():
    import inspect

    assert inspect.signature(algos.viewshed).parameters["refraction"].default == 1 / 7
    assert algos.DEFAULT_REFRACTION == 1 / 7 and "1/7" in algos.viewshed.__doc__
    assert algos.WGS84_SEMI_MAJOR_AXIS_M == 6378137.0
    assert algos.IUGG_MEAN_EARTH_RADIUS_M == 6371008.8


# ---- observers in map coordinates -------------------------------------------------------------

def test_map_coordinates_to_grid_and_back(tmp_path):
    dem = np.zeros((10, 12), np.float32)
    field = datasets_gen.load_file(write_tif(tmp_path / "m.tif", dem))
    x, y = field.grid_to_map(3, 4)
    assert (x, y) == (500000.0 + 3.5 * 30, 4000000.0 - 4.5 * 30)
    assert field.map_to_grid(x, y) == (3.0, 4.0)
    assert field.map_to_grid(x + 15, y - 15) == (3.5, 4.5)
    with pytest.raises(ValueError, match=r"observer 400000,4000000: outside m.tif, whose "
                                         r"vertices span x 500015..500345"):
        field.map_to_grid(400000, 4000000, what="400000,4000000")
    south = datasets_gen.load_file(write_tif(
        tmp_path / "s.tif", dem, transform=Affine(30.0, 0, 500000.0, 0, 30.0, 4000000.0)))
    assert south.map_to_grid(*south.grid_to_map(5, 2)) == (5.0, 2.0)
    plain = HeightField(dem)
    with pytest.raises(ValueError, match="not georeferenced"):
        plain.map_to_grid(1, 2)


# ---- GeoTIFF in, product, GeoTIFF out ------------------------------------------------------------

@pytest.mark.parametrize("south_up", [False, True])
def test_round_trip_keeps_crs_transform_and_nodata(tmp_path, south_up):
    dem = (fields.generate("fbm", (40, 50), seed=8) * 100).astype(np.float32)
    dem[5, 7] = -32768
    transform = Affine(20.0, 0, 600000.0, 0, 20.0 if south_up else -20.0, 4100000.0)
    src = write_tif(tmp_path / "in.tif", dem, transform=transform, nodata=-32768,
                    compress="lzw")
    field = datasets_gen.load_file(src)
    svf = algos.sky_view_factor(field, 8)
    out = raster.write_product(tmp_path / "svf.tif", svf, field, product="sky_view_factor",
                               units="1", params={"n_azimuths": 8, "max_distance": None})
    lit = algos.shadows(field, 135, 25)
    out2 = raster.write_product(tmp_path / "shadows.tif", lit, field, product="shadows",
                                units="1 in shadow, 0 lit", params={"azimuth": 135})
    with rasterio.open(src) as a, rasterio.open(out) as b, rasterio.open(out2) as c:
        assert b.crs == a.crs and b.transform == a.transform and c.transform == a.transform
        assert b.profile["tiled"] and b.compression is not None
        assert math.isnan(b.nodata) and c.nodata == 255 and c.dtypes[0] == "uint8"
        assert b.tags()["units"] == "1" and b.tags()["n_azimuths"] == "8"
        assert b.tags()["max_distance"] == "none" and b.tags()["product"] == "sky_view_factor"
        back = b.read(1)
        assert np.isnan(back[5, 7]) and c.read(1)[5, 7] == 255
        np.testing.assert_allclose(back[~field.nodata_mask], svf[~field.nodata_mask], rtol=1e-6)
        assert set(np.unique(c.read(1))) <= {0, 1, 255}


def test_windows_of_a_created_product(tmp_path):
    dem = (fields.generate("fbm", (40, 50), seed=9) * 100).astype(np.float32)
    field = datasets_gen.load_file(write_tif(tmp_path / "in.tif", dem))
    whole = algos.horizon(field, [45.0], 300.0)[0]
    path = raster.create_product(tmp_path / "h.tif", field, dtype=np.float64,
                                 product="horizon", units="radians", params={"azimuth": 45})
    for r0 in range(0, 40, 16):
        for c0 in range(0, 50, 16):
            raster.write_window(path, whole[r0:r0 + 16, c0:c0 + 16], r0, c0)
    with rasterio.open(path) as b:
        np.testing.assert_allclose(b.read(1), whole, rtol=1e-6)
        assert b.transform == field.transform
    lazy = datasets_gen.open_lazy(tmp_path / "in.tif", chunks=16)
    assert lazy.transform == field.transform and lazy.crs == field.crs
    np.testing.assert_array_equal(lazy.heights.compute(), dem)
    np.testing.assert_allclose(algos.horizon(lazy, [45.0], 300.0)[0].compute(), whole,
                               rtol=0, atol=1e-12)


# ---- xarray -----------------------------------------------------------------------------------------

def _dataarray(dem, step=30.0):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("rioxarray")
    rows, cols = dem.shape
    da = xr.DataArray(dem, dims=("y", "x"), name="elevation",
                      coords={"y": 4000000.0 - (np.arange(rows) + 0.5) * step,
                              "x": 500000.0 + (np.arange(cols) + 0.5) * step},
                      attrs={"long_name": "elevation", "source": "test"})
    return da.rio.write_crs(UTM17)


def test_dataarray_in_dataarray_out():
    dem = fields.generate("fbm", (30, 40), seed=12, amplitude=50.0).astype(np.float64)
    da = _dataarray(dem)
    out = algos.sky_view_factor(da, 8)
    assert type(out).__name__ == "DataArray" and out.dims == da.dims
    np.testing.assert_array_equal(out.x, da.x)
    np.testing.assert_array_equal(out.y, da.y)
    assert out.rio.crs == da.rio.crs and out.attrs["long_name"] == "elevation"
    assert out.attrs["units"] == "1"
    np.testing.assert_allclose(out.values, algos.sky_view_factor(dem, 8, spacing=30.0),
                               rtol=0, atol=1e-15)
    h = algos.horizon(da, [0, 90])
    assert h.dims == ("azimuth", "y", "x") and list(h.azimuth.values) == [0.0, 90.0]
    assert h.attrs["units"] == "radians"


def test_dataarray_stored_x_first_is_refused():
    """A DataArray transposed to dims (x, y) is refused with the transpose that fixes it;
    before, its columns were read as rows and a 45-degree slope east gave 0 degrees."""
    rows, cols = 20, 24
    ramp = 30.0 * np.tile(np.arange(cols, dtype=np.float64), (rows, 1))  # 45 degrees east
    da = _dataarray(ramp)
    assert deg(algos.horizon(da, [90]).values[0, 10, 10]) == pytest.approx(45.0, abs=1e-9)
    with pytest.raises(ValueError, match=r"heights: the DataArray's dims \('x', 'y'\) put x "
                                         r"first; rows must be y: pass "
                                         r"array.transpose\('y', 'x'\)"):
        algos.horizon(da.transpose("x", "y"), [90])
    with pytest.raises(ValueError, match="put x first"):
        HeightField.from_dataarray(da.transpose("x", "y"))


def test_band_unit_type_other_than_the_crs_unit_is_converted(tmp_path):
    """A GeoTIFF on a UTM grid whose band declares its unit type "ft" (gdal_edit.py
    -units ft) has its heights converted by load_file and open_lazy (a 45-degree ramp
    read 73 degrees before); rioxarray's DataArray of it carries units="ft" and is
    refused with the factor."""
    rows, cols = 20, 24
    ramp = 30.0 * np.tile(np.arange(cols, dtype=np.float64), (rows, 1))
    path = write_tif(tmp_path / "feet.tif", (ramp / 0.3048).astype(np.float32))
    with rasterio.open(path, "r+") as ds:
        ds.units = ("ft",)
    field = datasets_gen.load_file(path)
    assert field.params["heights_converted_from"] == "ft"
    assert deg(algos.horizon(field, [90])[0, 10, 10]) == pytest.approx(45.0, abs=1e-4)
    lazy = datasets_gen.open_lazy(path, chunks=16)
    np.testing.assert_allclose(np.asarray(lazy.heights.compute()), field.heights, rtol=1e-6)
    rioxarray = pytest.importorskip("rioxarray")
    da = rioxarray.open_rasterio(path).squeeze("band")
    assert da.attrs["units"] == "ft"
    with pytest.raises(ValueError, match="heights are in 'ft'"):
        algos.horizon(da, [90])


@pytest.mark.parametrize("units, factor", [("ft", 0.3048), ("feet", 0.3048), ("km", 1000.0)])
def test_dataarray_heights_in_another_unit_are_refused(units, factor):
    """A DataArray on a metre grid whose CF ``units`` attribute says its heights are in
    feet or kilometres is refused with the factor (before, a 45-degree slope read 73 or
    0.06 degrees); converted as the message says, it reads 45 degrees. Units that name
    the CRS's own unit, or no linear unit, are not in the way."""
    rows, cols = 20, 24
    ramp = 30.0 * np.tile(np.arange(cols, dtype=np.float64), (rows, 1))
    da = _dataarray(ramp / factor).assign_attrs(units=units)
    with pytest.raises(ValueError, match=rf"heights are in '{units}' \(attrs\['units'\]\) but "
                                         r"its lengths in m .*assign_attrs\(units='m'\)"):
        algos.horizon(da, [90])
    fixed = (da * factor).assign_attrs(units="m")
    assert deg(algos.horizon(fixed, [90]).values[0, 10, 10]) == pytest.approx(45.0, abs=1e-9)
    for same in ("metres", "m", "metres above sea level"):
        out = algos.horizon(_dataarray(ramp).assign_attrs(units=same), [90])
        assert deg(out.values[0, 10, 10]) == pytest.approx(45.0, abs=1e-9)


def test_chunked_dataarray_stays_lazy():
    dem = fields.generate("fbm", (40, 40), seed=13, amplitude=50.0).astype(np.float64)
    da = _dataarray(dem).chunk(16)
    out = algos.sky_view_factor(da, 4, max_distance=200.0)
    assert type(out.data).__module__.startswith("dask")
    np.testing.assert_allclose(out.compute().values,
                               algos.sky_view_factor(dem, 4, 200.0, spacing=30.0),
                               rtol=0, atol=1e-12)


# ---- pictures -----------------------------------------------------------------------------------------

def test_product_png_is_readable(tmp_path):
    from PIL import Image

    from datasets_gen.preview import product_png

    dem = (fields.generate("fbm", (30, 40), seed=14) * 100).astype(np.float32)
    dem[4, 4] = np.nan
    field = HeightField(dem, "dem", spacing=30.0, unit="m",
                        transform=None)
    h = np.degrees(algos.horizon(field, [90])[0])
    path = product_png(tmp_path / "h.png", h, field, product="horizon",
                       units="degrees above the horizontal", params={"azimuth": 90},
                       observers=[(10, 12)], cmap="magma", border=-90.0)
    with Image.open(path) as image:
        assert image.size[0] > 300 and image.size[1] > 300


# ---- a peer on a projected DEM ---------------------------------------------------------------------

def test_viewshed_agrees_with_xarray_spatial_on_a_projected_dem(tmp_path):
    xrspatial = pytest.importorskip("xrspatial")
    dem = (fields.generate("fbm", (50, 60), seed=15) * 120).astype(np.float32)
    field = datasets_gen.load_file(write_tif(tmp_path / "p.tif", dem))
    x, y = field.grid_to_map(31, 22)
    col, row = field.map_to_grid(x, y)
    ours = algos.viewshed(field, (col, row), observer_height=1.75)
    da = _dataarray(dem.astype(np.float64))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        theirs = xrspatial.viewshed(da, x=x, y=y, observer_elev=1.75).values > -1
    agree = float(np.mean(ours == theirs))
    # the peer models cells, not two triangles: they differ only near the decision margin
    print(f"agreement with xarray-spatial: {agree:.5f}")
    assert agree > 0.99, agree


def test_observers_as_typed(tmp_path):
    from datasets_gen.observers import parse_observer, read_observers_csv

    dem = np.zeros((10, 12), np.float32)
    field = datasets_gen.load_file(write_tif(tmp_path / "m.tif", dem))
    x, y = field.grid_to_map(3, 4)
    assert parse_observer(f"{x},{y}", field) == (3.0, 4.0, None)
    assert parse_observer(f"{x},{y},2.5", field) == (3.0, 4.0, 2.5)
    with pytest.raises(ValueError, match=r"--observer '1,2,3,4': expected X,Y or X,Y,HEIGHT"):
        parse_observer("1,2,3,4", field)
    with pytest.raises(ValueError, match=r"observer 1,2: outside m.tif"):
        parse_observer("1,2", field)
    # pixels count rows from the north on every input, the embedded DEM's too
    jacks = datasets_gen.load("jacksboro", size=64)
    assert jacks.north == "+y"
    assert parse_observer("5,0", jacks, pixel=True)[:2] == (5.0, jacks.shape[0] - 1.0)
    assert parse_observer("5,0", field, pixel=True)[:2] == (5.0, 0.0)
    with pytest.raises(ValueError, match=r"observer pixel 5,99: outside"):
        parse_observer("5,99", field, pixel=True)
    with pytest.raises(ValueError, match="not georeferenced.*--observer-pixel"):
        parse_observer("5,9", jacks)
    (tmp_path / "obs.csv").write_text(f"x,y,height\n{x},{y}\n{x + 30},{y},10\n")
    assert read_observers_csv(tmp_path / "obs.csv", field) == [(3.0, 4.0, None), (4.0, 4.0, 10.0)]
    (tmp_path / "bad.csv").write_text(f"{x},{y}\nfoo,bar\n")
    with pytest.raises(ValueError, match=r"bad.csv, line 2: --observer 'foo,bar'"):
        read_observers_csv(tmp_path / "bad.csv", field)


def test_lazy_raster_reads_nodata_as_voids(tmp_path):
    """The Dask path reads windows through rasterio: -9999 is a void, not a height."""
    dem = (fields.generate("fbm", (40, 44), seed=16) * 100).astype(np.float32)
    dem[20:22, 10:13] = -9999.0
    path = write_tif(tmp_path / "v.tif", dem, nodata=-9999.0, tiled=True, blockxsize=16,
                     blockysize=16, compress="zstd")
    lazy = datasets_gen.open_lazy(path, chunks=16)
    heights = lazy.heights.compute()
    assert np.isnan(heights[20:22, 10:13]).all() and np.isfinite(heights).sum() == 40 * 44 - 6
    whole = algos.horizon(datasets_gen.load_file(path), [30.0, 210.0], 200.0)
    tiled = algos.horizon(lazy, [30.0, 210.0], 200.0).compute()
    np.testing.assert_allclose(tiled, whole, rtol=0, atol=1e-12)
    assert np.isnan(tiled[:, 20:22, 10:13]).all()


def test_horizon_bands_are_written_with_their_azimuths(tmp_path):
    dem = (fields.generate("fbm", (20, 24), seed=17) * 100).astype(np.float32)
    field = datasets_gen.load_file(write_tif(tmp_path / "in.tif", dem))
    az = [0.0, 135.0]
    angles = np.degrees(algos.horizon(field, az))
    path = raster.write_product(tmp_path / "h.tif", angles, field, product="horizon",
                                units="degrees", params={"azimuths": az},
                                band_names=[f"azimuth {a:g}" for a in az])
    with rasterio.open(path) as b:
        assert b.count == 2 and b.descriptions == ("azimuth 0", "azimuth 135")
        assert b.tags(2)["units"] == "degrees"
        np.testing.assert_allclose(b.read(2), angles[1], rtol=1e-6)


def test_save_product_writes_the_geotiff_and_the_picture(tmp_path):
    dem = (fields.generate("fbm", (24, 30), seed=18) * 100).astype(np.float32)
    field = datasets_gen.load_file(write_tif(tmp_path / "in.tif", dem))
    seen = algos.viewshed(field, (12, 10))
    tif, png = datasets_gen.save_product(tmp_path / "vs", seen, field, product="viewshed",
                                         units="1 visible, 0 not",
                                         params={"observer_height": 1.75},
                                         observers=[(12, 10)], cmap="Greens")
    with rasterio.open(tif) as b:
        assert b.crs == field.crs and b.tags()["observer_height"] == "1.75"
        np.testing.assert_array_equal(b.read(1), seen.astype(np.uint8))
    assert (tmp_path / "vs.png").stat().st_size > 1000 and png.endswith("vs.png")


# ---- a hand-built field's CRS: its unit wins, a geographic one is refused --------------------

TEXAS_FEET = "EPSG:2277"  # NAD83 / Texas Central, US survey feet


def test_a_crs_in_feet_built_by_hand_equals_the_geotiff(tmp_path):
    h = np.zeros((64, 64), np.float32)
    h[20:30, 40:44] = 250.0
    transform = Affine(100.0, 0.0, 2000000.0, 0.0, -100.0, 10000000.0)
    path = write_tif(tmp_path / "feet.tif", h, crs=TEXAS_FEET, transform=transform)
    read = datasets_gen.load_file(path)
    built = HeightField(h, crs=TEXAS_FEET, transform=transform)
    assert read.unit == built.unit == "US survey foot"
    assert read.unit_metres == built.unit_metres == pytest.approx(1200 / 3937, rel=1e-12)
    assert built.params["unit_metres"] == built.unit_metres
    for mode in ("angle", "ground"):
        want = algos.viewshed(read, (0, 0), mode=mode, curvature=True, observer_height=5)
        got = algos.viewshed(built, (0, 0), mode=mode, curvature=True, observer_height=5)
        np.testing.assert_array_equal(got, want)
    # and the feet are converted: a metre field of the same numbers drops more
    metres = HeightField(h, spacing=100.0, unit="m")
    assert algos.viewshed(metres, (0, 0), mode="angle", curvature=True,
                          observer_height=0)[63, 63] < \
        algos.viewshed(built, (0, 0), mode="angle", curvature=True, observer_height=0)[63, 63]


def test_a_unit_that_contradicts_the_crs_raises():
    transform = Affine(100.0, 0.0, 2000000.0, 0.0, -100.0, 10000000.0)
    h = np.zeros((4, 4))
    with pytest.raises(ValueError, match=r"unit: 'ft' contradicts the CRS's linear unit "
                                         r"'US survey foot'"):
        HeightField(h, crs=TEXAS_FEET, transform=transform, unit="ft")
    with pytest.raises(ValueError, match=r"unit: 'map unit' contradicts the CRS's linear unit 'm'"):
        HeightField(h, crs=UTM17, spacing=30, unit="map unit")
    # naming the CRS's own unit (or an alias of it) is fine
    assert HeightField(h, crs=TEXAS_FEET, transform=transform, unit="us-ft").unit == \
        "US survey foot"
    assert HeightField(h, crs=UTM17, spacing=30, unit="metre").unit_metres == 1.0


def test_a_geographic_crs_built_by_hand_is_refused_as_load_file_refuses_it(tmp_path):
    h = np.zeros((20, 20), np.float32)
    transform = Affine(1 / 1200, 0.0, -81.0, 0.0, -1 / 1200, 46.0)
    path = write_tif(tmp_path / "geo.tif", h, crs="EPSG:4326", transform=transform)
    with pytest.raises(ValueError) as from_file:
        datasets_gen.load_file(path)
    with pytest.raises(ValueError, match=r"^crs: its CRS \(EPSG:4326\) is geographic") as built:
        HeightField(h, crs="EPSG:4326", transform=transform)
    # the same explanation and the same gdalwarp command (target CRS and pixel size)
    tail = str(from_file.value).split(": ", 1)[1]
    assert str(built.value).split(": ", 1)[1].split(" -r bilinear")[0] == \
        tail.split(" -r bilinear")[0]
    assert "gdalwarp -t_srs EPSG:32617 -tr" in str(built.value)
    with pytest.raises(ValueError, match=r"crs: its CRS \(EPSG:4326\) is geographic.*gdalwarp"):
        HeightField(h, crs="EPSG:4326", spacing=1 / 1200)


# ---- georeferencing never silently lost -------------------------------------------------

def _cliff():
    """A 30 m cliff one 30 m pixel east of column 14: 45 degrees from its foot."""
    h = np.zeros((20, 30), np.float32)
    h[:, 15:] = 30.0
    return h


def _gcp_tif(path):
    from rasterio.control import GroundControlPoint as GCP

    gcps = [GCP(row=r, col=c, x=500000.0 + 30 * c, y=4000000.0 - 30 * r)
            for r, c in ((0, 0), (0, 30), (20, 0), (20, 30))]
    with rasterio.open(path, "w", driver="GTiff", height=20, width=30, count=1,
                       dtype="float32", gcps=gcps, crs=UTM17) as dst:
        dst.write(_cliff(), 1)
    return path


def _rpc_tif(path):
    from rasterio.rpc import RPC

    one = [1.0] + [0.0] * 19
    rpcs = RPC(height_off=100, height_scale=500, lat_off=36.0, lat_scale=0.05,
               line_den_coeff=one, line_num_coeff=[0, 0, -1.0] + [0.0] * 17, line_off=10,
               line_scale=10, long_off=-81.0, long_scale=0.05, samp_den_coeff=one,
               samp_num_coeff=[0, 1.0] + [0.0] * 18, samp_off=15, samp_scale=15)
    with rasterio.open(path, "w", driver="GTiff", height=20, width=30, count=1,
                       dtype="float32", rpcs=rpcs) as dst:
        dst.write(_cliff(), 1)
    return path


def _geoloc_tif(path):
    with rasterio.open(path, "w", driver="GTiff", height=20, width=30, count=1,
                       dtype="float32") as dst:
        dst.write(_cliff(), 1)
        dst.update_tags(ns="GEOLOCATION", X_DATASET="lon.tif", X_BAND="1", Y_DATASET="lat.tif",
                        Y_BAND="1", PIXEL_OFFSET="0", LINE_OFFSET="0", PIXEL_STEP="1",
                        LINE_STEP="1", SRS="EPSG:4326")
    return path


# (maker, what the message names, the gdalwarp command it gives)
NON_AFFINE = [
    (_gcp_tif, "ground control points", r"gdalwarp -t_srs EPSG:32617 -r bilinear \S*gcp.tif"),
    (_rpc_tif, "RPCs", r"gdalwarp -rpc -t_srs EPSG:32617 -r bilinear \S*rpc.tif"),
    (_geoloc_tif, "geolocation arrays", r"gdalwarp -geoloc -t_srs EPSG:"),
]


@pytest.mark.parametrize("make,kind,fix", NON_AFFINE, ids=["gcps", "rpcs", "geoloc"])
def test_gcp_rpc_and_geolocation_rasters_are_refused_with_the_gdalwarp_command(tmp_path, make,
                                                                                kind, fix):
    """Read as a plain grid such a file was cell units: 88 deg where the cliff is 45 deg."""
    path = make(tmp_path / f"{make.__name__.strip('_').split('_')[0]}.tif")
    for read in (datasets_gen.load_file, datasets_gen.open_lazy):
        with pytest.raises(ValueError, match=rf"georeferenced by {kind}.*{fix}"):
            read(path)


@pytest.mark.parametrize("make,kind,fix", NON_AFFINE[:2], ids=["gcps", "rpcs"])
def test_dataarray_of_a_gcp_or_rpc_raster_is_refused(tmp_path, make, kind, fix):
    rioxarray = pytest.importorskip("rioxarray")
    path = make(tmp_path / f"{make.__name__.strip('_').split('_')[0]}.tif")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        array = rioxarray.open_rasterio(path).squeeze("band", drop=True)
    with pytest.raises(ValueError, match=rf"georeferenced by {kind}.*gdalwarp"):
        algos.horizon(array, [90])


def _counts_tif(path, *, nodata=None):
    """The cliff stored as uint16 counts of 0.5 m above -10 m (scale 0.5, offset -10)."""
    counts = ((_cliff() + 10.0) / 0.5).astype(np.uint16)
    counts[3, 4] = 65535 if nodata is not None else counts[3, 4]
    path = write_tif(path, counts, nodata=nodata)
    with rasterio.open(path, "r+") as dst:
        dst.scales, dst.offsets = (0.5,), (-10.0,)
    return path


def test_rioxarray_raw_counts_are_scaled_as_the_file_is(tmp_path):
    """``open_rasterio(path)`` keeps raw counts with scale_factor/add_offset in attrs: the
    horizon over it is the file's (45 deg), not the counts' (84 deg)."""
    rioxarray = pytest.importorskip("rioxarray")
    path = _counts_tif(tmp_path / "counts.tif", nodata=65535)
    array = rioxarray.open_rasterio(path).squeeze("band", drop=True)
    assert array.attrs["scale_factor"] == 0.5 and array.dtype == np.uint16
    from_array = algos.horizon(array, [90])
    from_file = algos.horizon(datasets_gen.load_file(path), [90])
    assert deg(float(from_array[0, 10, 14])) == pytest.approx(45.0, abs=1e-9)
    np.testing.assert_array_equal(np.asarray(from_array), from_file)
    # the count 65535 is the void, as in the file
    assert np.isnan(np.asarray(from_array)[0, 3, 4])
    # decoded by rioxarray (mask_and_scale=True): the rules are in encoding, not applied twice;
    # masked only (masked=True): voids NaN, scale and offset still in attrs and applied here
    for options in (dict(mask_and_scale=True), dict(masked=True)):
        decoded = rioxarray.open_rasterio(path, **options).squeeze("band", drop=True)
        np.testing.assert_array_equal(np.asarray(algos.horizon(decoded, [90])), from_file)
    # chunked (dask) raw counts are decoded lazily, to the file's heights
    lazy = algos.HeightField.from_dataarray(
        rioxarray.open_rasterio(path, chunks=8).squeeze("band", drop=True))
    assert is_dask(lazy.heights)
    np.testing.assert_array_equal(np.asarray(lazy.heights.compute()),
                                  datasets_gen.load_file(path).heights)


def test_cf_packing_and_missing_values_in_attrs_are_applied():
    xr = pytest.importorskip("xarray")
    rows, cols = 12, 16
    raw = np.full((rows, cols), 100, np.int16)
    raw[:, 8:] = 130  # 100 -> 0 m, 130 -> 30 m with scale 1, offset -100
    raw[2, 3], raw[4, 5] = -32768, -1
    y = 1000.0 - 30.0 * (np.arange(rows) + 0.5)
    x = 30.0 * (np.arange(cols) + 0.5)
    array = xr.DataArray(raw, dims=("y", "x"), coords={"y": y, "x": x},
                         attrs={"scale_factor": 1.0, "add_offset": -100.0,
                                "_FillValue": -32768, "missing_value": -1})
    field = algos.HeightField.from_dataarray(array, unit="m")
    assert field.heights[0, 0] == 0.0 and field.heights[0, 10] == 30.0
    assert np.isnan(field.heights[2, 3]) and np.isnan(field.heights[4, 5])
    assert field.nodata_mask[2, 3] and field.nodata_mask[4, 5] and field.nodata_mask.sum() == 2
    bad = array.copy()
    bad.attrs["scale_factor"] = 0.0
    with pytest.raises(ValueError, match="scale_factor"):
        algos.HeightField.from_dataarray(bad, unit="m")
    both = array.copy()
    both.encoding["add_offset"] = -100.0
    with pytest.raises(ValueError, match="add_offset is both an attribute"):
        algos.HeightField.from_dataarray(both, unit="m")
    # GDAL's per-band lists of one band are the same rules; lists of several are refused
    listed = array.copy()
    listed.attrs = {"scales": (1.0,), "offsets": (-100.0,), "nodatavals": (-32768.0,),
                    "missing_value": -1}
    np.testing.assert_array_equal(algos.HeightField.from_dataarray(listed, unit="m").heights,
                                  field.heights)
    listed.attrs["scales"] = (1.0, 2.0)
    with pytest.raises(ValueError, match=r"scales=\(1.0, 2.0\) holds one value per band"):
        algos.HeightField.from_dataarray(listed, unit="m")


def test_an_explicit_nodata_no_sample_can_equal_is_refused_with_both_values(tmp_path):
    """-9999 on a uint8 file replaced its own nodata 255: its voids became 255 m spikes."""
    data = np.full((8, 9), 20, np.uint8)
    data[2, 2] = 255
    path = write_tif(tmp_path / "u8.tif", data, nodata=255)
    with pytest.raises(ValueError, match=r"nodata: -9999 can never equal.*uint8.*\[0, 255\]"):
        datasets_gen.load_file(path, nodata=-9999)
    with pytest.raises(ValueError, match=r"nodata: 20 contradicts the nodata value 255"):
        datasets_gen.load_file(path, nodata=20)
    field = datasets_gen.load_file(path, nodata=255)  # the file's own: fine
    assert field.nodata_mask[2, 2] and np.nanmax(field.heights) == 20
    plain = write_tif(tmp_path / "plain.tif", data)  # no nodata declared: 255 marks voids
    assert datasets_gen.load_file(plain, nodata=255).nodata_mask[2, 2]
    with pytest.raises(ValueError, match=r"nodata: 2.5 can never equal"):
        datasets_gen.load_file(plain, nodata=2.5)
    with pytest.raises(TypeError, match=r"nodata: expected a number, got 'abc'"):
        datasets_gen.load_file(plain, nodata="abc")
    np.save(tmp_path / "u8.npy", data)
    with pytest.raises(ValueError, match=r"nodata: -9999 can never equal"):
        datasets_gen.load_file(tmp_path / "u8.npy", nodata=-9999)


def test_algos_imports_nothing_from_datasets_gen_or_bench():
    """The package boundary bench -> datasets_gen -> algos is never crossed upward (the
    CRS rules live in algos.georef)."""
    import ast
    import pathlib

    root = pathlib.Path(algos.__file__).parent
    upward = []
    for source in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(source.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level \
                else []
            upward += [f"{source.relative_to(root)}:{node.lineno} imports {n}" for n in names
                       if n.split(".")[0] in ("datasets_gen", "bench")]
    assert not upward, upward


def test_float64_sample_beyond_float32_is_refused_with_its_place(tmp_path):
    """A float64 DEM whose sample is finite but beyond float32 (here -DBL_MAX, a common
    undeclared void marker) is refused with its row, column and value; declared as nodata
    it is a void. Cast silently, it became -inf and then a void without a word."""
    data = np.arange(30, dtype=np.float64).reshape(5, 6)
    data[3, 4] = -np.finfo(np.float64).max
    path = write_tif(tmp_path / "big.tif", data, dtype="float64")
    with pytest.raises(ValueError, match=r"big\.tif: the sample at row 3, column 4 is "
                                         r"-1\.79.*e\+308, beyond float32.*nodata value"):
        raster.read_raster(path)
    lazy = raster.LazyRaster(path)
    with pytest.raises(ValueError, match=r"row 3, column 4"):
        lazy[2:5, 1:6]
    assert np.isfinite(lazy[0:3, 0:6]).all()  # a window without it reads
    field = raster.read_raster(path, nodata=-np.finfo(np.float64).max)
    assert field.nodata_mask[3, 4] and field.nodata_mask.sum() == 1


def test_infinite_or_overflowing_samples_are_refused_not_voided(tmp_path):
    """Found by a new user's trial: a float64 sample that overflows float64 once scaled
    (1e300 with a scale tag of 1e10), an infinite sample without a nodata tag, and 1e39 in
    a .npy read window by window all became voids without a word."""
    data = np.arange(30, dtype=np.float64).reshape(5, 6)
    data[1, 2] = 1e300
    path = write_tif(tmp_path / "e300.tif", data, dtype="float64")
    with rasterio.open(path, "r+") as ds:
        ds.scales = (1e10,)
    with pytest.raises(ValueError, match=r"e300\.tif: the sample at row 1, column 2 is inf "
                                         r"once scaled \(in the file 1e\+300\)"):
        raster.read_raster(path)
    data[1, 2] = np.inf
    path = write_tif(tmp_path / "inf.tif", data, dtype="float64")
    with pytest.raises(ValueError, match=r"inf\.tif: the sample at row 1, column 2 is inf, "
                                         r"an infinite height"):
        raster.read_raster(path)
    data[1, 2] = 1e39
    npy = tmp_path / "e39.npy"
    np.save(npy, data)
    with pytest.raises(ValueError, match=r"e39\.npy: the sample at row 1, column 2 is 1e\+39"):
        raster.LazyRaster(npy)[0:3, 0:6]
    # read whole into memory, the same sample is refused naming the file too, and with a
    # vertical scale, the value the file holds
    with pytest.raises(ValueError, match=r"e39\.npy: the sample at row 1, column 2 is 1e\+39, "
                                         r"beyond float32"):
        datasets_gen.load_file(npy)
    data[1, 2] = 1e38
    np.save(npy, data)
    with pytest.raises(ValueError, match=r"e39\.npy: the sample at row 1, column 2 is 1e\+39 "
                                         r"once scaled \(in the file 1e\+38\)"):
        datasets_gen.load_file(npy, vertical_scale=10.0)
    data[1, 2] = np.nan  # NaN stays a void
    np.save(npy, data)
    window = raster.LazyRaster(npy)[0:3, 0:6]
    assert np.isnan(window[1, 2]) and np.isfinite(window).sum() == 17


def test_a_bad_sample_of_a_reprojected_raster_is_named_as_in_the_file(tmp_path):
    """Found by a new user's trial: with reproject="utm" an infinite sample was refused
    at a bilinear blend of it on the UTM grid, not at the file's row and column."""
    dem = np.full((12, 12), 100.0)
    dem[3, 7] = np.inf
    path = write_tif(tmp_path / "geo_inf.tif", dem, dtype="float64", crs="EPSG:4326",
                     transform=Affine(1 / 1200, 0, -84.0, 0, -1 / 1200, 46.01))
    with pytest.raises(ValueError, match=r"geo_inf\.tif: the sample at row 3, column 7 is inf, "
                                         r"an infinite height; 1 sample\(s\) in all"):
        datasets_gen.load_file(path, reproject="utm")
    dem[3, 7] = 120.0  # the same file mended reprojects
    path = write_tif(tmp_path / "geo_ok.tif", dem, dtype="float64", crs="EPSG:4326",
                     transform=Affine(1 / 1200, 0, -84.0, 0, -1 / 1200, 46.01))
    field = datasets_gen.load_file(path, reproject="utm")
    assert field.crs.to_epsg() == 32617 and np.nanmax(field.heights) <= 120.0
