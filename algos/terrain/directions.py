"""Azimuths as unit directions in grid coordinates, their octant frames, and the
rational slopes the exact sweep needs."""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

__all__ = ["Direction", "azimuth_direction", "MAX_SNAP_DENOMINATOR", "SNAP_TOLERANCE_DEG"]

#: Azimuths this close to a small rational slope are taken as exactly that slope.
MAX_SNAP_DENOMINATOR = 128
SNAP_TOLERANCE_DEG = 1e-9


@dataclass(frozen=True)
class Direction:
    """An azimuth as a unit direction (dx, dy) in grid coordinates, and its octant frame:
    mirror x when sx < 0, mirror y when sy < 0, then swap x and y when swap, which maps it to
    (a, b) with a >= b >= 0. rational: (q, p) when the octant slope is exactly p / q."""

    azimuth: float
    dx: float
    dy: float
    sx: int
    sy: int
    swap: bool
    a: float
    b: float
    rational: tuple[int, int] | None

    @property
    def anti(self) -> bool:
        """In the octant frame, the cells are split on u + v = 1 instead of u = v."""
        return (self.sx < 0) != (self.sy < 0)


def azimuth_direction(azimuth) -> Direction:
    """The :class:`Direction` of an azimuth in degrees (clockwise from north = -y)."""
    try:
        az = float(azimuth)
    except (TypeError, ValueError):
        raise TypeError(f"azimuth: expected a number, got {azimuth!r}") from None
    if not math.isfinite(az):
        raise ValueError(f"azimuth: expected a finite number of degrees, got {azimuth!r}")
    az = az % 360.0
    rad = math.radians(az)
    ux, uy = math.sin(rad), -math.cos(rad)
    ax, ay = abs(ux), abs(uy)
    big, small = max(ax, ay), min(ax, ay)
    rational = None
    frac = Fraction(small / big).limit_denominator(MAX_SNAP_DENOMINATOR)
    q, p = frac.denominator, frac.numerator
    if abs(math.degrees(math.atan2(p, q) - math.atan2(small, big))) <= SNAP_TOLERANCE_DEG:
        rational = (q, p)
        norm = math.hypot(q, p)
        big, small = q / norm, p / norm
        if ax >= ay:
            ax, ay = big, small
        else:
            ax, ay = small, big
        # exact zeros keep the half-open cell rules exact along grid lines
    sx = 1 if ux > 0 and ax > 0 else -1 if ux < 0 and ax > 0 else 0
    sy = 1 if uy > 0 and ay > 0 else -1 if uy < 0 and ay > 0 else 0
    swap = ay > ax
    return Direction(az, sx * ax if sx else 0.0, sy * ay if sy else 0.0, sx, sy, swap,
                     max(ax, ay), min(ax, ay), rational)


def _to_frame(a: np.ndarray, d: Direction) -> np.ndarray:
    if d.sx < 0:
        a = a[:, ::-1]
    if d.sy < 0:
        a = a[::-1, :]
    if d.swap:
        a = a.T
    return a


def _from_frame(a: np.ndarray, d: Direction) -> np.ndarray:
    if d.swap:
        a = a.T
    if d.sy < 0:
        a = a[::-1, :]
    if d.sx < 0:
        a = a[:, ::-1]
    return a
