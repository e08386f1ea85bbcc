"""Bad input raises a clear error naming the argument and the ray; odd layouts work."""
import math

import numpy as np
import pytest

import algos

ALL = list(algos.TRAVERSALS)
ORIGINS = np.array([[0.5, 0.5], [1.5, 0.25], [2.0, 3.0]])
DIRECTIONS = np.array([[1.0, 0.3], [-0.2, 1.0], [1.0, -1.0]])


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("argument,bad", [("origins", np.nan), ("origins", np.inf),
                                          ("directions", -np.inf), ("directions", np.nan)])
def test_non_finite_rays(name, argument, bad):
    o, d = ORIGINS.copy(), DIRECTIONS.copy()
    (o if argument == "origins" else d)[2, 1] = bad
    with pytest.raises(ValueError, match=rf"{argument}: ray 2 .*\[2, 1\]"):
        algos.traverse(name, o, d, (4, 4))


@pytest.mark.parametrize("name", ALL)
def test_nan_in_t_range(name):
    with pytest.raises(ValueError, match=r"tmin: ray 1 "):
        algos.traverse(name, ORIGINS, DIRECTIONS, (4, 4), tmin=[0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match=r"tmax: ray 0 "):
        algos.traverse(name, ORIGINS, DIRECTIONS, (4, 4), tmax=[np.nan, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"tmax: expected a scalar or shape \(3,\)"):
        algos.traverse(name, ORIGINS, DIRECTIONS, (4, 4), tmax=[1.0, 2.0])


@pytest.mark.parametrize("shape", [(ORIGINS[:, :1], DIRECTIONS), (ORIGINS, DIRECTIONS[:2]),
                                   (ORIGINS.ravel(), DIRECTIONS), (ORIGINS, DIRECTIONS[:, None])])
def test_wrong_ray_shapes(shape):
    o, d = shape
    with pytest.raises(ValueError, match=r"origins|directions"):
        algos.traverse("runs", o, d, (4, 4))


@pytest.mark.parametrize("grid,error,words", [
    ((0, 4), ValueError, "shape: shape[0] = 0; a grid needs at least one cell"),
    ((4, -1), ValueError, "shape: shape[1] = -1; a grid needs at least one cell"),
    ((4,), ValueError, "shape: expected (nx, ny), got (4,)"),
    ((4, 2.5), TypeError, "shape: shape[1] must be an integer, got 2.5"),
    ((2**24 + 1, 4), ValueError, "shape: shape[0] = 16777217 exceeds the limit 2**24"),
    ("44", TypeError, "shape: shape[0] must be an integer, got '4'")])
def test_bad_grids(grid, error, words):
    """Each entry of the grid is named as shape[k], as the entries of other tuple
    arguments are (origin[0], spacing[1])."""
    with pytest.raises(error) as info:
        algos.traverse("runs", ORIGINS, DIRECTIONS, grid)
    assert words in str(info.value)


def test_limits():
    with pytest.raises(ValueError, match=r"origins: ray 0 .*2\*\*30"):
        algos.traverse("runs", [[2.0**31, 0.0]], [[1.0, 0.0]], (4, 4))
    with pytest.raises(ValueError, match=r"directions: ray 0 .*2\*\*1000"):
        algos.traverse("runs", [[0.0, 0.0]], [[1e305, 0.0]], (4, 4))
    # the largest documented grid is accepted
    paths = algos.traverse("runs", [[0.5, 0.5]], [[1.0, 0.0]], (2**24, 1), tmax=3.0)
    assert paths[0].tolist() == [[0, 0], [1, 0], [2, 0], [3, 0]]


def test_bad_types_and_names():
    with pytest.raises(TypeError, match="origins"):
        algos.traverse("runs", [["a", "b"]], DIRECTIONS[:1], (4, 4))
    with pytest.raises(TypeError, match="directions"):
        algos.traverse("runs", ORIGINS, DIRECTIONS.astype(complex), (4, 4))
    with pytest.raises(ValueError, match="unknown traversal 'nope'; valid names are dda"):
        algos.traverse("nope", ORIGINS, DIRECTIONS, (4, 4))
    with pytest.raises(ValueError, match="output"):
        algos.traverse("runs", ORIGINS, DIRECTIONS, (4, 4), output="everything")
    with pytest.raises(ValueError, match="workload"):
        algos.walk_timed("runs", ORIGINS, DIRECTIONS, (4, 4), workload="sleep")


def test_reference_rejects_bad_input():
    with pytest.raises(ValueError, match="origin"):
        algos.reference_cells((math.nan, 0), (1, 0), (4, 4))
    with pytest.raises(ValueError, match=r"shape\[0\] must be positive, got 0"):
        algos.reference_cells((0, 0), (1, 0), (0, 4))
    with pytest.raises(ValueError, match="tmax"):
        algos.reference_cells((0, 0), (1, 0), (4, 4), tmax=math.nan)


@pytest.mark.parametrize("origin,direction,shape,error,words", [
    ((0.5, 0.5), (1, 0), (4.5, 4), TypeError, "shape[0] must be an integer, got 4.5"),
    ((0.5, 0.5), (1, 0), "44", ValueError, "shape must be"),
    ((0.5, 0.5), (1, 0), (4, 4, 4), ValueError, "shape must be"),
    ((0.5, 0.5), (1, 0), 4, ValueError, "shape must be"),
    ((0.5, 0.5), (1, 0), (True, 4), TypeError, "shape[0] must be an integer, got True"),
    ((0.5, 0.5, 1.0), (1, 0), (4, 4), ValueError, "origin must be a pair"),
    (0.5, (1, 0), (4, 4), ValueError, "origin must be a pair"),
    ((0.5, 0.5), "10", (4, 4), TypeError, "direction must be a pair"),
    (("1", 0.5), (1, 0), (4, 4), TypeError, "origin[0] must be a real number"),
    ((0.5, 1j), (1, 0), (4, 4), TypeError, "origin[1] must be a real number"),
])
def test_reference_names_the_bad_argument(origin, direction, shape, error, words):
    """The reference checks its arguments as traverse does, naming each: it took a
    shape of (4.5, 4) as 4 x 4 cells and the string "44" as (4, 4), read the string "1"
    as the number 1, and answered a 3D origin with "too many values to unpack"."""
    with pytest.raises(error) as info:
        algos.reference_cells(origin, direction, shape)
    assert words in str(info.value)
    # numbers of any NumPy type, Fractions and a huge grid stay accepted
    from fractions import Fraction
    assert algos.reference_cells((np.float32(0.5), Fraction(1, 2)), np.array([1, 0]),
                                 (np.int64(2), 2**40), tmax=2.0) == [(0, 0), (1, 0)]


@pytest.mark.parametrize("name", ALL)
def test_layouts_and_dtypes(name):
    """float32, big-endian, Fortran order, strided views and lists give the same cells,
    and the inputs are never modified."""
    rng = np.random.Generator(np.random.PCG64(3))
    o = rng.uniform(0, 30, (50, 2)).astype(np.float32).astype(np.float64)
    d = rng.normal(size=(50, 2)).astype(np.float32).astype(np.float64)
    expected = algos.traverse(name, o, d, (30, 30))
    wide = np.zeros((50, 5))
    wide[:, 1], wide[:, 3] = o[:, 0], o[:, 1]
    variants = [
        (o.astype(np.float32), d.astype(np.float32)),
        (o.astype(">f8"), d.astype(">f8")),
        (np.asfortranarray(o), np.asfortranarray(d)),
        (wide[:, 1::2], d[::-1][::-1]),
        (o.tolist(), d.tolist()),
    ]
    for vo, vd in variants:
        before = (np.array(vo, copy=True), np.array(vd, copy=True))
        got = algos.traverse(name, vo, vd, (30, 30))
        assert np.array_equal(got.cells, expected.cells) and np.array_equal(got.offsets, expected.offsets)
        assert np.array_equal(np.asarray(vo), before[0]) and np.array_equal(np.asarray(vd), before[1])


def test_empty_batch():
    for name in ALL:
        paths = algos.traverse(name, np.zeros((0, 2)), np.zeros((0, 2)), (4, 4))
        assert len(paths) == 0 and paths.cells.shape == (0, 2)


def test_zero_direction_is_vertical():
    paths = algos.traverse("runs", [[1.5, 2.5], [9.0, 9.0]], [[0.0, 0.0], [0.0, 0.0]], (4, 4))
    assert paths[0].tolist() == [[1, 2]] and paths[1].tolist() == []


def test_python_numbers_numpy_keeps_as_objects():
    """A Python int beyond int64 (2**70, within the documented |d| <= 2**1000) or a
    Fraction made an object array, refused as "expected real numbers, got dtype object":
    they are real numbers, taken as float64; one beyond float64 is refused by its index."""
    from fractions import Fraction

    cells = algos.traverse("runs", [[0.5, 0.5]], [[2**70, 1]], (4, 4))[0]
    assert [tuple(c) for c in cells.tolist()] == [(0, 0), (1, 0), (2, 0), (3, 0)]
    got = algos.traverse("runs", [[Fraction(1, 2), 0.5]], [[1, 0]], (4, 4), tmin=-2**70)[0]
    assert [tuple(c) for c in got.tolist()] == [(0, 0), (1, 0), (2, 0), (3, 0)]
    hits = algos.intersect("runs", np.zeros((3, 3)), [[0.5, 0.5, Fraction(5, 2)]], [[0, 0, -1]])
    assert hits.t[0] == 2.5
    with pytest.raises(ValueError, match=r"directions: directions\[0, 1\] = 100000000000\.\.\. "
                                         r"\(401 digits\) is beyond float64's range"):
        algos.traverse("runs", [[0.5, 0.5]], [[1, 10**400]], (4, 4))
    with pytest.raises(TypeError, match="directions: expected real numbers, got dtype object"):
        algos.traverse("runs", [[0.5, 0.5]], [[None, 1]], (4, 4))
