"""Exact references for the terrain products, in pure Python and rational arithmetic.

They share nothing with the kernels: no patterns, no frames, no walks. Each one lists every
point where a straight line crosses a grid line x = k, y = k or a cell diagonal x - y = k
(docs/CONVENTIONS.md: the two triangles of cell (i, j) meet on u = v), evaluates the
two-triangle surface there with :class:`fractions.Fraction`, and compares.

Why the breakpoints suffice. Along a line the surface is linear between consecutive
breakpoints. For a horizon from vertex v, the ratio (s(t) - H(v)) / t on a piece where
s = a + b t equals (a - H(v)) / t + b, which is monotone in t, so its supremum over the
piece is at one of its two ends. On the first piece s(0) = H(v), so the ratio is the
constant b there and the slope limit at t -> 0+ equals the ratio at the first breakpoint.
The far end (the edge of the footprint, or max_distance) is the last point considered.
For a line of sight the gap between surface and segment is linear on every piece, so the
surface rises strictly above the segment somewhere if and only if it does at a breakpoint.

Curvature. With the surface at distance t lowered by kappa t^2, the ratio on a piece is
g(t) = (a - H(v)) / t + b - kappa t, which for kappa > 0 and a < H(v) is concave with its
peak at t* = sqrt((H(v) - a) / kappa), where g = b - 2 sqrt(kappa (H(v) - a)). The
supremum over a piece is at its ends or at t* when t* lies inside it (decided exactly, by
comparing t*^2 with the ends' squares). On the first piece g = b - kappa t, whose
supremum is the slope limit b at t -> 0+. The peak is irrational in general: it is
evaluated with an integer square root to 2^-200, far below float64 rounding; everything
else stays rational.

These run in seconds on fields of a few dozen samples a side, which is what the tests use.
"""
from __future__ import annotations

import math
from fractions import Fraction

__all__ = ["surface_exact", "horizon_tangent_exact", "horizon_reference", "line_of_sight_exact",
           "viewshed_reference", "viewshed_threshold_exact"]


def surface_exact(heights, x: Fraction, y: Fraction) -> Fraction:
    """The two-triangle surface at a point of the footprint, exactly."""
    rows, cols = len(heights), len(heights[0])
    i = min(max(math.floor(x), 0), cols - 2)
    j = min(max(math.floor(y), 0), rows - 2)
    u, v = x - i, y - j
    h00, h10 = Fraction(heights[j][i]), Fraction(heights[j][i + 1])
    h01, h11 = Fraction(heights[j + 1][i]), Fraction(heights[j + 1][i + 1])
    if u >= v:
        return h00 + (h10 - h00) * u + (h11 - h10) * v
    return h00 + (h11 - h01) * u + (h01 - h00) * v


def _crossings(ox: Fraction, oy: Fraction, dx: Fraction, dy: Fraction, t_end: Fraction,
               cols: int, rows: int) -> list[Fraction]:
    """Every t in (0, t_end] where o + t d crosses x = k, y = k or x - y = k, plus t_end."""
    ts = {t_end}
    for o, d, n in ((ox, dx, cols), (oy, dy, rows)):
        if d != 0:
            for k in range(0, n):
                t = (k - o) / d
                if 0 < t <= t_end:
                    ts.add(t)
    rate = dx - dy
    if rate != 0:
        for k in range(-(rows - 1), cols):
            t = (k - (ox - oy)) / rate
            if 0 < t <= t_end:
                ts.add(t)
    return sorted(ts)


def _footprint_exit(ox, oy, dx, dy, cols, rows):
    t = None
    for o, d, n in ((ox, dx, cols), (oy, dy, rows)):
        if d > 0:
            e = (n - 1 - o) / d
        elif d < 0:
            e = -o / d
        else:
            continue
        t = e if t is None else min(t, e)
    return t


def _sqrt_fraction(x: Fraction, bits: int = 200) -> Fraction:
    """sqrt(x) for a Fraction x >= 0, rounded down to a multiple of 2^-bits / denominator."""
    n, d = x.numerator, x.denominator
    return Fraction(math.isqrt(n * d << (2 * bits)), d << bits)


def horizon_tangent_exact(heights, i: int, j: int, dx: Fraction, dy: Fraction,
                          max_t: Fraction | None = None, kappa_t: Fraction = Fraction(0)):
    """The supremum of (s(p) - kappa_t t^2 - H[j][i]) / t over the points
    p = (i, j) + t (dx, dy) of the footprint with 0 < t <= max_t, as a Fraction (exact, or
    to 2^-200 when an interior peak wins: module docstring), or None when there are none.
    Divide by |d| for the tangent of the horizon angle; kappa_t is the drop per t^2
    (kappa |d|^2)."""
    rows, cols = len(heights), len(heights[0])
    t_end = _footprint_exit(Fraction(i), Fraction(j), dx, dy, cols, rows)
    if max_t is not None:
        t_end = min(t_end, max_t)
    if t_end <= 0:
        return None
    h = Fraction(heights[j][i])
    kappa_t = Fraction(kappa_t)
    best = None
    t0, rise0 = Fraction(0), Fraction(0)  # the previous breakpoint, relative to h
    for t in _crossings(Fraction(i), Fraction(j), dx, dy, t_end, cols, rows):
        rise = surface_exact(heights, i + t * dx, j + t * dy) - h
        slope = (rise - rise0) / (t - t0)
        candidates = [rise / t - kappa_t * t]
        if t0 == 0:
            candidates.append(slope)  # the first piece's limit at t -> 0+
        elif kappa_t > 0:
            minus_a = slope * t0 - rise0  # H(v) - a of the piece's line
            if minus_a > 0 and t0 * t0 < minus_a / kappa_t < t * t:
                candidates.append(slope - 2 * _sqrt_fraction(minus_a * kappa_t))
        for r in candidates:
            if best is None or r > best:
                best = r
        t0, rise0 = t, rise
    return best


def horizon_reference(heights, direction, max_distance=None, kappa=0.0):
    """Horizon angles (radians) of every vertex along ``direction`` (two numbers: a float
    pair is taken at its exact binary value), as a list of rows; -pi/2 where the ray has
    no point in the footprint. ``max_distance`` is a distance (not a ray parameter).
    ``kappa``: curvature, the surface at distance D lowered by kappa D^2 (taken at its
    exact binary value; negative raises it)."""
    heights = [[float(v) for v in row] for row in heights]
    rows, cols = len(heights), len(heights[0])
    dx, dy = Fraction(direction[0]), Fraction(direction[1])
    kappa_t = Fraction(kappa) * (dx * dx + dy * dy)
    norm = math.sqrt(float(dx * dx + dy * dy))
    max_t = None
    if max_distance is not None and math.isfinite(max_distance):
        # |d| is irrational in general: the end parameter is exact only up to rounding
        max_t = Fraction(max_distance) / Fraction(norm)
    out = []
    for j in range(rows):
        line = []
        for i in range(cols):
            best = horizon_tangent_exact(heights, i, j, dx, dy, max_t, kappa_t)
            line.append(-math.pi / 2 if best is None else math.atan(float(best) / norm))
        out.append(line)
    return out


def line_of_sight_exact(heights, observer, z0, target, z_target, drop=Fraction(0)):
    """True when the segment (observer, z0) -> (target, z_target) never passes strictly
    below the surface lowered by drop * d^2 (d the horizontal distance from the observer,
    applied at the breakpoints as the kernels do); z_target is the unlowered height of the
    target point, which sinks with the surface. The target point itself is not tested."""
    rows, cols = len(heights), len(heights[0])
    ox, oy = Fraction(observer[0]), Fraction(observer[1])
    tx, ty = Fraction(target[0]), Fraction(target[1])
    dx, dy = tx - ox, ty - oy
    if dx == 0 and dy == 0:
        return True
    z0, drop = Fraction(z0), Fraction(drop)
    length2 = dx * dx + dy * dy
    z1 = Fraction(z_target) - drop * length2  # the target sinks with the surface
    for t in _crossings(ox, oy, dx, dy, Fraction(1), cols, rows):
        if t >= 1:
            continue
        s = surface_exact(heights, ox + t * dx, oy + t * dy) - drop * length2 * t * t
        if s > z0 + (z1 - z0) * t:
            return False
    return True


def viewshed_reference(heights, observer, observer_height, target_height=0.0, drop=0.0):
    """Visibility of every vertex from one observer, exactly, as a list of rows of bools."""
    heights = [[float(v) for v in row] for row in heights]
    rows, cols = len(heights), len(heights[0])
    ox, oy = Fraction(observer[0]), Fraction(observer[1])
    z0 = surface_exact(heights, ox, oy) + Fraction(observer_height)
    th = Fraction(target_height)
    return [[line_of_sight_exact(heights, (ox, oy), z0, (i, j), Fraction(heights[j][i]) + th,
                                 Fraction(drop))
             for i in range(cols)] for j in range(rows)]


def viewshed_threshold_exact(heights, observer, z0, target, z_target, kind, drop=Fraction(0)):
    """The bound a line of sight from (observer, z0) to (target, z_target) puts on one of
    its ends, exactly, over the breakpoints t in (0, 1) of the segment, with the surface
    lowered by drop * d^2 (the target top sinks with it, as in line_of_sight_exact):

    * ``kind="target"``: max of (sigma - z0) / t; the segment clears the surface exactly
      when the (lowered) target top is at least z0 + that;
    * ``kind="observer"``: max of (sigma - z1 t) / (1 - t), z1 the lowered target top; the
      segment clears the surface exactly when the eye is at least that.

    None when the segment has no breakpoint (nothing lies between its ends)."""
    rows, cols = len(heights), len(heights[0])
    ox, oy = Fraction(observer[0]), Fraction(observer[1])
    tx, ty = Fraction(target[0]), Fraction(target[1])
    dx, dy = tx - ox, ty - oy
    if dx == 0 and dy == 0:
        return None
    z0, drop = Fraction(z0), Fraction(drop)
    length2 = dx * dx + dy * dy
    z1 = Fraction(z_target) - drop * length2
    best = None
    for t in _crossings(ox, oy, dx, dy, Fraction(1), cols, rows):
        if t >= 1:
            continue
        sigma = surface_exact(heights, ox + t * dx, oy + t * dy) - drop * length2 * t * t
        r = (sigma - z0) / t if kind == "target" else (sigma - z1 * t) / (1 - t)
        if best is None or r > best:
            best = r
    return best
