"""The terrain commands on a user's own files: ``hftrace svf their_dem.tif``
gives a georeferenced, nodata-aware result equal to the API's on the same file, or a
one-line refusal that says how to fix the input. Every GeoTIFF is made here with rasterio.
"""
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import algos
import datasets_gen
from bench.cli import main

rasterio = pytest.importorskip("rasterio")
from affine import Affine  # noqa: E402  (rasterio's dependency)

UTM15 = "EPSG:32615"
NORTH_UP = Affine(30.0, 0.0, 600000.0, 0.0, -30.0, 3650000.0)


def write_tif(path, data, *, crs=UTM15, transform=NORTH_UP, nodata=None, **options):
    data = np.asarray(data)
    with rasterio.open(path, "w", driver="GTiff", height=data.shape[0], width=data.shape[1],
                       count=1, dtype=data.dtype.name, crs=crs, transform=transform,
                       nodata=nodata, **options) as dst:
        dst.write(data, 1)
    return str(path)


def dem(rows=40, cols=48, seed=5):
    """A fBm DEM in metres (a few hundred metres of relief over 30 m pixels)."""
    return (datasets_gen.load("fbm", size=(rows, cols), seed=seed).heights * 8.0).astype(np.float32)


def run(args, capsys):
    code = main(args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_svf_of_a_dem_with_voids_is_georeferenced_and_equals_the_api(tmp_path, capsys):
    h = dem()
    h[10:13, 20:24] = -9999.0
    path = write_tif(tmp_path / "dem.tif", h, nodata=-9999.0, compress="lzw", predictor=3)
    out = str(tmp_path / "svf")
    code, stdout, stderr = run(["svf", path, "--n-azimuths", "8", "--max-distance", "600",
                                "--out", out, "--no-progress"], capsys)
    assert code == 0, stderr
    assert "12 void vertices" in stdout
    field = datasets_gen.load_file(path)
    want = algos.sky_view_factor(field, 8, 600.0)
    with rasterio.open(out + ".tif") as src, rasterio.open(path) as dem_file:
        assert src.crs == dem_file.crs and src.transform == dem_file.transform
        assert src.tags()["units"] == "1" and src.tags()["product"] == "sky_view_factor"
        assert src.tags()["max_distance"] == "600.0"
        got = src.read(1, masked=True)
    assert got.mask[10:13, 20:24].all() and got.mask.sum() == 12
    np.testing.assert_array_equal(got.filled(np.nan), want.astype(np.float32))
    assert (tmp_path / "svf.png").stat().st_size > 0


def test_horizon_in_metres_from_a_file_without_georeferencing(tmp_path, capsys):
    """The issue's first row through the CLI: a 30 m cliff one 30 m pixel away is 45 deg."""
    h = np.zeros((5, 5), np.float32)
    h[:, 3:] = 30
    np.save(tmp_path / "cliff.npy", h)
    out = str(tmp_path / "hz")
    code, _, stderr = run(["horizon", str(tmp_path / "cliff.npy"), "--spacing", "30",
                           "--azimuths", "90", "--out", out, "--no-progress"], capsys)
    assert code == 0, stderr
    with rasterio.open(out + ".tif") as src:
        assert src.tags()["units"] == "degrees"
        assert src.read(1)[2, 2] == pytest.approx(45.0, abs=1e-5)


def test_rectangular_pixels_and_south_up_keep_their_grid(tmp_path, capsys):
    h = dem()
    south_up = Affine(10.0, 0.0, 600000.0, 0.0, 20.0, 3640000.0)  # 10 m x 20 m, rows north
    path = write_tif(tmp_path / "rect.tif", h, transform=south_up)
    out = str(tmp_path / "sh")
    code, _, stderr = run(["shadows", path, "--azimuth", "200", "--elevation", "20",
                           "--out", out, "--no-progress"], capsys)
    assert code == 0, stderr
    field = datasets_gen.load_file(path)
    assert (field.dx, field.dy, field.north) == (10.0, 20.0, "+y")
    with rasterio.open(out + ".tif") as src:
        assert src.transform == south_up  # the input's grid and orientation
        np.testing.assert_array_equal(src.read(1), algos.shadows(field, 200, 20).astype(np.uint8))


def test_geographic_dem_is_refused_with_the_fix_or_reprojected(tmp_path, capsys):
    h = dem()
    path = write_tif(tmp_path / "geo.tif", h, crs="EPSG:4326",
                     transform=Affine(1 / 1200, 0, -94.0, 0, -1 / 1200, 33.0))
    code, _, stderr = run(["svf", path, "--n-azimuths", "4", "--out",
                           str(tmp_path / "a"), "--no-progress"], capsys)
    assert code == 2 and "gdalwarp -t_srs EPSG:32615" in stderr
    assert "Traceback" not in stderr and len(stderr.strip().splitlines()) == 1
    code, _, stderr = run(["svf", path, "--n-azimuths", "4", "--reproject", "utm", "--out",
                           str(tmp_path / "b"), "--no-progress"], capsys)
    assert code == 0, stderr
    with rasterio.open(tmp_path / "b.tif") as src:
        assert src.crs.to_epsg() == 32615


def test_rotated_geotransform_is_refused(tmp_path, capsys):
    rotated = Affine.rotation(10.0) @ Affine(30.0, 0, 0, 0, -30.0, 0)
    path = write_tif(tmp_path / "rot.tif", dem(), transform=Affine.translation(6e5, 3.65e6) @ rotated)
    code, _, stderr = run(["svf", path, "--out", str(tmp_path / "r"), "--no-progress"], capsys)
    assert code == 2 and "rotat" in stderr.lower()


def test_observers_in_map_coordinates_pixels_and_csv_agree(tmp_path, capsys):
    h = dem()
    path = write_tif(tmp_path / "dem.tif", h)
    # the vertex of pixel (col 7, row 5) is the pixel's centre in map coordinates
    x, y = NORTH_UP @ (7 + 0.5, 5 + 0.5)
    outs = {}
    for name, extra in (("map", ["--observer", f"{x},{y}"]),
                        ("pixel", ["--observer-pixel", "7,5"])):
        out = str(tmp_path / name)
        code, _, stderr = run(["viewshed", path, *extra, "--observer-height", "10",
                               "--out", out, "--no-progress"], capsys)
        assert code == 0, stderr
        with rasterio.open(out + ".tif") as src:
            outs[name] = src.read(1)
    np.testing.assert_array_equal(outs["map"], outs["pixel"])
    field = datasets_gen.load_file(path)
    want = algos.viewshed(field, (7.0, 5.0), 10.0)
    np.testing.assert_array_equal(outs["map"], want.astype(np.uint8))
    (tmp_path / "obs.csv").write_text(f"x,y,height\n{x},{y},10\n{x + 300},{y - 300}\n")
    code, _, stderr = run(["viewshed", path, "--observers", str(tmp_path / "obs.csv"),
                           "--out", str(tmp_path / "csv"), "--no-progress"], capsys)
    assert code == 0, stderr
    with rasterio.open(tmp_path / "csv.tif") as src:
        count = src.read(1)
    both = (algos.viewshed(field, (7.0, 5.0), 10.0).astype(np.uint16)
            + algos.viewshed(field, (17.0, 15.0), 1.75))
    np.testing.assert_array_equal(count, both)


@pytest.mark.parametrize("args, message", [
    (["--observer", "1,2,3,4"], "--observer '1,2,3,4': expected X,Y"),
    (["--observer-pixel", "900,2"], "observer pixel 900,2: outside"),
    (["--observer", "0,0"], "observer 0,0: outside dem.tif"),
])
def test_observer_errors_echo_what_was_typed(tmp_path, capsys, args, message):
    path = write_tif(tmp_path / "dem.tif", dem())
    code, _, stderr = run(["viewshed", path, *args, "--out", str(tmp_path / "v"),
                           "--no-progress"], capsys)
    assert code == 2 and message in stderr and "Traceback" not in stderr


def test_missing_file_and_unknown_dataset_say_which(tmp_path, capsys):
    code, _, stderr = run(["svf", str(tmp_path / "nope.tif")], capsys)
    assert code == 2 and "nope.tif does not exist" in stderr
    code, _, stderr = run(["svf", "nosuchdataset"], capsys)
    assert code == 2 and "neither a file nor a dataset" in stderr
    code, _, stderr = run(["svf", "fbm", "--spacing", "30"], capsys)
    assert code == 2 and "--spacing: describes a file" in stderr


def test_fill_is_explicit(tmp_path, capsys):
    h = dem()
    h[4, 4] = -9999.0
    path = write_tif(tmp_path / "dem.tif", h, nodata=-9999.0)
    code, stdout, stderr = run(["horizon", path, "--azimuths", "45", "--fill", "min", "--out",
                                str(tmp_path / "f"), "--no-progress"], capsys)
    assert code == 0, stderr
    assert "void" not in stdout
    with rasterio.open(tmp_path / "f.tif") as src:
        assert not src.read(1, masked=True).mask.any()
    field = datasets_gen.load_file(path, nodata_policy="fill-min")
    with rasterio.open(tmp_path / "f.tif") as src:
        np.testing.assert_array_equal(
            src.read(1), np.degrees(algos.horizon(field, [45])[0]).astype(np.float32))
    assert not math.isnan(float(field.heights[4, 4]))


def test_dask_path_keeps_voids_as_nodata(tmp_path):
    """``--dask`` reads the file through rasterio windows (the nodata value is a void, not
    a height) and writes the georeferenced product with nodata at the voids."""
    h = dem(rows=60, cols=50)
    h[30:33, 10:14] = -9999.0
    path = write_tif(tmp_path / "dem.tif", h, nodata=-9999.0)
    out = str(tmp_path / "hz")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = subprocess.run([sys.executable, "-m", "bench.cli", "horizon", path, "--dask",
                           "local:1", "--max-distance", "300", "--chunk", "32", "--azimuths",
                           "90", "--out", out, "--no-progress"], cwd=root,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    want = np.degrees(algos.horizon(datasets_gen.load_file(path), [90], 300.0)[0])
    with rasterio.open(out + ".tif") as src, rasterio.open(path) as dem_file:
        assert src.crs == dem_file.crs and src.transform == dem_file.transform
        got = src.read(1, masked=True)
    assert got.mask[30:33, 10:14].all() and got.mask.sum() == 12
    np.testing.assert_array_equal(got.filled(np.nan), want.astype(np.float32))


# ---- found by a new user's trial (pinned) ------------------------------------------------

def test_dask_south_up_equals_in_memory_and_halo_may_exceed_the_raster(tmp_path):
    h = dem(rows=40, cols=36)
    south_up = Affine(20.0, 0.0, 600000.0, 0.0, 20.0, 3640000.0)
    path = write_tif(tmp_path / "su.tif", h, transform=south_up)
    out = str(tmp_path / "hz")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = subprocess.run([sys.executable, "-m", "bench.cli", "horizon", path, "--dask",
                           "local:1", "--max-distance", "5000", "--chunk", "16", "--azimuths",
                           "0,180", "--out", out, "--no-progress"], cwd=root,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    want = np.degrees(algos.horizon(datasets_gen.load_file(path), [0, 180], 5000.0))
    with rasterio.open(out + ".tif") as src:
        assert src.transform == south_up
        np.testing.assert_array_equal(src.read(), want.astype(np.float32))


def test_dask_bad_sample_is_one_line_without_the_workers_task_dump(tmp_path):
    """Found by a new user's trial: a sample beyond float32 in a .npy read window by
    window was refused, but the local workers first logged the failed task with its
    arguments and traceback. Now stderr is the one error line, naming the file's sample
    (after the note on a file without georeferencing, which both paths print)."""
    heights = np.zeros((64, 64))
    heights[10, 20] = 1e39
    path = tmp_path / "e39.npy"
    np.save(path, heights)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = subprocess.run([sys.executable, "-m", "bench.cli", "horizon", str(path), "--dask",
                           "local:1", "--max-distance", "5", "--chunk", "32", "--azimuths", "90",
                           "--out", str(tmp_path / "hz"), "--no-progress"], cwd=root,
                          capture_output=True, text=True)
    assert done.returncode == 2, done.stderr[-3000:]
    lines = [x for x in done.stderr.splitlines() if x.strip()]
    # the note the in-memory path prints on loading a file without georeferencing (the
    # lazy load reads no sample, so it comes before the error), then the one error line
    assert lines[0] == (f"hftrace: note: {path} has no georeferencing and no --spacing: its "
                        "heights are taken in multiples of the pixel size (cell units)")
    assert lines[1:] == [f"hftrace: error: {path}: the sample at row 10, column 20 is 1e+39, beyond "
                     "float32 (heights are held in float32, |h| <= 3.4e38); 1 sample(s) in all. "
                     "If it marks voids, declare it as the nodata value; otherwise rescale the "
                     "heights"], done.stderr[-3000:]


_HEARTBEAT = """
import logging, sys
from bench.sweep_dask import _quiet_teardown, close_client, dask_client

def heartbeat_failure():
    logging.getLogger("distributed.worker").error(
        "Failed to communicate with scheduler during heartbeat.")

client, cluster = dask_client("local:1")
if sys.argv[1] == "quiet":
    client.run(_quiet_teardown)  # the first step of close_client
client.run(heartbeat_failure)
if sys.argv[1] == "quiet":
    close_client(client, cluster)
else:
    client.close()
    cluster.close()
"""


@pytest.mark.parametrize("mode", ["plain", "quiet"])
def test_local_cluster_teardown_does_not_print_a_heartbeat_failure(mode):
    """CI failed once on the test above: a worker's heartbeat in flight while the cluster
    closed logged "Failed to communicate with scheduler" and a traceback after the error
    line. The same record, logged by a worker once the quiet teardown has begun, is not
    printed; the plain close prints it (the race, made certain)."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = subprocess.run([sys.executable, "-c", _HEARTBEAT, mode], cwd=root,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    printed = "Failed to communicate with scheduler" in done.stderr
    assert printed == (mode == "plain"), done.stderr[-3000:]
    if mode == "quiet":
        assert done.stderr.strip() == "", done.stderr[-3000:]


_PORT_TAKEN = """
import socket

from bench.sweep_dask import close_client, dask_client

held = socket.socket()
try:
    held.bind(("", 8787))
    held.listen()
except OSError:
    pass  # taken already: by another process, which serves the test as well
client, cluster = dask_client("local:1")
close_client(client, cluster)
"""


def test_local_cluster_starts_quietly_when_port_8787_is_taken():
    """A CI run failed when another cluster held Dask's default port 8787: the scheduler's
    HTTP routes, bound there by default, moved and Dask warned on stderr. The local
    cluster binds them to a free port instead."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = subprocess.run([sys.executable, "-c", _PORT_TAKEN], cwd=root,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "already in use" not in done.stderr, done.stderr[-3000:]


def test_out_never_overwrites_the_input_and_takes_names_or_folders(tmp_path, capsys):
    path = write_tif(tmp_path / "dem.tif", dem())
    code, _, stderr = run(["svf", path, "--n-azimuths", "4", "--out", str(tmp_path / "dem")],
                          capsys)
    assert code == 2 and "is the input file" in stderr
    code, _, stderr = run(["svf", path, "--n-azimuths", "4", "--no-progress", "--out",
                           str(tmp_path / "named.tif")], capsys)
    assert code == 0 and (tmp_path / "named.tif").exists() and (tmp_path / "named.png").exists()
    code, _, stderr = run(["svf", path, "--n-azimuths", "4", "--no-progress", "--out",
                           str(tmp_path / "folder") + os.sep], capsys)
    assert code == 0 and (tmp_path / "folder" / "svf.tif").exists()
    code, _, stderr = run(["svf", path, "--n-azimuths", "4", "--no-progress", "--out",
                           "/proc/no/such/place"], capsys)
    assert code == 2 and "Traceback" not in stderr and len(stderr.strip().splitlines()) == 1


def test_observer_csv_with_a_byte_order_mark_keeps_every_line(tmp_path, capsys):
    path = write_tif(tmp_path / "dem.tif", dem())
    x, y = NORTH_UP @ (7 + 0.5, 5 + 0.5)
    (tmp_path / "bom.csv").write_bytes(f"\ufeff{x},{y}\r\n{x + 300},{y - 300}\r\n".encode())
    code, _, stderr = run(["viewshed", path, "--observers", str(tmp_path / "bom.csv"),
                           "--out", str(tmp_path / "v"), "--no-progress"], capsys)
    assert code == 0, stderr
    with rasterio.open(tmp_path / "v.tif") as src:
        assert src.tags()["observers"].count("[") == 3  # the list and two observers
    (tmp_path / "semi.csv").write_text(f"{x};{y}\n")
    code, _, stderr = run(["viewshed", path, "--observers", str(tmp_path / "semi.csv"),
                           "--out", str(tmp_path / "w"), "--no-progress"], capsys)
    assert code == 2 and "line 1" in stderr


def test_a_viewshed_needs_an_observer_and_negative_coordinates_parse(tmp_path, capsys):
    west = Affine(30.0, 0.0, -1000000.0, 0.0, -30.0, 4000000.0)  # negative eastings (EPSG:3857)
    path = write_tif(tmp_path / "west.tif", dem(), crs="EPSG:3857", transform=west)
    code, _, stderr = run(["viewshed", path, "--out", str(tmp_path / "a")], capsys)
    assert code == 2 and "at least one observer" in stderr
    x, y = west @ (4.5, 6.5)
    code, _, stderr = run(["viewshed", path, "--observer", f"{x},{y}", "--out",
                           str(tmp_path / "b"), "--no-progress"], capsys)
    assert code == 0, stderr


def test_a_geotransform_without_crs_is_refused(tmp_path, capsys):
    path = write_tif(tmp_path / "nocrs.tif", dem(), crs=None,
                     transform=Affine(1 / 3600, 0, -99.0, 0, -1 / 3600, 37.0))
    code, _, stderr = run(["svf", path, "--out", str(tmp_path / "a")], capsys)
    assert code == 2 and "no CRS" in stderr and "gdal_edit.py -a_srs" in stderr


def test_dataarray_products_carry_no_stale_nodata(tmp_path):
    rioxarray = pytest.importorskip("rioxarray")
    h = dem()
    h[3, 3] = -9999.0
    path = write_tif(tmp_path / "dem.tif", h, nodata=-9999.0)
    da_in = rioxarray.open_rasterio(path, masked=True).squeeze(drop=True)
    svf = algos.sky_view_factor(da_in, 4)
    assert math.isnan(svf.rio.nodata) and np.isnan(svf.values[3, 3])
    seen = algos.viewshed(da_in, (10.0, 10.0))
    assert seen.rio.nodata is None
    seen.astype(np.uint8).rio.to_raster(tmp_path / "seen.tif")
    svf.rio.to_raster(tmp_path / "svf.tif")
    with rasterio.open(tmp_path / "svf.tif") as src:
        assert src.read(1, masked=True).mask[3, 3]


# ---- hftrace render on a user's file: the API's image, or a refusal before any camera ----

UTM14 = "EPSG:32614"
RENDER_VIEW = ["--width", "64", "--height", "36", "--threads", "1"]
EXR_CHANNELS = ("Z", "N.x", "N.y", "N.z", "cellsVisited", "runsVisited")


def read_exr(path):
    import OpenEXR

    with OpenEXR.File(str(path)) as f:
        return {name: np.array(f.channels()[name].pixels) for name in EXR_CHANNELS}


def exr_of(image):
    """The channels ``hftrace render`` writes for ``image``, as float32 (what the file holds)."""
    return {name: np.asarray(value, dtype=np.float32) for name, value in (
        ("Z", image.depth), ("N.x", image.normal[..., 0]), ("N.y", image.normal[..., 1]),
        ("N.z", image.normal[..., 2]), ("cellsVisited", image.cells_visited),
        ("runsVisited", image.runs_visited))}


def assert_same_image(got, want):
    for name in EXR_CHANNELS:
        assert got[name].dtype == np.float32, name
        assert np.array_equal(got[name], want[name], equal_nan=True), name


@pytest.mark.parametrize("algorithm", ["runs", "zbuffer"])
def test_render_of_a_utm_dem_equals_the_api_in_cell_units(tmp_path, capsys, algorithm):
    """A GeoTIFF of metres on 30 m pixels (UTM 14N) renders through the CLI exactly as
    ``algos.render(load_file(...))``, and that image is the one of the heights divided
    by the pixel size (cell units), not of the metres read as cells (30x relief)."""
    h = dem()
    path = write_tif(tmp_path / "utm.tif", h, crs=UTM14)
    out = tmp_path / "img"
    code, stdout, stderr = run(["render", path, "--algorithm", algorithm, "--out", str(out)]
                               + RENDER_VIEW, capsys)
    assert code == 0, stderr
    field = datasets_gen.load_file(path)
    assert (field.spacing, field.unit) == (30.0, "m")
    want = algos.render(field, algorithm, width=64, height=36, threads=1)
    got = read_exr(str(out) + ".exr")
    assert_same_image(got, exr_of(want))
    from PIL import Image

    with Image.open(str(out) + ".png") as png:
        assert np.array_equal(np.asarray(png), np.round(want.rgb * 255).astype(np.uint8))
    # the reference in cell units, divided here: the same image, camera and shading too
    cells = algos.render(np.asarray(h, dtype=np.float64) / 30.0, algorithm, width=64,
                         height=36, threads=1)
    assert_same_image(got, exr_of(cells))
    assert np.array_equal(want.rgb, cells.rgb)
    assert 0.2 < np.isfinite(want.depth).mean() < 1.0  # terrain and sky in view
    # the old CLI's image (metres taken as cells) is another picture
    metres = algos.render(algos.Field(h), algorithm, width=64, height=36, threads=1)
    assert not np.array_equal(metres.depth, want.depth, equal_nan=True)


def test_render_of_a_generated_dataset_is_unchanged(tmp_path, capsys):
    """A generated field (cell units) renders as before: ``algos.render`` of its heights."""
    out = tmp_path / "fbm"
    code, _, stderr = run(["render", "fbm", "--size", "24", "--out", str(out)] + RENDER_VIEW,
                          capsys)
    assert code == 0, stderr
    heights = datasets_gen.load("fbm", size=24, seed=1).heights
    want = algos.render(algos.Field(heights), "runs", width=64, height=36, threads=1)
    assert_same_image(read_exr(str(out) + ".exr"), exr_of(want))


def test_render_refuses_rectangular_pixels_naming_them(tmp_path, capsys):
    """30 m x 20 m pixels: the CLI names the pixel size and the resampling that fixes it,
    the API names the pixel size; nothing is written."""
    path = write_tif(tmp_path / "rect.tif", dem(), crs=UTM14,
                     transform=Affine(30.0, 0.0, 500000.0, 0.0, -20.0, 4100000.0))
    out = tmp_path / "img"
    code, _, stderr = run(["render", path, "--out", str(out)] + RENDER_VIEW, capsys)
    assert code == 2
    assert "rectangular pixels (30 x 20 m)" in stderr and "gdalwarp -tr 20 20" in stderr
    assert path in stderr and stderr.count("\n") == 1
    assert not list(tmp_path.glob("img*"))
    field = datasets_gen.load_file(path)
    with pytest.raises(ValueError, match=r"rectangular pixels \(30 x 20 m\)"):
        algos.render(field, width=8, height=4)
    with pytest.raises(ValueError, match=r"rectangular pixels \(30 x 20 m\)"):
        algos.render(field, "zbuffer", width=8, height=4)


def test_render_of_a_dem_with_voids_says_fill_and_fill_renders(tmp_path, capsys):
    """Voids: the CLI names the file, the count, the first void and ``--fill``; the API
    names the void sample (never the camera), with or without a camera given. ``--fill
    min`` renders the API's image of the filled file."""
    h = dem()
    h[10:13, 20:24] = -9999.0
    path = write_tif(tmp_path / "void.tif", h, crs=UTM14, nodata=-9999.0)
    out = tmp_path / "img"
    code, _, stderr = run(["render", path, "--out", str(out)] + RENDER_VIEW, capsys)
    assert code == 2
    assert f"{path}: 12 void (nodata) samples, the first at (row 10, col 20)" in stderr
    assert "--fill min" in stderr and "position" not in stderr
    assert not list(tmp_path.glob("img*"))
    field = datasets_gen.load_file(path)
    for camera in ({}, dict(position=(-5.0, -5.0, 40.0), look_at=(20.0, 20.0, 10.0))):
        with pytest.raises(ValueError, match=r"sample \(row 10, col 20\) is nan \(nodata\)"):
            algos.render(field, width=8, height=4, **camera)
    code, _, stderr = run(["render", path, "--fill", "min", "--out", str(out)] + RENDER_VIEW,
                          capsys)
    assert code == 0, stderr
    want = algos.render(datasets_gen.load_file(path, nodata_policy="fill-min"), width=64,
                        height=36, threads=1)
    assert_same_image(read_exr(str(out) + ".exr"), exr_of(want))
    code, _, stderr = run(["render", "fbm", "--size", "16", "--fill", "min", "--out",
                           str(out)], capsys)
    assert code == 2 and "--fill: fills the voids of a file; fbm" in stderr


def test_curvature_on_a_npy_needs_its_unit(tmp_path, capsys):
    """A .npy has no CRS: --spacing alone names no unit, so --curvature is refused with
    the way to give it (--unit); with --unit the result is the API's."""
    np.save(tmp_path / "flat.npy", np.zeros((64, 64), np.float32))
    source = str(tmp_path / "flat.npy")
    common = ["viewshed", source, "--spacing", "100", "--observer-pixel", "0,0",
              "--observer-height", "0", "--mode", "angle", "--curvature", "--no-progress"]
    code, _, stderr = run(common + ["--out", str(tmp_path / "none")], capsys)
    assert code == 2 and "curvature: needs spacing in a real unit" in stderr \
        and "--unit" in stderr
    code, _, stderr = run(common + ["--unit", "ft", "--out", str(tmp_path / "ft")], capsys)
    assert code == 0, stderr
    with rasterio.open(tmp_path / "ft.tif") as src:
        got = src.read(1)[63, 63]
    want = algos.viewshed(algos.HeightField(np.zeros((64, 64)), spacing=100, unit="ft"),
                          (0, 0), mode="angle", curvature=True, observer_height=0)[63, 63]
    assert got == pytest.approx(math.degrees(want), rel=1e-6)
    assert math.degrees(want) == pytest.approx(math.degrees(-0.000182474), abs=1e-7)
    with pytest.raises(SystemExit) as exit_:  # argparse: not one of the choices
        main(common + ["--unit", "furlong", "--out", str(tmp_path / "x")])
    assert exit_.value.code == 2 and "--unit" in capsys.readouterr().err


def test_a_gcp_georeferenced_dem_is_refused_not_called_ungeoreferenced(tmp_path, capsys):
    """A GeoTIFF placed by ground control points only was read as cell units, with a note
    that it "has no georeferencing"; now one line with the gdalwarp command."""
    from rasterio.control import GroundControlPoint as GCP

    h = dem()
    rows, cols = h.shape
    gcps = [GCP(row=r, col=c, x=600000.0 + 30 * c, y=3650000.0 - 30 * r)
            for r, c in ((0, 0), (0, cols), (rows, 0), (rows, cols))]
    path = str(tmp_path / "gcp.tif")
    with rasterio.open(path, "w", driver="GTiff", height=rows, width=cols, count=1,
                       dtype="float32", gcps=gcps, crs=UTM15) as dst:
        dst.write(h, 1)
    for extra in ([], ["--dask", "local:1", "--max-distance", "300", "--chunk", "16"]):
        code, _, stderr = run(["svf", path, "--n-azimuths", "4", "--out", str(tmp_path / "s"),
                               "--no-progress", *extra], capsys)
        assert code == 2, stderr
        assert "ground control points" in stderr and \
            f"gdalwarp -t_srs EPSG:32615 -r bilinear {path}" in stderr
        assert "has no georeferencing" not in stderr and "Traceback" not in stderr
        assert len(stderr.strip().splitlines()) == 1


# ---- a one-row or one-column raster: a line, which the viewshed takes (as the API) -----

def _line_heights(shape):
    """Heights along a line: a ridge and a valley, so that some vertices are hidden."""
    n = max(shape)
    t = np.arange(n, dtype=np.float64)
    return (20.0 * np.sin(t / 3.0) + 0.5 * t).astype(np.float32).reshape(shape)


@pytest.mark.parametrize("shape", [(1, 40), (40, 1)])
def test_viewshed_of_a_one_row_or_column_npy_equals_the_api(tmp_path, capsys, shape):
    """Found by a new user's trial: ``hftrace viewshed`` refused a one-row raster ("needs at
    least 2 x 2 samples"), which ``algos.viewshed`` takes as a line."""
    h = _line_heights(shape)
    path = str(tmp_path / "line.npy")
    np.save(path, h)
    at = (7, 0) if shape[0] == 1 else (0, 7)
    for extra, api in (([], {}), (["--max-distance", "12"], {"max_distance": 12.0}),
                       (["--observer-height", "30"], {"observer_height": 30.0}),
                       (["--mode", "angle"], {"mode": "angle"}),
                       (["--mode", "ground"], {"mode": "ground"})):
        out = str(tmp_path / "vs")
        code, stdout, stderr = run(["viewshed", path, "--observer-pixel", f"{at[0]},{at[1]}",
                                    "--out", out, "--no-progress", *extra], capsys)
        assert code == 0, stderr
        want = algos.viewshed(h, at, **api)
        assert want.shape == shape
        if "mode" in api:  # files hold degrees; the API gives radians
            want = (np.degrees(want) if api["mode"] == "angle" else want).astype(np.float32)
        else:
            assert 0 < want.sum() < want.size  # seen and hidden vertices
            want = want.astype(np.uint8)
        with rasterio.open(out + ".tif") as src:
            assert (src.height, src.width) == shape
            np.testing.assert_array_equal(src.read(1), want)
        import OpenEXR

        with OpenEXR.File(out + ".exr") as f:
            exr = np.array(f.channels()["Y"].pixels)
        np.testing.assert_array_equal(exr, want.astype(np.float32))
        assert f"{shape[0]}x{shape[1]}" in stdout


def test_viewshed_of_a_one_row_geotiff_keeps_its_place_north_up_and_south_up(tmp_path, capsys):
    h = _line_heights((1, 30))
    x, y = NORTH_UP @ (12 + 0.5, 0 + 0.5)  # the centre of pixel 12
    want = algos.viewshed(h, (12, 0), spacing=30.0, max_distance=400.0)
    south_up = Affine(30.0, 0.0, 600000.0, 0.0, 30.0, 3650000.0)
    for transform in (NORTH_UP, south_up):
        path = write_tif(tmp_path / "line.tif", h, transform=transform)
        x, y = transform @ (12 + 0.5, 0 + 0.5)
        for observer in (["--observer", f"{x},{y}"], ["--observer-pixel", "12,0"]):
            out = str(tmp_path / "vs")
            code, _, stderr = run(["viewshed", path, *observer, "--max-distance", "400",
                                   "--out", out, "--no-progress"], capsys)
            assert code == 0, stderr
            with rasterio.open(out + ".tif") as src:
                assert src.transform == transform and (src.height, src.width) == (1, 30)
                assert src.tags()["observers"] == "[[12.0, 0.0]]"
                np.testing.assert_array_equal(src.read(1), want.astype(np.uint8))


def test_an_observer_off_the_line_is_refused_as_the_api_refuses_it(tmp_path, capsys):
    h = _line_heights((1, 20))
    with pytest.raises(ValueError) as api:
        algos.viewshed(h, [(3.0, 0.0), (4.5, 0.5)])
    assert str(api.value).startswith("observer[1]: (4.5, 0.5) outside the footprint [0, 19] x "
                                     "[0, 0] of a one-row raster (a line)")
    # map coordinates half a pixel south of the line: the API's message, same coordinates
    path = write_tif(tmp_path / "line.tif", h)
    on, off = NORTH_UP @ (3 + 0.5, 0 + 0.5), NORTH_UP @ (4.5 + 0.5, 0.5 + 0.5)
    code, _, stderr = run(["viewshed", path, "--observer", f"{on[0]},{on[1]}", "--observer",
                           f"{off[0]},{off[1]}", "--out", str(tmp_path / "vs"),
                           "--no-progress"], capsys)
    assert code == 2 and stderr.strip().splitlines()[-1] == f"hftrace: error: {api.value}"
    # a pixel beyond the line is refused as any pixel outside a file, naming the line's
    # own rows (not the doubled field's)
    np.save(tmp_path / "line.npy", h)
    code, _, stderr = run(["viewshed", str(tmp_path / "line.npy"), "--observer-pixel", "3,0",
                           "--observer-pixel", "4.5,0.5", "--out", str(tmp_path / "vs"),
                           "--no-progress"], capsys)
    assert code == 2 and stderr.strip().splitlines()[-1] == (
        "hftrace: error: observer pixel 4.5,0.5: outside line.npy, whose columns are 0..19 "
        "and rows 0..0 (row 0 north)")
    assert not list(tmp_path.glob("vs.*"))


def test_one_sample_is_refused_by_the_api_and_the_command_naming_its_shape(tmp_path, capsys):
    """The API said "got (2, 1)" of a (1, 1) array, a shape the caller never gave."""
    with pytest.raises(ValueError, match=r"^heights: one sample \(shape \(1, 1\)\) is neither "
                                         "a line nor a field"):
        algos.viewshed(np.zeros((1, 1)), (0, 0))
    path = str(tmp_path / "one.npy")
    np.save(path, np.zeros((1, 1), np.float32))
    code, _, stderr = run(["viewshed", path, "--observer-pixel", "0,0", "--out",
                           str(tmp_path / "vs"), "--no-progress"], capsys)
    assert code == 2 and stderr.strip().splitlines()[-1] == (
        f"hftrace: error: {path}: a height field needs at least 2 x 2 samples, got (1, 1)")


def test_the_other_products_and_dask_refuse_a_line_saying_where_it_is_taken(tmp_path, capsys):
    """The same line in memory and with --dask (the readers said it differently: the
    window-by-window one named "heights" and "each side must be in [2, 16777216]")."""
    path = str(tmp_path / "line.npy")
    np.save(path, _line_heights((1, 20)))
    tif = write_tif(tmp_path / "line.tif", _line_heights((1, 20)))
    for source in (path, tif):
        for command in (["horizon", source, "--max-distance", "5"],
                        ["horizon", source, "--max-distance", "5", "--dask", "local:1"],
                        ["viewshed", source, "--observer-pixel", "3,0", "--max-distance", "5",
                         "--dask", "local:1"]):
            code, _, stderr = run([*command, "--out", str(tmp_path / "p"), "--no-progress"],
                                  capsys)
            assert code == 2 and stderr.strip().splitlines()[-1] == (
                f"hftrace: error: {source}: a height field needs at least 2 x 2 samples, got "
                "(1, 20); a one-row or one-column file is a line, which only the viewshed "
                "takes, in memory (load_file(lines=True); hftrace viewshed without --dask)"), \
                (command, stderr)
            assert not list(tmp_path.glob("p.*"))


def test_the_observers_tag_counts_rows_from_the_north_so_it_can_be_given_back(tmp_path, capsys):
    # a south-up file: stored row 0 is the southern row; --observer-pixel counts from the
    # north, and the tag must too (it recorded the stored row before)
    h = dem(rows=12, cols=14)
    south_up = Affine(30.0, 0.0, 600000.0, 0.0, 30.0, 3650000.0)
    path = write_tif(tmp_path / "south.tif", h, transform=south_up)
    tags, images = [], []
    for pixel in ("3,2,1.5", None):
        if pixel is None:  # the tag given back
            col, row, height = tags[0]
            pixel = f"{col:g},{row:g},{height:g}"
        out = str(tmp_path / f"vs{len(tags)}")
        code, _, stderr = run(["viewshed", path, "--observer-pixel", pixel, "--out", out,
                               "--no-progress"], capsys)
        assert code == 0, stderr
        with rasterio.open(out + ".tif") as src:
            tags.append(eval(src.tags()["observers"])[0])
            images.append(src.read(1))
    assert tags[0] == [3.0, 2.0, 1.5] and tags[1] == tags[0]
    np.testing.assert_array_equal(images[1], images[0])
    # the pixel is the stored row rows - 1 - 2 of the south-up array
    field = datasets_gen.load_file(path)
    assert not field.north_up
    want = algos.viewshed(field, (3, 12 - 1 - 2), observer_height=1.5)
    np.testing.assert_array_equal(images[0], want.astype(np.uint8))  # the file keeps its orientation


def test_undeclared_minus_9999_gets_a_note_and_nodata_declares_it(tmp_path, capsys):
    """A file whose voids hold -9999 without a nodata tag: render and the products take
    them as heights but say so on stderr with the option that declares them; --nodata
    -9999 makes them voids (the render then needs --fill, the products leave them nodata),
    equal to load_file(..., nodata=-9999)."""
    h = dem()
    h[10:13, 20:24] = -9999.0
    path = write_tif(tmp_path / "undeclared.tif", h, crs=UTM14)  # no nodata tag
    found = datasets_gen.undeclared_nodata(datasets_gen.load_file(path))
    assert found == (-9999.0, 12, (10, 20))
    declared = datasets_gen.load_file(path, nodata=-9999.0)
    assert datasets_gen.undeclared_nodata(declared) is None
    assert np.count_nonzero(declared.nodata_mask) == 12
    assert datasets_gen.undeclared_nodata(datasets_gen.load_file(write_tif(
        tmp_path / "plain.tif", dem(), crs=UTM14))) is None
    note = (f"hftrace: note: {path} declares no nodata, but 12 samples equal -9999 (the "
            "first at row 10, col 20), a common nodata value; they are taken as heights. If "
            "they are voids, give --nodata -9999")
    out = tmp_path / "img"
    code, _, stderr = run(["render", path, "--out", str(out)] + RENDER_VIEW, capsys)
    assert code == 0 and note in stderr
    code, _, stderr = run(["render", path, "--nodata", "-9999", "--out", str(out)]
                          + RENDER_VIEW, capsys)
    assert code == 2 and "12 void (nodata) samples" in stderr and "note" not in stderr
    code, _, stderr = run(["render", path, "--nodata", "-9999", "--fill", "min", "--out",
                           str(out)] + RENDER_VIEW, capsys)
    assert code == 0 and "note" not in stderr, stderr
    want = algos.render(datasets_gen.load_file(path, nodata=-9999.0, nodata_policy="fill-min"),
                        width=64, height=36, threads=1)
    assert_same_image(read_exr(str(out) + ".exr"), exr_of(want))
    code, _, stderr = run(["svf", path, "--out", str(tmp_path / "svf"), "--no-progress"],
                          capsys)
    assert code == 0 and note in stderr
    code, _, stderr = run(["svf", path, "--nodata", "-9999", "--out", str(tmp_path / "svf"),
                           "--no-progress"], capsys)
    assert code == 0 and "note" not in stderr, stderr
    with rasterio.open(tmp_path / "svf.tif") as src:
        got = src.read(1, masked=True)
    np.testing.assert_array_equal(np.ma.getmaskarray(got), declared.nodata_mask)
    code, _, stderr = run(["render", "fbm", "--size", "16", "--nodata", "-9999", "--out",
                           str(out)], capsys)
    assert code == 2 and "--nodata: declares the voids of a file; fbm" in stderr
