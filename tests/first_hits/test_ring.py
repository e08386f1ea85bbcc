"""ring_maxmip: bit-identical to the per-ray dda_maxmip (t, cell, normal and the
statistics) on every batch, and equal to the exact reference (the brute force) within the
first-hit tolerance. The hazards: terraces, grazing and lattice-aligned rays, vertical
rays, rays along grid lines and diagonals, eyes below the surface and far above it, rays
going up, per-ray tmin/tmax, rays that miss; and batches of every length around the
ring's size, so that the ring fills, refills and drains in every way."""
import numpy as np
import pytest

import algos
from datasets_gen import fields
from datasets_gen import rays as raysets

from ..helpers import first_hit_fields

SHAPE = (33, 41)  # (rows, cols)
OUTPUTS = ("t", "cell", "normal", "stats")
#: the ring's slots (cext/dispatch/ring.h, HF_RING_SLOTS)
SLOTS = 8


def _assert_identical(ref, got, o, d, what):
    """Bit for bit: t and normal as int64 bit patterns, cell and every statistic exactly.
    The message is a reproducer."""
    checks = [("t", ref.t.view(np.int64), got.t.view(np.int64)),
              ("cell", ref.cell, got.cell),
              ("normal", ref.normal.view(np.int64), got.normal.view(np.int64))]
    checks += [(f"stats {k}", ref.stats[k], got.stats[k]) for k in ref.stats]
    for name, a, b in checks:
        assert a.shape == b.shape, f"{what}: {name} shapes {a.shape} and {b.shape} differ"
        if a.size == 0:  # an empty batch
            continue
        differ = np.nonzero((a != b).reshape(len(a), -1).any(axis=1))[0]
        if len(differ):
            k = differ[0]
            raise AssertionError(
                f"{what}: {len(differ)} of {len(a)} rays differ in {name}; first: ray {k}, "
                f"origin={o[k].tolist()!r} direction={d[k].tolist()!r} "
                f"dda_maxmip {name}={a[k]!r} ring_maxmip {name}={b[k]!r}")


def _check(fld, o, d, what, surfaces=algos.SURFACES, **kw):
    for surface in surfaces:
        ref = algos.intersect("dda_maxmip", fld, o, d, surface=surface, outputs=OUTPUTS,
                              threads=1, **kw)
        got = algos.intersect("ring_maxmip", fld, o, d, surface=surface, outputs=OUTPUTS,
                              threads=1, **kw)
        _assert_identical(ref, got, o, d, f"{what}, {surface}")


def _check_brute(H, o, d, what, surfaces=algos.SURFACES, tmin=None, tmax=None):
    """The exact reference: hit or miss alike, |dt| <= 1e-9 (1 + |t|)."""
    fld = algos.Field(H)
    for surface in surfaces:
        ref_t, _ = algos.brute_force_hits(H, o, d, surface, tmin=tmin, tmax=tmax)
        got = algos.intersect("ring_maxmip", fld, o, d, surface=surface, threads=1,
                              tmin=tmin, tmax=tmax).t
        hit_ref, hit_got = np.isfinite(ref_t), np.isfinite(got)
        both = hit_ref & hit_got
        far = np.zeros(len(got), bool)
        far[both] = np.abs(got[both] - ref_t[both]) > 1e-9 * (1 + np.abs(ref_t[both]))
        bad = np.union1d(np.nonzero(hit_ref != hit_got)[0], np.nonzero(far)[0])
        if len(bad):
            k = bad[0]
            raise AssertionError(
                f"{what}, {surface}: {len(bad)} rays differ from the brute force; first: "
                f"origin={o[k].tolist()!r} direction={d[k].tolist()!r} brute t={ref_t[k]!r} "
                f"ring_maxmip t={got[k]!r}")


def _directions(seed, n=10):
    """Horizontal directions: random azimuths, both axes both ways, the four diagonals,
    lattice-aligned (integer) ones and none (vertical rays)."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0, 2 * np.pi, n)
    random = np.stack([np.cos(a), np.sin(a)], axis=1)
    axes = np.array([(1, 0), (-1, 0), (0, 1), (0, -1)], float)
    diagonals = np.array([(1, 1), (-1, 1), (1, -1), (-1, -1)], float)
    lattice = np.array([(2, 1), (-3, 2), (1, -4), (5, 3), (0, 0)], float)
    return np.concatenate([random, axes, diagonals, lattice])


#: z slopes: steep to grazing, level, going up
SLOPES = np.concatenate([-np.geomspace(2.0, 1e-3, 8), [-1e-9, 0.0, 1e-9], [1e-3, 0.3]])


def _eyes(H):
    """Eyes of every kind over an H of shape SHAPE: above the surface inside the
    footprint, at a grid vertex (rays along grid lines and through vertices), on a grid
    line, outside the footprint, below the surface, far above the top."""
    rows, cols = H.shape
    top = float(H.max())
    return {
        "above": (12.3, 17.6, top + 0.5),
        "vertex": (20.0, 16.0, top + 0.25),
        "line": (7.0, 11.375, top + 0.125),
        "outside": (-3.5, -2.25, top * 0.5 + 1.0),
        "below": (9.5, 9.5, float(H[9, 9]) - 1.0),
        "high": (cols / 2 + 0.3, rows / 2 - 0.1, top + 40.0),
    }


def _fans(H, seed, n=10, slopes=SLOPES):
    """Every eye with every direction and slope, shuffled (seeded): a batch of independent
    rays of every hazard."""
    o, d = [], []
    for k, eye in enumerate(_eyes(H).values()):
        for dx, dy in _directions(seed + k, n):
            for dz in slopes:
                o.append(eye)
                d.append((dx, dy, dz if (dx, dy) != (0, 0) else -abs(dz) - 0.5))
    o, d = np.array(o, float), np.array(d, float)
    order = np.random.default_rng(seed).permutation(len(o))
    return o[order], d[order]


@pytest.mark.parametrize("field_name", list(first_hit_fields(SHAPE)))
def test_identical_to_dda_maxmip(field_name):
    H = first_hit_fields(SHAPE)[field_name]
    fld = algos.Field(H)
    o, d = _fans(H, seed=1)
    _check(fld, o, d, f"{field_name}, fans")
    rs = raysets.first_hit_hazards(SHAPE, 29, per_family=40, families=raysets.HAZARD_FAMILIES)
    _check(fld, rs.origins, rs.directions, f"{field_name}, hazards")


@pytest.mark.parametrize("field_name", ["terraces", "spike", "fbm", "flat"])
def test_equals_brute_force(field_name):
    """The fans (fewer directions) and the hazards against the exact reference."""
    H = first_hit_fields(SHAPE)[field_name]
    o, d = _fans(H, seed=2, n=2, slopes=SLOPES[::2])
    _check_brute(H, o, d, f"{field_name}, fans")
    rs = raysets.first_hit_hazards(SHAPE, 31, per_family=12, families=raysets.HAZARD_FAMILIES)
    _check_brute(H, rs.origins, rs.directions, f"{field_name}, hazards")


def test_tmin_tmax():
    """Per-ray ranges (seeded, some empty, some a single parameter)."""
    H = first_hit_fields(SHAPE)["terraces"]
    fld = algos.Field(H)
    rng = np.random.default_rng(7)
    o, d = _fans(H, seed=3, n=4)
    tmin = rng.choice([0.0, 0.0, 0.5, 3.0, 7.25], len(o))
    tmax = tmin + rng.choice([np.inf, np.inf, 2.0, 10.0, 0.0], len(o))
    _check(fld, o, d, "tmin/tmax", tmin=tmin, tmax=tmax)
    _check_brute(H, o, d, "tmin/tmax", tmin=tmin, tmax=tmax)


def test_misses_and_empty_ranges():
    """Rays that miss the box, go up from above it, or end before reaching it: misses
    (t inf, cell -1), alike in both kernels."""
    H = first_hit_fields(SHAPE)["fbm"]
    fld = algos.Field(H)
    top = float(H.max())
    o = np.array([(-5.0, -5.0, 3.0), (50.0, 10.0, 3.0), (10.5, 10.5, top + 1.0),
                  (10.5, 10.5, top + 1.0), (-2.0, 5.5, 3.0)] * 4, float)
    d = np.array([(-1.0, -0.5, -0.1), (1.0, 0.0, -0.1), (0.3, 0.4, 0.2), (0.0, 0.0, 1.0),
                  (1.0, 0.0, -0.01)] * 4, float)
    tmax = np.tile([np.inf, np.inf, np.inf, np.inf, 1.0], 4)
    _check(fld, o, d, "misses", tmax=tmax)
    got = algos.intersect("ring_maxmip", fld, o, d, tmax=tmax, outputs=("t", "cell"))
    assert np.isinf(got.t).all() and (got.cell == -1).all()


@pytest.mark.parametrize("n", [0, 1, SLOTS - 1, SLOTS, SLOTS + 1, 2 * SLOTS + 3, 61])
def test_every_batch_length(n):
    """Batches shorter than the ring, as long, and longer (refills, then the drain), with
    rays that need no walk (misses, vertical rays on grid lines) mixed in."""
    H = fields.generate("fbm", (65, 80), seed=9, amplitude=12.0, scale=24.0)
    fld = algos.Field(H)
    rng = np.random.default_rng(n)
    o = np.column_stack([rng.uniform(-5, 85, n), rng.uniform(-5, 70, n),
                         rng.uniform(0, 30, n)])
    d = np.column_stack([rng.normal(size=n), rng.normal(size=n), -rng.uniform(0, 0.5, n)])
    if n > 3:
        o[::4, :2] = np.round(o[::4, :2])  # on grid vertices
        d[::4, :2] = 0.0                   # straight down there
    _check(fld, o, d, f"{n} rays")


@pytest.mark.parametrize("fine_level", [0, 1, 3, 5])
def test_bench_rays_every_floor_level(fine_level):
    """The benchmark's random rays (5-20 degrees down) over fBm with several mip levels,
    at several floor levels of the walk."""
    H = fields.generate("fbm", (257, 300), seed=7, amplitude=40.0, scale=64.0)
    fld = algos.Field(H)
    for r in (1, 3, 25):
        o, d = raysets.first_hit_rays(fld, r, 150, seed=11 + r)
        _check(fld, o, d, f"fbm r={r}, fine_level={fine_level}", fine_level=fine_level)


def test_threads_and_render():
    """Threads split the batch and change nothing; render draws dda_maxmip's image."""
    H = fields.generate("fbm", (97, 97), seed=2, amplitude=15.0, scale=24.0)
    fld = algos.Field(H)
    o, d = raysets.first_hit_rays(fld, 3, 400, seed=5)
    one = algos.intersect("ring_maxmip", fld, o, d, threads=1)
    two = algos.intersect("ring_maxmip", fld, o, d, threads=2)
    assert np.isfinite(one.t).any()
    assert np.array_equal(one.t.view(np.int64), two.t.view(np.int64))
    assert np.array_equal(one.cell, two.cell)
    a = algos.render(H, "dda_maxmip", width=48, height=27, threads=1)
    b = algos.render(H, "ring_maxmip", width=48, height=27, threads=1)
    assert np.isfinite(a.depth).any()
    assert np.array_equal(a.depth.view(np.int64), b.depth.view(np.int64))
    assert np.array_equal(a.cell, b.cell)


def test_rejects_bad_input():
    H = first_hit_fields(SHAPE)["flat"]
    o = np.array([[1.0, 1.0, 5.0], [2.0, 2.0, 5.0]])
    with pytest.raises(ValueError, match="direction"):
        algos.intersect("ring_maxmip", H, o, np.array([[0.5, 0.0, -1.0], [np.nan, 0.0, -1.0]]))
    with pytest.raises(ValueError, match="fine_level"):
        algos.intersect("ring_maxmip", H, o, np.array([[0.5, 0.0, -1.0]] * 2), fine_level=-1)
