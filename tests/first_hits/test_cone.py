"""The cone intersector (cone step mapping made exact, ``algos.accel.cone`` and ``cext/hierarchies/cone.c``):
the structure's guarantee checked cell pair by cell pair, the hits against the cell walk
and the brute force (grazing rays, where cones collapse, included), and bad input.

The registry cross-checks (tests/first_hits/test_intersect.py, tests/first_hits/test_hit_pin.py) cover it too."""
import numpy as np
import pytest

import algos
from algos import _kernels
from algos.accel.cone import build_cone, cone_for
from datasets_gen import fields


def _ring_distance(shape):
    """Chebyshev ring distance between every pair of cells: (ny*nx, ny*nx)."""
    ny, nx = shape
    j, i = np.divmod(np.arange(ny * nx), nx)
    return np.maximum(np.abs(i[:, None] - i[None, :]), np.abs(j[:, None] - j[None, :]))


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("radius", [2, 3, 32])
def test_every_cell_maximum_lies_below_every_cone(seed, radius):
    """For cells c and a at ring n: cellmax[a] <= top[c] + slope[c] * max(0, n - 1), in
    float64: the guarantee the kernel's steps rely on (module docstring of algos.accel.cone),
    including rings beyond the searched radius."""
    rng = np.random.Generator(np.random.PCG64(seed))
    shape = (int(rng.integers(1, 14)), int(rng.integers(1, 14)))
    scale = 10.0 ** rng.uniform(-3, 3)
    cellmax = (rng.standard_normal(shape) * scale).astype(np.float32)
    cone = build_cone(cellmax, radius)
    assert cone.dtype == np.float32 and cone.shape == shape + (2,)
    top, slope = cone[..., 0], cone[..., 1]
    assert np.all(slope >= 0) and np.all(np.isfinite(slope))
    n = _ring_distance(shape)
    bound = (top.ravel().astype(np.float64)[:, None]
             + slope.ravel().astype(np.float64)[:, None] * np.maximum(n - 1, 0))
    worst = np.argmax(cellmax.ravel()[None, :] - bound)
    c, a = np.unravel_index(worst, bound.shape)
    assert np.all(cellmax.ravel()[None, :] <= bound), (
        f"seed={seed} radius={radius} shape={shape}: cell {a} (max {cellmax.ravel()[a]!r}) "
        f"above the cone of cell {c} (top {top.ravel()[c]!r}, slope {slope.ravel()[c]!r})")


def test_cone_is_tight_on_a_single_peak():
    """A single peak of height 10 on a flat field: the cone of a cell 5 rings away has
    its top at 0 and slope 10 / (5 - 1), rounded up by at most a few float32 ulps."""
    cellmax = np.zeros((21, 21), np.float32)
    cellmax[10, 10] = 10.0
    cone = build_cone(cellmax, 32)
    top, slope = cone[..., 0], cone[..., 1]
    assert top[10, 5] == 0.0
    assert 2.5 <= slope[10, 5] <= np.nextafter(np.nextafter(np.float32(2.5), np.float32(3)),
                                               np.float32(3))
    assert top[10, 9] == 10.0 and slope[10, 9] == 0.0  # the peak's neighbours: flat top


def _grazing_rays(fld, n, seed):
    """Rays a hair above the surface at their start, nearly horizontal: cones collapse."""
    rng = np.random.Generator(np.random.PCG64(seed))
    rows, cols = fld.heights.shape
    x = rng.uniform(1, cols - 2, n)
    y = rng.uniform(1, rows - 2, n)
    i, j = np.floor(x).astype(int), np.floor(y).astype(int)
    z = fld.cellmax[j, i].astype(float) + 10.0 ** rng.uniform(-9, -1, n)
    angle = rng.uniform(0, 2 * np.pi, n)
    d = np.column_stack([np.cos(angle), np.sin(angle), -(10.0 ** rng.uniform(-6, -1, n))])
    return np.column_stack([x, y, z]), d


@pytest.mark.parametrize("surface", algos.SURFACES)
@pytest.mark.parametrize("field_name", ["fbm", "terraces", "spike"])
def test_cone_equals_the_cell_walk_bit_for_bit(surface, field_name):
    """Steep, bench-like and grazing rays: t and cell equal dda's (the cell walk whose
    cells the cone kernel finishes with), and the cone does skip."""
    H = fields.generate(field_name, (97, 130), seed=5, amplitude=30.0, scale=40.0) \
        if field_name != "spike" else fields.generate("spike", (97, 130), height=30.0, radius=20.0)
    fld = algos.Field(H)
    from datasets_gen.rays import first_hit_rays

    groups = [first_hit_rays(fld, r, 200, seed=3 + r) for r in (1, 5, 100)]
    groups.append(_grazing_rays(fld, 300, 9))
    steps = 0
    for o, d in groups:
        cone = algos.intersect("cone", fld, o, d, surface=surface,
                               outputs=("t", "cell", "stats"))
        walk = algos.intersect("dda", fld, o, d, surface=surface, outputs=("t", "cell"))
        differ = np.nonzero((cone.t != walk.t) | np.any(cone.cell != walk.cell, axis=1))[0]
        if len(differ):
            k = differ[0]
            raise AssertionError(
                f"cone vs dda on {field_name}/{surface}: {len(differ)} rays differ; first: "
                f"origin={o[k].tolist()!r} direction={d[k].tolist()!r} "
                f"dda t={walk.t[k]!r} cell={walk.cell[k].tolist()} cone t={cone.t[k]!r} "
                f"cell={cone.cell[k].tolist()}")
        steps += int(cone.stats["tiles_skipped"].sum())
    assert steps > 0, "the cone never stepped"


def test_grazing_rays_match_the_brute_force():
    H = fields.generate("fbm", (40, 50), seed=11, amplitude=8.0, scale=16.0)
    fld = algos.Field(H)
    o, d = _grazing_rays(fld, 200, 4)
    for surface in algos.SURFACES:
        t_ref, _ = algos.brute_force_hits(H, o, d, surface)
        got = algos.intersect("cone", fld, o, d, surface=surface).t
        assert np.array_equal(np.isfinite(got), np.isfinite(t_ref)), surface
        hit = np.isfinite(t_ref)
        assert np.all(np.abs(got[hit] - t_ref[hit]) <= 1e-9 * (1 + np.abs(t_ref[hit]))), surface


def test_the_structure_is_built_once_and_recorded():
    fld = algos.Field(fields.generate("fbm", (33, 41), seed=3, amplitude=6.0, scale=16.0))
    first = cone_for(fld)
    assert cone_for(fld) is first
    algos.intersect("cone", fld, [[1.0, 1.0, 20.0]], [[1.0, 0.5, -1.0]])
    assert fld.build_stats["cone"]["bytes"] == 2 * 4 * 32 * 40  # 8 bytes per cell
    algos.intersect("cone", fld, [[1.0, 1.0, 20.0]], [[1.0, 0.5, -1.0]], surface="plane3")
    assert "cone/plane3" in fld.build_stats


def test_bad_structure_input():
    with pytest.raises(ValueError, match="radius"):
        build_cone(np.zeros((3, 3), np.float32), 1)
    with pytest.raises(ValueError, match="cellmax"):
        build_cone(np.zeros(5, np.float32))


def test_the_binding_checks_the_cone_arrays():
    """The C entry refuses the cone kernel without its structure, a structure for another
    kernel, and arrays of the wrong shape or dtype."""
    from algos.intersect import _Prepared
    from algos.registry import get_intersector

    fld = algos.Field(np.zeros((5, 6)))
    o, d = np.array([[0.5, 0.5, 1.0]]), np.array([[1.0, 0.0, -0.1]])
    run = _Prepared(get_intersector("cone"), fld, "triangles", o, d, None, None, ("t",),
                    {"cull_cells": True})
    cone = run.cone
    with pytest.raises(ValueError, match="cone"):
        _kernels.intersect(*run.args)
    plain = _Prepared(get_intersector("dda"), fld, "triangles", o, d, None, None, ("t",),
                      {"cull_cells": True})
    with pytest.raises(ValueError, match="cone"):
        _kernels.intersect_cone(cone, *plain.args)
    with pytest.raises(ValueError, match="cone"):
        _kernels.intersect_cone(cone[:, :-1].copy(), *run.args)
    with pytest.raises(TypeError, match="cone"):
        _kernels.intersect_cone(cone[..., 0].copy(), *run.args)
    with pytest.raises(TypeError, match="cone"):
        _kernels.intersect_cone(cone.astype(np.float64), *run.args)
    with pytest.raises(TypeError):
        _kernels.intersect_cone()
    assert _kernels.intersect_cone(cone, *run.args) >= 0


def _fuzz_harness():
    """The fuzz harness module (tests/fuzz/harness.py)."""
    from tests.fuzz import harness

    return harness


def test_fuzz_hook_holds_on_the_corpus_and_random_inputs():
    """tests/fuzz/cone_cases.check_cone, the hook for the fuzz harness, on the committed corpus
    and a seeded batch of random inputs: the cone kernel gives dda's hits on every
    decoded first-hit case."""
    import os
    import warnings

    from tests.fuzz.cone_cases import check_cone

    fuzz = _fuzz_harness()
    rng = np.random.Generator(np.random.PCG64(22))
    paths = sorted(os.path.join(root, name) for root, _, names in os.walk(fuzz.CORPUS)
                   for name in names)
    inputs = [open(p, "rb").read() for p in paths]
    inputs += [rng.bytes(int(rng.integers(0, 600))) for _ in range(1500)]
    checked = 0
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for data in inputs:
            case = fuzz.decode(data)
            if case["op"] == "intersect":
                check_cone(case, fuzz._call)
                checked += 1
    assert checked > 300


# ---- cone_relaxed (Policarpo & Oliveira 2007): approximate by design ----------------------

def _relaxed_reference(cellmax, radius):
    """The relaxed cone slopes by the definition in algos.accel.cone.build_relaxed_cone, in plain
    Python: the readable twin of cext/hierarchies/cone.c's build."""
    ny, nx = cellmax.shape
    m = cellmax.astype(float)
    top = m.max()
    out = np.zeros((ny, nx))
    for sj in range(ny):
        for si in range(nx):
            centre = np.array([si + 0.5, sj + 0.5])
            best = 0.0
            for dj in range(max(0, sj - radius), min(ny, sj + radius + 1)):
                for di in range(max(0, si - radius), min(nx, si + radius + 1)):
                    if (di, dj) == (si, sj) or not m[dj, di] < top:
                        continue
                    p = np.array([di + 0.5, dj + 0.5])
                    length = float(np.sqrt(((p - centre) ** 2).sum()))
                    unit, drop, z = (p - centre) / length, (top - m[dj, di]) / length, m[dj, di]
                    for _ in range(4 * radius + 4):
                        p, z = p + 0.5 * unit, z - 0.5 * drop
                        ci, cj = int(np.floor(p[0])), int(np.floor(p[1]))
                        if not (0 <= ci < nx and 0 <= cj < ny) or \
                                abs(ci - si) > radius or abs(cj - sj) > radius or z > m[cj, ci]:
                            break
                    if z > m[sj, si]:
                        best = max(best, (z - m[sj, si]) / float(np.sqrt(((p - centre) ** 2).sum())))
            out[sj, si] = best
    return out


@pytest.mark.parametrize("seed", range(3))
def test_relaxed_slopes_equal_the_definition(seed):
    from algos.accel.cone import build_relaxed_cone

    rng = np.random.Generator(np.random.PCG64(seed))
    cellmax = (rng.standard_normal((9, 11)) * 3).astype(np.float32)
    for radius in (1, 3):
        got = build_relaxed_cone(cellmax, radius)
        want = _relaxed_reference(cellmax, radius)
        assert got.dtype == np.float32 and np.all(got >= 0)
        assert np.allclose(got, want, rtol=1e-6, atol=1e-6), (seed, radius, np.abs(got - want).max())
    assert not build_relaxed_cone(np.zeros((4, 5), np.float32), 3).any()  # flat: no slope


def test_relaxed_error_is_small_and_shrinks_with_halvings():
    """Approximate by design: measured against the brute force on bench-like rays, where
    nearly every ray agrees on hit or miss and more halvings give smaller errors."""
    from datasets_gen.rays import first_hit_rays

    H = fields.generate("fbm", (97, 130), seed=5, amplitude=30.0, scale=40.0)
    fld = algos.Field(H)
    o, d = first_hit_rays(fld, 5, 300, seed=8)
    t_ref, _ = algos.brute_force_hits(H, o, d, "triangles")
    medians = []
    for halvings in (4, 16):
        got = algos.intersect("cone_relaxed", fld, o, d, march_refinements=halvings).t
        agree = np.isfinite(got) == np.isfinite(t_ref)
        assert agree.mean() > 0.95
        both = np.isfinite(got) & np.isfinite(t_ref)
        medians.append(float(np.median(np.abs(got[both] - t_ref[both]))))
    assert medians[1] < medians[0] / 100


def test_the_binding_checks_the_relaxed_structure():
    from algos.accel.cone import build_relaxed_cone, relaxed_cone_for
    from algos.intersect import _Prepared
    from algos.registry import get_intersector

    fld = algos.Field(np.zeros((5, 6)))
    o, d = np.array([[0.5, 0.5, 1.0]]), np.array([[1.0, 0.0, -0.1]])
    run = _Prepared(get_intersector("cone_relaxed"), fld, "triangles", o, d, None, None, ("t",),
                    {"march_steps": 8, "march_refinements": 4})
    slope = relaxed_cone_for(fld)
    with pytest.raises(TypeError, match="cone"):
        _kernels.intersect_cone(np.stack([slope, slope], axis=-1), *run.args)
    with pytest.raises(ValueError, match="cone"):
        _kernels.intersect(*run.args)
    assert _kernels.intersect_cone(slope, *run.args) >= 0
    with pytest.raises(ValueError, match="radius"):
        build_relaxed_cone(np.zeros((3, 3), np.float32), 65)
    with pytest.raises(ValueError, match="radius"):
        _kernels.cone_relaxed_slopes(np.zeros((3, 3), np.float32), 0, np.zeros((3, 3), np.float32))
    with pytest.raises(ValueError, match="slope"):
        _kernels.cone_relaxed_slopes(np.zeros((3, 3), np.float32), 2, np.zeros((3, 4), np.float32))
