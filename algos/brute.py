"""Brute-force first hits: every cell tested, no traversal, vectorised NumPy float64.

The reference the intersectors are compared with (tests, accuracy study). For each ray
and every cell at once it computes the half-open parameter interval ``[ta, tb)`` in which
the ray lies in that cell by the half-open rule of the visited cells (docs/CONVENTIONS.md,
"The visited-cell sequence"), keeps the cells whose interval is not empty, finds in each
the earliest parameter of the closed ``[ta, tb]`` at which the ray is at or below that
cell's own surface, and takes the minimum over the cells. So a point on a cell border is
tested against the one cell that holds it for this ray's direction ("Points on a cell
border", under "The first hit"): a taller neighbour that the ray only touches along an
edge or at a vertex is never hit. Slow (O(cells) per ray) by design.

What is decided exactly:

- Which cells are visited (rational arithmetic wherever float64 cannot tell a tie apart),
  so rays along grid lines and through vertices follow the rule, on every surface.
- On the piecewise linear surfaces (flat, plane3, triangles), the whole first hit of
  every ray whose float64 signs cannot be trusted: a gap z - s at an event (a cell's
  entry or exit, the triangles' diagonal crossing) within a generous bound of its
  rounding error of 0 (``_error_bounds``), a diagonal crossing within its error of a cell
  border (with a gap there near 0) or with a direction nearly along the diagonal, or a
  clipped range whose ends are within a few ulps of each other. Those events lie at parameters that are not
  floats (t = 1/3), where a touch could be missed, a hit found one cell early, or a hit
  reported where the exact ray stays above. Such a ray is recomputed in rational
  arithmetic by ``algos.exact_hits.exact_first_hit`` on the cells the float pass found
  along it, and its t is that exact t rounded to the nearest float. So on these surfaces
  the brute force equals the rational reference: t to the rounding of the float roots of
  the other rays, and the cell. Not on rays whose clipped range is infinite (a vertical
  ray over ``[tmin, inf)``: no grid-line events there), nor on bilinear (float64, with
  the exact border test ``_touches_at_exit``).
"""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from .exact_hits import LINEAR_SURFACES, exact_first_hit
from .field import as_field
from .registry import SURFACES
from .validate import check_rays3, check_rising_from_below, check_t

__all__ = ["brute_force_hits"]


def _axis_intervals(o, d, n_cells):
    """Per cell k in 0..n_cells-1 along one axis: the half-open parameter interval
    ``[lo, hi)`` in which the coordinate lies in that cell's half-open range (``[k, k+1)``
    for ``d >= 0``, ``(k, k+1]`` for ``d < 0``); an empty one is ``(inf, -inf)``. With
    ``d = 0`` the far border ``o = n_cells`` belongs to the last cell: it has no cell on
    its ``+`` side, and the box is closed."""
    k = np.arange(n_cells, dtype=np.float64)
    if d == 0:  # -0.0 included: the cell on the + side
        inside = ((k <= o) & (o < k + 1)) | ((k == n_cells - 1) & (o == n_cells))
        return np.where(inside, -np.inf, np.inf), np.where(inside, np.inf, -np.inf)
    if d > 0:
        return (k - o) / d, (k + 1 - o) / d
    return (k + 1 - o) / d, (k - o) / d


def _along(o, d, t):
    """One coordinate ``o + t d`` of the ray at parameters ``t``; a zero component stays
    at ``o`` even where ``t`` is infinite (a range from ``tmin = -inf``), which ``t * 0``
    would make NaN."""
    return o + t * d if d != 0 else np.full_like(t, o, dtype=np.float64)


def _exact(value):
    """A finite float at its exact binary value."""
    return Fraction(float(value))


def _exactly_visited(i, j, o, d, tmin, tmax):
    """Whether cell (i, j) holds p(t) for some t in [tmin, tmax), in rational arithmetic."""
    lows = [_exact(tmin)] if np.isfinite(tmin) else []
    highs = [_exact(tmax)] if np.isfinite(tmax) else []
    for k, oa, da in ((i, o[0], d[0]), (j, o[1], d[1])):
        if da == 0:
            continue  # decided exactly by the float test: the cell holds it for every t
        near, far = (k, k + 1) if da > 0 else (k + 1, k)
        lows.append((near - _exact(oa)) / _exact(da))
        highs.append((far - _exact(oa)) / _exact(da))
    if not lows or not highs:
        return True  # unbounded on one side; the float test found the other side finite
    return max(lows) < min(highs)


def _half_open_index(oa, da, t) -> int:
    """The index along one axis of the cell that holds ``oa + t da`` by the half-open rule
    (``(k, k+1]`` when ``da < 0``, else ``[k, k+1)``), with ``t`` exact (a Fraction)."""
    x = _exact(oa) + (t * _exact(da) if da != 0 else 0)
    return math.ceil(x) - 1 if da < 0 else math.floor(x)


def _cell_at_start(o, d, nx, ny, tmin):
    """The cell holding p(t0) when the clipped range ``[t0, t1]`` is one point (the ray
    starts on a box face it leaves through, or ``tmin = tmax``): the half-open rule's cell,
    clamped into the grid, from the exact t0."""
    t0 = _exact(tmin) if np.isfinite(tmin) else None
    for oa, da, n in ((o[0], d[0], nx), (o[1], d[1], ny)):
        if da != 0:
            entry = min((0 - _exact(oa)) / _exact(da), (n - _exact(oa)) / _exact(da))
            t0 = entry if t0 is None else max(t0, entry)
    i, j = (min(max(_half_open_index(oa, da, t0), 0), n - 1)
            for oa, da, n in ((o[0], d[0], nx), (o[1], d[1], ny)))
    return j, i


def _cell_at_end(o, d, nx, ny, t1):
    """The cell of the grid that holds p(t1) by the half-open rule (a zero component in
    the far face: the last cell), from the exact t1; None when it lies outside the grid
    (t1 on the box's far side, or beyond the grid)."""
    index = []
    for oa, da, n in ((o[0], d[0], nx), (o[1], d[1], ny)):
        k = _half_open_index(oa, da, _exact(t1))
        if da == 0 and k == n:
            k = n - 1
        if not 0 <= k < n:
            return None
        index.append(k)
    return index[0], index[1]


_EPS = float(np.finfo(np.float64).eps)


def _near(a, b):
    """Where ``a`` lies within a few ulps of ``b`` (both finite)."""
    with np.errstate(invalid="ignore"):
        return np.abs(a - b) <= 8 * _EPS * np.maximum(np.abs(a), np.abs(b))


def _error_bounds(H, o, d, t0, t1, nx, ny, h_max=None):
    """(window, split tolerance) of one ray on [t0, t1].

    window: a bound, generous by far, on the float64 error of a gap z - s that the brute
    force evaluates at an event (a grid-line crossing ``(k - o) / d`` or the triangles'
    diagonal crossing, which are not floats, rounded, then fed into z and s): a gap within
    it has no trustworthy sign. ``2**-40 M``, with M the size of the terms (the origin,
    T |d|, the heights times the coordinates X, and the diagonal crossing's shift
    ``X |dz| / (|dx| + |dy|)``). Split tolerance: a bound on the error of the diagonal
    crossing's parameter ``(i - j - (ox - oy)) / (dx - dy)``."""
    T = max(abs(t0), abs(t1))
    h_max = float(np.max(np.abs(H))) if h_max is None else h_max
    horizontal = abs(d[0]) + abs(d[1])
    X = abs(o[0]) + abs(o[1]) + T * horizontal + nx + ny + 2
    M = abs(o[2]) + T * abs(d[2]) + h_max + 2 * h_max * X
    if horizontal > 0:
        M += X * abs(d[2]) / horizontal
    w = abs(d[0] - d[1])
    split_tol = 16 * _EPS * (T + X / w) if w > 0 else 0.0
    return 2.0 ** -40 * M, split_tol


def _exact_hit(H, o, d, surface, tmin, tmax, t0, candidates):
    """The first hit of one ray in rational arithmetic (``algos.exact_hits``), tested
    on the candidate cells only ((ny, nx) bool mask, a superset of the visited cells), t
    rounded to the nearest float. ``tmin = -inf`` is passed as a finite parameter before
    the box entry ``t0`` (the exact clip then starts at the box)."""
    if not np.isfinite(tmin):
        tmin = max(t0 - 1.0 - abs(t0), -np.finfo(np.float64).max)
    jj, ii = np.nonzero(candidates)
    t, cell = exact_first_hit(H, o, d, surface, tmin, tmax, cells=zip(ii, jj))
    return (np.inf, (-1, -1)) if t is None else (float(t), cell)


def _first_hit_one(H, o, d, surface, tmin, tmax, h_max=None):
    """(t, (i, j)) of one ray; ``h_max``: max |H| (computed when None)."""
    rows, cols = H.shape
    nx, ny = cols - 1, rows - 1
    # the closed range [t0, t1]: [tmin, tmax] clipped to the box [0, nx] x [0, ny]
    t0, t1 = tmin, tmax
    for axis, top in ((0, nx), (1, ny)):
        if d[axis] == 0:
            if not 0 <= o[axis] <= top:
                return np.inf, (-1, -1)
        else:
            a, b = sorted(((0 - o[axis]) / d[axis], (top - o[axis]) / d[axis]))
            t0, t1 = max(t0, a), min(t1, b)
    # t0 and t1 within a few ulps (a range that starts or ends on a box face or grid line
    # at a parameter like 2/3, tmax its rounding): whether the range is empty, one point
    # or a sliver is decided in rational arithmetic, below
    exact_clip = (surface in LINEAR_SURFACES and np.isfinite(t0) and np.isfinite(t1)
                  and bool(_near(t0, t1)))
    if (not t0 <= t1 or t0 == np.inf) and not exact_clip:  # t0 = inf: beyond float64
        return np.inf, (-1, -1)
    xa, xb = _axis_intervals(o[0], d[0], nx)
    ya, yb = _axis_intervals(o[1], d[1], ny)
    # per cell (ny, nx): the half-open interval [ta, tb) of the ray inside it (the cells
    # lie in the box, so it is clipped to the box already)
    ta = np.maximum(np.maximum(xa[None, :], ya[:, None]), tmin)
    tb = np.minimum(np.minimum(xb[None, :], yb[:, None]), tmax)
    # a cell is visited when ta < tb. Each bound is (k - o) / d with two roundings, so
    # within a few ulps the float test cannot tell an exact vertex or edge touch (empty)
    # from a tiny visit: those cells are decided in rational arithmetic
    finite_ta = np.where(np.isfinite(ta), ta, 0.0)
    finite_tb = np.where(np.isfinite(tb), tb, 0.0)
    scale = np.maximum(np.abs(finite_ta), np.abs(finite_tb))
    with np.errstate(invalid="ignore"):
        margin = tb - ta
    unsure = np.abs(finite_tb - finite_ta) <= 8 * np.finfo(np.float64).eps * scale
    unsure &= np.isfinite(ta) & np.isfinite(tb)
    visited = (margin > 0) & ~unsure
    # every cell the ray may visit (a superset of the exactly visited ones): where the
    # exact cold path below looks for the hit
    candidates = visited | unsure
    if exact_clip:
        return _exact_hit(H, o, d, surface, tmin, tmax, min(t0, t1), candidates)
    for j, i in zip(*np.nonzero(unsure)):
        visited[j, i] = _exactly_visited(i, j, o, d, tmin, tmax)
    if not visited.any():
        # [t0, t1) is empty, [t0, t1] one point: the one cell that holds it
        j, i = _cell_at_start(o, d, nx, ny, tmin)
        visited[j, i] = True
        ta[j, i] = tb[j, i] = t0
    # the range's closed end inside the grid (tmax before the box's far side): the cell
    # that holds p(t1) decides that point, and when t1 lies on a border the ray crosses
    # there, that cell is the one entered, with the one-point interval [t1, t1]
    end_cell = None
    if np.isfinite(tmax) and t1 == tmax and t0 < t1:
        end_cell = _cell_at_end(o, d, nx, ny, t1)
        if end_cell is not None and not visited[end_cell[1], end_cell[0]]:
            visited[end_cell[1], end_cell[0]] = True
            ta[end_cell[1], end_cell[0]] = tb[end_cell[1], end_cell[0]] = t1
    if not np.isfinite(t1) or (d[2] != 0 and not (t1 - t0) * abs(d[2]) < 2.0 ** 900):
        # a vertical ray, or one whose horizontal components are so small (subnormal) that
        # leaving the box takes a parameter near or beyond the float64 range, where z(t)
        # may overflow (dx = -2.2e-308, dy = 0: one cell's interval is [0, 4.5e307)): end
        # it where z has passed every possible surface height (plane3 extrapolates to
        # 2 min - max at worst). Below them the ray is inside the solid of the cell it is
        # over, above them it can hit nothing more, so a cell entered later is dropped
        # (its surface, extrapolated to a parameter outside it, means nothing)
        lo_s = 2.0 * float(H.min()) - float(H.max()) - 1.0
        hi_s = 2.0 * float(H.max()) - float(H.min()) + 1.0
        end = ((lo_s if d[2] < 0 else hi_s) - o[2]) / d[2] if d[2] != 0 else t0
        end = max(end, t0)
        visited &= ta <= end
        tb = np.minimum(tb, end)
        if d[2] < 0 and t0 < 0 and not (-t0) * (-d[2]) < 2.0 ** 900:
            # the range starts so far back (tmin = -inf on a vertical ray, or a box entry
            # beyond float64) that z(t0) overflows: the ray comes down from above every
            # possible surface height, where it hits nothing, so it starts where z reaches
            # it (without this, the gap at t0 was NaN, and a huge [t0, t1] rounded the
            # linear root away: a vertical ray from tmin = -1e300 hit flat at t = 0)
            start = (hi_s - o[2]) / d[2]
            visited &= tb > start
            ta = np.maximum(ta, start)
            if not visited.any():
                return np.inf, (-1, -1)
    jj, ii = np.nonzero(visited)
    ta, tb = ta[visited], tb[visited]
    # which candidate holds p(t1) (True everywhere when no end cell applies)
    holds_end = np.ones(len(ii), bool) if end_cell is None else \
        (ii == end_cell[0]) & (jj == end_cell[1])
    h00, h10 = H[jj, ii].astype(np.float64), H[jj, ii + 1].astype(np.float64)
    h01, h11 = H[jj + 1, ii].astype(np.float64), H[jj + 1, ii + 1].astype(np.float64)

    def gap(t, lower=None):
        """z - s at parameter t, per candidate cell, by the cell's own surface; for
        triangles ``lower`` forces the triangle (default: the one containing the point)."""
        u, v, z = _along(o[0], d[0], t) - ii, _along(o[1], d[1], t) - jj, _along(o[2], d[2], t)
        if surface == "flat":
            s = (h00 + h10 + h01 + h11) / 4
        elif surface == "plane3":
            s = h00 + (h10 - h00) * u + (h01 - h00) * v
        elif surface == "triangles":
            side = (u >= v) if lower is None else lower
            s = np.where(side, h00 + (h10 - h00) * u + (h11 - h10) * v,
                         h00 + (h11 - h01) * u + (h01 - h00) * v)
        else:
            s = h00 * (1 - u) * (1 - v) + h10 * u * (1 - v) + h01 * (1 - u) * v + h11 * u * v
        return z - s

    fa = gap(ta)
    best = np.where(fa <= 0, ta, np.inf)
    gaps = [fa]
    if surface in ("flat", "plane3"):
        # linear along the ray inside a cell. These surfaces jump at cell borders, where a
        # point belongs to the cell the ray enters: a cell's interval is [ta, tb), closed
        # only where tb ends the range, so a touch exactly at its exit (z = s at tb, above
        # before) is not a hit of this cell; the next cell's surface decides that point
        fb = gap(tb)
        cross = (fa > 0) & ((fb < 0) | ((fb == 0) & (tb >= t1) & holds_end))
        with np.errstate(divide="ignore", invalid="ignore"):
            root = ta + (tb - ta) * (fa / (fa - fb))
        best = np.where(cross, np.minimum(best, np.clip(root, ta, tb)), best)
    elif surface == "triangles":
        # split at the diagonal u = v, then linear on each piece
        w = d[0] - d[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            ts = (ii - jj - (o[0] - o[1])) / w if w != 0 else np.full_like(ta, np.inf)
        ts_raw, split = ts, (ts > ta) & (ts < tb)
        ts = np.where(split, ts, tb)
        # each piece lies in one triangle: the one holding its midpoint; evaluate each
        # piece with its own plane, at both of its ends
        # (halved first: ta + ts passes the float range when both lie beyond 2**1023, a
        # ray with a subnormal component; for others the same value bit for bit)
        mid1, mid2 = 0.5 * ta + 0.5 * ts, 0.5 * ts + 0.5 * tb
        lower1 = (_along(o[0], d[0], mid1) - ii) >= (_along(o[1], d[1], mid1) - jj)
        lower2 = (_along(o[0], d[0], mid2) - ii) >= (_along(o[1], d[1], mid2) - jj)
        fs1, fs2 = gap(ts, lower1), gap(ts, lower2)
        fb = gap(tb, lower2)
        with np.errstate(divide="ignore", invalid="ignore"):
            r1 = ta + (ts - ta) * (fa / (fa - fs1))
            r2 = ts + (tb - ts) * (fs2 / (fs2 - fb))
        first = (fa > 0) & (fs1 <= 0)
        at_split = (fa > 0) & (fs1 > 0) & (fs2 <= 0) & (ts < tb)
        second = (fa > 0) & (fs1 > 0) & (fs2 > 0) & (fb <= 0)
        best = np.where(first, np.minimum(best, np.clip(r1, ta, ts)), best)
        best = np.where(at_split, np.minimum(best, ts), best)
        best = np.where(second, np.minimum(best, np.clip(r2, ts, tb)), best)
        gaps.extend([fs1, fs2])
    else:
        # bilinear: z - s is quadratic in t; A t^2 + B t + C in absolute t
        a, b, c = h10 - h00, h01 - h00, h00 - h10 - h01 + h11
        u0, v0 = o[0] - ii, o[1] - jj
        A = -c * d[0] * d[1]
        B = d[2] - a * d[0] - b * d[1] - c * (u0 * d[1] + v0 * d[0])
        C = o[2] - (h00 + a * u0 + b * v0 + c * u0 * v0)
        disc = B * B - 4 * A * C
        with np.errstate(divide="ignore", invalid="ignore"):
            sq = np.sqrt(np.maximum(disc, 0))
            roots = [np.where(np.abs(A) > 1e-300, (-B - sq) / (2 * A), -C / B),
                     np.where(np.abs(A) > 1e-300, (-B + sq) / (2 * A), np.nan)]
        for r in roots:
            # the closed form loses digits when the twist c is tiny; polish each root with
            # Newton steps on the directly evaluated gap z - s
            with np.errstate(divide="ignore", invalid="ignore"):
                for _ in range(3):
                    step = gap(np.where(np.isfinite(r), r, ta)) / (2 * A * r + B)
                    r = np.where(np.isfinite(step) & np.isfinite(r), r - step, r)
            # a root where the ray goes from above to at-or-below the surface
            ok = (disc >= 0) & (r >= ta) & (r <= tb) & (fa > 0)
            best = np.where(ok, np.minimum(best, r), best)
        # a sign change the root formula lost to rounding: refine by bisection
        fb = gap(tb)
        lost = (fa > 0) & (fb <= 0) & ~np.isfinite(best)
        if lost.any():
            lo_t, hi_t = ta[lost].copy(), tb[lost].copy()
            sub = np.nonzero(lost)[0]
            for _ in range(80):
                mid = 0.5 * (lo_t + hi_t)
                u = o[0] + mid * d[0] - ii[sub]
                v = o[1] + mid * d[1] - jj[sub]
                s = h00[sub] * (1 - u) * (1 - v) + h10[sub] * u * (1 - v) + h01[sub] * (1 - u) * v + h11[sub] * u * v
                below = o[2] + mid * d[2] - s <= 0
                hi_t = np.where(below, mid, hi_t)
                lo_t = np.where(below, lo_t, mid)
            best[sub] = hi_t
    k = int(np.argmin(best))
    if surface in LINEAR_SURFACES and np.isfinite(t0) and np.isfinite(t1):
        gaps.append(fb)
        # the cells that can hold the first hit or tie with it: those entered by the end
        # of the float hit's cell (all of them on a miss)
        limit = tb[k] + 8 * _EPS * abs(tb[k]) if np.isfinite(best[k]) else np.inf
        window, split_tol = _error_bounds(H, o, d, t0, t1, nx, ny, h_max)
        unsure_sign = np.any([~(np.abs(g) > window) for g in gaps], axis=0)
        if surface == "triangles":
            # the diagonal crossing within its error of a cell border: a piece that may
            # or may not exist, whose hit would lie at that border, so the gap there is
            # near 0 when it matters (tested with a window 2**20 times wider). A direction
            # nearly along the diagonal places the crossing poorly: every split is unsure
            wide = 2.0 ** 20 * window
            with np.errstate(invalid="ignore"):
                unsure_sign |= (np.abs(ts_raw - ta) <= split_tol) & ~(np.abs(fa) > wide)
                unsure_sign |= (np.abs(ts_raw - tb) <= split_tol) & ~(np.abs(fb) > wide)
            if abs(w) < 2.0 ** -12 * (abs(d[0]) + abs(d[1])):
                unsure_sign |= split
        if np.any(unsure_sign & (ta <= limit)):
            return _exact_hit(H, o, d, surface, tmin, tmax, t0, candidates)
    if not np.isfinite(best[k]):
        return np.inf, (-1, -1)
    # a point on a border reached at the same t by two cells (a touch where a triangles
    # or bilinear cell meets the next, or the end cell at t1): the one that holds it by
    # the half-open rule (the cell entered) is the hit's cell. That is the tied cell whose
    # interval starts last: the cell left ends at that t, the cell entered starts there.
    # (Locating p(t) at the rounded t instead picked the cell left whenever the border's
    # parameter is not a float: t = 1/3 rounds below 1/3, where p lies in that cell.)
    same = np.nonzero(best == best[k])[0]
    if len(same) > 1:
        k = int(same[np.argmax(ta[same])])
    elif surface in ("triangles", "bilinear") and best[k] < tb[k] and np.isfinite(tb[k]):
        # the root of the cell left can round a few ulps below its exit when the ray
        # comes down onto the surface exactly on the border (t = 5/3): the next cell then
        # hits at its entry, one ulp later. The border decides in rational arithmetic:
        # a touch exactly there is the entered cell's
        nxt = np.nonzero((ta == tb[k]) & (best == ta))[0]
        if len(nxt) and tb[k] - best[k] <= 8 * np.finfo(np.float64).eps * abs(tb[k]) and \
                _touches_at_exit(H, o, d, surface, int(ii[k]), int(jj[k]), tmax):
            return float(best[k]), (int(ii[nxt[0]]), int(jj[nxt[0]]))
    return float(best[k]), (int(ii[k]), int(jj[k]))


def _touches_at_exit(H, o, d, surface, i, j, tmax):
    """Whether the ray is exactly on cell (i, j)'s ``triangles`` or ``bilinear`` surface
    where it leaves the cell (the exit of its half-open interval, before ``tmax``), in
    rational arithmetic."""
    exits = [(_exact(k + (1 if da > 0 else 0)) - _exact(oa)) / _exact(da)
             for k, oa, da in ((i, o[0], d[0]), (j, o[1], d[1])) if da != 0]
    if not exits:
        return False
    t = min(exits)
    if np.isfinite(tmax) and _exact(tmax) <= t:
        return False
    u = _exact(o[0]) + t * _exact(d[0]) - i
    v = _exact(o[1]) + t * _exact(d[1]) - j
    z = _exact(o[2]) + t * _exact(d[2])
    h00, h10 = _exact(H[j, i]), _exact(H[j, i + 1])
    h01, h11 = _exact(H[j + 1, i]), _exact(H[j + 1, i + 1])
    if surface == "triangles":
        s = (h00 + (h10 - h00) * u + (h11 - h10) * v if u >= v else
             h00 + (h11 - h01) * u + (h01 - h00) * v)
    else:
        s = h00 * (1 - u) * (1 - v) + h10 * u * (1 - v) + h01 * (1 - u) * v + h11 * u * v
    return z == s


def brute_force_hits(heights, origins, directions, surface="triangles", tmin=None, tmax=None):
    """(t, cell) of the first hit of every ray, testing every cell; t = inf on a miss.

    Same conventions as ``algos.intersect`` (docs/CONVENTIONS.md, "The first hit"),
    points on a cell border included: each is tested against the one cell that holds it
    for the ray's direction (a zero component takes the ``+`` side; the box's far side
    and a one-point range take the nearest cell of the grid; the range's end ``tmax``
    inside the grid is the cell that holds that point). On ``flat`` and ``plane3`` a touch
    exactly at a cell's exit is therefore the next cell's to decide. A
    :class:`algos.HeightField` gives its cell heights.

    Parameters
    ----------
    heights : 2D array of real numbers (rows, cols), HeightField or DataArray
        Read as ``algos.intersect`` reads them (float32 cell heights).
    origins, directions : (N, 3) array_like
        Float rays, validated as ``algos.intersect`` validates them (finite, no zero
        direction, largest direction component in ``[2**-400, 2**400]``,
        ``|origins| <= 2**30``).
    surface : {"flat", "plane3", "triangles", "bilinear"}
    tmin, tmax : None, float or (N,) array
        Default ``[0, inf)``; no NaN. An empty range (``tmin > tmax``) is a miss.

    Raises
    ------
    ValueError, TypeError
        As ``algos.intersect``: naming the argument and the offending ray.

    Returns
    -------
    t : ndarray (n,) float64
    cell : ndarray (n, 2) int32
        ``(i, j)`` of the cell whose surface or wall is hit (the one that holds the hit
        point by the half-open rule when two cells reach it at the same t, as where two
        triangles or bilinear cells meet), ``(-1, -1)`` on a miss.
    """
    if surface not in SURFACES:
        raise ValueError(f"surface: unknown surface {surface!r}; valid surfaces are {', '.join(SURFACES)}")
    # the validation of algos.intersect: the same inputs are accepted, the same refused
    H = as_field(heights).cell_heights
    o, d = check_rays3(origins, directions)
    n = len(o)
    lo, hi = check_t(tmin, "tmin", n), check_t(tmax, "tmax", n)
    check_rising_from_below(d, lo, hi)
    lo = np.zeros(n) if lo is None else lo
    hi = np.full(n, np.inf) if hi is None else hi
    t = np.empty(n)
    cell = np.empty((n, 2), np.int32)
    # a parameter beyond float64 (a subnormal direction component) overflows to +-inf,
    # which is what the clip and the cell intervals mean by it
    h_max = float(np.max(np.abs(H)))
    with np.errstate(over="ignore"):
        for k in range(n):
            t[k], cell[k] = _first_hit_one(H, o[k], d[k], surface, lo[k], hi[k], h_max)
    return t, cell
