"""Brute-force first hits: every cell tested, no traversal, vectorised NumPy float64.

The reference the intersectors are compared with (tests, accuracy study). For each ray
it computes, for all cells at once, the closed parameter interval in which the ray lies
over the cell's closed footprint, the earliest parameter in it where the ray is at or
below that cell's surface, and takes the minimum over all cells. Cells share their
borders, so a point on a border is tested against every cell around it: where flat and
plane3 jump, the solid is the union (the higher side), which is the closure of
``{z <= s(x, y)}``. Slow (O(cells) per ray) by design.
"""
from __future__ import annotations

import numpy as np

from .field import HeightField

__all__ = ["brute_force_hits"]


def _interval(o, d, lo_edge, n_cells):
    """Per cell k in 0..n_cells-1 along one axis: the parameter interval over [k, k+1]."""
    k = np.arange(n_cells, dtype=np.float64)
    if d == 0:
        inside = (o >= k) & (o <= k + 1)
        return np.where(inside, -np.inf, np.inf), np.where(inside, np.inf, -np.inf)
    a = (k - o) / d
    b = (k + 1 - o) / d
    return np.minimum(a, b), np.maximum(a, b)


def _first_hit_one(H, o, d, surface, tmin, tmax):
    rows, cols = H.shape
    nx, ny = cols - 1, rows - 1
    # the box [0, cols-1] x [0, rows-1]
    t0, t1 = tmin, tmax
    for axis, top in ((0, nx), (1, ny)):
        if d[axis] == 0:
            if not 0 <= o[axis] <= top:
                return np.inf, (-1, -1)
        else:
            a, b = sorted(((0 - o[axis]) / d[axis], (top - o[axis]) / d[axis]))
            t0, t1 = max(t0, a), min(t1, b)
    if not t0 <= t1:
        return np.inf, (-1, -1)
    if not np.isfinite(t1):
        # a vertical ray: end it where z has passed every possible surface height (plane3
        # extrapolates to 2 min - max at worst); below them the ray is inside the solid
        lo_s = 2.0 * float(H.min()) - float(H.max()) - 1.0
        hi_s = 2.0 * float(H.max()) - float(H.min()) + 1.0
        t1 = min(t1, ((lo_s if d[2] < 0 else hi_s) - o[2]) / d[2])
        if not t0 <= t1:
            t1 = t0
    xa, xb = _interval(o[0], d[0], 0, nx)
    ya, yb = _interval(o[1], d[1], 0, ny)
    ta = np.maximum(np.maximum(xa[None, :], ya[:, None]), t0)  # (ny, nx)
    tb = np.minimum(np.minimum(xb[None, :], yb[:, None]), t1)
    valid = ta <= tb
    if not valid.any():
        return np.inf, (-1, -1)
    jj, ii = np.nonzero(valid)
    ta, tb = ta[valid], tb[valid]
    h00, h10 = H[jj, ii].astype(np.float64), H[jj, ii + 1].astype(np.float64)
    h01, h11 = H[jj + 1, ii].astype(np.float64), H[jj + 1, ii + 1].astype(np.float64)

    def gap(t, lower=None):
        """z - s at parameter t, per candidate cell, by the cell's own surface; for
        triangles ``lower`` forces the triangle (default: the one containing the point)."""
        u = o[0] + t * d[0] - ii
        v = o[1] + t * d[1] - jj
        z = o[2] + t * d[2]
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
    if surface in ("flat", "plane3"):
        # linear along the ray inside a cell
        fb = gap(tb)
        cross = (fa > 0) & (fb <= 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            root = ta + (tb - ta) * fa / (fa - fb)
        best = np.where(cross, np.minimum(best, np.clip(root, ta, tb)), best)
    elif surface == "triangles":
        # split at the diagonal u = v, then linear on each piece
        w = d[0] - d[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            ts = (ii - jj - (o[0] - o[1])) / w if w != 0 else np.full_like(ta, np.inf)
        ts = np.where((ts > ta) & (ts < tb), ts, tb)
        # each piece lies in one triangle: the one holding its midpoint; evaluate each
        # piece with its own plane, at both of its ends
        mid1, mid2 = 0.5 * (ta + ts), 0.5 * (ts + tb)
        lower1 = (o[0] + mid1 * d[0] - ii) >= (o[1] + mid1 * d[1] - jj)
        lower2 = (o[0] + mid2 * d[0] - ii) >= (o[1] + mid2 * d[1] - jj)
        fs1, fs2 = gap(ts, lower1), gap(ts, lower2)
        fb = gap(tb, lower2)
        with np.errstate(divide="ignore", invalid="ignore"):
            r1 = ta + (ts - ta) * fa / (fa - fs1)
            r2 = ts + (tb - ts) * fs2 / (fs2 - fb)
        first = (fa > 0) & (fs1 <= 0)
        at_split = (fa > 0) & (fs1 > 0) & (fs2 <= 0) & (ts < tb)
        second = (fa > 0) & (fs1 > 0) & (fs2 > 0) & (fb <= 0)
        best = np.where(first, np.minimum(best, np.clip(r1, ta, ts)), best)
        best = np.where(at_split, np.minimum(best, ts), best)
        best = np.where(second, np.minimum(best, np.clip(r2, ts, tb)), best)
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
    if not np.isfinite(best[k]):
        return np.inf, (-1, -1)
    return float(best[k]), (int(ii[k]), int(jj[k]))


def brute_force_hits(heights, origins, directions, surface="triangles", tmin=None, tmax=None):
    """(t, cell) of the first hit of every ray, testing every cell; t = inf on a miss.

    Same conventions as ``algos.intersect`` (docs/CONVENTIONS.md, "The first hit"); a
    :class:`algos.HeightField` gives its cell heights.
    """
    H = heights.cell_heights if isinstance(heights, HeightField) else \
        np.asarray(heights, dtype=np.float32)
    o = np.asarray(origins, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    n = len(o)
    lo = np.zeros(n) if tmin is None else np.broadcast_to(np.asarray(tmin, float), (n,))
    hi = np.full(n, np.inf) if tmax is None else np.broadcast_to(np.asarray(tmax, float), (n,))
    t = np.empty(n)
    cell = np.empty((n, 2), np.int32)
    for k in range(n):
        t[k], cell[k] = _first_hit_one(H, o[k], d[k], surface, lo[k], hi[k])
    return t, cell
