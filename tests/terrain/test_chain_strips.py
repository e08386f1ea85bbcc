"""The chain walk's strips: the bins bound the surface on every ray of their strip, the walk
that skips along them is exact on the hidden-style fields (terraces, spikes, flat fields,
thin edges, voids) at RVT's 16 azimuths and at random ones, and the kernels refuse strips
that do not fit the grid."""
import math

import numpy as np
import pytest

import algos.terrain as T
from algos import _kernels
from algos.terrain.grid import _prepare
from algos.terrain.reference import horizon_reference, surface_exact
from algos.terrain.walks import CHAIN_STRIP_BIN, CHAIN_STRIP_WIDTH, chain_strips

SIXTEEN = [22.5 * k for k in range(16)]
#: seeded azimuths off every lattice direction
RANDOM = [float(a) for a in np.random.default_rng(31).uniform(0.0, 360.0, 5)]


def _fields():
    """The named fields of the exactness tests: (name, heights)."""
    rng = np.random.default_rng(7)
    terraces = np.floor(np.add.outer(np.arange(13), 2 * np.arange(12)) / 5.0)
    spikes = np.zeros((12, 13))
    spikes[3, 4], spikes[8, 9], spikes[10, 1] = 9.0, 4.0, 6.5
    voids = rng.integers(0, 7, size=(11, 12)).astype(float)
    voids[4, 5] = voids[0, 3] = voids[7, 11] = np.nan
    return [("terraces", terraces), ("spikes", spikes), ("flat", np.full((9, 10), 3.0)),
            ("zero", np.zeros((7, 8))), ("row_pair", rng.integers(0, 5, size=(2, 13)) * 1.0),
            ("column_pair", rng.integers(0, 5, size=(12, 2)) * 1.0), ("one_cell", np.array(
                [[0.0, 2.0], [1.0, 5.0]])), ("voids", voids)]


def _reference(heights, azimuth, max_distance):
    """The exact reference on the kernels' heights (voids as their deep pits), NaN at the
    voids (the documented contract)."""
    grid = _prepare(heights, None)
    d = T.azimuth_direction(azimuth)
    want = np.array(horizon_reference(grid.h, (d.dx, d.dy), max_distance))
    return grid.voids_to(want, np.nan)


@pytest.mark.parametrize("name, heights", _fields(), ids=[f[0] for f in _fields()])
@pytest.mark.parametrize("max_distance", [None, 4.5])
def test_chain_equals_exact_reference(name, heights, max_distance):
    for az in SIXTEEN + RANDOM:
        got = T.horizon(heights, az, max_distance, algorithm="chain")[0]
        want = _reference(heights, az, max_distance)
        assert np.array_equal(np.isnan(got), np.isnan(want)), f"{name} az={az!r}"
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12,
                                   err_msg=f"chain {name} az={az!r} md={max_distance!r}")


def test_chain_bit_identical_to_cell_walk():
    """The strips only decide which breakpoints are skipped; every one evaluated uses the
    plain cell walk's expressions, so the angles are the same bits (here on a Jacksboro
    crop and on terraces, where ties between breakpoints are common)."""
    datasets_gen = pytest.importorskip("datasets_gen")
    crop = np.asarray(datasets_gen.load("jacksboro", size=256).heights, dtype=float)[:48, :40]
    terraces = np.floor(np.add.outer(np.arange(30), np.arange(27)) / 4.0)
    for h in (crop, terraces):
        azimuths = SIXTEEN + RANDOM
        assert np.array_equal(T.horizon(h, azimuths, algorithm="chain"),
                              T.horizon(h, azimuths, algorithm="dda"))


@pytest.mark.parametrize("width, bin_length", [(1.0, 2.0), (2.0, 2.0), (0.5, 1.0), (3.0, 4.0),
                                               (1.0, 8.0)])
def test_chain_bit_identical_for_every_strip_shape(monkeypatch, width, bin_length):
    """Whatever the strips' width and bin length, the walk evaluates the same expressions:
    its climb (the next bin by integer arithmetic after a pass, the level-0 bin after a
    failed one retested in the walk) and its cells stepped along incrementally give the
    cell walk's angles bit for bit, with and without max_distance, on a Jacksboro crop,
    terraces, a tilted plane (lattice-aligned rays run along its level lines), a flat
    field and isolated spikes (ties everywhere)."""
    import functools

    from algos.terrain import walks

    datasets_gen = pytest.importorskip("datasets_gen")
    monkeypatch.setattr(walks, "chain_strips", functools.partial(
        chain_strips, width=width, bin_length=bin_length))
    rng = np.random.default_rng(11)
    crop = np.asarray(datasets_gen.load("jacksboro", size=256).heights, dtype=float)[60:96, 20:50]
    terraces = np.floor(np.add.outer(np.arange(24), 3 * np.arange(21)) / 7.0)
    plane = np.add.outer(0.25 * np.arange(17), 0.5 * np.arange(19))
    spikes = np.zeros((16, 18))
    spikes[rng.integers(0, 16, 6), rng.integers(0, 18, 6)] = rng.uniform(1, 9, 6)
    azimuths = SIXTEEN + RANDOM
    for h in (crop, terraces, plane, np.full((10, 12), 2.5), spikes):
        for md in (None, 6.5):
            got = T.horizon(h, azimuths, md, algorithm="chain")
            want = T.horizon(h, azimuths, md, algorithm="dda")
            assert np.array_equal(got, want), (width, bin_length, h.shape, md)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_strip_bins_bound_the_surface(seed):
    """Every point of a vertex ray lies at most at the bin of the ray's strip that holds
    its distance along the direction, at every level; each level is the pairwise maximum
    of the one below."""
    rng = np.random.default_rng(seed)
    h = rng.normal(size=(9, 11)).cumsum(axis=1)
    rows, cols = h.shape
    for az in [22.5, 90.0, 200.0] + list(rng.uniform(0, 360, 3)):
        d = T.azimuth_direction(az)
        for width, bin_length in ((CHAIN_STRIP_WIDTH, CHAIN_STRIP_BIN), (0.5, 1.0), (3.0, 4.0)):
            (data, offset, n_bins, width, bin_length), _ = chain_strips(h, d, width, bin_length)
            c_min, a_min, n_strips, _ = _kernels.horizon_strips_frame(rows, cols, d.dx, d.dy,
                                                                      width, bin_length)
            levels = [data[offset[k]:offset[k] + n_strips * n_bins[k]].reshape(-1, n_strips).T
                      for k in range(len(n_bins))]
            for below, above in zip(levels, levels[1:]):
                pad = np.full((n_strips, 2 * above.shape[1]), -np.inf)
                pad[:, :below.shape[1]] = below
                assert np.array_equal(above, pad.reshape(n_strips, -1, 2).max(axis=2))
            for j in range(rows):
                for i in range(cols):
                    strip = int(math.floor((d.dx * j - d.dy * i - c_min) / width))
                    along = d.dx * i + d.dy * j - a_min
                    for t in rng.uniform(0, math.hypot(rows, cols), 6):
                        x, y = i + t * d.dx, j + t * d.dy
                        if not (0 <= x <= cols - 1 and 0 <= y <= rows - 1):
                            continue
                        s = float(surface_exact(h, x, y))
                        for k, level in enumerate(levels):
                            slot = int((along + t) // (bin_length * 2 ** k))
                            assert s <= level[strip, slot], (az, i, j, t, k)


def _valid_strips(h, d):
    return chain_strips(h, d)[0]


def test_kernels_refuse_strips_that_do_not_fit():
    h = np.zeros((5, 6))
    d = T.azimuth_direction(22.5)
    data, offset, n_bins, width, bin_length = _valid_strips(h, d)
    nb = T.chain_neighbours(d)
    out, occ = np.empty(h.size), np.empty(h.size)

    def chain(strips, dx=d.dx, dy=d.dy):
        return _kernels.horizon_chain(h, strips, dx, dy, math.inf, *nb, 4, 0, 2, out, occ)

    chain((data, offset, n_bins, width, bin_length))  # the valid call runs
    with pytest.raises(ValueError, match="strips data"):
        chain((data[:-1], offset, n_bins, width, bin_length))
    with pytest.raises(ValueError, match="level 1"):
        chain((data, offset + np.array([0] + [1] * (len(offset) - 1)), n_bins, width, bin_length))
    with pytest.raises(ValueError, match="power of two"):
        chain((data, offset, n_bins, width, 3.0))
    with pytest.raises(ValueError, match="level 0"):  # strips of another direction
        chain((data, offset, n_bins, width, bin_length), 1.0, 0.0)
    with pytest.raises(ValueError, match="unit vector"):
        chain((data, offset, n_bins, width, bin_length), 2 * d.dx, 2 * d.dy)
    with pytest.raises(TypeError, match="strips"):
        chain([data, offset, n_bins, width, bin_length])
    with pytest.raises(ValueError, match="width, bin"):
        _kernels.horizon_strips_frame(5, 6, d.dx, d.dy, 0.0, 2.0)
    with pytest.raises(ValueError, match="unit vector"):
        _kernels.horizon_strips_frame(5, 6, 0.0, 0.0, 1.0, 2.0)
    with pytest.raises(TypeError, match="writable"):
        frozen = data.copy()
        frozen.flags.writeable = False
        _kernels.horizon_strips(h, (frozen, offset, n_bins, width, bin_length), d.dx, d.dy)
