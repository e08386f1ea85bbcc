"""The viewshed of a dask array (``algos.terrain.tiled.tiled_viewshed``): equal to the in-memory
``algos.viewshed`` on every sample, and a graph of O(chunks) tasks (one per chunk, one per
observer, one per piece of a window spanning several chunks) built without reading the
input."""
import dataclasses

import numpy as np
import pytest

import algos
import datasets_gen

da = pytest.importorskip("dask.array")
dask = pytest.importorskip("dask")


@pytest.fixture(autouse=True)
def synchronous():
    """One thread, in order: failures point at the task (tests/bench/test_scale.py runs the
    same graphs on a LocalCluster)."""
    with dask.config.set(scheduler="synchronous"):
        yield


@pytest.fixture(scope="module")
def fbm():
    return datasets_gen.load("fbm", size=(150, 210), seed=2).heights.astype(np.float64)


# chunk edges: rows 40, 80, 120; columns 64, 128, 192
CHUNKS = (40, 64)
#: on a chunk corner vertex, just inside and outside corners and edges, the field's corners
BORDER_OBSERVERS = [(64.0, 40.0), (63.5, 39.5), (63.99, 40.01), (128.0, 75.5), (191.2, 120.0),
                    (0.0, 0.0), (209.0, 149.0), (209.0, 0.0), (0.0, 149.0), (100.3, 50.2)]


def _same(lazy_result, want, what):
    got = lazy_result.compute()
    assert got.dtype == want.dtype, (what, got.dtype, want.dtype)
    differ = np.argwhere(got != want)
    assert len(differ) == 0, f"{what}: {len(differ)} samples differ, first (row, col) {differ[:5]}"


@pytest.mark.parametrize("max_distance", [0.0, 6.0, 45.5, 130.0, None, float("inf")])
def test_single_observers_near_chunk_borders_equal_the_in_memory_viewshed(fbm, max_distance):
    lazy = da.from_array(fbm, chunks=CHUNKS)
    for observer in BORDER_OBSERVERS:
        seen = algos.viewshed(lazy, observer, max_distance=max_distance)
        assert seen.dtype == bool and seen.chunks == lazy.chunks
        _same(seen, algos.viewshed(fbm, observer, max_distance=max_distance),
              f"observer {observer}, max_distance {max_distance}")


@pytest.mark.parametrize("max_distance", [6.0, 45.5, None])
def test_many_observers_count_as_in_memory(fbm, max_distance):
    lazy = da.from_array(fbm, chunks=CHUNKS)
    seen = algos.viewshed(lazy, BORDER_OBSERVERS, max_distance=max_distance)
    assert seen.dtype == np.uint16
    _same(seen, algos.viewshed(fbm, BORDER_OBSERVERS, max_distance=max_distance),
          f"{len(BORDER_OBSERVERS)} observers, max_distance {max_distance}")
    # one observer given as a list of one is a count, not a bool
    one = algos.viewshed(lazy, [(100.3, 50.2)], max_distance=max_distance)
    assert one.dtype == np.uint16
    _same(one, algos.viewshed(fbm, [(100.3, 50.2)], max_distance=max_distance), "[observer]")


def test_uneven_chunks_thinner_than_the_window(fbm):
    lazy = da.from_array(fbm, chunks=((30, 3, 67, 50), (100, 1, 9, 100)))
    many = [(100.5, 31.5), (101.0, 33.0), (110.0, 100.0), (5.0, 140.0)]
    for md in (2.0, 20.0, None):
        _same(algos.viewshed(lazy, many, max_distance=md),
              algos.viewshed(fbm, many, max_distance=md), f"uneven chunks, max_distance {md}")


def test_options_pass_through(fbm):
    lazy = da.from_array(fbm, chunks=CHUNKS)
    observer = (70.0, 45.0)
    for options in (dict(observer_height=0.0, target_height=3.0),
                    dict(observer_height=25.0, algorithm="dda", threads=2),
                    dict(spacing=30.0, curvature=True, refraction=0.3, observer_height=40.0)):
        _same(algos.viewshed(lazy, observer, max_distance=40.0 * options.get("spacing", 1.0),
                             **options),
              algos.viewshed(fbm, observer, max_distance=40.0 * options.get("spacing", 1.0),
                             **options), f"options {options}")


def test_rectangular_pixels(fbm):
    lazy = da.from_array(fbm * 10.0, chunks=CHUNKS)
    spacing = (10.0, 20.0)
    for md in (35.0, 455.0, None):
        _same(algos.viewshed(lazy, BORDER_OBSERVERS[:4], max_distance=md, spacing=spacing),
              algos.viewshed(fbm * 10.0, BORDER_OBSERVERS[:4], max_distance=md, spacing=spacing),
              f"spacing {spacing}, max_distance {md}")
    flat = da.zeros((9, 9), chunks=4)
    seen = algos.viewshed(flat, (4, 4), 1.0, max_distance=35.0, spacing=spacing).compute()
    jj, ii = np.mgrid[0:9, 0:9]
    np.testing.assert_array_equal(seen, ((ii - 4) * 10.0) ** 2 + ((jj - 4) * 20.0) ** 2 <= 35 ** 2)


def test_a_heightfield_with_rows_running_north():
    hf = datasets_gen.load("jacksboro", size=160)
    assert hf.north == "+y"
    lazy = dataclasses.replace(hf, heights=da.from_array(hf.heights, chunks=50))
    for md in (900.0, None):
        _same(algos.viewshed(lazy, [(49.5, 50.0), (120.0, 10.0)], max_distance=md),
              algos.viewshed(hf, [(49.5, 50.0), (120.0, 10.0)], max_distance=md),
              f"jacksboro, max_distance {md}")


def test_voids(fbm):
    holes = fbm.copy()
    holes[35:45, 60:70] = np.nan  # across a chunk corner
    holes[100, 5] = np.nan
    lazy = da.from_array(holes, chunks=CHUNKS)
    many = [(50.0, 30.0), (75.0, 50.0), (10.0, 100.0)]
    for md in (12.0, 60.0, None):
        _same(algos.viewshed(lazy, many, max_distance=md),
              algos.viewshed(holes, many, max_distance=md), f"voids, max_distance {md}")
    # an observer on a void is refused when the heights are read, with the in-memory
    # message: its index and coordinates in the whole array, not in its window (a new
    # user's trial saw "observer[0]: (6, 6)" for observer 1 at (64.5, 40.5))
    observers = [(50.0, 30.0), (64.5, 40.5)]
    seen = algos.viewshed(lazy, observers, max_distance=12.0)
    with pytest.raises(ValueError) as lazy_error:
        seen.compute()
    with pytest.raises(ValueError) as memory_error:
        algos.viewshed(holes, observers, max_distance=12.0)
    assert str(lazy_error.value) == str(memory_error.value)
    assert str(lazy_error.value).startswith("observer[1]: (64.5, 40.5) stands on a cell "
                                            "touching a void")


def test_bad_observers_and_distances_are_refused_at_once():
    lazy = da.zeros((20, 30), chunks=10)
    with pytest.raises(ValueError, match=r"observer\[1\]: \(30.0, 2.0\) outside the footprint"):
        algos.viewshed(lazy, [(1, 1), (30, 2)])
    with pytest.raises(ValueError, match="observer: expected"):
        algos.viewshed(lazy, [(1, 1, 1)])
    with pytest.raises(ValueError, match="max_distance: expected a non-negative length"):
        algos.viewshed(lazy, (1, 1), max_distance=-1.0)
    with pytest.raises(ValueError, match="heights: expected a 2D array"):
        algos.viewshed(da.zeros((2, 20, 30), chunks=10), (1, 1))


# ---- the graph ---------------------------------------------------------------------------

def _refuse(block):
    raise RuntimeError("an input chunk was read")


def _unreadable(side, chunk):
    """A lazy field whose every chunk raises when computed."""
    return da.zeros((side, side), chunks=chunk).map_blocks(_refuse, dtype=np.float64)


def _tasks(lazy):
    return len(dict(lazy.__dask_graph__()))


@pytest.mark.parametrize("side", [2000, 4000])
def test_the_graph_has_o_of_chunks_tasks_and_reads_nothing(side):
    chunk = 100
    field = _unreadable(side, chunk)
    chunks = field.npartitions
    input_tasks = _tasks(field)
    one = algos.viewshed(field, (side / 2, side / 2), max_distance=40.0)
    grid = [(250.0 + i * side / 4, 250.0 + j * side / 4) for j in range(4) for i in range(4)]
    many = algos.viewshed(field, grid, max_distance=40.0)
    unlimited = algos.viewshed(field, (side / 3, side / 5), max_distance=None)
    # one task per chunk and per observer, and a piece per chunk of a window spanning
    # several: the centre's window (side / 2 -+ 41, around a chunk corner) is cut in 4, the
    # grid's (rows and columns 209:292 and so on) lie in one chunk each, the unlimited one
    # spans all
    for seen, extra in ((one, 1 + 4), (many, 16), (unlimited, 1 + chunks)):
        assert _tasks(seen) - input_tasks == chunks + extra
        assert _tasks(seen) - input_tasks <= 2 * chunks + 16
    # a chunk beyond every window is known without reading the input
    assert not one.blocks[0, 0].compute().any()
    assert not many.blocks[0, 0].compute().any()
    # one that a window overlaps reads it: the graph really depends on the input
    with pytest.raises(RuntimeError, match="an input chunk was read"):
        one.blocks[side // chunk // 2, side // chunk // 2].compute()


def test_xarray_spatials_100000_squared_lazy_field():
    """As xarray-spatial's lazy test: a 100000^2 field of 1000^2 chunks (80 GB as float64,
    never made), one observer at the centre 5 above a flat ground, max_distance 10. The
    result is lazy, its graph O(chunks), and the window around the observer is exact."""
    big = da.tile(da.zeros((1000, 1000), chunks=1000), (100, 100))
    seen = algos.viewshed(big, (50000.0, 50000.0), observer_height=5.0, max_distance=10.0)
    assert isinstance(seen, da.Array) and seen.shape == (100000, 100000)
    assert _tasks(seen) <= 3 * big.npartitions + 1
    centre = seen[49989:50012, 49989:50012].compute()
    want = algos.viewshed(np.zeros((23, 23)), (11.0, 11.0), observer_height=5.0,
                          max_distance=10.0)
    np.testing.assert_array_equal(centre, want)
    assert centre[11, 11] and centre[11, 13] and not centre[0, 0]


def test_different_calls_get_different_names(fbm):
    lazy = da.from_array(fbm, chunks=CHUNKS)
    names = {algos.viewshed(lazy, (5, 5), max_distance=10.0).name,
             algos.viewshed(lazy, (5, 6), max_distance=10.0).name,
             algos.viewshed(lazy, (5, 5), max_distance=11.0).name,
             algos.viewshed(lazy, (5, 5), max_distance=10.0, observer_height=2.0).name,
             algos.viewshed(lazy, [(5, 5)], max_distance=10.0).name}
    assert len(names) == 5
    # the same call twice is the same graph
    assert (algos.viewshed(lazy, (5, 5), max_distance=10.0).name
            == algos.viewshed(lazy, (5, 5), max_distance=10.0).name)


def test_an_observers_task_does_not_carry_the_input():
    """Each observer's task holds the field's description, not the lazy field: pickled
    for a distributed worker, it stays small however big the input's graph is (the input
    here holds 32 MB of heights in its graph)."""
    cloudpickle = pytest.importorskip("cloudpickle")
    hf = datasets_gen.load("jacksboro", size=160)
    lazy = dataclasses.replace(hf, heights=da.from_array(np.zeros((2000, 2000)), chunks=100))
    seen = algos.viewshed(lazy, [(10.0, 10.0), (1500.0, 700.0)], max_distance=500.0)
    windows = next(layer for name, layer in seen.__dask_graph__().layers.items()
                   if name.startswith("viewshed-window-"))
    assert len(windows) == 2
    for key, task in dict(windows).items():
        assert len(cloudpickle.dumps(task)) < 100_000, key
