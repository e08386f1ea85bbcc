"""The exact reference traversal, in pure Python with :class:`fractions.Fraction`.

It is deliberately a different algorithm from every kernel in ``cext/``. The kernels walk
an integer recurrence in a reduced octant; this module works straight from the
definition in ``docs/CONVENTIONS.md``: it lists every parameter ``t`` at which the ray crosses
an x or y grid line, merges the two lists, and evaluates the half-open cell rule at the
start of each piece. Nothing is incremental, so a rounding or stepping bug in a kernel
cannot be mirrored here.
"""
from __future__ import annotations

import math
import numbers
from fractions import Fraction
from typing import Iterable

__all__ = ["reference_cells", "reference_runs", "runs_from_cells", "major_axis"]


def _cell_index(position: Fraction, velocity: Fraction) -> int:
    """Index along one axis of the cell holding ``position`` when moving at ``velocity``.

    Cells are half-open toward the direction of travel: ``[k, k+1)`` for ``velocity >= 0``
    and ``(k, k+1]`` for ``velocity < 0``.
    """
    if velocity < 0:
        return math.ceil(position) - 1
    return math.floor(position)


def _axis_range(origin: Fraction, velocity: Fraction, size: int):
    """The parameter interval ``[lo, hi)`` during which the axis index lies in
    ``[0, size)``; ``None`` for "never"; ``(-inf, +inf)`` is ``(None, None)``."""
    if velocity == 0:
        return (None, None) if 0 <= origin < size else None
    a = (0 - origin) / velocity
    b = (size - origin) / velocity
    return (a, b) if velocity > 0 else (b, a)


def _crossings(origin: Fraction, velocity: Fraction, t0: Fraction, t1: Fraction):
    """Sorted parameters in ``(t0, t1)`` at which the coordinate is an integer."""
    if velocity == 0:
        return []
    x0 = origin + t0 * velocity
    x1 = origin + t1 * velocity
    lo, hi = (x0, x1) if velocity > 0 else (x1, x0)
    # integers strictly between the two end positions
    first, last = math.floor(lo) + 1, math.ceil(hi) - 1
    ks = range(first, last + 1) if velocity > 0 else range(last, first - 1, -1)
    return [(k - origin) / velocity for k in ks]


def _merge(a: list, b: list) -> list:
    """Merge two sorted lists, keeping equal values once (a vertex crossing)."""
    out, i, j = [], 0, 0
    while i < len(a) or j < len(b):
        if j == len(b) or (i < len(a) and a[i] < b[j]):
            value = a[i]
            i += 1
        elif i == len(a) or b[j] < a[i]:
            value = b[j]
            j += 1
        else:
            value = a[i]
            i += 1
            j += 1
        out.append(value)
    return out


def _exact(value, name: str) -> Fraction:
    if isinstance(value, Fraction):
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return Fraction(value)


def _pair(value, name: str) -> tuple:
    """``(x, y)`` of ``origin`` or ``direction`` as exact Fractions; anything else raises,
    naming the argument (a 3D point, a bare number and a string of digits too)."""
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be a pair (x, y) of real numbers, got {value!r}")
    try:
        x, y = value
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (x, y), got {value!r}") from None
    return _exact(x, f"{name}[0]"), _exact(y, f"{name}[1]")


def _grid(shape) -> tuple:
    """``(nx, ny)``: two integers >= 1 (no upper limit: the reference is pure Python)."""
    if hasattr(shape, "cell_heights"):  # a HeightField: its grid of cells
        return shape.cols - 1, shape.rows - 1
    try:
        sides = tuple(shape)
    except TypeError:
        sides = ()
    if isinstance(shape, (str, bytes)) or len(sides) != 2:
        raise ValueError(f"shape must be (nx, ny), got {shape!r}")
    for k, side in enumerate(sides):
        if isinstance(side, bool) or not isinstance(side, numbers.Integral):
            raise TypeError(f"shape[{k}] must be an integer, got {side!r}")
        if side < 1:
            raise ValueError(f"shape[{k}] must be positive, got {side!r}")
    return int(sides[0]), int(sides[1])


def reference_cells(origin, direction, shape, tmin=0.0, tmax=float("inf")):
    """Cells visited by the ray ``o + t d`` for ``t`` in ``[tmin, tmax)``, exactly.

    Parameters
    ----------
    origin, direction : pair of float or Fraction
        ``(x, y)``; every float is taken at its exact binary value. ``direction`` need
        not be normalised; ``(0, 0)`` is a vertical ray and visits at most one cell.
    shape : (nx, ny) or HeightField
        Grid size in cells, in (x, y) order (a HeightField: ``(cols - 1, rows - 1)``).
    tmin, tmax : float or Fraction
        The parameter range; ``-inf``/``inf`` are allowed.

    Returns
    -------
    list of (i, j)
        Postconditions (docs/CONVENTIONS.md): the cells containing ``p(t)`` for ``t`` in
        ``[t0, t1)`` in order of ``t``, where ``[t0, t1)`` is ``[tmin, tmax)`` clipped to
        the box ``[0, nx] x [0, ny]``; cells are half-open toward the direction of
        travel (``-0.0`` counts as ``0``); at an exact vertex crossing both indices
        change at once; consecutive cells share an edge (or a vertex only at a vertex
        crossing); no cell repeats.
    """
    nx, ny = _grid(shape)
    ox, oy = _pair(origin, "origin")
    dx, dy = _pair(direction, "direction")
    t_lo = None if tmin == -math.inf else _exact(tmin, "tmin") if tmin != math.inf else None
    t_hi = None if tmax == math.inf else _exact(tmax, "tmax") if tmax != -math.inf else None
    if tmin == math.inf or tmax == -math.inf or (
        t_lo is not None and t_hi is not None and not t_lo < t_hi
    ):
        return []

    # the parameter interval in which both indices are inside the grid
    ranges = [_axis_range(ox, dx, nx), _axis_range(oy, dy, ny)]
    if None in ranges:
        return []
    lows = [r[0] for r in ranges if r[0] is not None] + ([t_lo] if t_lo is not None else [])
    highs = [r[1] for r in ranges if r[1] is not None] + ([t_hi] if t_hi is not None else [])
    if dx == 0 and dy == 0:
        # vertical: the cell under the origin, for any non-empty parameter range
        return [(_cell_index(ox, dx), _cell_index(oy, dy))]
    t0, t1 = max(lows), min(highs)  # a moving ray always has finite axis bounds
    if not t0 < t1:
        return []

    events = [t0] + _merge(_crossings(ox, dx, t0, t1), _crossings(oy, dy, t0, t1))
    return [
        (_cell_index(ox + t * dx, dx), _cell_index(oy + t * dy, dy)) for t in events
    ]


def major_axis(direction) -> int:
    """0 if x is the major axis (the larger ``|d|``, x on a tie), else 1."""
    dx, dy = (abs(float(v)) for v in direction)
    return 1 if dy > dx else 0


def runs_from_cells(cells: Iterable, major: int) -> list:
    """Group a cell sequence into runs ``(minor, first, last)``.

    A run is a maximal stretch of consecutive cells with one minor index; ``first`` and
    ``last`` are the major-axis indices of its first and last cell in travel order.
    """
    runs = []
    for cell in cells:
        minor, along = cell[1 - major], cell[major]
        if runs and runs[-1][0] == minor:
            runs[-1][2] = along
        else:
            runs.append([minor, along, along])
    return [tuple(r) for r in runs]


def reference_runs(origin, direction, shape, tmin=0.0, tmax=float("inf")) -> list:
    """The run sequence of :func:`reference_cells` (see :func:`runs_from_cells`)."""
    cells = reference_cells(origin, direction, shape, tmin, tmax)
    return runs_from_cells(cells, major_axis(direction))
