"""Lists of azimuths: validated, equally spaced, or snapped to rational cell directions
(where the exact sweep applies)."""
from __future__ import annotations

import math

import numpy as np

from ..field import HeightField, is_dataarray
from ..validate import check_spacing
from .directions import MAX_SNAP_DENOMINATOR
from .grid import Grid, _field_spacing

__all__ = ["rational_azimuths", "snap_azimuths"]


def rational_azimuths(n: int, max_denominator: int = 5) -> np.ndarray:
    """``n`` azimuths (degrees) near 0, 360/n, 2*360/n, ..., each moved to the nearest
    direction whose octant slope is p/q with q <= max_denominator, so that the exact sweep
    applies.

    The sweep reads about 2 q (or 2 (q + p) against the diagonals) breakpoints per vertex,
    so small denominators are fast. The default 5 moves 16 azimuths by at most 0.70
    degrees (22.5 becomes atan(2/5) = 21.80); 12 moves them by at most 0.12 degrees
    (atan(5/12) = 22.62) at about 2.4 times the cost."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n: expected a positive int, got {n!r}")
    if not 1 <= max_denominator <= MAX_SNAP_DENOMINATOR:
        raise ValueError(f"max_denominator: expected 1..{MAX_SNAP_DENOMINATOR}, got {max_denominator}")
    candidates = sorted({math.degrees(math.atan2(p, q))
                         for q in range(1, max_denominator + 1) for p in range(0, q + 1)
                         if math.gcd(p, q) == 1})
    out = []
    for k in range(n):
        az = 360.0 * k / n
        octant, rest = divmod(az, 45.0)
        octant = int(octant) % 8
        # within an octant, the angle from its start (even octants) or to its end (odd)
        offset = rest if octant % 2 == 0 else 45.0 - rest
        best = min(candidates, key=lambda c: (abs(c - offset), c))
        snapped = octant * 45.0 + (best if octant % 2 == 0 else 45.0 - best)
        out.append(snapped % 360.0)
    return np.array(out)


def _snap_cell_azimuth(azimuth: float, max_denominator: int) -> float:
    """The direction nearest ``azimuth`` (degrees, cell space) whose octant slope is p/q
    with q <= max_denominator (ties: the smaller q, then the smaller angle)."""
    octant, rest = divmod(azimuth % 360.0, 45.0)
    octant = int(octant) % 8
    offset = rest if octant % 2 == 0 else 45.0 - rest  # degrees from the octant's axis
    ratio = math.tan(math.radians(offset))
    best = None
    for q in range(1, max_denominator + 1):
        for p in {math.floor(ratio * q), math.ceil(ratio * q)}:
            if 0 <= p <= q and math.gcd(p, q) == 1:
                angle = math.degrees(math.atan2(p, q))
                key = (abs(angle - offset), q, angle)
                if best is None or key < best:
                    best = key
    angle = best[2]
    return (octant * 45.0 + (angle if octant % 2 == 0 else 45.0 - angle)) % 360.0


def snap_azimuths(azimuths, max_denominator, spacing=None, *, name="max_denominator"):
    """Move each azimuth to the nearest direction whose slope *in cell space* is p/q with
    q <= ``max_denominator``, where the exact sweep applies at unlimited distance.

    Parameters
    ----------
    azimuths : float or sequence of floats
        Degrees clockwise from north.
    max_denominator : int
        1 to :data:`MAX_SNAP_DENOMINATOR`. A larger one moves less and costs more: the
        sweep reads about 2 q breakpoints per vertex.
    spacing : float or (dx, dy), optional
        The pixel size; on rectangular pixels an azimuth is snapped in cell space and
        mapped back (:meth:`Grid.cell_azimuth`).
    name : str
        The argument named in errors (the products pass ``"snap_denominator"``).

    Returns
    -------
    (float64 array (K,), float)
        The snapped azimuths (degrees, in [0, 360)) and the largest angular change, in
        degrees of map azimuth.

    Raises
    ------
    ValueError, TypeError
        Naming ``max_denominator``, ``azimuths[k]`` or ``spacing``.
    """
    if isinstance(max_denominator, bool) or not isinstance(max_denominator, (int, np.integer)) \
            or not 1 <= max_denominator <= MAX_SNAP_DENOMINATOR:
        raise ValueError(f"{name}: expected an int in 1..{MAX_SNAP_DENOMINATOR}, "
                         f"got {max_denominator!r}")
    dx, dy = check_spacing(spacing) if spacing is not None else (1.0, 1.0)
    grid = Grid(np.zeros((2, 2)), dx, dy, dx, True, None, None)
    out, change = [], 0.0
    for a in _azimuth_list(azimuths):
        snapped = grid.map_azimuth(_snap_cell_azimuth(grid.cell_azimuth(a % 360.0),
                                                      int(max_denominator)))
        out.append(snapped)
        change = max(change, abs((snapped - a + 180.0) % 360.0 - 180.0))
    return np.array(out), change


def _azimuth_list(azimuths):
    scalar = np.ndim(azimuths) == 0
    az = np.atleast_1d(np.asarray(azimuths, dtype=object if scalar else None))
    if az.ndim != 1 or len(az) == 0:
        raise ValueError(f"azimuths: expected a number or a non-empty 1D sequence, got shape {az.shape}")
    return [finite_degrees(a, f"azimuths[{k}]") for k, a in enumerate(az)]


def finite_degrees(value, name: str) -> float:
    """``value`` as a float number of degrees; a bool, a non-number or a non-finite value
    raises, naming ``name`` (an argument, or an entry such as ``azimuths[2]``)."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name}: expected a number of degrees, got {value!r}")
    try:
        degrees = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected a number of degrees, got {value!r}") from None
    if not math.isfinite(degrees):
        raise ValueError(f"{name}: expected a finite number of degrees, got {degrees!r}")
    return degrees


def _rational_map_azimuths(heights, spacing, n):
    """:func:`rational_azimuths` taken in cell space: on square pixels they are the map
    azimuths; on rectangular ones, each equally spaced map azimuth goes to cell space, to
    the nearest rational cell direction (q <= 5) and back."""
    field = heights if isinstance(heights, HeightField) else None
    if field is None and is_dataarray(heights):
        field = HeightField.from_dataarray(heights)
    dx, dy = (field.dx, field.dy) if field is not None else (
        check_spacing(spacing) if spacing is not None else (1.0, 1.0))
    if dx == dy:
        return rational_azimuths(n)
    grid = Grid(np.zeros((2, 2)), dx, dy, dx, True, None, None)
    candidates = rational_azimuths(8 * 5 * 6 * 4, 5)  # every slope p/q, q <= 5, in all octants
    candidates = np.unique(np.round(candidates, 12))
    out = []
    for k in range(n):
        cell = grid.cell_azimuth(360.0 * k / n)
        gap = np.abs((candidates - cell + 180.0) % 360.0 - 180.0)
        out.append(grid.map_azimuth(float(candidates[int(np.argmin(gap))])))
    return np.array(out)


def _product_azimuths(heights, n_azimuths, azimuths, rational, spacing, snap_denominator):
    """The azimuths of a product over many of them (:func:`sky_view_factor`,
    :func:`openness`), with the record of their snapping.

    The explicit ``azimuths`` (degrees) when given, else ``n_azimuths`` equally spaced
    from north (with ``rational``, taken to the nearest rational cell directions,
    :func:`_rational_map_azimuths`); then, with ``snap_denominator``, all snapped to cell
    directions of q <= snap_denominator on the field's pixels (:func:`snap_azimuths`).

    Returns
    -------
    (azimuths, snap)
        The azimuths (degrees; a float64 array, or ``azimuths`` as given), and None or
        :func:`snap_azimuths`' (snapped azimuths, largest change) for the statistics and
        the DataArray attrs.

    Raises
    ------
    ValueError, TypeError
        Naming ``n_azimuths``, ``snap_denominator``, ``azimuths[k]`` or ``spacing``; or
        ``azimuths`` given with ``n_azimuths`` or ``rational``, which apply to the equally
        spaced azimuths only (they would be ignored).
    """
    if azimuths is not None:
        if n_azimuths is not None:
            raise ValueError(f"azimuths: give n_azimuths or azimuths, not both (got n_azimuths="
                             f"{n_azimuths!r} with explicit azimuths)")
        if rational:
            raise ValueError("rational: applies to the n_azimuths equally spaced azimuths only "
                             "(got rational=True with explicit azimuths); snap_denominator=5 "
                             "snaps explicit ones")
    if azimuths is None:
        if n_azimuths is None:
            n_azimuths = 16
        if isinstance(n_azimuths, bool) or not isinstance(n_azimuths, (int, np.integer)) or n_azimuths < 1:
            raise ValueError(f"n_azimuths: expected a positive int, got {n_azimuths!r}")
        azimuths = np.arange(n_azimuths) * (360.0 / n_azimuths)
        if rational:
            azimuths = _rational_map_azimuths(heights, spacing, n_azimuths)
    snap = None
    if snap_denominator is not None:
        snap = snap_azimuths(azimuths, snap_denominator, _field_spacing(heights, spacing),
                             name="snap_denominator")
        azimuths = snap[0]
    return azimuths, snap
