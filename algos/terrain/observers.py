"""Observers and targets of a viewshed: positions, the ground under them, heights above
it, output values, and a one-line raster thickened to a field."""
from __future__ import annotations

import math

import numpy as np

from .. import _kernels
from ..field import HeightField

__all__ = ["VIEWSHED_MODES", "DEFAULT_OBSERVER_HEIGHT", "VIEWSHED_UINT8_NODATA"]


def _observers(observer, h):
    rows, cols = h.shape
    obs = np.asarray(observer, dtype=np.float64) if not isinstance(observer, np.ndarray) \
        else observer.astype(np.float64)
    single = obs.ndim == 1
    obs = np.atleast_2d(obs)
    if obs.ndim != 2 or obs.shape[1] != 2 or obs.shape[0] == 0:
        raise ValueError(f"observer: expected (x, y) or an (N, 2) array, got shape {np.shape(observer)}")
    for k, (x, y) in enumerate(obs):
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"observer[{k}]: non-finite position ({x}, {y})")
        if not (0 <= x <= cols - 1 and 0 <= y <= rows - 1):
            raise ValueError(f"observer[{k}]: ({x}, {y}) outside the footprint "
                             f"[0, {cols - 1}] x [0, {rows - 1}]")
    return obs, single


def _surface_float(h, x, y):
    rows, cols = h.shape
    i = min(max(int(math.floor(x)), 0), cols - 2)
    j = min(max(int(math.floor(y)), 0), rows - 2)
    u, v = x - i, y - j
    h00, h10, h01, h11 = h[j, i], h[j, i + 1], h[j + 1, i], h[j + 1, i + 1]
    if u >= v:
        return float(h00 + (h10 - h00) * u + (h11 - h10) * v)
    return float(h00 + (h11 - h01) * u + (h01 - h00) * v)


def _touches_void(void, x, y):
    """Whether the grid point (x, y) lies in a cell one of whose corners is a void."""
    rows, cols = void.shape
    i0, j0 = int(math.floor(x)), int(math.floor(y))
    i_lo, i_hi = max(0, i0 - (x == i0)), min(cols - 1, i0 + 1)
    j_lo, j_hi = max(0, j0 - (y == j0)), min(rows - 1, j0 + 1)
    if x == i0 and y == j0:
        return bool(void[j0, i0])  # on a vertex: its own height is the observer's ground
    return bool(void[j_lo:j_hi + 1, i_lo:i_hi + 1].any())


#: What :func:`viewshed` returns per vertex (``mode``); see its docstring.
VIEWSHED_MODES = ("normal", "dem", "ground", "observer", "angle")
#: The observer's eye above the surface when ``observer_height`` is left out.
DEFAULT_OBSERVER_HEIGHT = 1.75
#: A uint8 viewshed with output values stores its voids as this (datasets_gen.raster).
VIEWSHED_UINT8_NODATA = 255


def _output_value(value, name, allow_nan=False):
    """An output value as a float: a real number, finite (NaN too where allowed)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer,
                                                                     np.floating)):
        raise TypeError(f"{name}: expected a number, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) or (allow_nan and math.isnan(v))):
        raise ValueError(f"{name}: expected a finite number{' or NaN' if allow_nan else ''}, "
                         f"got {value!r}")
    return v


def _height_above(value, name):
    """A height above the ground as a float: any finite number (negative: below it)."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name}: expected a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: expected a finite length (negative: below the ground), "
                         f"got {value!r}")
    return v


def _thicken(heights, observer):
    """A one-row or one-column array repeated to two rows (columns), and the slice that
    crops a result back; ``(heights, None)`` for any other input (a HeightField has two
    samples a side at least). Along the one line the repeated field's surface is the
    polyline through the samples, the line's own surface; observers must lie on it."""
    if isinstance(heights, (HeightField, str, bytes, dict)) or heights is None:
        return heights, None
    shape = np.shape(heights)
    if len(shape) != 2 or min(shape) != 1 or max(shape) > _kernels.MAX_GRID_SIDE:
        return heights, None
    if shape == (1, 1):  # repeated it would be named (2, 1), a shape the caller never gave
        raise ValueError("heights: one sample (shape (1, 1)) is neither a line nor a field; "
                         "a viewshed needs at least two samples in a row or a column")
    rows, cols = shape
    for k, (x, y) in enumerate(np.atleast_2d(np.asarray(observer, dtype=np.float64))):
        if not ((y == 0 and 0 <= x <= cols - 1) if rows == 1 else (x == 0 and 0 <= y <= rows - 1)):
            raise ValueError(f"observer[{k}]: ({x}, {y}) outside the footprint "
                             f"[0, {cols - 1}] x [0, {rows - 1}] of a one-"
                             f"{'row' if rows == 1 else 'column'} raster (a line)")
    axis = 0 if rows == 1 else 1
    crop = (slice(0, 1), slice(None)) if axis == 0 else (slice(None), slice(0, 1))
    return np.repeat(np.asarray(heights), 2, axis=axis), crop
