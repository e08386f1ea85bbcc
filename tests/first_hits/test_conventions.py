"""The conventions themselves: this repository's copy agrees with the shared reference, and
the brute force follows its rule for points on a cell border ("The first hit", "Points on
a cell border"), against hand-worked cases and against every strict kernel on rays along
grid lines, through vertices and starting on them, on all four surfaces."""
import os
import re

import numpy as np
import pytest

import algos
from algos.registry import INTERSECTOR_REGISTRY

from ..helpers import JUMPING_SURFACES
from .exact_hits import exact_first_hit

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SHARED = os.path.join(ROOT, "..", "shared", "spec", "CONVENTIONS.md")
OURS = os.path.join(ROOT, "docs", "CONVENTIONS.md")
#: The heading after which this copy states its own readings; above it, word for word.
OWN_PART = "\n## How this repository reads the conventions"
EXACT = [n for n, a in INTERSECTOR_REGISTRY.items() if a.accuracy == "exact"]
STRICT = [n for n, a in INTERSECTOR_REGISTRY.items() if a.accuracy in ("exact", "float64")]


@pytest.mark.skipif(not os.path.isfile(SHARED), reason="no shared reference beside the repository")
def test_shared_part_equals_the_shared_reference():
    with open(SHARED, encoding="utf-8") as f:
        shared = f.read()
    with open(OURS, encoding="utf-8") as f:
        ours = f.read()
    assert OWN_PART in ours, f"docs/CONVENTIONS.md lost its heading {OWN_PART.strip()!r}"
    common = ours[:ours.index(OWN_PART)]
    if common.rstrip("\n") != shared.rstrip("\n"):
        ours_lines, shared_lines = common.splitlines(), shared.splitlines()
        k = next((i for i, (a, b) in enumerate(zip(ours_lines, shared_lines)) if a != b),
                 min(len(ours_lines), len(shared_lines)))
        raise AssertionError(
            f"docs/CONVENTIONS.md differs from ../shared/spec/CONVENTIONS.md at line {k + 1}:\n"
            f"  ours:   {ours_lines[k] if k < len(ours_lines) else '<end>'!r}\n"
            f"  shared: {shared_lines[k] if k < len(shared_lines) else '<end>'!r}")


def test_the_border_rule_is_in_the_conventions():
    with open(OURS, encoding="utf-8") as f:
        text = f.read()
    assert re.search(r"\*\*Points on a cell border\*\* belong to one cell", text)


# ---- the brute force on hand-worked cases -------------------------------------------------

def _brute(H, o, d, surface="flat", **kw):
    t, cell = algos.brute_force_hits(H, [o], [d], surface, **kw)
    return float(t[0]), tuple(int(v) for v in cell[0])


def _cells_around_a_vertex():
    """Samples chosen so that the four flat cells around the vertex (5, 5) stand at
    distinct heights: (4, 4) 8, (5, 4) 6, (4, 5) 4, (5, 5) 1 (every other cell their own
    mean of the same samples)."""
    H = np.zeros((11, 11), np.float32)
    H[:6, :6] = 8.0  # rows 0..5, columns 0..5
    H[:6, 6:] = 4.0
    H[6:, :6] = 0.0
    H[6:, 6:] = -4.0
    # cell (i, j) mean: (4, 4): 8; (5, 4): (8 + 4 + 8 + 4) / 4 = 6; (4, 5): (8 + 8 + 0 + 0) / 4
    # = 4; (5, 5): (8 + 4 + 0 - 4) / 4 = 2
    return H


@pytest.mark.parametrize("direction,cell,height", [
    ((1.0, 1.0), (5, 5), 2.0),     # the diagonal cell ahead; (5, 4) and (4, 5) only touch
    ((-1.0, -1.0), (4, 4), 8.0),
    ((1.0, -1.0), (5, 4), 6.0),
    ((-1.0, 1.0), (4, 5), 4.0),
    ((1.0, 0.0), (5, 5), 2.0),     # dy = 0 takes the row on the + side
    ((0.0, -1.0), (5, 4), 6.0),    # dx = 0 takes the column on the + side
    ((-0.0, -1.0), (5, 4), 6.0),   # -0.0 counts as 0
    ((-1.0, 0.0), (4, 5), 4.0),
    ((0.0, 0.0), (5, 5), 2.0),     # vertical: the cell on the + side of both lines
])
def test_flat_ray_starting_on_a_vertex_reads_only_the_cell_it_enters(direction, cell, height):
    """The developers' pinned case: ``flat``, a ray starting on a vertex between cells of
    different heights. Started just above the cell it enters, it is not inside the solid,
    whatever its three taller neighbours; started just below, it hits at t = 0 in it."""
    H = _cells_around_a_vertex()
    dz = -1.0 if direction == (0.0, 0.0) else 0.0
    above = _brute(H, (5.0, 5.0, height + 0.5), (*direction, dz))
    if direction == (0.0, 0.0):
        assert above == (0.5, cell)  # falls 0.5 onto the top of the cell under it
    elif direction in ((1.0, 1.0), (1.0, 0.0)):
        assert above[0] == np.inf  # every cell ahead is at most as high
    else:
        assert above[0] > 0 and above[1] != cell
    assert _brute(H, (5.0, 5.0, height - 0.5), (*direction, dz)) == (0.0, cell)
    if 0.0 not in direction:  # (on a grid line the kernels still differ: see the end)
        for z in (height + 0.5, height - 0.5):
            o, d = [[5.0, 5.0, z]], [[*direction, dz]]
            t, ref_cell = _brute(H, o[0], d[0])
            for name in EXACT:
                hits = algos.intersect(name, H, o, d, surface="flat", outputs=("t", "cell"))
                assert (float(hits.t[0]), tuple(int(v) for v in hits.cell[0])) == \
                    (t, ref_cell), (name, o, d)


def test_ray_along_x_25_reads_column_25_only():
    """The conventions' example: ``flat``, a ray along the line x = 25 with dx = 0 reads
    column 25 only, whatever the height of column 24."""
    H = np.zeros((40, 40), np.float32)
    H[:, 26:] = 1.0  # column 25 (samples 25, 26): flat 0.5; columns >= 26: 1
    o, d = (25.0, 3.5, 6.0), (0.0, 1.0, -0.25)
    expected = (6.0 - 0.5) / 0.25  # z = 0.5 at t = 22, y = 25.5: column 25's top
    for column_24 in (-5.0, 0.0, 3.0, 100.0):
        H[:, :25] = column_24  # column 24 (samples 24, 25): (column_24 + 0) / 2
        assert _brute(H, o, d) == (expected, (25, 25))
    H[:, :26] = 100.0  # column 25 itself tall: hit at t = 0
    assert _brute(H, o, d)[0] == 0.0


def test_diagonal_vertex_crossing_enters_the_diagonal_cell():
    """From (4, 5) (4 high) through the vertex (5, 5) into (5, 4) (6 high), level at z = 7:
    the side cell (4, 4), 8 high, only touches the ray at the vertex and is not hit, so
    the ray flies on over cells of 6 and 4 and misses; the other way round, (5, 4) -> (4, 5)
    misses too, while a ray at z = 5 hits the wall of (5, 4) at the vertex."""
    H = _cells_around_a_vertex()
    assert _brute(H, (4.5, 5.5, 7.0), (1.0, -1.0, 0.0)) == (np.inf, (-1, -1))
    assert _brute(H, (5.5, 4.5, 7.0), (-1.0, 1.0, 0.0)) == (np.inf, (-1, -1))
    assert _brute(H, (4.5, 5.5, 5.0), (1.0, -1.0, 0.0)) == (0.5, (5, 4))


def test_a_touch_at_a_cells_exit_belongs_to_the_next_cell():
    """flat: cell (0, 0) stands 1 high, cell (1, 0) 0. The ray reaches z = 1 exactly where
    it leaves (0, 0), at x = 1; that point belongs to (1, 0), which is lower, so it is not
    a hit: the ray hits (1, 0)'s top at the box's far side x = 2, t = 1.5 (the range's
    closed end). Before, the brute force and every kernel took the touch, t = 0.5. The
    exact reference agrees."""
    H = np.array([[2, 0, 0], [2, 0, 0]], np.float32)
    o, d = (0.5, 0.5, 1.5), (1.0, 0.0, -1.0)
    assert exact_first_hit(H, o, d, "flat") == (1.5, (1, 0))  # (a Fraction equals 1.5)
    assert _brute(H, o, d) == (1.5, (1, 0))
    for name in STRICT:
        hits = algos.intersect(name, H, [o], [d], surface="flat")
        assert (float(hits.t[0]), tuple(int(v) for v in hits.cell[0])) == (1.5, (1, 0)), name
    # the same ray a hair lower does go below (0, 0)'s top inside it
    lower = (0.5, 0.5, 1.25)
    assert _brute(H, lower, d) == (0.25, (0, 0)) == exact_first_hit(H, lower, d, "flat")


def test_a_side_cell_of_a_vertex_crossing_is_not_hit_by_any_strict_kernel():
    """flat: cell (4, 3) stands 6 high, its neighbours lower. The ray from outside the box
    crosses the vertex (5, 4) at t = 2, z = 2.5, from (5, 3) into the diagonal cell (4, 4)
    (2 high): (4, 3) only touches it there, so it is not hit, and the ray misses. dda
    computed both crossings of that vertex as t = 2, stepped through (4, 3) with the one-
    point interval [2, 2] and took it as a hit."""
    H = np.zeros((9, 10), np.float32)
    H[3, 4] = H[3, 5] = H[4, 4] = 8.0
    o, d = (11.0, 2.0, 3.5), (-3.0, 1.0, -0.5)
    assert _brute(H, o, d) == (np.inf, (-1, -1))
    assert exact_first_hit(H, o, d, "flat") == (None, (-1, -1))
    for name in STRICT:
        assert algos.intersect(name, H, [o], [d], surface="flat").t[0] == np.inf, name


def test_bilinear_hit_at_the_ranges_closed_end():
    """bilinear, one cell with corners 3, 1 / 3, 3: along the ray, z - s = 1 - t^2, which
    reaches 0 exactly where the ray leaves the box (t = 1, y = 1): a hit at the range's
    closed end. Every kernel missed it (found by a new user's trial): the z clip leaves a
    hair-thin interval whose local quadratic rounds the end a hair above the surface. Where
    tmax = 1 ends the range inside the grid, p(1) = (0.75, 1) lies on the border y = 1 and
    belongs to the cell entered, (0, 1), whose surface meets the first cell's there."""
    o, d = (0.25, 0.0, 3.5), (0.5, 1.0, -0.5)
    fields = {"box exit": (np.array([[3.0, 1.0], [3.0, 3.0]]), None, (0, 0)),
              "tmax": (np.where(np.arange(9).reshape(3, 3) == 1, 1.0, 3.0), 1.0, (0, 1))}
    for what, (H, tmax, want) in fields.items():
        t, cell = algos.brute_force_hits(H, [o], [d], "bilinear", tmax=tmax)
        assert (float(t[0]), tuple(cell[0])) == (1.0, want), what
        for name in STRICT:
            got = algos.intersect(name, H, [o], [d], surface="bilinear", tmax=tmax)
            assert got.t[0] == 1.0 and tuple(got.cell[0]) == want, (what, name)


def test_bilinear_kernels_equal_the_brute_force_on_dyadic_rays():
    """Quarter-lattice rays with dyadic ranges on small integer fields: every strict kernel
    gives the brute force's t on bilinear (before the fix above, 132 of 360,000 checks
    missed a hit at the range's end)."""
    rng = np.random.Generator(np.random.PCG64(3))
    for _ in range(6):
        H = rng.integers(0, 5, (6, 6)).astype(np.float32)
        n = 500
        o = np.column_stack([rng.integers(0, 21, n) / 4, rng.integers(0, 21, n) / 4,
                             rng.integers(0, 24, n) / 4])
        steps = [0.0, 1.0, -1.0, 0.5, -0.5, 2.0]
        d = np.column_stack([rng.choice(steps, n), rng.choice(steps, n),
                             rng.choice([-1.0, -0.5, -0.25, 0.25], n)])
        tmax = rng.choice([0.5, 1.0, 1.5, 2.0, 3.0, np.inf], n)
        ref, _ = algos.brute_force_hits(H, o, d, "bilinear", tmax=tmax)
        for name in STRICT:
            t = algos.intersect(name, H, o, d, surface="bilinear", tmax=tmax).t
            bad = np.nonzero(~(np.isclose(t, ref, rtol=1e-9, atol=1e-12)
                               | (np.isinf(t) & np.isinf(ref))))[0]
            assert not len(bad), (name, o[bad[0]].tolist(), d[bad[0]].tolist(), tmax[bad[0]],
                                  ref[bad[0]], t[bad[0]])


def _dyadic_rays(shape, seed, n=240):
    """Rays whose every breakpoint and flat root is a dyadic rational, so float64 decides
    each touch as exact arithmetic does: origins on a 1/4 lattice (some outside the box),
    horizontal components in {0, +-1, +-2, +-4}, dz in {-2, -1, -1/2, -1/4, 0, 1/4}."""
    rng = np.random.Generator(np.random.PCG64(seed))
    rows, cols = shape
    o = np.column_stack([rng.integers(-4, 4 * cols + 4, n) / 4, rng.integers(-4, 4 * rows + 4, n) / 4,
                         rng.integers(0, 19, n) / 4])
    d = np.column_stack([rng.choice([0.0, 1, -1, 2, -2, 4, -4], (n, 2)),
                         rng.choice([-2.0, -1, -0.5, -0.25, 0.0, 0.25], n)])
    vertical = (d[:, 0] == 0) & (d[:, 1] == 0)
    d[vertical, 0] = 1.0
    return o, d


@pytest.mark.parametrize("surface", ["flat", "plane3", "triangles"])
def test_brute_force_and_strict_kernels_equal_the_exact_reference_on_terraces(surface):
    """Every touch decided as the conventions say. On terraces (integer and quarter-integer
    steps) and dyadic rays, the brute force and every exact and float64 kernel give the
    rational reference's t (to 1e-12, the rounding of a root), hit or miss alike."""
    shape = (9, 10)
    rng = np.random.Generator(np.random.PCG64(5))
    fields = {"integers": rng.integers(0, 4, shape).astype(np.float32),
              "quarters": (rng.integers(0, 13, shape) / 4).astype(np.float32)}
    for fname, H in fields.items():
        o, d = _dyadic_rays(shape, seed=len(fname))
        # the default range, then dyadic [tmin, tmax] (a touch at tmax: the closed end)
        lo = np.concatenate([np.zeros(len(o)), rng.integers(0, 8, len(o)) / 4])
        hi = np.concatenate([np.full(len(o), np.inf), lo[len(o):] + rng.integers(0, 12, len(o)) / 4])
        o, d = np.concatenate([o, o]), np.concatenate([d, d])
        exact = [exact_first_hit(H, o[k], d[k], surface, lo[k], hi[k])[0] for k in range(len(o))]
        want = np.array([np.inf if t is None else float(t) for t in exact])
        got = {"brute force": algos.brute_force_hits(H, o, d, surface, tmin=lo, tmax=hi)[0]}
        got.update((name, algos.intersect(name, H, o, d, surface=surface, tmin=lo, tmax=hi).t)
                   for name in STRICT)
        for name, t in got.items():
            # a root inside a plane3 or triangles piece is not dyadic: its last bit may
            # round either way
            bad = np.nonzero(~(np.isclose(t, want, rtol=1e-12, atol=0)
                               | (np.isinf(t) & np.isinf(want))))[0]
            assert not len(bad), (
                f"{name} on {surface}/{fname}: {len(bad)} of {len(o)} rays differ from the "
                f"exact reference; first: origin={o[bad[0]].tolist()} "
                f"direction={d[bad[0]].tolist()} range=[{lo[bad[0]]}, {hi[bad[0]]}] exact "
                f"t={want[bad[0]]!r} got {t[bad[0]]!r}")


def test_ray_on_the_grid_line_leaves_continuous_surfaces_unchanged():
    """For triangles and bilinear the surface is the same from both sides of a border."""
    rng = np.random.Generator(np.random.PCG64(4))
    H = rng.uniform(0, 5, (9, 12)).astype(np.float32)
    for surface in ("triangles", "bilinear"):
        for o, d in (((4.0, 1.5, 6.0), (0.0, 1.0, -0.8)), ((2.5, 3.0, 6.0), (1.0, 0.0, -0.5)),
                     ((4.0, 3.0, 6.0), (0.0, 0.0, -1.0))):
            t, _ = _brute(H, o, d, surface)
            assert np.isfinite(t), (surface, o, d)
            x, y, z = (np.add(o, np.multiply(t, d)))
            i, j = min(int(x), 10), min(int(y), 7)
            u, v = x - i, y - j
            h00, h10, h01, h11 = (float(H[j, i]), float(H[j, i + 1]), float(H[j + 1, i]),
                                  float(H[j + 1, i + 1]))
            if surface == "bilinear":
                s = h00 * (1 - u) * (1 - v) + h10 * u * (1 - v) + h01 * (1 - u) * v + h11 * u * v
            elif u >= v:
                s = h00 + (h10 - h00) * u + (h11 - h10) * v
            else:
                s = h00 + (h11 - h01) * u + (h01 - h00) * v
            assert z == pytest.approx(s, abs=1e-9), (surface, o, d)


# ---- every exact kernel against the brute force on border rays --------------------------

def _border_rays(shape, seed):
    """Rays along grid lines, through vertices and starting on vertices or edges, with
    directions of small integer components (exact vertex crossings) and float ones."""
    rng = np.random.Generator(np.random.PCG64(seed))
    rows, cols = shape
    n = 60
    integer_xy = np.column_stack([rng.integers(0, cols, n), rng.integers(0, rows, n)]).astype(float)
    small = rng.integers(-3, 4, (n, 2)).astype(float)
    small[np.all(small == 0, axis=1)] = (1.0, 1.0)
    axis = np.zeros((n, 2))
    axis[np.arange(n), rng.integers(0, 2, n)] = rng.choice([-1.0, 1.0, 0.5, -2.0], n)
    z0 = rng.uniform(-1.0, 9.0, n)
    dz = rng.choice([0.0, -0.05, -0.3, 0.1, -2.0], n)
    o, d = [], []
    # along grid lines (a zero component at an integer coordinate), both axes, any start
    start = np.column_stack([rng.uniform(0, cols - 1, n), rng.uniform(0, rows - 1, n)])
    on_x = rng.random(n) < 0.5
    start[on_x, 0] = integer_xy[on_x, 0]
    start[~on_x, 1] = integer_xy[~on_x, 1]
    line = np.where(on_x[:, None], np.column_stack([np.zeros(n), axis.sum(1)]),
                    np.column_stack([axis.sum(1), np.zeros(n)]))
    o.append(np.column_stack([start, z0]))
    d.append(np.column_stack([line, dz]))
    # starting on a vertex: integer directions (through more vertices) and float ones
    o.append(np.column_stack([integer_xy, z0]))
    d.append(np.column_stack([small, dz]))
    o.append(np.column_stack([integer_xy, z0]))
    d.append(np.column_stack([rng.normal(size=(n, 2)), dz]))
    # from a cell centre through vertices: (i + 1/2, j + 1/2) along (+-1, +-1) or (+-2, +-2)
    centre = integer_xy[:, :2] + 0.5
    o.append(np.column_stack([centre, z0]))
    d.append(np.column_stack([np.sign(small) + (small == 0), dz]))
    # starting on an edge (one integer coordinate), random directions
    edge = np.column_stack([rng.uniform(0, cols - 1, n), rng.uniform(0, rows - 1, n)])
    edge[on_x, 0] = integer_xy[on_x, 0]
    edge[~on_x, 1] = integer_xy[~on_x, 1]
    o.append(np.column_stack([edge, z0]))
    d.append(np.column_stack([rng.normal(size=(n, 2)), dz]))
    # vertical, on vertices and edges
    o.append(np.column_stack([np.where(on_x[:, None], integer_xy, edge), z0 + 3]))
    d.append(np.tile([0.0, 0.0, -1.0], (n, 1)))
    return np.concatenate(o), np.concatenate(d)


def _steps(shape, seed):
    """Cells of different heights: integer steps with flat plateaus (so that many rays
    start level with a top and walls meet at vertices)."""
    rng = np.random.Generator(np.random.PCG64(seed))
    H = rng.integers(0, 8, shape).astype(np.float32)
    H[rng.random(shape) < 0.3] = 4.0
    return H


@pytest.fixture(scope="module")
def border_cases():
    shape = (13, 17)
    o, d = _border_rays(shape, seed=31)
    out = {}
    for fname, H in (("steps", _steps(shape, 7)), ("plateaus", np.where(
            np.add.outer(np.arange(13), np.arange(17)) % 5 < 2, 6.0, 1.0).astype(np.float32))):
        for surface in algos.SURFACES:
            t, _ = algos.brute_force_hits(H, o, d, surface)
            out[(fname, surface)] = (H, o, d, t)
    return out


@pytest.mark.parametrize("name", EXACT)
def test_exact_kernels_follow_the_border_rule(name, border_cases):
    """Hit or miss alike, |dt| <= 1e-9 (1 + |t|). (The float64 walks are measured, not
    held to this: dda steps to a side cell at some exact vertex crossings, e.g. origin
    (16, 7) direction (-3, 2) on plane3 over ``plateaus``, where (13 - 16) / -3 is taken
    as (13 - 16) * (1 / -3).)"""
    for (fname, surface), (H, o, d, ref) in border_cases.items():
        got = algos.intersect(name, algos.Field(H), o, d, surface=surface).t
        hit_ref, hit_got = np.isfinite(ref), np.isfinite(got)
        both = hit_ref & hit_got
        err = np.zeros_like(ref)
        err[both] = np.abs(got[both] - ref[both]) / (1 + np.abs(ref[both]))
        bad = np.nonzero((hit_ref != hit_got) | (err > 1e-9))[0]
        if len(bad):
            k = bad[0]
            raise AssertionError(
                f"{name} on {surface}/{fname}: {len(bad)} border rays differ from the brute "
                f"force; first: origin={o[k].tolist()!r} direction={d[k].tolist()!r} "
                f"brute t={ref[k]!r} got t={got[k]!r}")


@pytest.mark.parametrize("surface", JUMPING_SURFACES)
def test_kernels_on_an_interior_grid_line_read_one_column(surface):
    """The conventions' example on the kernels: along x = 25 with dx = 0, column 25 only.
    Column 24 stands up to 10 high at x = 25 on both surfaces (its samples alternate 0 and
    10 row by row); column 25 is 0 high, and the ray stays above it."""
    H = np.zeros((40, 40), np.float32)
    H[1::2, :25] = 10.0
    o, d = [[25.0, 3.0, 6.0]], [[0.0, 1.0, -0.1]]
    ref, _ = algos.brute_force_hits(H, o, d, surface)
    assert ref[0] == np.inf  # column 25 alone is never reached before y = 39
    wrong = [name for name in EXACT
             if algos.intersect(name, H, o, d, surface=surface).t[0] != ref[0]]
    assert not wrong, f"{wrong} hit column 24 along x = 25"


def _subnormal_component_rays():
    """Rays with one subnormal horizontal component (1 / d overflows to infinity), starting
    on each box face, on a grid line inside, and inside a cell, each leaving or entering.
    The first is the fuzzer's find: on the far x face, leaving it, the hierarchies read
    0 * inf = NaN as 'no x face' and hit the cell behind it."""
    tiny = 1.6e-309
    o, d = [], []
    for x0 in (4.0, 0.0, 2.0, 2.5):
        for sx in (tiny, -tiny):
            for dy, dz in ((-63.9, -64.0), (0.7, -0.2), (0.0, -1.0)):
                o.append([x0, 4.0 if dy < 0 else 0.5, 4.0])
                d.append([sx, dy, dz])
                o.append([0.5 if dy >= 0 else 3.5, x0, 4.0])  # the same along y
                d.append([dy, sx, dz])
    return np.array(o), np.array(d)


@pytest.mark.parametrize("surface", algos.SURFACES)
def test_subnormal_direction_component_on_a_box_face(surface):
    """Every exact and float64 kernel equals the brute force on rays whose x or y
    component is subnormal, on a flat field and on steps. Fuzz find: flat 5x5, origin
    (4, 4, 4), direction (1.6e-309, -63.9, -64) was a hit at t = 0.0625 for the
    max-mipmap family, a miss for the brute force. The same set found the float64 walks
    missing rays that leave the far face inward (an empty cell interval from 0 * inf),
    the lattice walks reading the wrong side of a grid line (the component rounds to
    zero), and the brute force missing rays whose exit parameter overflows."""
    o, d = _subnormal_component_rays()
    kernels = [n for n, a in INTERSECTOR_REGISTRY.items() if a.accuracy in ("exact", "float64")]
    for H in (np.zeros((5, 5), np.float32), _steps((5, 5), 3)):
        ref, _ = algos.brute_force_hits(H, o, d, surface)
        assert np.isfinite(ref).sum() > len(o) // 3  # hits and misses both tested
        for name in kernels:
            got = algos.intersect(name, H, o, d, surface=surface).t
            bad = np.nonzero(np.isfinite(ref) != np.isfinite(got))[0]
            assert not len(bad), (f"{name}: {len(bad)} of {len(o)} rays differ; first: origin "
                                  f"{o[bad[0]].tolist()} direction {d[bad[0]].tolist()}: brute "
                                  f"{ref[bad[0]]}, got {got[bad[0]]}")
            both = np.isfinite(ref)
            assert np.allclose(got[both], ref[both], rtol=1e-9, atol=1e-9), name
