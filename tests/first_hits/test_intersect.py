"""First hits: every intersector against the brute force, culling against no culling,
Embree against us, and the hit record's conventions."""
import math

import numpy as np
import pytest

import algos
from algos.registry import INTERSECTOR_REGISTRY
from datasets_gen import fields

from ..helpers import first_hit_fields

STRICT = [n for n, a in INTERSECTOR_REGISTRY.items() if a.accuracy in ("exact", "float64")]
SHAPE = (33, 41)  # rows, cols: not square


def _rays(seed, n=160):
    """Grazing, steep, vertical, starting inside, entering through the sides."""
    rng = np.random.Generator(np.random.PCG64(seed))
    rows, cols = SHAPE
    o, d = [], []
    k = n // 5
    # grazing: nearly horizontal, from inside and around
    o.append(np.column_stack([rng.uniform(-5, cols + 5, k), rng.uniform(-5, rows + 5, k), rng.uniform(0, 8, k)]))
    d.append(np.column_stack([rng.normal(size=k), rng.normal(size=k), rng.uniform(-0.05, 0.0, k)]))
    # steep
    o.append(np.column_stack([rng.uniform(0, cols - 1, k), rng.uniform(0, rows - 1, k), rng.uniform(6, 20, k)]))
    d.append(np.column_stack([rng.normal(size=k) * 0.2, rng.normal(size=k) * 0.2, -np.ones(k)]))
    # vertical, some exactly on grid lines and vertices
    xy = np.column_stack([rng.uniform(0, cols - 1, k), rng.uniform(0, rows - 1, k)])
    xy[: k // 2] = np.round(xy[: k // 2])
    o.append(np.column_stack([xy, rng.uniform(-2, 20, k)]))
    d.append(np.tile([0.0, 0.0, -1.0], (k, 1)))
    # starting inside the solid (low), any direction
    o.append(np.column_stack([rng.uniform(0, cols - 1, k), rng.uniform(0, rows - 1, k), rng.uniform(-3, 1, k)]))
    d.append(np.column_stack([rng.normal(size=k), rng.normal(size=k), rng.normal(size=k)]))
    # entering through the sides, low enough to hit the side wall or soon after
    side = rng.integers(0, 4, k)
    start = np.column_stack([rng.uniform(0, cols - 1, k), rng.uniform(0, rows - 1, k)])
    start[side == 0, 0] = -3
    start[side == 1, 0] = cols + 2
    start[side == 2, 1] = -3
    start[side == 3, 1] = rows + 2
    centre = np.array([(cols - 1) / 2, (rows - 1) / 2])
    towards = centre + rng.normal(size=(k, 2)) * 5 - start
    o.append(np.column_stack([start, rng.uniform(-1, 9, k)]))
    d.append(np.column_stack([towards, rng.uniform(-0.3, 0.1, k) * np.linalg.norm(towards, axis=1)]))
    return np.concatenate(o), np.concatenate(d)


@pytest.fixture(scope="module")
def cases():
    out = {}
    o, d = _rays(17)
    for fname, H in first_hit_fields(SHAPE).items():
        fld = algos.Field(H)
        for surface in algos.SURFACES:
            t, cell = algos.brute_force_hits(H, o, d, surface)
            out[(fname, surface)] = (fld, o, d, t, cell)
    return out


def _compare(name, surface, fname, got_t, ref_t, o, d):
    hit_ref, hit_got = np.isfinite(ref_t), np.isfinite(got_t)
    disagree = np.nonzero(hit_ref != hit_got)[0]
    both = hit_ref & hit_got
    err = np.zeros_like(ref_t)
    err[both] = np.abs(got_t[both] - ref_t[both]) / (1 + np.abs(ref_t[both]))
    far = np.nonzero(err > 1e-9)[0]
    for label, idx in (("hit/miss differs", disagree), ("|dt| > 1e-9 (1+|t|)", far)):
        if len(idx):
            k = idx[0]
            raise AssertionError(
                f"{name} on {surface}/{fname}: {len(idx)} rays {label}; first: origin="
                f"{o[k].tolist()!r} direction={d[k].tolist()!r} brute t={ref_t[k]!r} got t={got_t[k]!r}")


@pytest.mark.parametrize("name", STRICT)
def test_matches_brute_force(name, cases):
    for (fname, surface), (fld, o, d, t, _) in cases.items():
        hits = algos.intersect(name, fld, o, d, surface=surface)
        _compare(name, surface, fname, hits.t, t, o, d)


@pytest.mark.parametrize("name", ["runs", "runs_f64", "runs_periodic", "runs_maxmip"])
def test_run_culling_changes_nothing(name, cases):
    for (fname, surface), (fld, o, d, _, _) in cases.items():
        culled = algos.intersect(name, fld, o, d, surface=surface, outputs=("t", "cell", "stats"))
        plain = algos.intersect(name, fld, o, d, surface=surface, cull_runs=False, cull_cells=False,
                                outputs=("t", "cell", "stats"))
        assert np.array_equal(culled.t, plain.t), (name, fname, surface)
        assert np.array_equal(culled.cell, plain.cell)
        assert plain.stats["runs_culled"].sum() == 0
    # long runs (the range-maximum cull takes runs of >= 16 cells): rays at slope ~1/40
    # over a long field, on every surface, must also agree, and the cull must fire
    fld = algos.Field(fields.generate("fbm", (70, 400), seed=21, amplitude=20.0, scale=60.0))
    rng = np.random.Generator(np.random.PCG64(8))
    n = 300
    o = np.column_stack([rng.uniform(0, 20, n), rng.uniform(0, 69, n),
                         rng.uniform(fld.heights.max() - 5, fld.heights.max() + 20, n)])
    d = np.column_stack([np.ones(n), rng.uniform(-1 / 40, 1 / 40, n), -rng.uniform(0.01, 0.08, n)])
    culled_total = 0
    for surface in algos.SURFACES:
        culled = algos.intersect(name, fld, o, d, surface=surface, outputs=("t", "cell", "stats"))
        plain = algos.intersect(name, fld, o, d, surface=surface, cull_runs=False, cull_cells=False)
        assert np.array_equal(culled.t, plain.t), (name, "long runs", surface)
        assert np.array_equal(culled.cell, plain.cell)
        culled_total += culled.stats["runs_culled"].sum()
    assert culled_total > 0 or name == "runs_maxmip"


@pytest.mark.parametrize("name,base", [("dda_maxmip", "dda"), ("runs_maxmip", "runs")])
def test_mipmap_skipping_changes_nothing(name, base, cases):
    skipped = 0
    for (fname, surface), (fld, o, d, _, _) in cases.items():
        fast = algos.intersect(name, fld, o, d, surface=surface, outputs=("t", "stats"))
        slow = algos.intersect(base, fld, o, d, surface=surface, cull_cells=False)
        both = np.isfinite(fast.t) & np.isfinite(slow.t)
        assert np.array_equal(np.isfinite(fast.t), np.isfinite(slow.t)), (name, fname, surface)
        assert np.allclose(fast.t[both], slow.t[both], rtol=1e-12, atol=1e-12)
        skipped += int(fast.stats["tiles_skipped"].sum())
    assert skipped > 0, "the mipmap never skipped a tile"


@pytest.mark.parametrize("fine_level", [0, 1, 2, 4, 30])
def test_runs_maxmip_fine_levels(fine_level, cases):
    fld, o, d, t, _ = cases[("fbm", "bilinear")]
    hits = algos.intersect("runs_maxmip", fld, o, d, surface="bilinear", fine_level=fine_level)
    _compare("runs_maxmip", "bilinear", "fbm", hits.t, t, o, d)


@pytest.mark.parametrize("side", [(7, 5), (64, 64), (65, 33), (2, 130)])
def test_every_size_works_for_the_mipmap(side):
    H = fields.generate("fbm", side, seed=1, amplitude=4.0, scale=8.0)
    rng = np.random.Generator(np.random.PCG64(2))
    n = 200
    o = np.column_stack([rng.uniform(-2, side[1] + 1, n), rng.uniform(-2, side[0] + 1, n), rng.uniform(2, 8, n)])
    d = np.column_stack([rng.normal(size=n), rng.normal(size=n), rng.uniform(-0.5, -0.02, n)])
    t, _ = algos.brute_force_hits(H, o, d, "triangles")
    for name in ("dda_maxmip", "runs_maxmip"):
        _compare(name, "triangles", f"fbm{side}", algos.intersect(name, H, o, d).t, t, o, d)


def test_dda_f32_mostly_agrees(cases):
    """float32 traversal: measured, not exact; on these small grids it nearly always agrees."""
    total = agree = 0
    for (fname, surface), (fld, o, d, t, _) in cases.items():
        got = algos.intersect("dda_f32", fld, o, d, surface=surface).t
        both = np.isfinite(got) & np.isfinite(t)
        close = np.ones_like(both)
        close[both] = np.abs(got[both] - t[both]) <= 1e-9 * (1 + np.abs(t[both]))
        ok = (np.isfinite(got) == np.isfinite(t)) & close
        total += len(t)
        agree += int(ok.sum())
    assert agree / total > 0.99


def test_marching_converges(cases):
    fld, o, d, t, _ = cases[("fbm", "triangles")]
    above = o[:, 2] > 5
    errors = {}
    for steps in (16, 128, 1024):
        got = algos.intersect("march_linear", fld, o[above], d[above], march_steps=steps).t
        both = np.isfinite(got) & np.isfinite(t[above])
        errors[steps] = float(np.median(np.abs(got[both] - t[above][both])))
    assert errors[1024] < errors[128] < errors[16]
    binary = algos.intersect("march_binary", fld, o[above], d[above]).t
    both = np.isfinite(binary) & np.isfinite(t[above])
    assert np.median(np.abs(binary[both] - t[above][both])) < errors[128] / 100
    growing = algos.intersect("march_growing", fld, o[above], d[above]).t
    assert np.mean(np.isfinite(growing) == np.isfinite(t[above])) > 0.9


def test_embree_agrees_on_triangles():
    H = fields.generate("fbm", (129, 129), seed=8, amplitude=12.0, scale=32.0)
    rng = np.random.Generator(np.random.PCG64(9))
    n = 4000
    o = np.column_stack([rng.uniform(0, 128, n), rng.uniform(0, 128, n), np.full(n, 20.0)])
    phi = rng.uniform(0, 2 * np.pi, n)
    elevation = np.radians(rng.uniform(5, 60, n))
    d = np.column_stack([np.cos(phi) * np.cos(elevation), np.sin(phi) * np.cos(elevation), -np.sin(elevation)])
    fld = algos.Field(H)
    ours = algos.intersect("runs", fld, o, d, outputs=("t", "cell"))
    theirs = algos.intersect("embree", fld, o, d, outputs=("t", "cell", "normal"))
    hit_ours, hit_theirs = np.isfinite(ours.t), np.isfinite(theirs.t)
    both = hit_ours & hit_theirs
    close = np.zeros(n, bool)
    close[both] = np.abs(theirs.t[both] - ours.t[both]) / ours.t[both] <= 1e-4
    agree = (hit_ours == hit_theirs) & (close | ~hit_ours)
    assert agree.mean() >= 0.999, f"{(~agree).sum()} of {n} rays disagree"
    # every disagreement lies within float32 tolerance of a triangle edge
    for k in np.nonzero(~agree)[0]:
        t = ours.t[k] if hit_ours[k] else theirs.t[k]
        x, y = o[k, 0] + t * d[k, 0], o[k, 1] + t * d[k, 1]
        u, v = x - math.floor(x), y - math.floor(y)
        edge = min(u, 1 - u, v, 1 - v, abs(u - v))
        assert edge < 1e-3, f"disagreement away from an edge: origin={o[k].tolist()} direction={d[k].tolist()}"
    assert np.all(np.abs(np.linalg.norm(theirs.normal[hit_theirs], axis=1) - 1) < 1e-6)


# ---- the hit record --------------------------------------------------------------------
def test_outputs_only_on_request():
    H = fields.generate("fbm", (16, 16), seed=1)
    o, d = np.array([[8.0, 8.0, 100.0]]), np.array([[0.1, 0.2, -1.0]])
    hits = algos.intersect("runs", H, o, d)
    assert hits.normal is None and hits.stats is None and hits.t is not None and hits.cell is not None
    hits = algos.intersect("runs", H, o, d, outputs=("normal",))
    assert hits.t is None and hits.cell is None and hits.normal.shape == (1, 3)


def test_plane_hit_and_normal():
    """A tilted plane: the analytic hit and normal for every surface."""
    H = fields.generate("tilted_plane", (20, 30), slope_x=0.25, slope_y=0.5, height=1.0)
    o, d = np.array([[10.3, 7.6, 40.0]]), np.array([[0.0, 0.0, -2.0]])
    expected_t = (40.0 - (1.0 + 0.25 * 10.3 + 0.5 * 7.6)) / 2.0
    for surface in algos.SURFACES:
        for name in STRICT:
            hits = algos.intersect(name, H, o, d, surface=surface, outputs=("t", "cell", "normal"))
            if surface == "flat":  # flat uses the cell's mean height
                continue
            assert hits.t[0] == pytest.approx(expected_t, rel=1e-12), (name, surface)
            assert tuple(hits.cell[0]) == (10, 7)
            n = np.array([-0.25, -0.5, 1.0]) / np.linalg.norm([-0.25, -0.5, 1.0])
            assert np.allclose(hits.normal[0], n), (name, surface)


def test_start_inside_and_side_walls():
    H = np.full((10, 10), 5.0, np.float32)
    # starts inside the solid: hits at t0 = tmin
    hits = algos.intersect("runs", H, [[4.5, 4.5, 1.0]], [[1.0, 0.0, 0.0]], outputs=("t", "normal"), tmin=0.25)
    assert hits.t[0] == 0.25
    # enters through the x = 0 side below the top: a wall facing the ray
    for surface in algos.SURFACES:
        hits = algos.intersect("midpoint", H, [[-2.0, 4.5, 1.0]], [[1.0, 0.0, 0.0]], surface=surface,
                               outputs=("t", "cell", "normal"))
        assert hits.t[0] == 2.0 and tuple(hits.cell[0]) == (0, 4)
        assert np.allclose(hits.normal[0], [-1.0, 0.0, 0.0])
    # from the far side, travelling -y
    hits = algos.intersect("dda", H, [[4.5, 12.0, 1.0]], [[0.0, -1.0, 0.0]], outputs=("t", "normal"))
    assert hits.t[0] == 3.0 and np.allclose(hits.normal[0], [0.0, 1.0, 0.0])


def test_flat_surface_wall_between_cells():
    """flat jumps at cell borders: a horizontal ray meets the wall of a higher cell."""
    H = np.zeros((4, 8), np.float32)
    H[:, 4:] = 10.0  # cells with i >= 4 average 10; cell 3 averages 5
    for name in STRICT:
        hits = algos.intersect(name, H, [[0.5, 1.5, 7.0]], [[1.0, 0.0, 0.0]], surface="flat",
                               outputs=("t", "cell", "normal"))
        assert hits.t[0] == 3.5 and tuple(hits.cell[0]) == (4, 1), name
        assert np.allclose(hits.normal[0], [-1.0, 0.0, 0.0]), name


def test_ray_on_a_grid_line_reads_the_cell_on_the_plus_side():
    """A ray in the plane x = 3 with dx = 0 reads column 3 only (docs/CONVENTIONS.md,
    "Points on a cell border"); column 2, taller, is not hit. (The kernels still test both
    sides here: tests/first_hits/test_conventions.py pins that difference.)"""
    H = np.zeros((4, 8), np.float32)
    H[:, :4] = 6.0  # cell 2 (x in [2, 3]) averages 6, cell 3 averages 3
    o, d = np.array([[3.0, 0.5, 10.0]]), np.array([[0.0, 1.0, -4.0]])
    ref, cell = algos.brute_force_hits(H, o, d, "flat")
    assert ref[0] == 1.75 and tuple(cell[0]) == (3, 2)  # z = 3 at t = 1.75 (y = 2.25)


def test_ray_on_the_far_face():
    H = np.zeros((5, 5), np.float32)
    H[:, 4] = 3.0
    for name in STRICT:
        hits = algos.intersect(name, H, [[4.0, 2.5, 10.0]], [[0.0, 0.0, -1.0]], surface="triangles",
                               outputs=("t", "cell"))
        assert hits.t[0] == 7.0 and tuple(hits.cell[0]) == (3, 2), name


def test_misses_and_tmax():
    H = np.zeros((5, 5), np.float32)
    hits = algos.intersect("runs", H, [[2.0, 2.0, 5.0], [2.0, 2.0, 5.0], [9.0, 9.0, 1.0]],
                           [[0.0, 0.0, 1.0], [0.1, 0.0, -1.0], [1.0, 1.0, -0.1]], tmax=[10, 4.0, 10],
                           outputs=("t", "cell", "normal"))
    assert np.all(np.isinf(hits.t)) and np.all(hits.cell == -1) and np.all(np.isnan(hits.normal))


def test_stats_count_work():
    H = fields.generate("fbm", (65, 65), seed=2, amplitude=4.0)
    o, d = np.array([[0.5, 3.2, 6.0]]), np.array([[1.0, 0.04, -0.2]])  # below hmax within the grid
    s = algos.intersect("runs", H, o, d, outputs=("t", "stats")).stats
    assert s["runs_visited"][0] >= 1 and s["cells_visited"][0] >= s["cells_tested"][0]


# ---- bad input -------------------------------------------------------------------------
def test_bad_heights():
    o, d = np.array([[1.0, 1.0, 5.0]]), np.array([[0.0, 0.0, -1.0]])
    bad = np.zeros((4, 4))
    bad[2, 3] = np.nan
    with pytest.raises(ValueError, match=r"heights: sample \(row 2, col 3\) is nan"):
        algos.intersect("runs", bad, o, d)
    with pytest.raises(ValueError, match="at least 2 x 2"):
        algos.intersect("runs", np.zeros((1, 5)), o, d)
    with pytest.raises(ValueError, match="2D"):
        algos.intersect("runs", np.zeros(5), o, d)
    with pytest.raises(TypeError, match="heights"):
        algos.intersect("runs", np.zeros((3, 3), complex), o, d)


def test_bad_rays_and_names():
    H = np.zeros((4, 4), np.float32)
    o, d = np.array([[1.0, 1.0, 5.0], [1.0, 1.0, 5.0]]), np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="directions: ray 1 is the zero vector"):
        algos.intersect("runs", H, o, d)
    d[1] = [np.inf, 0, 0]
    with pytest.raises(ValueError, match=r"directions: ray 1 .*\[1, 0\]"):
        algos.intersect("runs", H, o, d)
    with pytest.raises(ValueError, match=r"origins: expected shape \(N, 3\)"):
        algos.intersect("runs", H, o[:, :2], d)
    with pytest.raises(ValueError, match="2 origins but 1 directions"):
        algos.intersect("runs", H, o, d[:1])
    with pytest.raises(ValueError, match="unknown surface 'smooth'; valid surfaces are flat"):
        algos.intersect("runs", H, o[:1], d[:1], surface="smooth")
    with pytest.raises(ValueError, match="unknown intersector 'bvh'; valid names are dda"):
        algos.intersect("bvh", H, o[:1], d[:1])
    with pytest.raises(ValueError, match="embree supports only triangles"):
        algos.intersect("embree", H, o[:1], np.array([[0, 0, -1.0]]), surface="bilinear")
    with pytest.raises(ValueError, match="march_steps: not an option of runs"):
        algos.intersect("runs", H, o[:1], np.array([[0, 0, -1.0]]), march_steps=4)
    with pytest.raises(ValueError, match="outputs: unknown output 'depth'"):
        algos.intersect("runs", H, o[:1], np.array([[0, 0, -1.0]]), outputs=("depth",))


def test_c_entry_takes_four_argument_groups():
    """The C entry reads the field, the rays, the options and the outputs as four tuples
    (cext/binding/intersect.c); a malformed group is a TypeError naming it."""
    from algos import _kernels
    from algos.intersect import prepare_intersect
    from algos.registry import get_intersector

    fld = algos.Field(fields.fbm(9, 9, seed=3))
    o = np.array([[1.5, 2.5, 50.0], [3.25, 1.0, 40.0]])
    d = np.array([[0.6, 0.3, -1.0], [0.2, 0.7, -0.8]])
    p = prepare_intersect(get_intersector("dda"), fld, "triangles", o, d, None, None, ("t",),
                          {"cull_cells": True})
    assert len(p.args) == 6
    assert _kernels.intersect(*p.args) >= 0
    expected = algos.intersect("dda", fld, o, d).t
    np.testing.assert_array_equal(p.t, expected)
    for k, name in ((2, "field"), (3, "rays"), (4, "options"), (5, "outputs")):
        args = list(p.args)
        args[k] = args[k][:-1]
        with pytest.raises(TypeError, match=f"{name}: expected a tuple of"):
            _kernels.intersect(*args)
        args[k] = list(p.args[k])
        with pytest.raises(TypeError, match=f"{name}: expected a tuple of"):
            _kernels.intersect(*args)


def test_threads_split_the_rays_bit_identically():
    """Rays split across threads (each range its own views and pattern scratch) give the
    one-thread hits bit for bit."""
    from algos.parallel import MIN_RAYS_PER_CHUNK, split

    n = 4 * MIN_RAYS_PER_CHUNK + 7
    assert len(split(n, 4)) == 4  # four ranges: the split path runs
    fld = algos.Field(fields.fbm(33, 33, seed=5))
    rng = np.random.default_rng(11)
    o = np.column_stack([rng.uniform(0, 32, n), rng.uniform(0, 32, n), np.full(n, 9.0)])
    d = np.column_stack([rng.normal(size=n), rng.normal(size=n), -np.ones(n)])
    for name in ("dda", "runs_periodic", "dda_maxmip"):
        one = algos.intersect(name, fld, o, d, outputs=("t", "cell", "stats"))
        four = algos.intersect(name, fld, o, d, outputs=("t", "cell", "stats"), threads=4)
        np.testing.assert_array_equal(four.t, one.t, err_msg=name)
        np.testing.assert_array_equal(four.cell, one.cell, err_msg=name)
