"""Topographic openness, positive and negative (:func:`openness`)."""
from __future__ import annotations

import math

import numpy as np

from ..field import is_dask, is_dataarray
from ..georef import WGS84_SEMI_MAJOR_AXIS_M
from .azimuths import _product_azimuths
from .curvature import DEFAULT_REFRACTION, _curvature_kappa
from .dataarray import _azimuth_product_dataarray
from .grid import VOID_HEIGHT, Grid, _check_surface, _prepare
from .horizon import _check_units, _horizon_angles
from .stats import check_return_stats, returned
from .tiled import tiled_product

__all__ = ["openness", "OPENNESS_KINDS"]


OPENNESS_KINDS = ("positive", "negative")


def openness(heights, kind="positive", n_azimuths=None, max_distance=None, *, azimuths=None,
             rational=False, units="degrees", algorithm=None, surface="triangles",
             spacing=None, curvature=False, refraction=DEFAULT_REFRACTION,
             earth_radius=WGS84_SEMI_MAJOR_AXIS_M, threads=None, progress=None,
             snap_denominator=None, return_stats=False):
    """Topographic openness (Yokoyama, Shirasawa & Pike 2002), positive or negative.

    Positive openness is the mean over the azimuths of 90 deg minus the horizon angle
    (:func:`horizon`, the largest elevation angle within ``max_distance``): how far the
    sky opens above a vertex. Negative openness is the mean of 90 deg plus the smallest
    elevation angle within ``max_distance``, which is the positive openness of the
    mirrored terrain -H: how far the ground opens below. Both come from the exact
    horizons, so they are exact to rounding. A flat plane gives 90 deg for both; ridges
    raise positive openness above 90, valleys lower it.

    An azimuth along which a vertex has no surface point (a vertex on the edge of the
    footprint looking out, or a ray that meets only voids) has no elevation angle and is
    left out of that vertex's mean; a vertex with none left is NaN. RVT instead pads the
    DEM by reflection, which makes its edge values differ.

    Parameters
    ----------
    heights, max_distance, algorithm, surface, spacing, threads, progress
        As in :func:`sky_view_factor`. Yokoyama et al. name the radius L; RVT's default is
        10 pixels (``svf_r_max``), here None means unlimited.
    kind : {"positive", "negative"}
    n_azimuths : int, optional
        Equally spaced azimuths from north; default 16 (None), RVT's (Yokoyama et al.
        used 8).
    azimuths, rational
        As in :func:`sky_view_factor`.
    units : {"degrees", "radians"}
        Default degrees, the unit of Yokoyama et al. and RVT (``horizon`` defaults to
        radians).
    curvature, refraction, earth_radius
        As in :func:`horizon` (default False, as RVT). For negative openness the mirrored
        terrain is raised, not lowered, by the drop, so that both read the same lowered
        surface.
    snap_denominator : int, optional
        As in :func:`horizon`: every azimuth snapped to a rational cell direction with
        q <= snap_denominator, recorded (statistics, DataArray attrs). Default None.
    return_stats : bool
        As in :func:`horizon`: also return the call's
        :class:`~algos.terrain.stats.TerrainStats`, as ``(result, stats)``.

    Returns
    -------
    float64 array (rows, cols)
        In [0, 180] degrees ([0, pi] radians); NaN at void vertices; the input's
        orientation. A DataArray gives a DataArray with ``units``, ``kind`` and the
        parameters as attrs. With ``return_stats``, the pair ``(that, TerrainStats)``.

    Raises
    ------
    ValueError, TypeError
        Naming the argument: ``kind``, ``units``, and everything :func:`horizon` checks.
    """
    if kind not in OPENNESS_KINDS:
        raise ValueError(f"kind: expected one of {OPENNESS_KINDS}, got {kind!r}")
    _check_units(units)
    check_return_stats(return_stats, heights)
    curve = dict(curvature=curvature, refraction=refraction, earth_radius=earth_radius)
    azimuths, snap = _product_azimuths(heights, n_azimuths, azimuths, rational, spacing,
                                       snap_denominator)
    options = dict(kind=kind, units=units, algorithm=algorithm, surface=surface,
                   threads=threads, **curve)
    if is_dataarray(heights):
        return _azimuth_product_dataarray(openness, "openness", heights, azimuths,
                                          max_distance, snap, return_stats,
                                          dict(units=units, kind=kind), **options)
    if is_dask(heights):
        return tiled_product(lambda b, **kw: openness(b, azimuths=azimuths, **kw), heights,
                             max_distance, spacing, np.float64, **options)
    _check_surface(surface)
    grid = _prepare(heights, spacing)
    kappa = _curvature_kappa(grid, curvature, refraction, earth_radius)
    if kind == "negative":
        # the mirrored terrain: -H, voids kept as pits; its drop mirrored too (raised)
        mirrored = -grid.h if grid.void is None else np.where(grid.void, VOID_HEIGHT, -grid.h)
        grid = Grid(np.ascontiguousarray(mirrored), grid.dx, grid.dy, grid.z_scale,
                    grid.has_unit, grid.void, grid.field, grid.unit_metres)
        kappa = -kappa
    angles, stats = _horizon_angles(grid, azimuths, max_distance, kappa, algorithm=algorithm,
                                    threads=threads, march_step=1.0, embree_tolerance=1e-4,
                                    progress=progress)
    seen = angles > -math.pi / 2  # an azimuth with a surface point
    count = seen.sum(axis=0)
    mean = np.where(seen, angles, 0.0).sum(axis=0) / np.maximum(count, 1)
    # 90 minus the mean angle (not the mean of 90 minus each): a flat plane gives 90 exactly
    out = 90.0 - np.degrees(mean) if units == "degrees" else math.pi / 2 - mean
    out[count == 0] = np.nan
    grid.voids_to(out, np.nan)
    return returned(np.ascontiguousarray(grid.to_north_up(out)), stats.with_snap(snap),
                    return_stats)
