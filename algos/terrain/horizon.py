"""Horizon elevation angles from every vertex (:func:`horizon`)."""
from __future__ import annotations

import math

import numpy as np

from ..accel.mipmap import terrain_mipmap
from ..field import is_dask, is_dataarray
from ..georef import WGS84_SEMI_MAJOR_AXIS_M
from ..parallel import resolve_threads
from ..validate import check_length
from .algorithms import _auto_path, _pick_horizon_algorithm
from .azimuths import _azimuth_list, snap_azimuths
from .curvature import DEFAULT_REFRACTION, _curvature_attrs, _curvature_kappa
from .dataarray import _attr, _to_dataarray, _with_path_attrs
from .directions import azimuth_direction
from .grid import Grid, _check_surface, _field_spacing, _prepare
from .stats import TerrainStats, check_return_stats, returned, with_stats
from .tiled import tiled_product
from .walks import _horizon_one

__all__ = ["horizon", "ANGLE_UNITS"]

#: The units a horizon angle can be given in (the DataArray attribute ``units``).
ANGLE_UNITS = ("radians", "degrees")


def _check_units(units):
    if units not in ANGLE_UNITS:
        raise ValueError(f"units: expected one of {ANGLE_UNITS}, got {units!r}")
    return units


def _horizon_angles(grid: Grid, azimuths, max_distance, kappa, *, algorithm, threads,
                    march_step, embree_tolerance, progress, tangents=False):
    """The horizon angles (radians, north-up, (len(azimuths), rows, cols)) of a prepared
    grid with curvature kappa (cell units; negative raises the surface, for
    :func:`openness`), voids not yet set, and the call's :class:`TerrainStats`.
    ``tangents``: the map tangents, not their angles."""
    h = grid.h
    directions = []
    for k, a in enumerate(_azimuth_list(azimuths)):
        directions.append(azimuth_direction(grid.cell_azimuth(a)))
    md = check_length(max_distance, "max_distance")
    # per direction: the distance limit in cells and the factor from cell-space tangents
    # (cell heights over cell distance) to map tangents (package docstring, "Units")
    limits, factors = [], []
    for d in directions:
        stretch = grid.stretch(d)
        limits.append(None if md is None else md / stretch)
        factors.append(1.0 if grid.square else grid.z_scale / stretch)
    step = float(march_step)
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"march_step: expected a positive number of cells, got {march_step!r}")
    curved = kappa != 0.0
    name = _pick_horizon_algorithm(algorithm, directions,
                                   None if md is None else max(limits), curvature=curved)
    if algorithm is None or algorithm == "auto":  # chosen per direction
        paths = [_auto_path(d, limits[k], curved) for k, d in enumerate(directions)]
    else:
        paths = [name] * len(directions)
    nthreads = resolve_threads(threads)
    stats = TerrainStats("+".join(dict.fromkeys(paths)), paths=tuple(paths))
    mip = terrain_mipmap(h) if "dda_maxmip" in paths else None
    out = np.empty((len(directions),) + h.shape)
    for k, d in enumerate(directions):
        out[k] = _horizon_one(h, d, paths[k], limits[k], nthreads, mip, stats, step,
                              embree_tolerance, kappa)
        if factors[k] != 1.0:
            out[k] *= factors[k]
        if progress is not None:
            progress(k + 1, len(directions))
    if not tangents:
        np.arctan(out, out=out)
    return out, stats


def horizon(heights, azimuths, max_distance=None, *, algorithm=None, surface="triangles",
            spacing=None, units="radians", curvature=False, refraction=DEFAULT_REFRACTION,
            earth_radius=WGS84_SEMI_MAJOR_AXIS_M, threads=None, march_step=1.0,
            embree_tolerance=1e-4, progress=None, snap_denominator=None, return_stats=False,
            _tangents=False):
    """Horizon elevation angles (radians by default) seen from every vertex.

    For each azimuth, the horizon of vertex v is the supremum, over the surface points p on
    the horizontal ray from v with 0 < dist(p, v) <= max_distance inside the footprint
    [0, cols-1] x [0, rows-1], of atan2(s(p) - H(v), dist), with heights and distances in
    the same linear unit; -pi/2 where there is none. On the two triangles the supremum is
    attained at a breakpoint of the ray (an edge or diagonal crossing, or the far end), or
    is the slope limit at dist -> 0+, which equals the ratio at the first breakpoint
    (package docstring). It is computed exactly, up to float64 rounding, by every exact
    algorithm, on square and rectangular pixels alike (package docstring, "Units").

    With ``curvature``, each surface point at map distance D is first lowered by
    (1 - refraction) D^2 / (2 R), as in :func:`viewshed`; the supremum then also looks
    inside the linear pieces (package docstring, "Curvature"), and stays exact.

    Parameters
    ----------
    heights : (rows, cols) array, HeightField or xarray.DataArray
        A raw array is north-up (row 0 north) and in the unit of ``spacing``; NaN marks a
        void. A HeightField or DataArray carries its own spacing, CRS, orientation and
        voids.
    azimuths : float or sequence of floats
        Degrees clockwise from north (north is row 0 of a north-up array).
    max_distance : float, optional
        A length in the field's unit (cells when there is no spacing). None: unlimited.
    algorithm : str, optional
        A key of :data:`HORIZON_ALGORITHMS`, or None/"auto", chosen per azimuth (by
        measurement): "sweep" for a direction rational in cell space at unlimited
        distance, "rows" for max_distance <= 384 cells, "chain" otherwise; with curvature,
        "pattern" up to 384 cells and "dda_maxmip" beyond. The path of each azimuth is
        recorded in the statistics (``return_stats``: ``algorithm``, ``paths``) and in a
        DataArray's attrs ``algorithm`` and ``paths``. With curvature, the algorithms of
        :data:`CURVATURE_REFUSED` raise.
    spacing : float or (dx, dy), optional
        The pixel size of a raw array, in the unit of its heights; None means cell units.
        A HeightField carries its own (giving a different one raises).
    units : {"radians", "degrees"}
        The unit of the angles returned (and of a DataArray's ``units`` attribute).
    curvature : bool
        Lower the surface for the earth's curvature and refraction. Default False: the
        horizon-based products of RVT (sky-view factor, openness) have no curvature, and
        over the radii they are used at it is negligible (the drop is 0.07 m at 1 km,
        6.7 m at 10 km); GRASS r.horizon applies it by default, so pass True to compare
        with it. Needs a real unit (a raw array's spacing, in metres, or a field
        whose ``unit_metres`` is known) and square pixels.
    refraction : float
        The refraction coefficient in [0, 1); default 1/7, GDAL's and GRASS's
        (:data:`DEFAULT_REFRACTION`). Another value without ``curvature=True`` raises
        ValueError (it would be ignored).
    earth_radius : float
        R in metres (default the WGS 84 semi-major axis, as GDAL), converted to the
        field's unit with its ``unit_metres`` (1 for a raw array).
    threads : None or int
        Vertices are split over threads; results are identical for every value.
    march_step, embree_tolerance : the baselines' step (cells) and angle tolerance (rad).
    progress : callable, optional
        Called as ``progress(done, total)`` after each azimuth (in memory only; a
        command's progress bar).
    snap_denominator : int, optional
        Snap each azimuth to the nearest direction whose slope in cell space is p/q with
        q <= snap_denominator (:func:`snap_azimuths`), so that the rational sweep applies.
        Default None: no snapping, the horizons are exact at the azimuths given. The
        azimuths used and the largest change are recorded (the statistics'
        ``snapped_azimuths``, ``snap_max_change_deg``, and DataArray attrs of those names).
    return_stats : bool
        Also return the call's :class:`~algos.terrain.stats.TerrainStats` (the paths that
        ran, C time, cells, tile skips, snapping): ``(result, stats)``. Default False.
        Refused (ValueError) for a lazy (dask) input, whose statistics are per tile.

    Returns
    -------
    float64 array (len(azimuths), rows, cols)
        Angles in [-pi/2, pi/2] radians (or [-90, 90] degrees), in the input's
        orientation; -pi/2 (-90) where the ray has no point; NaN at void vertices. A
        DataArray gives a DataArray with an ``azimuth`` dimension, the input's coords, CRS
        and attrs, ``units`` (the unit), ``curvature`` (0 or 1) and ``refraction``.
        With ``return_stats``, the pair ``(that, TerrainStats)``.

    Raises
    ------
    ValueError, TypeError
        Naming the argument: bad heights (a non-finite value other than a NaN void, too
        large, too small), azimuths, lengths, algorithm, surface, units, curvature,
        refraction, earth_radius or threads.

    A dask array (or a HeightField or DataArray holding one) gives a lazy dask array,
    computed tile by tile with a halo of ``max_distance`` (which must be finite):
    :mod:`algos.terrain.tiled`.
    """
    _check_units(units)
    check_return_stats(return_stats, heights)
    curve = dict(curvature=curvature, refraction=refraction, earth_radius=earth_radius)
    snap = None
    if snap_denominator is not None:
        snap = snap_azimuths(azimuths, snap_denominator, _field_spacing(heights, spacing),
                             name="snap_denominator")
    if is_dataarray(heights):
        az = _azimuth_list(azimuths)
        out, stats = _to_dataarray(heights, lambda f: with_stats(
            horizon, f, az if snap is None else snap[0], max_distance, algorithm=algorithm,
            surface=surface, threads=threads, march_step=march_step,
            embree_tolerance=embree_tolerance, units=units, **curve),
            "horizon", dict(units=units, max_distance=_attr(max_distance),
                            **_curvature_attrs(curvature, refraction)), ("azimuth", az))
        return returned(*_with_path_attrs(out, stats, snap), return_stats)
    if snap is not None:
        out, stats = with_stats(horizon, heights, snap[0], max_distance, algorithm=algorithm,
                                surface=surface, spacing=spacing, units=units, threads=threads,
                                march_step=march_step, embree_tolerance=embree_tolerance,
                                progress=progress, _tangents=_tangents, **curve)
        return out if stats is None else returned(out, stats.with_snap(snap), return_stats)
    if is_dask(heights):
        return _tiled_horizon(heights, azimuths, max_distance, spacing, dict(
            algorithm=algorithm, surface=surface, threads=threads, march_step=march_step,
            embree_tolerance=embree_tolerance, units=units, **curve))
    _check_surface(surface)
    grid = _prepare(heights, spacing)
    kappa = _curvature_kappa(grid, curvature, refraction, earth_radius)
    out, stats = _horizon_angles(grid, azimuths, max_distance, kappa, algorithm=algorithm,
                                 threads=threads, march_step=march_step,
                                 embree_tolerance=embree_tolerance, progress=progress,
                                 tangents=_tangents)
    if units == "degrees" and not _tangents:
        np.degrees(out, out=out)
    grid.voids_to(out, np.nan)
    return returned(np.ascontiguousarray(grid.to_north_up(out)), stats, return_stats)


def _tiled_horizon(heights, azimuths, max_distance, spacing, options):
    """horizon() of a dask array: one tiled map per azimuth, stacked."""
    import dask.array as da

    az = np.atleast_1d(np.asarray(azimuths, dtype=float))
    layers = [tiled_product(lambda b, a=a, **kw: horizon(b, [a], **kw)[0], heights,
                            max_distance, spacing, np.float64, **options) for a in az]
    return da.stack(layers)
