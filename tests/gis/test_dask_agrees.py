"""The terrain commands in memory and with ``--dask`` on the same small file: the same
product (bit-identical GeoTIFF bands, the same nodata and tags), the documented set of files
(``--dask`` writes no EXR: docs/gis.md), and the same one-line errors. Found by a new user's
trial (docs/notes closing5, section 6): a ``.npy`` with +-inf was a void in memory but
refused by ``--dask``, and the ``--dask`` files lacked the EXR and some tags."""
import contextlib
import glob
import io

import numpy as np
import pytest

import datasets_gen
from bench.cli import main

rasterio = pytest.importorskip("rasterio")
pytest.importorskip("distributed")

#: product -> its options (every product on the same field, a short distance)
PRODUCTS = {
    "horizon": ["--azimuths", "0,90,200"],
    "svf": ["--n-azimuths", "8"],
    "openness": ["--n-azimuths", "8", "--kind", "negative"],
    "shadows": ["--azimuth", "300", "--elevation", "20"],
    "viewshed": ["--observer-pixel", "20,30", "--observer-pixel", "40,41,3"],
}
DASK = ["--dask", "local:1", "--chunk", "32"]


def run(args):
    """(exit code, stdout, stderr lines) of ``hftrace ARGS`` in this process."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(args)
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), [x for x in err.getvalue().splitlines() if x.strip()]


def field_with_infinities(path):
    """A 64 x 64 fBm field (heights in cells, a few tens of cells of relief) with +inf and
    -inf samples: voids by the loaders' default nodata policy ("void")."""
    h = (datasets_gen.load("fbm", size=(64, 64), seed=3).heights * 8.0).astype(np.float32)
    h[10, 20] = np.inf
    h[30, 31] = -np.inf
    h[63, 0] = np.nan
    np.save(path, h)
    return str(path)


@pytest.fixture(scope="module")
def products(tmp_path_factory):
    """Every product of the field, in memory and with --dask: {(kind, path): (code,
    stdout, stderr, files written, bands, profile, tags, band descriptions)}."""
    d = tmp_path_factory.mktemp("agree")
    source = field_with_infinities(d / "inf.npy")
    out = {}
    for kind, options in PRODUCTS.items():
        for path, extra in (("memory", []), ("dask", DASK)):
            prefix = str(d / f"{kind}_{path}")
            code, stdout, stderr = run([kind, source, "--max-distance", "5", "--no-progress",
                                        "--out", prefix, *options, *extra])
            files = sorted(p[len(prefix):] for p in glob.glob(prefix + ".*"))
            bands = profile = tags = names = None
            if code == 0:
                with rasterio.open(prefix + ".tif") as src:
                    bands, tags, names = src.read(), src.tags(), src.descriptions
                    profile = (src.dtypes, src.nodata, src.crs, src.transform)
            out[kind, path] = (code, stdout, stderr, files, bands, profile, tags, names)
    return out


@pytest.mark.parametrize("kind", list(PRODUCTS))
def test_infinities_are_voids_on_both_paths_and_the_products_are_equal(products, kind):
    memory, dask = products[kind, "memory"], products[kind, "dask"]
    assert memory[0] == 0, memory[2]
    assert dask[0] == 0, dask[2]
    np.testing.assert_array_equal(dask[4], memory[4])  # bit-identical, NaN where NaN
    assert repr(dask[5]) == repr(memory[5])  # dtypes, nodata (NaN too), CRS, transform
    bands = memory[4].astype(np.float64)
    nodata = memory[5][1]
    # the three voids (+inf, -inf, NaN) are nodata in the file (a .npy is north up)
    for row, col in ((10, 20), (30, 31), (63, 0)):
        value = bands[:, row, col]
        assert (np.isnan(value) if np.isnan(nodata) else value == nodata).all(), (row, col)


@pytest.mark.parametrize("kind", list(PRODUCTS))
def test_both_paths_record_the_same_tags_and_band_names(products, kind):
    """Every tag (the viewshed's observers too) but ``paths``, each azimuth's algorithm: a
    statistic of an in-memory call, which a tiled run does not return (docs/gis.md)."""
    memory, dask = products[kind, "memory"], products[kind, "dask"]
    tags = dict(memory[6])
    if kind != "viewshed":
        assert tags.pop("paths")
    assert dask[6] == tags
    assert dask[7] == memory[7]


@pytest.mark.parametrize("kind", list(PRODUCTS))
def test_the_documented_files_are_written(products, kind):
    """In memory: GeoTIFF, PNG and EXR; --dask: GeoTIFF and PNG (an EXR is written from
    the whole array in memory, which --dask never holds; docs/gis.md)."""
    assert products[kind, "memory"][3] == [".exr", ".png", ".tif"]
    assert products[kind, "dask"][3] == [".png", ".tif"]


@pytest.mark.parametrize("kind", list(PRODUCTS))
def test_both_paths_note_a_file_without_georeferencing(products, kind):
    for path in ("memory", "dask"):
        stderr = products[kind, path][2]
        assert len(stderr) == 1 and "has no georeferencing and no --spacing" in stderr[0], \
            (path, stderr)


#: Bad values, each named as the in-memory path names it (one line, exit code 2)
BAD = [
    ("horizon", ["--max-distance", "nan"], "max_distance: expected a non-negative length, got nan"),
    ("horizon", ["--max-distance", "-5"], "max_distance: expected a non-negative length, got -5.0"),
    ("horizon", ["--max-distance", "5", "--azimuths", "inf"],
     "azimuths[0]: expected a finite number of degrees, got inf"),
    ("shadows", ["--max-distance", "5", "--elevation", "100"],
     "elevation: expected degrees in [-90, 90], got 100.0"),
    ("viewshed", ["--max-distance", "5", "--observer-pixel", "20,10"],
     "observer[0]: (20, 10) stands on a cell touching a void (nodata) vertex"),
    ("viewshed", ["--max-distance", "5", "--observer-pixel", "20,30", "--target-height", "nan"],
     "target_height: expected a finite length"),
]


@pytest.mark.parametrize("kind, options, message", BAD, ids=[" ".join(b[1]) for b in BAD])
def test_both_paths_name_a_bad_value_the_same_way_and_leave_no_file(tmp_path, kind, options,
                                                                    message):
    source = field_with_infinities(tmp_path / "inf.npy")
    said = []
    for path, extra in (("memory", []), ("dask", DASK)):
        prefix = str(tmp_path / path)
        code, _, stderr = run([kind, source, "--no-progress", "--out", prefix, *options, *extra])
        errors = [x for x in stderr if "note:" not in x]
        assert code == 2 and len(errors) == 1 and message in errors[0], (path, stderr)
        assert glob.glob(prefix + ".*") == [], path
        said.append(errors[0])
    assert said[0] == said[1]


def test_a_dask_run_that_fails_in_its_tasks_leaves_no_geotiff(tmp_path):
    """The sample beyond float32 is found by the task that reads it, after the GeoTIFF was
    created; the run removes it (in memory nothing is written)."""
    heights = np.zeros((64, 64))
    heights[40, 50] = 1e39
    np.save(tmp_path / "e39.npy", heights)
    for path, extra in (("memory", []), ("dask", DASK)):
        code, _, stderr = run(["svf", str(tmp_path / "e39.npy"), "--max-distance", "5",
                               "--n-azimuths", "4", "--no-progress", "--out",
                               str(tmp_path / path), *extra])
        assert code == 2 and "row 40, column 50 is 1e+39" in stderr[-1], stderr
        assert glob.glob(str(tmp_path / path) + ".*") == [], path


def test_a_sample_the_scale_takes_beyond_float64_is_refused_on_both_paths(tmp_path):
    """In memory such a sample became a void without a word (its scaled value was read as
    non-finite, a void); the window-by-window reader refused it. Both refuse it now, naming
    the sample; the file's own infinities stay voids on both."""
    heights = np.zeros((8, 8))
    heights[2, 5] = 1e10
    heights[6, 1] = -np.inf
    path = tmp_path / "big.npy"
    np.save(path, heights)
    said = []
    for read in (lambda: datasets_gen.load_file(path, vertical_scale=1e300),
                 lambda: datasets_gen.open_lazy(path, vertical_scale=1e300).heights.compute()):
        with pytest.raises(ValueError) as error:
            read()
        said.append(str(error.value))
    assert said[0] == said[1]
    assert said[0].startswith(f"{path}: the sample at row 2, column 5 is inf once scaled (in "
                              "the file 10000000000.0), beyond float32"), said[0]
    assert "; 1 sample(s) in all" in said[0]
    field = datasets_gen.load_file(path, vertical_scale=2.0)
    lazy = datasets_gen.open_lazy(path, vertical_scale=2.0).heights.compute()
    assert field.nodata_mask[6, 1] and np.isnan(lazy[6, 1])
    np.testing.assert_array_equal(np.asarray(field.heights), lazy)
