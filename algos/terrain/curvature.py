"""The earth's curvature and refraction: the drop of a surface point with its map
distance (package docstring, "Curvature"), and which algorithms apply it."""
from __future__ import annotations

import math

import numpy as np

from .grid import Grid

__all__ = ["DEFAULT_REFRACTION", "CURVATURE_REFUSED"]

#: The default refraction coefficient of curvature, as in GDAL and GRASS (1/7).
DEFAULT_REFRACTION = 1.0 / 7.0

#: Algorithms that refuse curvature, and why.
CURVATURE_REFUSED = {
    "sweep": "the upper hull of the breakpoints misses the peaks inside pieces",
    "rows": "the row-vectorised pattern evaluates breakpoints only",
    "chain": "its borrowed lower bounds and tile skips assume no drop",
    "embree": "the peer traces straight rays over the unlowered mesh",
}


#: Why curvature refuses a grid without a real unit, and how to give one.
_NO_UNIT_CURVATURE = (
    "curvature: needs spacing in a real unit, to convert the earth's radius: give a raw "
    "array's spacing (taken in metres), a field with a CRS, or HeightField(..., spacing=D, "
    "unit='m') (units: 'm', 'km', 'ft', 'US survey foot'; on the command line --unit next to "
    "--spacing); a field in cell units or in an unnamed 'map unit' has none")


def _check_refraction(curvature, refraction) -> float:
    """``refraction`` as a float in [0, 1), refused when it is not, or when it differs
    from :data:`DEFAULT_REFRACTION` without ``curvature`` (it would be ignored: the
    command line's ``--refraction`` without ``--curvature`` is refused the same way)."""
    try:
        r = float(refraction)
    except (TypeError, ValueError):
        raise TypeError(f"refraction: expected a number, got {refraction!r}") from None
    if not (math.isfinite(r) and 0 <= r < 1):
        raise ValueError(f"refraction: expected a coefficient in [0, 1), got {refraction!r}")
    if not curvature and r != DEFAULT_REFRACTION:
        raise ValueError(f"refraction: applies with curvature=True only (got refraction={r:g} "
                         "without it)")
    return r


def _curvature_kappa(grid: Grid, curvature, refraction, earth_radius) -> float:
    """kappa, the drop per squared cell distance in cell height units:
    (1 - refraction) dx / (2 R), R in the field's unit; 0 without curvature. Validated as
    :func:`viewshed` does (square pixels, a real unit; ``refraction`` by
    :func:`_check_refraction`)."""
    if not isinstance(curvature, (bool, np.bool_)):
        raise TypeError(f"curvature: expected a bool, got {curvature!r}")
    r = _check_refraction(curvature, refraction)
    if not curvature:
        return 0.0
    if not grid.has_unit:
        raise ValueError(_NO_UNIT_CURVATURE)
    if not grid.square:
        raise ValueError(f"curvature: needs square pixels, got {grid.dx:g} x {grid.dy:g}; "
                         "resample first (e.g. gdalwarp -tr D D)")
    try:
        radius = float(earth_radius)
    except (TypeError, ValueError):
        raise TypeError(f"earth_radius: expected a number of metres, got {earth_radius!r}") from None
    if not (math.isfinite(radius) and radius > 0):
        raise ValueError(f"earth_radius: expected a positive length, got {earth_radius!r}")
    radius /= grid.unit_metres
    return (1.0 - r) * grid.dx / (2.0 * radius)


def _curvature_attrs(curvature, refraction):
    """The curvature parameters as file/DataArray attributes."""
    out = dict(curvature=int(bool(curvature)))
    if curvature:
        out["refraction"] = float(refraction)
    return out
