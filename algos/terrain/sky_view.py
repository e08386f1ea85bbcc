"""The sky-view factor (:func:`sky_view_factor`)."""
from __future__ import annotations

import numpy as np

from ..field import is_dask, is_dataarray
from ..georef import WGS84_SEMI_MAJOR_AXIS_M
from .azimuths import _product_azimuths
from .curvature import DEFAULT_REFRACTION
from .dataarray import _azimuth_product_dataarray
from .horizon import horizon
from .stats import check_return_stats, returned
from .tiled import tiled_product

__all__ = ["sky_view_factor"]


def sky_view_factor(heights, n_azimuths=None, max_distance=None, *, rational=False,
                    azimuths=None, algorithm=None, surface="triangles", spacing=None,
                    curvature=False, refraction=DEFAULT_REFRACTION,
                    earth_radius=WGS84_SEMI_MAJOR_AXIS_M, threads=None, progress=None,
                    snap_denominator=None, return_stats=False):
    """Sky-view factor (Zaksek et al. 2011, as in RVT): 1 - mean_k sin(max(horizon_k, 0)).

    Parameters
    ----------
    heights, max_distance, algorithm, surface, spacing, threads
        As in :func:`horizon` (``max_distance`` a length in the field's unit).
    n_azimuths : int, optional
        Equally spaced azimuths starting at north; default 16 (None), RVT's.
    rational : bool
        Move each equally spaced azimuth to the nearest direction whose slope *in cell
        space* is p/q with q <= 5 (:func:`rational_azimuths`), where the exact sweep
        applies. On rectangular pixels the map azimuths are then those directions' images.
    azimuths : sequence of float, optional
        Explicit azimuths (degrees), instead of ``n_azimuths``; giving both, or
        ``rational=True`` with them, raises ValueError (``snap_denominator`` snaps explicit
        azimuths).
    curvature, refraction, earth_radius
        As in :func:`horizon`. Default False, as RVT's sky-view factor (Zaksek et al.
        2011), which has no curvature; with unlimited distance the exact sweep does not
        apply and a per-vertex walk runs (:func:`horizon`).
    progress : callable, optional
        Called as ``progress(done, total)`` after each azimuth (in memory only).
    snap_denominator : int, optional
        As in :func:`horizon`: every azimuth snapped to a rational cell direction with
        q <= snap_denominator, recorded (statistics, DataArray attrs). Default None:
        no snapping (``rational=True`` is the older spelling of snap_denominator=5 for
        the equally spaced azimuths).
    return_stats : bool
        As in :func:`horizon`: also return the call's
        :class:`~algos.terrain.stats.TerrainStats`, as ``(result, stats)``.

    Returns
    -------
    float64 array (rows, cols)
        Dimensionless, in [0, 1]; NaN at void vertices; the input's orientation. A
        DataArray gives a DataArray (input's coords, CRS and attrs, and the algorithm of
        each azimuth: attrs ``algorithm`` and ``paths``). With ``return_stats``, the pair
        ``(that, TerrainStats)``.
    """
    check_return_stats(return_stats, heights)
    curve = dict(curvature=curvature, refraction=refraction, earth_radius=earth_radius)
    azimuths, snap = _product_azimuths(heights, n_azimuths, azimuths, rational, spacing,
                                       snap_denominator)
    if is_dataarray(heights):
        return _azimuth_product_dataarray(
            sky_view_factor, "sky_view_factor", heights, azimuths, max_distance, snap,
            return_stats, dict(units="1"), algorithm=algorithm, surface=surface,
            threads=threads, **curve)
    if is_dask(heights):
        return tiled_product(lambda b, **kw: sky_view_factor(b, azimuths=azimuths, **kw),
                             heights, max_distance, spacing, np.float64, algorithm=algorithm,
                             surface=surface, threads=threads, **curve)
    tangents, stats = horizon(heights, azimuths, max_distance, algorithm=algorithm,
                              surface=surface, spacing=spacing, threads=threads,
                              progress=progress, return_stats=True, _tangents=True, **curve)
    # one azimuth at a time, so each pass stays in the cache (the layers summed in order,
    # as np.mean over the first axis does)
    total = _sin_of_positive_atan(tangents[0])
    for k in range(1, len(tangents)):
        total += _sin_of_positive_atan(tangents[k])
    total /= len(tangents)
    return returned(1.0 - total, stats.with_snap(snap), return_stats)


def _sin_of_positive_atan(x):
    """sin(max(atan(x), 0)) = max(x, 0) / sqrt(1 + max(x, 0)^2), in place, NaN kept: no
    transcendental function (the sky-view factor's inner step; equal to the angle form
    to rounding). Tangents beyond 1e150 give 1 (their square would overflow)."""
    np.maximum(x, 0.0, out=x)
    np.minimum(x, 1e150, out=x)
    root = np.multiply(x, x)
    root += 1.0
    np.sqrt(root, out=root)
    np.divide(x, root, out=x)
    return x
