"""Cast shadows under a sun (:func:`shadows`)."""
from __future__ import annotations

import math

import numpy as np

from ..field import is_dask, is_dataarray
from ..georef import WGS84_SEMI_MAJOR_AXIS_M
from .azimuths import finite_degrees, snap_azimuths
from .curvature import DEFAULT_REFRACTION, _curvature_attrs
from .dataarray import _attr, _to_dataarray, _with_path_attrs
from .grid import _field_spacing
from .horizon import horizon
from .stats import check_return_stats, returned, with_stats
from .tiled import tiled_product

__all__ = ["shadows"]


def shadows(heights, azimuth, elevation, *, max_distance=None, algorithm=None,
            surface="triangles", spacing=None, curvature=False, refraction=DEFAULT_REFRACTION,
            earth_radius=WGS84_SEMI_MAJOR_AXIS_M, threads=None, snap_denominator=None,
            return_stats=False):
    """Cast shadows under a sun at ``azimuth`` and ``elevation`` (degrees).

    A vertex is in shadow when its horizon along the sun's azimuth (:func:`horizon`) is
    strictly above the sun's elevation; a tie is lit.

    Parameters
    ----------
    heights, max_distance, algorithm, surface, spacing, threads
        As in :func:`horizon` (``max_distance`` a length in the field's unit).
    curvature, refraction, earth_radius
        As in :func:`horizon`: the surface lowered for the earth's curvature. Default
        False, as the horizon; it matters for long shadows at a low sun, over tens of
        kilometres.
    azimuth : float
        Degrees clockwise from north.
    elevation : float
        Degrees above the horizontal, in [-90, 90].
    snap_denominator : int, optional
        As in :func:`horizon`: the sun's azimuth snapped to a rational cell direction,
        recorded (statistics, DataArray attrs). Default None: no snapping.
    return_stats : bool
        As in :func:`horizon`: also return the call's
        :class:`~algos.terrain.stats.TerrainStats`, as ``(result, stats)``.

    Returns
    -------
    bool array (rows, cols)
        True in shadow, in the input's orientation. A void vertex is False (its own
        value is unknown: the field's ``nodata_mask`` marks it; writers store it as
        nodata). A DataArray gives a DataArray (input's coords, CRS and attrs).
        With ``return_stats``, the pair ``(that, TerrainStats)``.
    """
    try:
        el = float(elevation)
    except (TypeError, ValueError):
        raise TypeError(f"elevation: expected a number of degrees, got {elevation!r}") from None
    if not -90.0 <= el <= 90.0:
        raise ValueError(f"elevation: expected degrees in [-90, 90], got {elevation!r}")
    if np.ndim(azimuth) != 0:
        raise ValueError("azimuth: expected one number (the sun's azimuth)")
    # checked here so that the error names this argument, not horizon's azimuths[0]
    finite_degrees(azimuth, "azimuth")
    check_return_stats(return_stats, heights)
    curve = dict(curvature=curvature, refraction=refraction, earth_radius=earth_radius)
    snap, used = None, azimuth
    if snap_denominator is not None:
        snap = snap_azimuths(azimuth, snap_denominator, _field_spacing(heights, spacing),
                             name="snap_denominator")
        used = float(snap[0][0])
    if is_dataarray(heights):
        out, stats = _to_dataarray(heights, lambda f: with_stats(
            shadows, f, used, el, max_distance=max_distance, algorithm=algorithm, surface=surface,
            threads=threads, **curve), "shadows",
            dict(units="1 in shadow, 0 lit", azimuth=float(azimuth), elevation=el,
                 max_distance=_attr(max_distance), **_curvature_attrs(curvature, refraction)))
        return returned(*_with_path_attrs(out, stats, snap), return_stats)
    if is_dask(heights):
        return tiled_product(lambda b, **kw: shadows(b, used, el, **kw), heights,
                             max_distance, spacing, bool, algorithm=algorithm,
                             surface=surface, threads=threads, **curve)
    angles, stats = horizon(heights, used, max_distance, algorithm=algorithm, surface=surface,
                            spacing=spacing, threads=threads, return_stats=True, **curve)
    with np.errstate(invalid="ignore"):
        shadowed = angles[0] > math.radians(el)  # NaN (a void) compares False
    return returned(shadowed, stats.with_snap(snap), return_stats)
