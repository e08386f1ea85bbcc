"""The compact maximum tree and dda_compact (``algos.accel.compact``, ``cext/hierarchies/compact.c``): the
tree's layout and its conservative, tight bounds checked against NumPy tile maxima; the
hits equal to dda_maxmip's bit for bit (t, cell, normal) and to the brute force; bad
input.

The registry cross-checks (tests/first_hits/test_intersect.py, tests/first_hits/test_hit_pin.py, the fuzz
corpus through tests/fuzz/compact_cases.py) cover it too."""
import numpy as np
import pytest

import algos
from algos import _kernels
from algos.accel.compact import (
    LEAF_CODE_MAX,
    NODE_BYTES,
    build_compact,
    compact_bounds,
    compact_layout,
    compact_leaves,
    compact_nodes,
    leaf_step,
)
from datasets_gen import fields
from datasets_gen.rays import first_hit_rays


def _tile_max(cellmax, level):
    """The maximum over every 4^level x 4^level tile (edge tiles clipped), float32."""
    m = cellmax
    for _ in range(level):
        ny, nx = m.shape
        pad = np.full((-(-ny // 4) * 4, -(-nx // 4) * 4), -np.inf, np.float32)
        pad[:ny, :nx] = m
        m = pad.reshape(pad.shape[0] // 4, 4, pad.shape[1] // 4, 4).max(axis=(1, 3))
    return m


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (4, 4), (5, 17), (64, 64), (65, 130),
                                   (300, 257)])
def test_layout_counts_nodes_and_aligns_them(shape):
    """Level L has ceil(n / 4^L) tiles per side, the top (at least level 2) one node; level
    1 is stored as one leaf per 2 x 2 tiles; the buffer is 64 bytes per record, aligned to
    64."""
    layout = compact_layout(*shape)
    ny, nx = shape
    for level, (offset, py, px) in enumerate(layout, start=1):
        assert (py, px) == (-(-ny // 4 ** level), -(-nx // 4 ** level))
    assert layout[-1][1:] == (1, 1)
    assert len(layout) == 2 or layout[-2][1:] != (1, 1)
    assert layout[1][0] == -(-layout[0][1] // 2) * -(-layout[0][2] // 2)  # the leaves
    tree = build_compact(np.zeros(shape, np.float32))
    assert tree.dtype == np.uint8 and tree.nbytes == (layout[-1][0] + 1) * NODE_BYTES
    assert tree.ctypes.data % NODE_BYTES == 0


def _check_cell_bounds(tree, cellmax, what):
    """The cells' decoded bounds: at or above the float32 maximum, each code the smallest
    that is (code 0, or the next code down falls below the maximum), so within one leaf
    step of the maximum."""
    ny, nx = cellmax.shape
    true = cellmax.astype(np.float64)
    bound = compact_bounds(tree, ny, nx, 0)
    worst = np.unravel_index(np.argmax(true - bound), true.shape)
    assert np.all(bound >= true), (
        f"{what}: cell {worst} max {true[worst]!r} above its bound {bound[worst]!r}")
    j, i = np.mgrid[0:ny, 0:nx]
    tj, ti = j // 4, i // 4
    parent = compact_nodes(tree, ny, nx, 2)[tj // 4, ti // 4]
    slot = (4 * (tj % 4) + ti % 4)[..., None]
    lo, scale = parent["base"].astype(np.float64), parent["scale"].astype(np.float64)
    hi = lo + np.take_along_axis(parent["q"], slot, -1)[..., 0] * scale
    step = leaf_step(hi, lo)
    code = compact_leaves(tree, ny, nx)[tj, ti, 4 * (j % 4) + i % 4].astype(np.float64)
    assert np.all(lo <= hi) and np.all(step * LEAF_CODE_MAX >= hi - lo), what
    assert np.all((code == 0) | (lo + (code - 1) * step < true)), what
    # the low end, the node's base, is its lowest cell maximum
    node_min = np.full((tj.max() // 4 + 1, ti.max() // 4 + 1), np.inf)
    np.minimum.at(node_min, (tj // 4, ti // 4), true)
    assert np.array_equal(lo, node_min[tj // 4, ti // 4]), what


@pytest.mark.parametrize("seed", range(8))
def test_bounds_are_never_below_the_true_maximum_and_tight(seed):
    """At every level: bound >= the float32 maximum, in the kernel's float64 arithmetic,
    and above it by at most one code step (the cells: _check_cell_bounds); each node's
    `max` is its tile's maximum exactly."""
    rng = np.random.Generator(np.random.PCG64(seed))
    shape = (int(rng.integers(1, 90)), int(rng.integers(1, 90)))
    scale = 10.0 ** rng.uniform(-30, 30)
    cellmax = (rng.standard_normal(shape) * scale + rng.uniform(-1, 1) * scale * 10)
    cellmax = cellmax.astype(np.float32)
    if seed == 0:
        cellmax[:] = np.float32(3.25)  # a flat field: every range empty
    tree = build_compact(cellmax)
    layout = compact_layout(*shape)
    _check_cell_bounds(tree, cellmax, f"seed={seed} shape={shape}")
    for level in range(1, len(layout)):
        true = _tile_max(cellmax, level).astype(np.float64)
        bound = compact_bounds(tree, *shape, level)
        assert bound.shape == true.shape
        worst = np.unravel_index(np.argmax(true - bound), true.shape)
        assert np.all(bound >= true), (
            f"seed={seed} shape={shape} level={level}: tile {worst} max {true[worst]!r} "
            f"above its bound {bound[worst]!r}")
        parents = compact_nodes(tree, *shape, level + 1)
        j, i = np.mgrid[0:true.shape[0], 0:true.shape[1]]
        step = parents["scale"][j // 4, i // 4].astype(np.float64)
        slack = 1e-6 * np.abs(true) + 1e-300
        assert np.all(bound - true <= step * (1 + 1e-6) + slack), (seed, shape, level)
        # the node's own maximum: the tile's, exactly
        assert np.array_equal(parents["max"], _tile_max(cellmax, level + 1))


def test_leaves_code_the_cells_and_codes_are_relative_to_the_node():
    """A leaf holds 2 x 2 tiles' cell codes (0 outside the grid), from the parent's base
    up to the tile's bound; a level-2 node's codes start at its lowest cell maximum, its
    highest child decodes to at least its max, and the used bits mark the children inside
    the grid."""
    cellmax = np.arange(21 * 6, dtype=np.float32).reshape(6, 21)  # 2 x 6 tiles, 1 x 3 leaves
    tree = build_compact(cellmax)
    layout = compact_layout(6, 21)
    assert layout[1][0] == 3  # the leaves: one line per 8 x 8 cells
    leaves = compact_leaves(tree, 6, 21)
    assert leaves.shape == (2, 6, 16)
    bounds = compact_bounds(tree, 6, 21, 0)
    # at or above the maximum, within a step ((hi - lo) / 254, hi - lo at most 120 here)
    assert np.all(bounds >= cellmax) and np.all(bounds - cellmax < 120.0 / 254)
    assert bounds[0, 0] == 0.0  # the node's lowest cell: code 0 at the node's base
    # the codes grow with the cell maxima, each tile's maximum coded highest
    for tile in (leaves[0, 0], leaves[1, 1][:8]):
        assert np.all(np.diff(tile.astype(int)) > 0) and tile.argmax() == len(tile) - 1
    # cells outside the grid: code 0 (in the raw records: rows 6 and 7 of every leaf)
    assert not leaves[1, 5].reshape(4, 4)[2:].any() and not leaves[1, 5].reshape(4, 4)[:, 1:].any()
    assert not tree[:3 * NODE_BYTES].reshape(3, 4, 16)[:, 2:, 8:].any()
    node = compact_nodes(tree, 6, 21, 2)[0, 0]  # tiles 0..3 x 0..1
    assert node["base"] == 0.0 and node["max"] == cellmax[:, :16].max()
    assert node["q"][4 + 3] == 65535 and np.all(node["q"][:8] > 0)
    assert node["used"] == 0xFF
    assert compact_nodes(tree, 6, 21, 2)[0, 1]["base"] == 16.0
    top = compact_nodes(tree, 6, 21, 3)
    assert top.shape == (1, 1) and top[0, 0]["max"] == cellmax.max()
    assert top[0, 0]["base"] == cellmax[:, :16].max()  # its lowest child maximum
    assert top[0, 0]["used"] == 0b11


def _rays(fld, n, seed):
    """Bench-like rays at three run lengths, grazing rays a hair above the cell maxima,
    and rising rays."""
    out_o, out_d = [], []
    for r in (1, 7, "random"):
        o, d = first_hit_rays(fld, r, n, seed)
        out_o.append(o)
        out_d.append(d)
    rng = np.random.Generator(np.random.PCG64(seed))
    rows, cols = fld.heights.shape
    x, y = rng.uniform(0, cols - 1, n), rng.uniform(0, rows - 1, n)
    i = np.minimum(np.floor(x).astype(int), cols - 2)
    j = np.minimum(np.floor(y).astype(int), rows - 2)
    z = fld.cellmax[j, i].astype(float) + 10.0 ** rng.uniform(-9, -1, n)
    a = rng.uniform(0, 2 * np.pi, n)
    dz = -(10.0 ** rng.uniform(-6, -1, n)) * np.where(np.arange(n) % 4 == 0, -1, 1)
    out_o.append(np.column_stack([x, y, z]))
    out_d.append(np.column_stack([np.cos(a), np.sin(a), dz]))
    return np.concatenate(out_o), np.concatenate(out_d)


FIELDS = {
    "fbm": lambda: fields.generate("fbm", (129, 203), seed=3, amplitude=30.0, scale=40.0),
    "terraces": lambda: fields.generate("terraces", (97, 130), seed=5, amplitude=30.0,
                                        scale=40.0),
    "spike": lambda: fields.generate("spike", (70, 61), height=30.0, radius=12.0),
    "tiny": lambda: np.array([[0.0, 1.0, 0.5], [2.0, -1.0, 0.25]]),
}


@pytest.mark.parametrize("cull", [True, False])
@pytest.mark.parametrize("surface", algos.SURFACES)
@pytest.mark.parametrize("field_name", list(FIELDS))
def test_equals_dda_maxmip_bit_for_bit(field_name, surface, cull):
    """t, cell and normal equal dda_maxmip's on every ray; the tree skips tiles."""
    fld = algos.Field(FIELDS[field_name]())
    o, d = _rays(fld, 120, seed=11)
    outputs = ("t", "cell", "normal", "stats")
    ref = algos.intersect("dda_maxmip", fld, o, d, surface=surface, outputs=outputs,
                          cull_cells=cull)
    got = algos.intersect("dda_compact", fld, o, d, surface=surface, outputs=outputs,
                          cull_cells=cull)
    for name in ("t", "cell", "normal"):
        a, b = getattr(got, name), getattr(ref, name)
        same = ((a == b) | (np.isnan(a) & np.isnan(b))).reshape(len(a), -1).all(axis=1)
        if not same.all():
            k = int(np.nonzero(~same)[0][0])
            raise AssertionError(
                f"{field_name} {surface} cull={cull}: {name} differs on ray {k}: "
                f"origin={o[k].tolist()!r} direction={d[k].tolist()!r} "
                f"dda_compact {a[k]!r} dda_maxmip {b[k]!r}")
    if field_name != "tiny":  # (the tiny field's rays leave it before they fall far)
        assert np.isfinite(ref.t).sum() > 50
        assert got.stats["tiles_skipped"].sum() > 0


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_equals_the_brute_force(surface):
    """Hits within the exact kernels' tolerance of the brute force (tests/first_hits/test_intersect.py
    checks every strict intersector the same way on its own inputs)."""
    from algos.brute import brute_force_hits

    fld = algos.Field(FIELDS["fbm"]())
    o, d = _rays(fld, 25, seed=4)
    got = algos.intersect("dda_compact", fld, o, d, surface=surface)
    ref = brute_force_hits(fld.heights, o, d, surface=surface)
    ref_t = ref[0] if isinstance(ref, tuple) else ref.t
    assert np.array_equal(np.isfinite(got.t), np.isfinite(ref_t))
    both = np.isfinite(ref_t)
    assert np.all(np.abs(got.t[both] - ref_t[both]) <= 1e-9 * (1 + np.abs(ref_t[both])))


def test_axis_parallel_and_vertical_rays():
    """Rays along x, along y, on grid lines (dda_maxmip's fallback walk) and vertical."""
    fld = algos.Field(FIELDS["fbm"]())
    rows, cols = fld.heights.shape
    top = float(fld.heights.max()) + 1
    o = np.array([[0.5, 10.25, top], [cols - 1.5, 7.0, top], [3.0, 0.0, top],
                  [17.25, rows - 1.0, top], [40.5, 40.5, top], [12.0, 13.0, top]])
    d = np.array([[1.0, 0.0, -0.5], [-1.0, 0.0, -0.75], [0.0, 1.0, -0.5],
                  [0.0, -1.0, -0.625], [0.0, 0.0, -1.0], [0.0, 0.0, -1.0]])
    for surface in algos.SURFACES:
        ref = algos.intersect("dda_maxmip", fld, o, d, surface=surface)
        got = algos.intersect("dda_compact", fld, o, d, surface=surface)
        assert np.array_equal(got.t.view(np.uint64), ref.t.view(np.uint64)), surface
        assert np.array_equal(got.cell, ref.cell), surface
        assert np.isfinite(got.t).all()


def test_build_stats_record_the_tree():
    fld = algos.Field(FIELDS["fbm"]())
    algos.intersect("dda_compact", fld, [[1.5, 1.5, 100.0]], [[1.0, 0.5, -1.0]])
    stats = fld.build_stats["compact"]
    ny, nx = fld.rows - 1, fld.cols - 1
    assert stats["bytes"] == (compact_layout(ny, nx)[-1][0] + 1) * NODE_BYTES
    assert stats["seconds"] >= 0
    assert 1.0 <= stats["bytes"] / (ny * nx) <= 1.6  # about 1.27 bytes per cell


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match="cellmax: NaN at cell"):
        build_compact(np.array([[0.0, np.nan]], np.float32))
    with pytest.raises(ValueError, match="cellmax"):
        build_compact(np.zeros(3, np.float32))
    cellmax = np.zeros((5, 6), np.float32)
    tree = build_compact(cellmax)
    with pytest.raises(ValueError, match="compact: expected"):
        _kernels.compact_build(cellmax, tree[:-64])
    with pytest.raises(TypeError, match="compact"):
        _kernels.compact_build(cellmax, tree.view(np.int8))
    raw = np.zeros(tree.nbytes + 64, np.uint8)
    start = (-raw.ctypes.data) % 64 + 1
    with pytest.raises(ValueError, match="aligned"):
        _kernels.compact_build(cellmax, raw[start:start + tree.nbytes])


def test_the_entry_runs_only_dda_compact():
    """intersect_compact refuses other kernels, and intersect refuses dda_compact."""
    from algos.intersect import prepare_intersect
    from algos.registry import get_intersector

    fld = algos.Field(FIELDS["fbm"]())
    o, d = np.array([[1.5, 1.5, 100.0]]), np.array([[1.0, 0.5, -1.0]])
    p = prepare_intersect(get_intersector("dda_compact"), fld, "triangles", o, d, None, None,
                          ("t",), {"cull_cells": True})
    with pytest.raises(ValueError, match="only intersect_compact runs dda_compact"):
        _kernels.intersect(*p.args)
    args = list(p.args)
    args[0] = get_intersector("dda_maxmip").kernel_id
    with pytest.raises(ValueError, match="only intersect_compact runs dda_compact"):
        _kernels.intersect_compact(p.compact, *args)


def test_study_quick_tier_writes_table_and_plot(tmp_path):
    """The study's quick tier (no callgrind here: tests/first_hits/test_compact.py's last test counts)
    writes the table, the CSV and the plot, with both kernels at every side."""
    from bench.studies import compact as study

    paths = study.run(str(tmp_path), dict(sizes=(64, 128), rays=40, repeats=1), counts=False,
                      echo=lambda *_: None)
    for p in paths.values():
        assert (tmp_path / p.rsplit("/", 1)[1]).stat().st_size > 0
    import csv

    rows = list(csv.DictReader(open(paths["csv"])))
    assert {(r["kernel"], r["size"]) for r in rows} == {
        (k, str(s)) for k in study.KERNELS for s in (64, 128)}
    assert all(float(r["bytes_per_sample"]) > 1 for r in rows)
    table = open(paths["md"]).read()
    assert "`dda_compact`" in table and "uptime" in table


@pytest.mark.skipif(__import__("shutil").which("valgrind") is None
                    or "libasan" in __import__("os").environ.get("LD_PRELOAD", ""),
                    reason="needs valgrind (and no preloaded sanitizer runtime)")
def test_callgrind_cache_counts_are_per_ray_and_exact():
    """callgrind's cache simulation: exact instructions and data accesses per ray for both
    kernels, misses within a few per cent across runs (they depend on where the arrays
    land in memory) and never above the accesses."""
    from bench.studies.compact import KERNELS, callgrind_cache_counts

    a = callgrind_cache_counts(64, 20)
    b = callgrind_cache_counts(64, 20)
    assert set(a) == set(KERNELS)
    for k in KERNELS:
        for key in ("instructions", "data_accesses"):  # exact whatever the load
            assert a[k][key] == b[k][key], (k, key)
        for key in ("d1_misses", "ll_misses"):
            assert abs(a[k][key] - b[k][key]) <= 0.05 * a[k][key], (k, key, a[k], b[k])
        assert 0 < a[k]["ll_misses"] <= a[k]["d1_misses"] <= a[k]["data_accesses"]
        assert a[k]["instructions"] > a[k]["data_accesses"]


@pytest.mark.skipif(__import__("shutil").which("valgrind") is None
                    or "libasan" in __import__("os").environ.get("LD_PRELOAD", ""),
                    reason="needs valgrind (and no preloaded sanitizer runtime)")
def test_callgrind_regimes_count_the_same_rays_cold_and_warm():
    """The flushed, warm and other-warmed regimes count the same rays (the same
    instructions and data accesses), and each warming removes LL misses (the other rays
    warm the very mappings the counted rays read)."""
    from bench.studies.compact import REGIMES, callgrind_cache_counts

    got = callgrind_cache_counts(64, 20, kernels=("dda_compact",), regimes=True)
    counts = got["dda_compact"]
    assert set(counts) == set(REGIMES)
    for key in ("instructions", "data_accesses"):
        assert len({c[key] for c in counts.values()}) == 1, (key, counts)
    assert counts["warm"]["ll_misses"] <= counts["other_warmed"]["ll_misses"] \
        < counts["flushed"]["ll_misses"], counts
    assert counts["flushed"]["ll_misses"] > 0
