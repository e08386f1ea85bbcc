"""First hits in exact rational arithmetic (fractions.Fraction), for the piecewise linear
surfaces (flat, plane3, triangles).

The arbiter when the brute force and the kernels disagree (the tests import it from
tests/first_hits/exact_hits.py), and the brute force's cold path on the rare rays whose
float64 signs it cannot trust (``algos.brute``). It reads docs/CONVENTIONS.md ("The
first hit", "Points on a cell border") directly: the half-open visited cells of the ray
clipped to the box, each tested with its own surface (the triangles split where the ray
crosses u = v, each piece on the triangle holding its interior), the smallest t at or below
the surface. A point on a cell border belongs to the cell the ray enters there, so on flat
and plane3 (which jump at borders) a cell's interval is open at its exit unless that exit
ends the range [t0, t1]; triangles are continuous, and a touch there is found at the same t
by both cells (the one that holds the point by the half-open rule is reported). The
range's closed end t1, where tmax ends it inside the grid, is tested in the cell that holds
p(t1) (the one entered when t1 lies on a border), and a touch there is that cell's. Slow:
every float is read at its exact binary value, and every cell (or every candidate cell the
caller names) is tested.
"""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

__all__ = ["exact_first_hit"]

#: The surfaces this module decides: the piecewise linear ones.
LINEAR_SURFACES = ("flat", "plane3", "triangles")


def _q(x) -> Fraction:
    """A finite float at its exact binary value."""
    return Fraction(float(x))


def _end_cell(org, dirn, t1, nx, ny):
    """The cell of the grid that holds p(t1) by the half-open rule, or None when that
    cell lies outside the grid (t1 on the box's far side, or no finite t1)."""
    if t1 is None:
        return None
    index = []
    for a, n in ((0, nx), (1, ny)):
        x = org[a] + t1 * dirn[a]
        k = math.ceil(x) - 1 if dirn[a] < 0 else math.floor(x)
        if dirn[a] == 0 and k == n:
            k = n - 1  # a ray in the far face: its last cell (the box is closed)
        if not 0 <= k < n:
            return None
        index.append(k)
    return tuple(index)


def _visited(org, dirn, t0, t1, nx, ny, end=None, cells=None):
    """(i, j, ta, tb) of every visited cell (tb None: unbounded), in row-major order; the
    one cell at t0 (clamped into the grid) when the range is one point. ``end``: the cell
    holding p(t1) where the range ends inside the grid; when no visited cell holds it (t1
    lies on a border the ray crosses there), it is added with the one-point interval
    [t1, t1]. ``cells``: None (every cell of the grid) or the (i, j) candidates to test, a
    superset of the visited cells."""
    def axis(a, k, n):
        if dirn[a] == 0:
            return None if (k <= org[a] < k + 1 or (k == n - 1 and org[a] == n)) else False
        near, far = (k, k + 1) if dirn[a] > 0 else (k + 1, k)
        return (near - org[a]) / dirn[a], (far - org[a]) / dirn[a]
    if cells is None:
        candidates = ((i, j) for j in range(ny) for i in range(nx))
    else:
        candidates = sorted({(int(i), int(j)) for i, j in cells}, key=lambda c: (c[1], c[0]))
    visited = []
    for i, j in candidates:
        lo, hi, ok = t0, t1, True
        for a, k, n in ((0, i, nx), (1, j, ny)):
            iv = axis(a, k, n)
            if iv is False:
                ok = False
                break
            if iv is not None:
                lo, hi = max(lo, iv[0]), iv[1] if hi is None else min(hi, iv[1])
        if ok and (hi is None or lo < hi):
            visited.append((i, j, lo, hi))
    if not visited:
        index = []
        for a, n in ((0, nx), (1, ny)):
            x = org[a] + t0 * dirn[a]
            k = math.ceil(x) - 1 if dirn[a] < 0 else math.floor(x)
            index.append(min(max(k, 0), n - 1))
        visited = [(index[0], index[1], t0, t0)]
    elif end is not None and not any((i, j) == end for i, j, _, _ in visited):
        visited.append(end + (t1, t1))
    return visited


def exact_first_hit(heights, origin, direction, surface, tmin=0.0, tmax=math.inf, cells=None):
    """The first hit of one ray on ``[tmin, tmax]`` (the closed range, clipped to the box),
    in rational arithmetic.

    Parameters
    ----------
    heights : 2D array (rows, cols)
        Cell-corner heights; read at float32, as the kernels and the brute force read them.
    origin, direction : sequence of 3 finite floats
        The ray ``p(t) = origin + t direction`` (direction not zero).
    surface : {"flat", "plane3", "triangles"}
    tmin, tmax : float
        ``tmin`` finite; ``tmax`` finite or ``inf``.
    cells : None or iterable of (i, j)
        None: every cell of the grid is tested. Otherwise only these cells (the brute
        force passes the cells its float64 pass found along the ray); they must include
        every cell the ray visits, or a hit may be missed.

    Returns
    -------
    t : Fraction or None
        The exact parameter of the first hit; None on a miss.
    cell : tuple (i, j)
        The cell that holds the hit point by the half-open rule, ``(-1, -1)`` on a miss.
    """
    if surface not in LINEAR_SURFACES:
        raise ValueError(f"surface: {surface!r} is not piecewise linear")
    H = np.asarray(heights, np.float32)
    nx, ny = H.shape[1] - 1, H.shape[0] - 1
    org, dirn = [_q(v) for v in origin], [_q(v) for v in direction]
    t0, t1 = _q(tmin), (None if math.isinf(tmax) else _q(tmax))
    for a, top in ((0, nx), (1, ny)):
        if dirn[a] == 0:
            if not 0 <= org[a] <= top:
                return None, (-1, -1)
        else:
            lo, hi = sorted(((0 - org[a]) / dirn[a], (top - org[a]) / dirn[a]))
            t0, t1 = max(t0, lo), hi if t1 is None else min(t1, hi)
    if t1 is not None and t0 > t1:
        return None, (-1, -1)
    # the range's closed end inside the grid (tmax before the box's far side): p(t1)
    # belongs to the cell that holds it by the half-open rule, which decides that point
    end = (_end_cell(org, dirn, t1, nx, ny)
           if not math.isinf(tmax) and t1 is not None and t1 == _q(tmax) else None)
    best = None
    for i, j, ta, tb in _visited(org, dirn, t0, t1, nx, ny, end, cells):
        h00, h10 = _q(H[j, i]), _q(H[j, i + 1])
        h01, h11 = _q(H[j + 1, i]), _q(H[j + 1, i + 1])
        u0, v0 = org[0] - i, org[1] - j

        def first(a, b, s0, su, sv):
            """Smallest t in [a, b] with z - (s0 + su u + sv v) <= 0 (linear in t); b
            itself only where it ends the range, or inside a triangles cell."""
            g0 = org[2] - s0 - su * u0 - sv * v0
            g1 = dirn[2] - su * dirn[0] - sv * dirn[1]
            if g0 + g1 * a <= 0:
                return a
            closed = (b is None or surface == "triangles"
                      or b == t1 and (end is None or (i, j) == end))
            if g1 < 0 and (closed and (b is None or -g0 / g1 <= b) or not closed and -g0 / g1 < b):
                return -g0 / g1
            return None

        if surface == "flat":
            pieces = [(ta, tb, (h00 + h10 + h01 + h11) / 4, 0, 0)]
        elif surface == "plane3":
            pieces = [(ta, tb, h00, h10 - h00, h01 - h00)]
        else:
            lower, upper = (h00, h10 - h00, h11 - h10), (h00, h11 - h01, h01 - h00)

            def plane(a, b):  # the triangle holding the piece's interior (u >= v: lower)
                m = a + 1 if b is None else (a + b) / 2
                return lower if u0 + m * dirn[0] >= v0 + m * dirn[1] else upper

            w = dirn[0] - dirn[1]
            ts = (v0 - u0) / w if w != 0 else None
            if ts is not None and ts > ta and (tb is None or ts < tb):
                pieces = [(ta, ts) + plane(ta, ts), (ts, tb) + plane(ts, tb)]
            else:
                pieces = [(ta, tb) + plane(ta, tb)]
        for piece in pieces:
            t = first(*piece)
            if t is not None:
                # a point reached at the same t by two cells (where two triangles cells
                # meet, or the end cell at t1) is the one's that holds it (half-open rule)
                if (best is None or t < best[0]
                        or t == best[0] and (i, j) == _end_cell(org, dirn, t, nx, ny)):
                    best = (t, (i, j))
                break
    return (None, (-1, -1)) if best is None else best
