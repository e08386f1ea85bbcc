"""The cone structures: ``cone``, cone step mapping (Dummer 2006) made exact, and
``cone_relaxed``, relaxed cone stepping (Policarpo & Oliveira 2007), approximate by design
(``cext/hierarchies/cone.c`` builds the relaxed one and walks the exact one; ``cext/dispatch/intersect.c`` marches
the relaxed one).

The exact cone.

For every cell ``c`` two float32 numbers, stored side by side (shape ``(ny, nx, 2)``, 8
bytes per cell, so one cache line serves both):

* ``top`` (``cone[..., 0]``, ``T_c``): the highest cell maximum (``Field.cellmax_for``)
  among ``c`` and its 8 neighbours;
* ``slope`` (``cone[..., 1]``, ``k_c >= 0``): a cone slope such that every surface point
  ``q`` of the field satisfies ``s(q) <= T_c + k_c * d(q, c)``, with ``d`` the Chebyshev
  distance from ``q`` to the closed square of ``c``.

Why it holds: a point of a cell at Chebyshev ring ``n >= 2`` around ``c`` lies at least
``n - 1`` from ``c`` and at most as high as the maximum ``B_n(c)`` of the cell maxima
within ring ``n``; cells of rings 0 and 1 are covered by ``T_c``. So

    k_c = max(0, max_{n = 2..R} (B_n(c) - T_c) / (n - 1), (max cellmax - T_c) / R)

works, the last term covering every ring beyond ``R`` (``CONE_RADIUS``). ``B_n`` is
``T`` dilated ``n - 1`` times by the 3 x 3 maximum, so the build costs ``R`` passes over
the field. The slope is computed in float64 and rounded *up* to float32 (after a relative
widening of 2^-30), so the stored cone never cuts into the surface; the kernel's step
keeps a further margin for its own rounding. The cone is the widest of this form, not the
per-texel widest cone of Dummer's precomputation (which is quadratic in the field size):
it is built from cell maxima, so one structure serves all four surfaces (the ``plane3``
one from its own bounds).
"""
from __future__ import annotations

import numpy as np

from .. import _kernels

__all__ = ["CONE_RADIUS", "RELAXED_RADIUS", "cone_for", "build_cone", "relaxed_cone_for",
           "build_relaxed_cone"]

#: rings searched exactly; beyond them the field's highest cell bounds the cone
CONE_RADIUS = 32


def _dilate(a: np.ndarray) -> np.ndarray:
    """The maximum over each cell's 3 x 3 neighbourhood (cells outside the grid ignored)."""
    rows = a.copy()
    np.maximum(rows[:, 1:], a[:, :-1], out=rows[:, 1:])
    np.maximum(rows[:, :-1], a[:, 1:], out=rows[:, :-1])
    out = rows.copy()
    np.maximum(out[1:], rows[:-1], out=out[1:])
    np.maximum(out[:-1], rows[1:], out=out[:-1])
    return out


def build_cone(cellmax: np.ndarray, radius: int = CONE_RADIUS) -> np.ndarray:
    """The cone structure of a cell-maximum array.

    Parameters
    ----------
    cellmax : ndarray, shape (ny, nx), float32
        An upper bound of each cell's surface (``algos.Field.cellmax_for``).
    radius : int
        Rings searched exactly, >= 2.

    Returns
    -------
    ndarray, shape (ny, nx, 2), float32
        ``[..., 0]``: ``T_c``, ``[..., 1]``: ``k_c`` of the module docstring (>= 0; a
        slope past float32's range is +inf, which the kernel never steps by).

    Raises
    ------
    ValueError
        If ``cellmax`` is not a 2D array or ``radius`` < 2.
    """
    m = np.asarray(cellmax, dtype=np.float32)
    if m.ndim != 2 or m.size == 0:
        raise ValueError(f"cellmax: expected a non-empty 2D array, got shape {m.shape}")
    if isinstance(radius, bool) or not isinstance(radius, (int, np.integer)) or radius < 2:
        raise ValueError(f"radius: expected an integer >= 2, got {radius!r}")
    top = _dilate(m)
    top64 = top.astype(np.float64)
    slope = np.zeros(m.shape, dtype=np.float64)
    ring_max = top
    for n in range(2, int(radius) + 1):
        ring_max = _dilate(ring_max)  # max over the cells within ring n
        np.maximum(slope, (ring_max - top64) / (n - 1), out=slope)
    np.maximum(slope, (float(m.max()) - top64) / radius, out=slope)
    # round up: a relative widening, then the next float32 above where rounding went down
    slope *= 1.0 + 2.0 ** -30
    slope32 = slope.astype(np.float32)
    low = slope32.astype(np.float64) < slope
    slope32[low] = np.nextafter(slope32[low], np.float32(np.inf))
    return np.ascontiguousarray(np.stack([top, slope32], axis=-1))


def cone_for(field, kind: str = "corners"):
    """The cone structure of ``field`` for a bound kind (``algos.field.bound_kind``),
    built on first use and kept in the field (``build_stats["cone"]`` or
    ``["cone/plane3"]`` record its seconds and bytes)."""
    key = "cone" if kind == "corners" else f"cone/{kind}"
    return field._build(key, lambda: build_cone(field.cellmax_for(kind)))


#: rings of destinations each relaxed cone is built from
RELAXED_RADIUS = 4


def build_relaxed_cone(cellmax: np.ndarray, radius: int = RELAXED_RADIUS) -> np.ndarray:
    """Relaxed cone slopes (Policarpo & Oliveira 2007) over the cell maxima.

    The relaxed cone of cell ``s`` has its apex at the centre of ``s`` at height
    ``cellmax[s]``; its slope (height per unit of horizontal Euclidean distance) is the
    smallest that keeps out every point where a ray from the field's top above ``s``,
    through the top of a cell within ``radius`` rings, comes back out of the solid
    (followed in half-cell steps; ``cext/hierarchies/cone.c``). So a ray inside the cone crosses the
    surface at most once, up to that sampling and the window: the cone is a heuristic
    bound, and the kernel that steps by it is approximate.

    Parameters
    ----------
    cellmax : ndarray, shape (ny, nx), float32
    radius : int
        1 to 64; the build costs about ``(2 radius + 1)^2 * 4 radius`` steps per cell.

    Returns
    -------
    ndarray, shape (ny, nx), float32, >= 0

    Raises
    ------
    ValueError
        If ``cellmax`` is not 2D or ``radius`` is out of range.
    """
    m = np.ascontiguousarray(cellmax, dtype=np.float32)
    if m.ndim != 2 or m.size == 0:
        raise ValueError(f"cellmax: expected a non-empty 2D array, got shape {m.shape}")
    if isinstance(radius, bool) or not isinstance(radius, (int, np.integer)) or \
            not 1 <= radius <= 64:
        raise ValueError(f"radius: expected an integer in [1, 64], got {radius!r}")
    slope = np.zeros(m.shape, dtype=np.float32)
    _kernels.cone_relaxed_slopes(m, int(radius), slope)
    return slope


def relaxed_cone_for(field, kind: str = "corners") -> np.ndarray:
    """The relaxed cone slopes of ``field`` for a bound kind, built on first use and kept
    (``build_stats["cone_relaxed"]``)."""
    key = "cone_relaxed" if kind == "corners" else f"cone_relaxed/{kind}"
    return field._build(key, lambda: build_relaxed_cone(field.cellmax_for(kind)))
