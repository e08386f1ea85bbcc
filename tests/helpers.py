"""Helpers shared by the tests: the exact expectation for a batch, and reproducers."""
from __future__ import annotations

import math

import numpy as np

import algos


def rounded(origins, directions):
    """The rays an exact kernel walks (algos.lattice)."""
    return algos.quantize(origins, directions)


def as_tuples(array) -> list:
    return [tuple(int(v) for v in row) for row in np.asarray(array).tolist()]


def reproducer(name, shape, origin, direction, tmin=None, tmax=None, seed=None) -> str:
    """A failure message that reproduces the case: algorithm, seed, grid, ray."""
    parts = [f"algorithm={name!r}", f"shape={tuple(shape)!r}",
             f"origin=({origin[0]!r}, {origin[1]!r})",
             f"direction=({direction[0]!r}, {direction[1]!r})"]
    if tmin is not None:
        parts.append(f"tmin={float(tmin)!r}")
    if tmax is not None:
        parts.append(f"tmax={float(tmax)!r}")
    if seed is not None:
        parts.append(f"seed={seed!r}")
    return ", ".join(parts)


def expected_cells(origins, directions, shape, tmin=None, tmax=None, exact=True):
    """reference_cells for each ray (of the lattice-rounded ray when exact)."""
    o, d = (rounded(origins, directions) if exact
            else (np.asarray(origins, float), np.asarray(directions, float)))
    n = len(o)
    lo = np.zeros(n) if tmin is None else np.broadcast_to(np.asarray(tmin, float), (n,))
    hi = np.full(n, np.inf) if tmax is None else np.broadcast_to(np.asarray(tmax, float), (n,))
    return [algos.reference_cells(o[k], d[k], shape, lo[k], hi[k]) for k in range(n)], o, d


def assert_paths_equal(name, got_paths, expected, origins, directions, shape, tmin=None,
                       tmax=None, seed=None, what="cells"):
    """Compare per ray; the message of the first mismatch is a reproducer."""
    n = len(expected)
    mismatches = [k for k in range(n) if as_tuples(got_paths[k]) != expected[k]]
    if mismatches:
        k = mismatches[0]
        lo = None if tmin is None else np.broadcast_to(tmin, (n,))[k]
        hi = None if tmax is None else np.broadcast_to(tmax, (n,))[k]
        raise AssertionError(
            f"{len(mismatches)} of {n} rays differ in {what}; first: "
            + reproducer(name, shape, origins[k], directions[k], lo, hi, seed)
            + f"\n expected {expected[k][:12]}{' ...' if len(expected[k]) > 12 else ''}"
            + f"\n got      {as_tuples(got_paths[k])[:12]}"
        )


def first_hit_fields(shape):
    """The six small fields of the first-hit tests (heights roughly in [0, 8]), by name:
    fBm, terraces, uniform random, a spike, flat and a tilted plane, all seeded."""
    from datasets_gen import fields

    return {
        "fbm": fields.generate("fbm", shape, seed=3, amplitude=6.0, scale=16.0),
        "terraces": fields.generate("terraces", shape, seed=4, amplitude=6.0, scale=16.0),
        "uniform": fields.generate("uniform", shape, seed=5, high=6.0),
        "spike": fields.generate("spike", shape, height=8.0, radius=9.0),
        "flat": fields.generate("flat", shape, height=2.0),
        "tilted": fields.generate("tilted_plane", shape, slope_x=0.1, slope_y=-0.05, height=1.0),
    }


#: The surfaces that jump at cell borders, where which cell holds a border point matters.
JUMPING_SURFACES = ("flat", "plane3")


def exact_first_hit(heights, origin, direction, surface, tmin=0.0, tmax=math.inf):
    """The first hit of one non-vertical ray on ``flat``, ``plane3`` or ``triangles``, in
    rational arithmetic (fractions.Fraction on the float64 inputs), read straight from
    docs/CONVENTIONS.md: the smallest t in [t0, t1] with z(t) <= s(x(t), y(t)), where a
    point on a cell border takes the surface of the cell the ray enters there (the
    half-open rule) and the end t1 that of the last cell (the closed end, clamped into the
    grid); ``[t0, t1]`` is ``[tmin, tmax]`` clipped to the box. Returns ``(t, (i, j))`` as
    float and ints, or ``(inf, None)``; independent of
    algos.brute_force_hits, which it checks.

    Between consecutive breakpoints (grid lines, and for triangles the diagonals u = v)
    the ray stays in one cell and one plane, where z - s is linear: its first zero there
    is a hit when it lies before the segment's end, or at the end t1 itself."""
    from fractions import Fraction

    H = np.asarray(heights)
    rows, cols = H.shape
    nx, ny = cols - 1, rows - 1
    o = [Fraction(float(v)) for v in origin]
    d = [Fraction(float(v)) for v in direction]
    if d[0] == 0 and d[1] == 0:
        raise ValueError("direction: a vertical ray (not covered here)")
    t0 = Fraction(float(tmin))
    t1 = None if math.isinf(tmax) else Fraction(float(tmax))
    for axis, top in ((0, nx), (1, ny)):
        if d[axis] == 0:
            if not 0 <= o[axis] <= top:
                return math.inf, None
        else:
            a, b = sorted(((0 - o[axis]) / d[axis], (top - o[axis]) / d[axis]))
            t0, t1 = max(t0, a), (b if t1 is None else min(t1, b))
    if t0 > t1:
        return math.inf, None
    cuts = {t0, t1}
    for axis, top in ((0, nx), (1, ny)):
        if d[axis] != 0:
            cuts.update(t for t in ((k - o[axis]) / d[axis] for k in range(top + 1))
                        if t0 < t < t1)
    if surface == "triangles" and d[0] != d[1]:
        cuts.update(t for t in ((k - (o[0] - o[1])) / (d[0] - d[1]) for k in range(-ny, nx + 1))
                    if t0 < t < t1)
    cuts = sorted(cuts)

    def holder(t):
        """The cell holding p(t): the half-open rule, clamped into the grid (at a
        segment's midpoint, the cell of the whole open segment)."""
        index = []
        for axis, top in ((0, nx), (1, ny)):
            x = o[axis] + t * d[axis]
            k = math.ceil(x) - 1 if d[axis] < 0 else math.floor(x)
            index.append(min(max(k, 0), top - 1))
        return tuple(index)

    def surface_at(cell, t):
        i, j = cell
        u, v = o[0] + t * d[0] - i, o[1] + t * d[1] - j
        h00, h10 = Fraction(float(H[j, i])), Fraction(float(H[j, i + 1]))
        h01, h11 = Fraction(float(H[j + 1, i])), Fraction(float(H[j + 1, i + 1]))
        if surface == "flat":
            return (h00 + h10 + h01 + h11) / 4
        if surface == "plane3":
            return h00 + (h10 - h00) * u + (h01 - h00) * v
        if u >= v:
            return h00 + (h10 - h00) * u + (h11 - h10) * v
        return h00 + (h11 - h01) * u + (h01 - h00) * v

    def gap(cell, t):
        return o[2] + t * d[2] - surface_at(cell, t)

    if len(cuts) == 1:  # a one-point range: the cell holding it
        cell = holder(t0)
        return (float(t0), cell) if gap(cell, t0) <= 0 else (math.inf, None)
    for a, b in zip(cuts, cuts[1:]):
        mid = (a + b) / 2
        cell = holder(mid)
        fa = gap(cell, a)
        if fa <= 0:
            return float(a), cell
        # linear on [a, b] in this cell's plane: extend from a and the midpoint (for
        # triangles the plane of the piece, which may differ from the one at b itself)
        fb = 2 * gap(cell, mid) - fa
        if fb <= 0:
            root = a + (b - a) * fa / (fa - fb)
            if root < b or b == t1:
                return float(root), cell
    return math.inf, None
