"""Shared breakpoint patterns: the crossings of a ray from a lattice vertex with the
grid lines and cell diagonals, the same list for every vertex of one direction
(package docstring, "Shared patterns" and "Rational sweep")."""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from .directions import Direction

__all__ = ["PATTERN_STOP_EVERY"]

#: Breakpoints between early-stop checks in the pattern walk.
PATTERN_STOP_EVERY = 32


def _period_pattern(q: int, p: int, anti: bool):
    """The breakpoints of one period of the direction (q, p) in the octant frame, from a
    vertex (exclusive) to the next vertex (q, p) (inclusive): a list of
    (T, xa, ya, xb, yb, w) with T an exact Fraction in (0, 1], sorted, without repeats."""
    points = {}

    def add(T, xa, ya, xb, yb, w):
        if w == 0:
            xb, yb = xa, ya
        points.setdefault(T, (T, xa, ya, xb, yb, w))

    for X in range(1, q + 1):  # x = X
        y = Fraction(X * p, q)
        y0 = math.floor(y)
        add(Fraction(X, q), X, y0, X, y0 + 1, y - y0)
    for Y in range(1, p + 1):  # y = Y
        x = Fraction(Y * q, p)
        x0 = math.floor(x)
        add(Fraction(Y, p), x0, Y, x0 + 1, Y, x - x0)
    if not anti and q != p:  # x - y = c, c = 1 .. q - p
        for c in range(1, q - p + 1):
            T = Fraction(c, q - p)
            x = T * q
            x0 = math.floor(x)
            add(T, x0, x0 - c, x0 + 1, x0 - c + 1, x - x0)
    if anti:  # x + y = c, c = 1 .. q + p (c = 0 is the start vertex)
        for c in range(1, q + p + 1):
            T = Fraction(c, q + p)
            x = T * q
            x0 = math.floor(x)
            y0 = c - 1 - x0
            u = x - x0
            if u == 0:  # a vertex: (x0, c - x0)
                add(T, x0, c - x0, x0, c - x0, Fraction(0))
            else:  # from (x0, y0 + 1) at u = 0 to (x0 + 1, y0) at u = 1
                add(T, x0, y0 + 1, x0 + 1, y0, u)
    return [points[T] for T in sorted(points)]


def _pattern_arrays(entries):
    cols = list(zip(*entries))
    T = np.array([float(v) for v in cols[0]])
    xa, ya, xb, yb = (np.array(c, dtype=np.int64) for c in cols[1:5])
    w = np.array([float(v) for v in cols[5]])
    return T, xa, ya, xb, yb, w


def _float_pattern(a: float, b: float, anti: bool, t_max: float):
    """Breakpoints of the octant direction (a, b) (unit, a >= b >= 0) up to distance t_max
    and one beyond, as arrays (t, xa, ya, xb, yb, w), sorted by t."""
    parts = []
    n = int(math.ceil(t_max * a)) + 2
    X = np.arange(1, n + 1, dtype=np.float64)
    t = X / a
    y = t * b
    y0 = np.floor(y)
    parts.append((t, X, y0, X, y0 + 1, y - y0))
    if b > 0:
        n = int(math.ceil(t_max * b)) + 2
        Y = np.arange(1, n + 1, dtype=np.float64)
        t = Y / b
        x = t * a
        x0 = np.floor(x)
        parts.append((t, x0, Y, x0 + 1, Y, x - x0))
    rate = (a + b) if anti else (a - b)
    if rate > 0:
        n = int(math.ceil(t_max * rate)) + 2
        C = np.arange(1, n + 1, dtype=np.float64)
        t = C / rate
        x = t * a
        x0 = np.floor(x)
        u = x - x0
        if anti:
            parts.append((t, x0, C - x0, x0 + 1, C - 1 - x0, u))
        else:
            parts.append((t, x0, x0 - C, x0 + 1, x0 - C + 1, u))
    t, xa, ya, xb, yb, w = (np.concatenate(c) for c in zip(*parts))
    order = np.argsort(t, kind="stable")
    t, xa, ya, xb, yb, w = (v[order] for v in (t, xa, ya, xb, yb, w))
    zero = w == 0
    xb = np.where(zero, xa, xb)
    yb = np.where(zero, ya, yb)
    keep = np.searchsorted(t, t_max, side="right") + 1
    return (t[:keep], xa[:keep].astype(np.int64), ya[:keep].astype(np.int64),
            xb[:keep].astype(np.int64), yb[:keep].astype(np.int64), w[:keep])


def _shared_pattern(d: Direction, rows: int, cols: int, max_distance):
    """The pattern of direction d in its octant frame (rows, cols of that frame)."""
    reach = math.hypot(rows - 1, cols - 1)  # no ray inside the footprint is longer
    t_max = reach if max_distance is None else min(max_distance, reach)
    if d.rational is not None:
        q, p = d.rational
        period = _period_pattern(q, p, d.anti)
        norm = math.hypot(q, p)
        T, xa, ya, xb, yb, w = _pattern_arrays(period)
        periods = int(math.ceil(t_max / norm)) + 1
        m = np.repeat(np.arange(periods), len(T))
        t = (np.tile(T, periods) + m) * norm
        xa, xb = np.tile(xa, periods) + m * q, np.tile(xb, periods) + m * q
        ya, yb = np.tile(ya, periods) + m * p, np.tile(yb, periods) + m * p
        w = np.tile(w, periods)
        keep = np.searchsorted(t, t_max * (1 + 1e-15), side="right") + 1
        t, xa, ya, xb, yb, w = (v[:keep] for v in (t, xa, ya, xb, yb, w))
    else:
        t, xa, ya, xb, yb, w = _float_pattern(d.a, d.b, d.anti, t_max)
    mx = np.maximum.accumulate(np.maximum(xa, xb))
    my = np.maximum.accumulate(np.maximum(ya, yb))
    limit_x = np.searchsorted(mx, np.arange(cols), side="right").astype(np.int64)
    limit_y = np.searchsorted(my, np.arange(rows), side="right").astype(np.int64)
    end_k, end_f, end_inv = -1, 0.0, 0.0
    if max_distance is not None and max_distance < reach:
        k = int(np.searchsorted(t, max_distance, side="right")) - 1
        if 0 <= k < len(t) - 1:
            end_k = k
            end_f = (max_distance - t[k]) / (t[k + 1] - t[k])
            end_inv = 1.0 / max_distance
        elif k < 0:
            # max_distance before the first breakpoint: the surface is linear from v to it,
            # so the ratio over (0, max_distance] is the ratio at that breakpoint; with
            # max_distance 0 the set is empty
            cap = 1 if max_distance > 0 else 0
            limit_x = np.minimum(limit_x, cap)
            limit_y = np.minimum(limit_y, cap)
    return dict(inv_t=1.0 / t, xa=xa, ya=ya, xb=xb, yb=yb, w=w, limit_x=limit_x,
                limit_y=limit_y, end_k=end_k, end_f=end_f, end_inv=end_inv, t=t)
