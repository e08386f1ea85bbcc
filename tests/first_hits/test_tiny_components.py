"""First hits of rays with one tiny horizontal direction component (subnormal, or far
below the other), against exact rational arithmetic (exact_hits.py): the kernels, the
brute force, and each against the other on a seeded sweep. Found by a new user's trial
(docs/CONVENTIONS.md, "Direction magnitudes")."""
from fractions import Fraction

import numpy as np
import pytest

import algos
from algos.brute import _first_hit_one
from algos.registry import INTERSECTOR_REGISTRY

from .exact_hits import exact_first_hit

#: every exact and float64 kernel (the float32, marching and peer ones are measured)
STRICT = [n for n, a in INTERSECTOR_REGISTRY.items() if a.accuracy in ("exact", "float64")]
#: the trial's field: one column of three cells, the top one tilted
TRIAL = np.array([[0, 0], [0, 0], [-0.1, -1.2], [0.7, 0.5]], np.float32)
_LARGEST = Fraction(float(np.finfo(np.float64).max))


def _close(got, want):
    """float t against an exact Fraction t (None: a miss; one past float64 is one too)."""
    if want is None or want > _LARGEST:
        return got == np.inf
    if not np.isfinite(got):
        return False
    return abs(Fraction(float(got)) - want) <= Fraction(1, 10 ** 9) * (1 + abs(want))


def _check_all(H, o, d, surface, want, cell):
    ref_t, ref_cell = algos.brute_force_hits(H, [o], [d], surface)
    assert _close(ref_t[0], want), f"brute force: t = {ref_t[0]!r}, exact {float(want)!r}"
    assert tuple(ref_cell[0]) == cell
    wrong = {}
    for name in STRICT:
        r = algos.intersect(name, H, [o], [d], surface=surface)
        if not _close(r.t[0], want) or tuple(r.cell[0]) != cell:
            wrong[name] = (r.t[0], tuple(r.cell[0]))
    assert not wrong, f"exact t = {float(want)!r} in {cell}; got {wrong}"


@pytest.mark.parametrize("mirror", [False, True])
def test_triangles_entering_by_the_lower_edge_beside_the_diagonal(mirror):
    """Along x = 0+ (dx = 1e-20) into cell (0, 2) through its edge v = 0: just after the
    entry u < v, the upper triangle. The kernels computed the diagonal crossing
    t = 2 + 2e-20 as ta - (ua - va) / w = 2 (rounded onto ta), saw no second piece, and
    tested all of [2, 3] on the lower triangle: t = 2.3 where its plane crosses z, a point
    (u - v = -0.3) over the upper triangle. Exact: the upper plane, z - s = 2.8 - 1.1 t
    (to 1e-9), t = 28/11 = 2.5454..."""
    o, d = (0.0, 0.0, 1.1), (1e-20, 1.0, -0.3)
    H, cell = TRIAL, (0, 2)
    if mirror:  # the same along y: the split is then entered from the other side
        o, d, H, cell = (0.0, 0.0, 1.1), (1.0, 1e-20, -0.3), TRIAL.T.copy(), (2, 0)
    want, at = exact_first_hit(H, o, d, "triangles")
    assert at == cell and abs(float(want) - 28 / 11) < 1e-7
    _check_all(H, o, d, "triangles", want, cell)


@pytest.mark.parametrize("surface", ["flat", "plane3", "triangles"])
@pytest.mark.parametrize("origin", [(1.0, 0.5, 4.0), (1.0, 0.0, 4.0), (1.0, 2.5, 4.0)])
def test_brute_force_on_a_cell_interval_beyond_1e307(surface, origin):
    """dx = -2.2e-308, dy = 0: the ray's interval in its cell is [0, 4.5e307). The brute
    force's root ta + (tb - ta) * fa / (fa - fb) overflowed in (tb - ta) * fa (fa = 4:
    1.8e308) and was clipped to tb = 4.5e307; exact (Fraction): t = 13.33... at (1, 0.5),
    where dda always gave 13.33."""
    d = (-2.2e-308, 0.0, -0.3)
    want, cell = exact_first_hit(TRIAL, origin, d, surface)
    assert want is not None and float(want) < 20
    _check_all(TRIAL, origin, d, surface, want, cell)


@pytest.mark.parametrize("surface", ["flat", "plane3", "triangles"])
@pytest.mark.parametrize("dx", [-2.2e-308, -1e-308, -5e-324])
def test_kernels_reach_the_box_face_at_a_huge_parameter(surface, dx):
    """An origin outside the box (x = 1 + offset) moving in with a subnormal dx enters at
    t = offset / |dx|, a float64. The walks take 1 / dx as -DBL_MAX (hf_inverse), which
    put that face at offset * DBL_MAX (4.5e307 for offset 1/4 where it is 1.14e307 for
    dx = -2.2e-308); the dispatch now scales such a ray's direction by a power of two
    first (algos.intersect._subnormal_scale), which changes no t."""
    offset = 0.25 if dx != -5e-324 else 2.0 ** -52
    o, d = (1.0 + offset, 2.125, 6.0), (dx, 0.0, -40.0)
    want, cell = exact_first_hit(TRIAL, o, d, surface)
    assert want == Fraction(offset) / -Fraction(dx)  # below every surface on entry
    _check_all(TRIAL, o, d, surface, want, cell)


TINY = [0.0, 5e-324, -5e-324, 1e-308, -1e-308, 2.2e-308, -2.2e-308, 1e-300, -1e-300,
        1e-20, -1e-20, 1e-10, -1e-10]


def _fields():
    rng = np.random.Generator(np.random.PCG64(5))
    terraces = rng.integers(0, 5, (5, 6)).astype(np.float32)
    terraces[rng.random((5, 6)) < 0.3] = 2.0
    return {"trial": TRIAL, "terraces": terraces,
            "random": rng.normal(size=(4, 5)).astype(np.float32)}


def _sweep_rays(H, seed, per_component=16):
    """One horizontal component from TINY, the other ordinary (zero included); origins on
    grid lines, box faces, vertices and off them (multiples of 2^-16, which the exact
    kernels' lattice keeps)."""
    rng = np.random.Generator(np.random.PCG64(seed))
    nx, ny = H.shape[1] - 1, H.shape[0] - 1
    xs = [0.0, 1.0, float(nx), 0.5, 1.25, nx - 0.375, nx + 0.25]
    ys = [0.0, 1.0, float(ny), 0.5, 2.125 % ny, ny - 0.25, -0.5]
    others = [1.0, -1.0, 0.7, -2.3, 13.0, 0.0]
    dzs = [-0.3, -1.0, -2.0, 0.0, 0.2, -0.05, -40.0, 1e-3]
    o, d = [], []
    for tiny in TINY:
        for k in range(per_component):
            x, y = xs[rng.integers(len(xs))], ys[rng.integers(len(ys))]
            z = rng.uniform(float(H.min()) - 0.2, float(H.max()) + (6 if k % 4 == 1 else 1))
            other, dz = others[rng.integers(len(others))], dzs[rng.integers(len(dzs))]
            o.append([x, y, z])
            d.append([tiny, other, dz] if k % 2 else [other, tiny, dz])
    o, d = np.array(o), np.array(d)
    keep = np.abs(d).max(axis=1) >= algos.validate.MIN_HIT_DIRECTION  # the others raise
    return o[keep], d[keep]


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_tiny_component_sweep(surface):
    """Every strict kernel against the brute force, t to 1e-9 (1 + |t|) and the cell; on
    the piecewise linear surfaces the brute force against exact rational arithmetic too.
    Before these fixes the sweep found the three cases above (and their mirrors)."""
    checked = 0
    for seed, (fname, H) in enumerate(_fields().items()):
        o, d = _sweep_rays(H, seed)
        ref, ref_cell = algos.brute_force_hits(H, o, d, surface)
        assert np.isfinite(ref).sum() > len(o) // 4 and (~np.isfinite(ref)).sum() > 0
        if surface != "bilinear":
            for k in range(len(o)):
                want, cell = exact_first_hit(H, o[k], d[k], surface)
                if want is not None and want > _LARGEST:  # past float64: a miss
                    want, cell = None, (-1, -1)
                assert _close(ref[k], want) and (want is None or tuple(ref_cell[k]) == cell), (
                    f"brute force on {fname}: origin {o[k].tolist()} direction "
                    f"{d[k].tolist()}: t = {ref[k]!r} {tuple(ref_cell[k])}, exact "
                    f"{None if want is None else float(want)!r} {cell}")
        for name in STRICT:
            r = algos.intersect(name, H, o, d, surface=surface)
            hit = np.isfinite(ref)
            err = np.zeros(len(o))
            err[hit] = np.abs(r.t[hit] - ref[hit]) / (1 + np.abs(ref[hit]))
            bad = (np.isfinite(r.t) != hit) | (err > 1e-9) | (hit & np.any(r.cell != ref_cell, 1))
            k = np.nonzero(bad)[0]
            assert not len(k), (f"{name} on {fname}: {len(k)} rays differ; first: origin "
                                f"{o[k[0]].tolist()} direction {d[k[0]].tolist()}: brute "
                                f"{ref[k[0]]!r} {tuple(ref_cell[k[0]])}, got {r.t[k[0]]!r} "
                                f"{tuple(r.cell[k[0]])}")
            checked += len(o)
    assert checked > 0


@pytest.mark.parametrize("surface", ["flat", "plane3", "triangles"])
def test_brute_force_level_ray_crossing_a_grid_line_at_2e307(surface):
    """dx = -2.2e-308, dy = dz = 0: from x = 1.5 it reaches column 0, whose samples are 5
    high, at t = 0.5 / 2.2e-308 = 2.27e307, a float64. A level ray's z never overflows,
    so its range is not cut short; the exact hit (Fraction) is matched. Its largest
    component is below 2**-400, so brute_force_hits refuses it as intersect does (it
    validates its input with intersect's checks); its per-ray routine, which the checked
    rays reach, still takes it."""
    H = np.array([[5, 0, 0], [5, 0, 0]], np.float32)
    o, d = (1.5, 0.5, 1.0), (-2.2e-308, 0.0, 0.0)
    want, cell = exact_first_hit(H, o, d, surface)
    assert want is not None and want > Fraction(2 * 10 ** 307)
    with pytest.raises(ValueError, match=r"directions: ray 0 has a largest component"):
        algos.brute_force_hits(H, [o], [d], surface)
    with np.errstate(over="ignore"):
        t, at = _first_hit_one(H, np.array(o), np.array(d), surface, 0.0, np.inf)
    assert _close(t, want) and tuple(at) == cell


@pytest.mark.parametrize("surface", ["flat", "triangles"])
def test_a_hit_beyond_the_float_range_is_a_miss(surface):
    """From x = 1.25, outside a one-column field, with dx = -5e-324 the ray enters at
    t = 0.25 / 5e-324 = 5.06e323 (exact), past float64: the brute force reports a miss
    (before, with warnings from inf * 0), and so does every strict kernel, cell and normal
    included (their scaled t, 1.1e307, overflows when scaled back; before the scaling
    they gave t = 0.25 * DBL_MAX in cell (0, 0))."""
    H = np.zeros((6, 2), np.float32)
    o, d = (1.25, 0.0, 4.7), (-5e-324, 0.0, -1.0)
    want, _ = exact_first_hit(H, o, d, surface)
    assert want == Fraction(1, 4) / Fraction(5e-324) and want > Fraction(np.finfo(float).max)
    with np.errstate(all="raise"):
        t, cell = algos.brute_force_hits(H, [o], [d], surface)
    assert t[0] == np.inf and tuple(cell[0]) == (-1, -1)
    for name in STRICT:
        r = algos.intersect(name, H, [o], [d], surface=surface, outputs=("t", "cell", "normal"))
        assert r.t[0] == np.inf and tuple(r.cell[0]) == (-1, -1), name
        assert np.isnan(r.normal[0]).all(), name
        assert tuple(algos.intersect(name, H, [o], [d], surface=surface,
                                     outputs=("cell",)).cell[0]) == (-1, -1), name
