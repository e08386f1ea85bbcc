"""datasets_gen: deterministic generators, the DEM, loaders, the cache and ray sets."""
import hashlib
import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

import algos
import datasets_gen
from datasets_gen import cache, fields, loaders
from datasets_gen import rays as raysets

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # tests/
HASHES = json.load(open(os.path.join(HERE, "data", "field_hashes.json")))


def sha(array):
    return hashlib.sha256(np.ascontiguousarray(array, dtype="<f4").tobytes()).hexdigest()


# ---- generators ----------------------------------------------------------------------
@pytest.mark.parametrize("name", list(fields.GENERATORS))
def test_committed_hashes(name):
    """Frozen outputs: a change here must bump the generator's version and this table."""
    h = fields.generate(name, tuple(HASHES["size"]), seed=HASHES["seed"])
    assert sha(h) == HASHES["sha256"][name], f"{name} changed its output"


def test_same_bytes_in_another_process():
    code = ("import hashlib, json; from datasets_gen import fields; "
            "print(json.dumps({n: hashlib.sha256(fields.generate(n, (40, 30), seed=5)"
            ".astype('<f4').tobytes()).hexdigest() for n in fields.GENERATORS}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=os.path.dirname(HERE))
    other = json.loads(out.stdout)
    mine = {n: sha(fields.generate(n, (40, 30), seed=5)) for n in fields.GENERATORS}
    assert other == mine


@pytest.mark.parametrize("name", list(fields.GENERATORS))
@pytest.mark.parametrize("size", [2, (3, 2), (33, 47)])
def test_shapes_dtype_and_range(name, size):
    h = fields.generate(name, size, seed=1)
    rows, cols = (size, size) if np.ndim(size) == 0 else size
    assert h.shape == (rows, cols) and h.dtype == np.float32 and h.flags.c_contiguous
    assert np.all(np.isfinite(h))
    assert np.all(np.abs(h) < 1e4)


def test_generator_character():
    assert np.all(fields.generate("flat", 16, height=3.0) == 3.0)
    t = fields.generate("terraces", 128, seed=2, levels=8)
    assert len(np.unique(t)) <= 9, "terraces: a few flat levels"
    u = fields.generate("uniform", 128, seed=2, low=1.0, high=2.0)
    assert 1.0 <= u.min() and u.max() < 2.0 and abs(u.mean() - 1.5) < 0.01
    s = fields.generate("spike", 65, height=10.0, radius=8.0)
    assert s.max() == 10.0 and s[32, 32] == 10.0 and s[0, 0] == 0.0
    r = fields.generate("ridged", 64, seed=1, amplitude=10.0)
    assert 0.0 <= r.min() and r.max() <= 10.0
    assert fields.generate("fbm", 64, seed=1).tobytes() != fields.generate("fbm", 64, seed=2).tobytes()


def test_det_sin_is_accurate():
    x = np.linspace(-1000, 1000, 200001)
    assert np.max(np.abs(fields.det_sin(x) - np.sin(x))) < 1e-12
    assert np.max(np.abs(fields.det_cos(x) - np.cos(x))) < 1e-12


def test_sines16_frequencies_follow_the_seed():
    s = fields.sines16_frequencies()
    assert len(s) == 16
    assert s[0] == ((0x1D4E) / 65536 - 0.5, (0x58F9) / 65536 - 0.5, (0x129F) / 65536 - 0.5)
    assert s[1][0] == ((0x1D4E1D4E >> 1) & 0xFFFF) / 65536 - 0.5


def test_size_limits_and_bad_parameters():
    assert fields.generate("uniform", (fields.MAX_SIDE, 2), seed=0).shape == (fields.MAX_SIDE, 2)
    with pytest.raises(ValueError, match="size: size = 1"):
        fields.generate("fbm", 1)
    with pytest.raises(ValueError, match=r"size: size\[1\] = 32769"):
        fields.generate("flat", (2, fields.MAX_SIDE + 1))
    with pytest.raises(ValueError, match="name: unknown generator 'nope'"):
        fields.generate("nope")
    with pytest.raises(ValueError, match="oct: not a parameter of fbm"):
        fields.generate("fbm", 8, oct=3)
    with pytest.raises(ValueError, match="octaves: fbm needs an integer"):
        fields.generate("fbm", 8, octaves=0)
    with pytest.raises(TypeError, match="scale: expected a number"):
        fields.generate("fbm", 8, scale="big")
    with pytest.raises(ValueError, match="seed"):
        fields.generate("fbm", 8, seed=-1)
    with pytest.raises(ValueError, match="low, high"):
        fields.generate("uniform", 8, low=2.0, high=1.0)


# ---- the DEM ---------------------------------------------------------------------------
def test_jacksboro(tmp_path):
    f = datasets_gen.load("jacksboro", cache_dir=tmp_path)
    assert f.shape == (428, 403)
    assert 74.3 < f.spacing < 74.5 and f.unit == "m"
    metres = f.heights.astype(np.float64) * f.spacing
    # bilinear resampling stays inside the source range 236..1076 m and keeps its shape
    assert 236 - 1e-3 <= metres.min() < 260 and 1000 < metres.max() <= 1076 + 1e-3
    big = datasets_gen.load("jacksboro", size=2048, cache_dir=tmp_path)
    assert max(big.shape) == 2048 and abs(big.heights.max() * big.spacing - metres.max()) < 1


# ---- the cache -------------------------------------------------------------------------
def test_cache_hits_and_no_cache(tmp_path):
    before = cache.CacheStats.misses, cache.CacheStats.hits
    a = datasets_gen.load("fbm", size=64, seed=3, cache_dir=tmp_path)
    b = datasets_gen.load("fbm", size=64, seed=3, cache_dir=tmp_path)
    assert (cache.CacheStats.misses - before[0], cache.CacheStats.hits - before[1]) == (1, 1)
    assert np.array_equal(a.heights, b.heights)
    c = datasets_gen.load("fbm", size=64, seed=3, octaves=2, cache_dir=tmp_path)
    assert not np.array_equal(a.heights, c.heights), "parameters are part of the key"
    n_files = len(os.listdir(tmp_path))
    datasets_gen.load("fbm", size=65, seed=3, use_cache=False, cache_dir=tmp_path)
    assert len(os.listdir(tmp_path)) == n_files


def test_corrupt_entries_are_rebuilt(tmp_path):
    good = datasets_gen.load("ridges", size=32, cache_dir=tmp_path).heights
    (data,) = [p for p in tmp_path.iterdir() if p.suffix == ".npy"]
    raw = bytearray(data.read_bytes())
    raw[-5] ^= 0xFF  # a flipped bit in the payload
    data.write_bytes(bytes(raw))
    with pytest.warns(RuntimeWarning, match="rebuilding corrupt entry"):
        again = datasets_gen.load("ridges", size=32, cache_dir=tmp_path).heights
    assert np.array_equal(again, good)
    data.write_bytes(b"truncated")
    with pytest.warns(RuntimeWarning):
        assert np.array_equal(datasets_gen.load("ridges", size=32, cache_dir=tmp_path).heights, good)


def test_leftover_temporary_file_is_harmless(tmp_path):
    (tmp_path / ".tmp-abc.npy").write_bytes(b"half-written by a killed process")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        h = datasets_gen.load("flat", size=8, cache_dir=tmp_path).heights
    assert h.shape == (8, 8)


# ---- loaders ---------------------------------------------------------------------------
@pytest.fixture
def terrain():
    return fields.generate("fbm", (20, 30), seed=4).astype(np.float64) + 100.0


def test_npy_npz_round_trip(tmp_path, terrain):
    np.save(tmp_path / "a.npy", terrain)
    f = loaders.load_file(tmp_path / "a.npy", spacing=2.0, vertical_scale=3.0)
    # heights stay in the unit of the spacing (they used to become cells)
    assert np.allclose(f.heights, terrain * 3.0, rtol=1e-6) and f.spacing == 2.0
    np.savez(tmp_path / "b.npz", other=terrain[:2], heights=terrain)
    assert np.allclose(loaders.load_file(tmp_path / "b.npz").heights, terrain, rtol=1e-6)
    np.savez(tmp_path / "c.npz", x=terrain, y=terrain)
    with pytest.raises(ValueError, match="key: .* holds x, y"):
        loaders.load_file(tmp_path / "c.npz")
    assert np.allclose(loaders.load_file(tmp_path / "c.npz", key="y").heights, terrain, rtol=1e-6)


def test_geotiff_round_trip_with_tags(tmp_path, terrain):
    """(Since the GIS round: written with rasterio; voids are the default policy and
    heights stay in metres.)"""
    import rasterio
    from affine import Affine

    data = terrain.astype(np.float32)
    data[3, 4] = -9999.0
    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", height=20, width=30,
                       count=1, dtype="float32", crs="EPSG:32617", nodata=-9999.0,
                       transform=Affine(30.0, 0, 500000.0, 0, -30.0, 4000000.0)) as dst:
        dst.write(data, 1)
    with pytest.raises(ValueError, match=r"dem.tif: 1 nodata.*\(row 3, col 4\)"):
        loaders.load_file(tmp_path / "dem.tif", nodata_policy="error")
    voids = loaders.load_file(tmp_path / "dem.tif")
    assert np.isnan(voids.heights[3, 4]) and voids.nodata_mask.sum() == 1
    f = loaders.load_file(tmp_path / "dem.tif", nodata_policy="fill-min")
    assert f.spacing == 30.0 and f.unit == "m"
    expected = data.astype(np.float64)
    expected[3, 4] = np.delete(expected.ravel(), 3 * 30 + 4).min()
    assert np.allclose(f.heights, expected, rtol=1e-6)
    f = loaders.load_file(tmp_path / "dem.tif", nodata_policy="fill", fill_value=0.0)
    assert f.heights[3, 4] == 0.0


@pytest.mark.parametrize("bits", [8, 16])
def test_png_round_trip(tmp_path, bits):
    from PIL import Image

    dtype = np.uint8 if bits == 8 else np.uint16
    data = (np.arange(12 * 9).reshape(12, 9) * (3 if bits == 8 else 600)).astype(dtype)
    Image.fromarray(data).save(tmp_path / "h.png")
    f = loaders.load_file(tmp_path / "h.png")
    assert np.array_equal(f.heights, data.astype(np.float32))


def test_jpeg_and_colour_images(tmp_path):
    from PIL import Image

    smooth = np.tile(np.linspace(0, 250, 32), (24, 1)).astype(np.uint8)
    Image.fromarray(smooth).save(tmp_path / "h.jpg", quality=95)
    f = loaders.load_file(tmp_path / "h.jpg")
    assert f.shape == (24, 32) and np.abs(f.heights - smooth).max() < 8  # lossy
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(tmp_path / "rgb.png")
    with pytest.raises(ValueError, match="rgb.png: image mode 'RGB' is not"):
        loaders.load_file(tmp_path / "rgb.png")


def test_exr_round_trip(tmp_path, terrain):
    import OpenEXR

    data = terrain.astype(np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"Y": data}) as f:
        f.write(str(tmp_path / "one.exr"))
    assert np.array_equal(loaders.load_file(tmp_path / "one.exr").heights, data)
    with OpenEXR.File(header, {"Y": data, "Z": data * 2}) as f:
        f.write(str(tmp_path / "two.exr"))
    with pytest.raises(ValueError, match="2 channels"):
        loaders.load_file(tmp_path / "two.exr")
    assert np.array_equal(loaders.load_file(tmp_path / "two.exr", channel="Z").heights, data * 2)


def test_bad_files(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        loaders.load_file(tmp_path / "missing.npy")
    (tmp_path / "x.dem").write_bytes(b"")
    with pytest.raises(ValueError, match="unknown extension '.dem'"):
        loaders.load_file(tmp_path / "x.dem")
    (tmp_path / "junk.npy").write_bytes(b"not numpy")
    with pytest.raises(ValueError, match="junk.npy: cannot be read"):
        loaders.load_file(tmp_path / "junk.npy")
    (tmp_path / "junk.tif").write_bytes(b"II*\x00garbage")
    with pytest.raises(ValueError, match="junk.tif: cannot be read"):
        loaders.load_file(tmp_path / "junk.tif")
    np.save(tmp_path / "line.npy", np.zeros(5))
    with pytest.raises(ValueError, match="expected a 2D height array"):
        loaders.load_file(tmp_path / "line.npy")
    np.save(tmp_path / "thin.npy", np.zeros((1, 5)))
    with pytest.raises(ValueError, match="at least 2 x 2"):
        loaders.load_file(tmp_path / "thin.npy")
    bad = np.ones((4, 4))
    bad[2, 1] = np.nan
    np.save(tmp_path / "nan.npy", bad)
    with pytest.raises(ValueError, match=r"nan.npy: .*\(row 2, col 1\)"):
        loaders.load_file(tmp_path / "nan.npy", nodata_policy="error")
    # the default keeps it as a void
    assert loaders.load_file(tmp_path / "nan.npy").nodata_mask[2, 1]
    np.save(tmp_path / "ok.npy", np.ones((4, 4)))
    with pytest.raises(ValueError, match="spacing"):
        loaders.load_file(tmp_path / "ok.npy", spacing=0.0)
    with pytest.raises(ValueError, match="nodata_policy"):
        loaders.load_file(tmp_path / "ok.npy", nodata_policy="ignore")


# ---- ray sets --------------------------------------------------------------------------
@pytest.mark.parametrize("r", [1, 1.5, 2, 3, 5, 8, 13, 25, 50, 100])
def test_by_run_length_gives_the_requested_r(r):
    rs = raysets.by_run_length(r, 64, (512, 512), seed=3)
    runs = algos.traverse("runs", rs.origins, rs.directions, (512, 512), output="runs")
    measured = raysets.mean_run_length([p[:, 1] for p in runs])
    assert measured == pytest.approx(r, rel=0.02)
    octants = {(np.sign(d[0]), np.sign(d[1]), abs(d[1]) > abs(d[0])) for d in rs.directions}
    assert len(octants) == 8 or r == 1


def test_by_run_length_random_and_3d():
    rs = raysets.by_run_length("random", 100, (64, 64), seed=1, elevation=10.0, height=50.0)
    assert rs.origins.shape == (100, 3) and np.all(rs.origins[:, 2] == 50.0)
    assert np.allclose(np.linalg.norm(rs.directions[:, :2], axis=1), 1.0)
    assert np.allclose(rs.directions[:, 2], -np.tan(np.radians(10.0)))
    again = raysets.by_run_length("random", 100, (64, 64), seed=1, elevation=10.0, height=50.0)
    assert np.array_equal(rs.directions, again.directions)
    with pytest.raises(ValueError, match="r: "):
        raysets.by_run_length(0.5, 4, (8, 8), seed=1)
    with pytest.raises(ValueError, match="seed"):
        raysets.by_run_length(2, 4, (8, 8), seed=None)


def test_pinhole():
    rs = raysets.pinhole((0, 0, 10), (0, 100, 10), 90, 3, 3)
    assert rs.origins.shape == (9, 3)
    assert np.allclose(rs.directions[4], [0, 1, 0])          # the centre pixel
    assert rs.directions[0, 2] > 0 and rs.directions[0, 0] < 0  # top-left looks up-left
    with pytest.raises(ValueError, match="look_at"):
        raysets.pinhole((0, 0, 0), (0, 0, 0), 60, 2, 2)


def test_parallel_rational_is_exact():
    rs = raysets.parallel(10, (64, 64), seed=2, rational=(17, 41), octant=5)
    assert np.all(rs.directions == rs.directions[0])
    assert sorted(np.abs(rs.directions[0]).tolist()) == [17.0, 41.0]
    paths = algos.traverse("runs_periodic", rs.origins, rs.directions, (64, 64))
    exact = algos.traverse("runs", rs.origins, rs.directions, (64, 64))
    assert np.array_equal(paths.cells, exact.cells)
    with pytest.raises(ValueError, match="exactly one"):
        raysets.parallel(3, (8, 8), seed=1)


def test_adversarial_families_exact_kernels_match_reference():
    fams = raysets.adversarial((40, 30), seed=9, n=32)
    assert {"axis_parallel", "diagonals", "through_vertices", "origins_on_lines",
            "origins_on_corners", "near_rational", "golden", "sqrt2", "vertical",
            "first_run_clipped"} <= set(fams)
    for name, rs in fams.items():
        oq, dq = algos.quantize(rs.origins, rs.directions)
        expected = [algos.reference_cells(oq[k], dq[k], (40, 30)) for k in range(len(rs))]
        for kernel in ("midpoint", "runs"):
            got = algos.traverse(kernel, rs.origins, rs.directions, (40, 30))
            assert [[tuple(c) for c in p.tolist()] for p in got] == expected, (name, kernel)
    firsts = algos.traverse("runs", fams["first_run_clipped"].origins,
                            fams["first_run_clipped"].directions, (40, 30), output="runs")
    first_lengths = {int(abs(p[0, 2] - p[0, 1])) for p in firsts}
    assert first_lengths == {0, 1}, "first runs of 0 and 1 cells (8-connected)"


# ---- the CLI ---------------------------------------------------------------------------
def test_cli_datasets(tmp_path, capsys):
    from bench.cli import main

    assert main(["datasets", "list"]) == 0
    listing = capsys.readouterr().out
    for name in list(fields.GENERATORS) + ["jacksboro"]:
        assert name in listing
    for row in datasets_gen.catalogue():  # whole sentences, not the docstring's first line
        assert row["summary"].endswith(".") and row["summary"] in listing, row["name"]
    assert main(["datasets"]) == 0  # alone, it lists them as `datasets list` does
    assert capsys.readouterr().out == listing
    png = tmp_path / "p.png"
    assert main(["datasets", "show", "terraces", "--size", "40", "--seed", "2", "--png",
                 str(png), "--cache-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert sha(fields.generate("terraces", 40, seed=2)) in out
    assert png.stat().st_size > 100
    assert main(["datasets", "show", "fbm", "--param", "octaves=0", "--no-cache"]) == 2
    assert "octaves" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["fbm", "ridged", "terraces"])
def test_banded_generators_give_the_whole_field_bytes(name):
    """Bands on every thread count give the bytes of one whole-field call."""
    rows, cols = 700, 513  # several bands of BAND_SAMPLES, the last one short
    whole = np.ascontiguousarray(np.asarray(
        fields.GENERATORS[name].function(rows, cols, 3), dtype=np.float64), dtype=np.float32)
    assert rows * cols >= 2 * fields.BAND_SAMPLES
    for threads in (1, 2, 3):
        banded = fields.generate(name, (rows, cols), seed=3, threads=threads)
        assert sha(banded) == sha(whole), (name, threads)
